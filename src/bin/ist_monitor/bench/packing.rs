//! `ist_monitor bench packing`: per sphere budget, the build of every link (coverage, surface
//! gap h, build and validation time), the cache load against the raw read of the same files,
//! and the two tree builders compared by the sum of their node volumes (m³).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::ist::{self, cache::TreeCache, BuildOptions, Origin, TreeBuilder};
use ist_monitor::robot::RobotModel;
use ist_monitor::stats::Spread;

use crate::args::RobotArgs;

#[derive(Args)]
pub struct BenchPackingArgs {
    /// The robot (default: the demo arm; the table in docs/benchmarks.md is the Panda of ../shared).
    #[command(flatten)]
    robot: RobotArgs,
    /// Sphere budgets per link to sweep.
    #[arg(long, value_delimiter = ',', default_values_t = [1000u32, 4096, 8192, 16000])]
    budgets: Vec<u32>,
    /// Repetitions of the timed cache load.
    #[arg(long, default_value_t = 20, value_parser = crate::args::parse_count)]
    runs: usize,
}

pub fn packing(args: BenchPackingArgs) -> Result<()> {
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
        if loaded.iter().any(|(_, o)| *o == Origin::Built) {
            bail!("cache miss in the load benchmark");
        }
        let t = Instant::now();
        let mut bytes = 0;
        // Each solid's file once, as the load reads them.
        let mut keys: Vec<[u8; 32]> = (model.links.iter())
            .map(|link| ist::cache::key(link, options))
            .collect();
        keys.sort_unstable();
        keys.dedup();
        for key in &keys {
            let path: PathBuf = cache.path(key);
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
