//! `ist_monitor bench gpu`: the GPU backend against the CPU on the Panda and the Kinect cloud,
//! for clouds of 307k to 5M points (larger clouds tile the real one with 1 mm offsets): end to
//! end and kernel time, and the crossover that `gpu_min_points` should be set to.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Result};
use serde::Serialize;

use ist_monitor::ist::BuildOptions;
use ist_monitor::query::{Backend, Engine, LinkSelection, Mode, QueryOptions};
use ist_monitor::stats::Spread;

use super::scenes::{load_scenario, ScenarioName};
use crate::cli::cached_trees;

/// Arguments of `bench gpu`.
#[derive(clap::Args)]
pub struct BenchGpuArgs {
    /// The shared data folder (default: ../shared beside the demo folder, or $IST_MONITOR_SHARED).
    #[arg(long)]
    shared: Option<PathBuf>,
    /// Cloud sizes for the CPU/GPU comparison: the Kinect cloud (307,200 points), tiled with
    /// 1 mm offsets for larger sizes, cut for smaller ones.
    #[arg(long, value_delimiter = ',', default_values_t = [307_200usize, 1_000_000, 5_000_000])]
    sizes: Vec<usize>,
    /// Sizes of the crossover sweep (the smallest at which the GPU wins end to end is printed).
    #[arg(long, value_delimiter = ',', default_values_t = [1_000usize, 3_000, 10_000, 30_000, 100_000, 307_200])]
    crossover: Vec<usize>,
    #[arg(long, value_enum, default_value_t = Mode::Certified)]
    mode: Mode,
    /// Timed queries per size and backend (the median is reported).
    #[arg(long, default_value_t = 20, value_parser = crate::cli::parse_count)]
    runs: usize,
    /// Tree cache folder (default as for `build`).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Serialize)]
struct GpuRow {
    points: usize,
    cpu_ms: Spread,
    gpu_end_to_end_ms: Spread,
    gpu_kernel_ms: Option<Spread>,
    cpu_over_gpu: f64,
    max_difference_m: f64,
}

/// `bench gpu`: the Panda and the Kinect cloud at the `ready` pose on the CPU and the GPU, in
/// one process: end-to-end time (upload, kernels, readback, assembly) and kernel time
/// (timestamp queries, where the adapter has them) against the CPU path on the same machine,
/// for several cloud sizes, and the crossover that `gpu_min_points` should be set to.
pub fn bench_gpu(args: BenchGpuArgs) -> Result<()> {
    let shared = crate::demo::shared(&args.shared)?;
    let scenario = load_scenario(&shared, &crate::demo::dir()?, ScenarioName::Kinect)?;
    let trees = cached_trees(
        &scenario.model,
        &BuildOptions::default(),
        args.cache_dir.as_deref(),
    )?;
    let mut engine = Engine::new(&scenario.model, &trees, &LinkSelection::default())?;
    let Some(gpu) = engine.gpu() else {
        bail!("no usable GPU adapter");
    };
    println!(
        "GPU: {} ({:?}, {:?}); CPU: {} threads",
        gpu.adapter.name,
        gpu.adapter.device_type,
        gpu.adapter.backend,
        rayon::current_num_threads()
    );
    let case = &scenario.cases[0];
    let base = &case.points;
    let cloud = |n: usize| -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let p = base[i % base.len()];
                let copy = (i / base.len()) as f32;
                [p[0], p[1], p[2] + 0.001 * copy]
            })
            .collect()
    };
    let poses = &case.link_poses;
    let sensor = case.root_from_sensor;
    let mut time = |points: &[[f32; 3]], backend: Backend| -> Result<(Vec<f64>, Vec<f64>, f64)> {
        let options = QueryOptions {
            mode: args.mode,
            backend,
            ..QueryOptions::default()
        };
        // One untimed query: shader compilation, buffer growth, caches.
        let first = engine.query(points, &sensor, poses, &options)?;
        let (mut wall, mut kernel) = (Vec::new(), Vec::new());
        for _ in 0..args.runs {
            let start = Instant::now();
            let r = engine.query(points, &sensor, poses, &options)?;
            wall.push(start.elapsed().as_secs_f64() * 1e3);
            if backend == Backend::Gpu {
                if let Some(s) = engine.gpu().and_then(|g| g.last_kernel_s) {
                    kernel.push(s * 1e3);
                }
            }
            std::hint::black_box(r);
        }
        let d = first.nearest.map_or(f64::INFINITY, |n| n.distance_m);
        Ok((wall, kernel, d))
    };
    let mut rows = Vec::new();
    println!(
        "{:>10} {:>24} {:>24} {:>24} {:>8} {:>10}",
        "points", "CPU ms [p10, p90]", "GPU end-to-end ms", "GPU kernel ms", "CPU/GPU", "|Δd| m"
    );
    let show = |t: Spread| format!("{:.3} [{:.3}, {:.3}]", t.median, t.p10, t.p90);
    for &n in &args.sizes {
        let points = cloud(n);
        let (cpu, _, dc) = time(&points, Backend::Cpu)?;
        let (gpu, kernel, dg) = time(&points, Backend::Gpu)?;
        let (cpu_ms, gpu_end_to_end_ms) = (Spread::of(cpu), Spread::of(gpu));
        let row = GpuRow {
            points: n,
            cpu_ms,
            gpu_end_to_end_ms,
            gpu_kernel_ms: (!kernel.is_empty()).then(|| Spread::of(kernel)),
            cpu_over_gpu: cpu_ms.median / gpu_end_to_end_ms.median,
            max_difference_m: (dc - dg).abs(),
        };
        println!(
            "{:>10} {:>24} {:>24} {:>24} {:>8.2} {:>10.1e}",
            n,
            show(row.cpu_ms),
            show(row.gpu_end_to_end_ms),
            row.gpu_kernel_ms.map_or_else(|| "-".into(), show),
            row.cpu_over_gpu,
            row.max_difference_m
        );
        rows.push(row);
    }
    let mut crossover = None;
    for &n in &args.crossover {
        let points = cloud(n);
        let (cpu, _, _) = time(&points, Backend::Cpu)?;
        let (gpu, _, _) = time(&points, Backend::Gpu)?;
        let (c, g) = (Spread::of(cpu).median, Spread::of(gpu).median);
        println!("crossover sweep: {n:>9} points: CPU {c:.3} ms, GPU {g:.3} ms");
        if g < c && crossover.is_none() {
            crossover = Some(n);
        }
    }
    match crossover {
        Some(n) => {
            println!("the GPU wins end to end from about {n} points: set gpu_min_points to {n}")
        }
        None => println!("the GPU never wins end to end here: keep backend auto off this GPU"),
    }
    if let Some(path) = &args.json {
        std::fs::write(
            path,
            serde_json::to_string_pretty(
                &serde_json::json!({"rows": rows, "crossover": crossover}),
            )?,
        )?;
    }
    Ok(())
}
