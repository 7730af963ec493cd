//! Benchmarks: `bench packing` (here), `bench query` (`query.rs`, with its plot in `plot.rs`),
//! `bench gpu` (`gpu.rs`), `bench ssm` (`ssm.rs`, the separation monitor) and `bench monitor`
//! (`monitor.rs`, fusion and the stray-point filter), over the real scenes of `scenes.rs`. Figures are medians with
//! the 10th and 90th percentiles ([`ist_monitor::stats::Spread`]), each beside a floor or a
//! peer measured in the same run.

mod gpu;
mod monitor;
mod plot;
mod query;
pub mod scenes;
mod ssm;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};

use ist_monitor::ist::{self, cache::TreeCache, BuildOptions, Origin, TreeBuilder};
use ist_monitor::robot::RobotModel;
use ist_monitor::stats::Spread;

use crate::cli::RobotArgs;

#[derive(Subcommand)]
pub enum Bench {
    /// Coverage, surface gap and build time against the sphere budget; cache load time; tree
    /// builders compared by the sum of node volumes.
    Packing(BenchPackingArgs),
    /// Error against run time of the query modes over sphere budgets, with the peers, on the
    /// real scenarios of ../shared; prints a table, and with --plot writes PNG plots.
    Query(query::BenchQueryArgs),
    /// The GPU backend against the CPU on the Panda and the Kinect cloud, for clouds of 307k to
    /// 5M points: end-to-end and kernel time, and the crossover for `--backend auto`.
    Gpu(gpu::BenchGpuArgs),
    /// The speed and separation monitor over the generated approach scene: its cost against
    /// the query of the same frames; with --plot, distance, S_p and the factor over time.
    Ssm(ssm::BenchSsmArgs),
    /// What the monitor adds to the query on the real Kinect cloud: the fusion across sources
    /// with the output messages, and the stray-point filter, as ratios to the query.
    Monitor(monitor::BenchMonitorArgs),
}

pub fn run(bench: Bench) -> Result<()> {
    match bench {
        Bench::Packing(args) => packing(args),
        Bench::Query(args) => query::bench_query(args),
        Bench::Gpu(args) => gpu::bench_gpu(args),
        Bench::Ssm(args) => ssm::bench_ssm(args),
        Bench::Monitor(args) => monitor::bench_monitor(args),
    }
}

#[derive(Args)]
pub struct BenchPackingArgs {
    /// The robot (default: the demo arm; the table in docs/benchmarks.md is the Panda of ../shared).
    #[command(flatten)]
    robot: RobotArgs,
    /// Sphere budgets per link to sweep.
    #[arg(long, value_delimiter = ',', default_values_t = [1000u32, 4096, 8192, 16000])]
    budgets: Vec<u32>,
    /// Repetitions of the timed cache load.
    #[arg(long, default_value_t = 20, value_parser = crate::cli::parse_count)]
    runs: usize,
}

fn packing(args: BenchPackingArgs) -> Result<()> {
    if args.budgets.contains(&0) {
        bail!("--budgets: every budget must be at least 1");
    }
    let model = args.robot.load(&Default::default())?;
    println!(
        "robot {} ({} links), {} threads",
        model.name,
        model.links.len(),
        rayon::current_num_threads()
    );
    let dir = tempfile::tempdir().context("creating a temporary cache folder")?;
    for &budget in &args.budgets {
        let mut options = BuildOptions::default();
        options.packing.max_spheres = budget;
        options.packing.start_spheres = budget;
        let cache = TreeCache::new(dir.path().join(budget.to_string()));
        let start = Instant::now();
        let trees = ist::build_robot(&model, &options, Some(&cache), &|_| {})?;
        let wall = start.elapsed().as_secs_f64();
        let worst_cov = trees
            .iter()
            .map(|(t, _)| t.quality.coverage)
            .fold(1.0, f64::min);
        let worst_gap = trees
            .iter()
            .map(|(t, _)| t.quality.gap_m)
            .fold(0.0, f64::max);
        println!(
            "\nbudget {budget}/link: all links built in {wall:.2} s; worst coverage {:.1}%, worst h {:.3} mm",
            100.0 * worst_cov,
            1e3 * worst_gap
        );
        println!(
            "{:<24} {:>8} {:>9} {:>8} {:>9} {:>10}",
            "link", "spheres", "coverage", "h [mm]", "build [s]", "valid. [s]"
        );
        for (t, _) in &trees {
            let q = &t.quality;
            println!(
                "{:<24} {:>8} {:>8.1}% {:>8.3} {:>9.2} {:>10.2}",
                t.link,
                q.spheres,
                100.0 * q.coverage,
                1e3 * q.gap_m,
                q.build_s,
                q.validate_s
            );
        }
        cache_load(&model, &options, &cache, args.runs)?;
        tree_builders(&trees);
    }
    Ok(())
}

/// Cache load against its floor, reading the same files' bytes.
fn cache_load(
    model: &RobotModel,
    options: &BuildOptions,
    cache: &TreeCache,
    runs: usize,
) -> Result<()> {
    let mut load = Vec::new();
    let mut read = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        let loaded = ist::build_robot(model, options, Some(cache), &|_| {})?;
        load.push(t.elapsed().as_secs_f64());
        if loaded.iter().any(|(_, o)| *o != Origin::Cache) {
            bail!("cache miss in the load benchmark");
        }
        let t = Instant::now();
        let mut bytes = 0;
        for link in &model.links {
            let path: PathBuf = cache.path(&ist::cache::key(link, options));
            bytes += std::fs::read(&path)
                .with_context(|| format!("reading {}", path.display()))?
                .len();
        }
        read.push(t.elapsed().as_secs_f64());
        std::hint::black_box(bytes);
    }
    let (l, r) = (Spread::of(load), Spread::of(read));
    println!(
        "cache load (hash meshes, read, verify, decode; {runs} runs): median {:.2} ms [p10 {:.2}, p90 {:.2}]; \
         peer raw file read: {:.2} ms [{:.2}, {:.2}]; ratio {:.1}×",
        1e3 * l.median,
        1e3 * l.p10,
        1e3 * l.p90,
        1e3 * r.median,
        1e3 * r.p10,
        1e3 * r.p90,
        l.median / r.median
    );
    Ok(())
}

/// The two tree builders on the same spheres, by the sum of node volumes.
fn tree_builders(trees: &[(ist::LinkTree, Origin)]) {
    let mut sums = [0.0f64; 2];
    for (t, _) in trees {
        for (k, builder) in [TreeBuilder::NeuralGas, TreeBuilder::MedianSplit]
            .into_iter()
            .enumerate()
        {
            let (nodes, _) = ist::build::build_tree(t.spheres.clone(), builder);
            sums[k] += ist::build::tree_volume(&nodes);
        }
    }
    println!(
        "sum of node volumes over all links: neural gas {:.4} m³, median split {:.4} m³ (ratio {:.3})",
        sums[0],
        sums[1],
        sums[0] / sums[1]
    );
}
