//! `ist_monitor bench gpu`: the GPU backend against the CPU on the Panda and the Kinect cloud,
//! for clouds of 307k to 5M points (larger clouds tile the real one with 1 mm offsets): end to
//! end and kernel time beside the upload floor (the cloud's bytes over the host-to-device
//! bandwidth measured in the same run), each backend's work counters (blocks culled, items,
//! descents, nodes), and the crossover that `gpu_min_points` should be set to. With `--depth`,
//! the clouds are 16UC1 depth images instead (the Kinect cloud's depths, in millimetres, seen by
//! the Kinect's nominal intrinsics): the CPU makes their points and measures them, the GPU
//! takes the image and makes them itself (`Engine::query_depth`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Result};
use nalgebra::Isometry3;
use serde::Serialize;

use ist_monitor::cloud::depth::{DepthView, PinholeCamera};
use ist_monitor::ist::BuildOptions;
use ist_monitor::msg::Image;
use ist_monitor::query::gpu::{GpuOptions, HOST_STEPS};
use ist_monitor::query::{
    Backend, Engine, LinkSelection, Mode, QueryOptions, QueryResult, WorkCounts,
};
use ist_monitor::stats::Spread;

use super::scenes::{load_scenario, ScenarioName};
use crate::choice::choice;
use crate::setup::cached_trees;
use ist_monitor::choice::Choice;

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
    /// Sizes of the crossover sweep (the smallest from which the GPU wins end to end at every
    /// size of the sweep is printed).
    #[arg(long, value_delimiter = ',', default_values_t = [1_000usize, 10_000, 100_000, 307_200, 1_000_000, 2_000_000, 5_000_000])]
    crossover: Vec<usize>,
    #[arg(long, value_parser = choice::<Mode>(), default_value = Mode::Certified.name())]
    mode: Mode,
    /// Timed queries per size and backend (the median is reported).
    #[arg(long, default_value_t = 20, value_parser = crate::args::parse_count)]
    runs: usize,
    /// Tree cache folder (default as for `build`).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// The GPU's portable path: no 64-bit atomics even where the adapter has them (the minima
    /// in 32-bit atomics and an arg-min pass).
    #[arg(long)]
    portable: bool,
    /// The workgroup reductions through workgroup memory even where the adapter has subgroup
    /// operations (to compare the two).
    #[arg(long)]
    no_subgroups: bool,
    /// The measure pass descends each sub-block's eight points as a packet, one stack for the
    /// eight (as the CPU does), instead of each point on its own (to compare the two).
    #[arg(long)]
    packets: bool,
    /// Also time each GPU dispatch on its own (each then in a compute pass of its own, which
    /// adds a little to the end-to-end time) and the host's steps, and print the medians.
    #[arg(long)]
    passes: bool,
    /// Depth images (16UC1) instead of clouds, sizes rounded to whole rows of 640 pixels: the
    /// Kinect cloud's depths, each further copy 1 mm farther; the upload floor is the image's.
    #[arg(long)]
    depth: bool,
}

/// A query's input in the bench: a cloud, or a depth image.
#[derive(Clone, Copy)]
enum Input<'a> {
    Cloud(&'a [[f32; 3]]),
    Depth(&'a DepthView<'a>),
}

impl Input<'_> {
    fn len(&self) -> usize {
        match self {
            Input::Cloud(p) => p.len(),
            Input::Depth(d) => d.len(),
        }
    }

    /// Bytes that cross to the device.
    fn bytes(&self) -> usize {
        match self {
            Input::Cloud(p) => 12 * p.len(),
            Input::Depth(d) => d.data().len(),
        }
    }
}

/// The Kinect's nominal intrinsics (fx = fy = 525 px, principal point at the centre of a
/// 640 × 480 image), for a depth image of `rows` rows.
fn kinect_camera(rows: usize) -> PinholeCamera {
    PinholeCamera {
        width: 640,
        height: rows as u32,
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
    }
}

/// A 16UC1 image of `n / 640` rows: the depths (z, mm) of the organized cloud `base`, row after
/// row, each further copy of it 1 mm farther; no return where the cloud has none.
fn depth_image(base: &[[f32; 3]], n: usize) -> Image<'static> {
    let rows = (n / 640).max(1);
    let data: Vec<u8> = (0..rows * 640)
        .flat_map(|i| {
            let z = base[i % base.len()][2];
            let copy = (i / base.len()) as f32;
            let mm = if z.is_finite() && z > 0.0 {
                (z * 1000.0 + copy).round().min(65535.0) as u16
            } else {
                0
            };
            mm.to_le_bytes()
        })
        .collect();
    Image {
        header: Default::default(),
        height: rows as u32,
        width: 640,
        encoding: "16UC1".into(),
        is_bigendian: 0,
        step: 1280,
        data: data.into(),
    }
}

#[derive(Serialize)]
struct GpuRow {
    points: usize,
    cpu_ms: Spread,
    gpu_end_to_end_ms: Spread,
    gpu_kernel_ms: Option<Spread>,
    /// The cloud's bytes over the measured host-to-device bandwidth.
    upload_floor_ms: f64,
    cpu_over_gpu: f64,
    max_difference_m: f64,
    cpu_work: WorkCounts,
    gpu_work: WorkCounts,
}

/// One backend's timed queries of one cloud.
struct Timed {
    /// End to end, ms.
    wall: Vec<f64>,
    /// The GPU's passes (timestamps), ms.
    kernel: Vec<f64>,
    /// The first query's distance, m.
    distance: f64,
    work: WorkCounts,
    /// With `--passes`: the host's steps and each dispatch, ms.
    steps: Vec<(&'static str, Spread)>,
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
    let options = GpuOptions {
        int64_atomics: !args.portable,
        subgroups: !args.no_subgroups,
        packets: args.packets,
    };
    let Some(gpu) = engine.gpu_with(options) else {
        bail!("no usable GPU adapter");
    };
    gpu.set_profile(args.passes);
    println!(
        "GPU: {}; CPU: {} threads",
        gpu.describe(),
        rayon::current_num_threads()
    );
    let bandwidth = gpu.upload_bandwidth(64 << 20)?;
    println!(
        "host to device: {:.1} GB/s (64 MiB written through the queue, median of 9)",
        bandwidth / 1e9
    );
    let case = &scenario.cases[0];
    // The Kinect cloud is organized (640 wide): a size that is whole rows is queried as one, in
    // tiles on both backends.
    let width = case.width.filter(|&w| w > 0);
    if args.depth && width != Some(640) {
        bail!("--depth: the Kinect cloud is not 640 points wide");
    }
    let mut timer = Timer {
        engine: &mut engine,
        sensor: case.root_from_sensor,
        poses: &case.link_poses,
        width,
        made: Vec::new(),
        mode: args.mode,
    };
    let mut inputs = Inputs {
        base: &case.points,
        depth: args.depth,
        points: Vec::new(),
        image: None,
    };
    let rows = sizes(&args, &mut timer, &mut inputs, bandwidth)?;
    let crossover = sweep(&args, &mut timer, &mut inputs)?;
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

/// The queries of the bench: the engine, at the Kinect case's pose.
struct Timer<'a> {
    engine: &'a mut Engine,
    sensor: Isometry3<f64>,
    poses: &'a [Isometry3<f64>],
    /// The cloud's row width, where it is organized.
    width: Option<usize>,
    /// The points the CPU makes from a depth image.
    made: Vec<[f32; 3]>,
    mode: Mode,
}

impl Timer<'_> {
    fn query(&mut self, input: Input, options: &QueryOptions) -> Result<QueryResult> {
        let (sensor, poses) = (&self.sensor, self.poses);
        Ok(match input {
            Input::Cloud(points) => {
                let width = self.width.filter(|w| points.len().is_multiple_of(*w));
                self.engine
                    .query_image(points, width, sensor, poses, options)?
            }
            // The CPU makes the points (and then measures them); the GPU takes the image.
            Input::Depth(depth) => {
                self.engine
                    .query_depth(depth, &mut self.made, sensor, poses, options)?
            }
        })
    }

    /// `runs` timed queries of `input` on `backend`, after one untimed.
    fn time(&mut self, input: Input, backend: Backend, runs: usize) -> Result<Timed> {
        let options = QueryOptions {
            mode: self.mode,
            backend,
            ..QueryOptions::default()
        };
        let n = input.len();
        // One untimed query: shader compilation, buffer growth, caches.
        let first = self.query(input, &options)?;
        if first.backend != backend {
            bail!(
                "{n} points: the {backend:?} query ran on {:?} (RUST_LOG=debug says why)",
                first.backend
            );
        }
        let work = self.engine.last_work();
        let (mut wall, mut kernel) = (Vec::new(), Vec::new());
        let mut passes: Vec<(&'static str, Vec<f64>)> = Vec::new();
        for _ in 0..runs {
            let start = Instant::now();
            let r = self.query(input, &options)?;
            wall.push(start.elapsed().as_secs_f64() * 1e3);
            if backend == Backend::Gpu {
                if let Some(g) = self.engine.gpu() {
                    kernel.extend(g.last_kernel_s.map(|s| s * 1e3));
                    let host = g.last_host_s;
                    for (name, s) in HOST_STEPS
                        .into_iter()
                        .zip(host)
                        .chain(g.last_passes.iter().copied())
                    {
                        match passes.iter_mut().find(|(n, _)| *n == name) {
                            Some((_, v)) => v.push(s * 1e3),
                            None => passes.push((name, vec![s * 1e3])),
                        }
                    }
                }
            }
            std::hint::black_box(r);
        }
        let d = first.nearest.map_or(f64::INFINITY, |n| n.distance_m);
        let passes = passes
            .into_iter()
            .map(|(n, v)| (n, Spread::of(v)))
            .collect();
        Ok(Timed {
            wall,
            kernel,
            distance: d,
            work,
            steps: passes,
        })
    }
}

/// The inputs of each size: the Kinect cloud tiled with 1 mm offsets, or its depth image.
struct Inputs<'a> {
    base: &'a [[f32; 3]],
    depth: bool,
    points: Vec<[f32; 3]>,
    image: Option<Image<'static>>,
}

impl Inputs<'_> {
    /// Makes the input of `n` points (or pixels); then [`Inputs::view`] and [`Input::of`].
    fn make(&mut self, n: usize) {
        if self.depth {
            self.image = Some(depth_image(self.base, n));
        } else {
            let base = self.base;
            self.points = (0..n)
                .map(|i| {
                    let p = base[i % base.len()];
                    let copy = (i / base.len()) as f32;
                    [p[0], p[1], p[2] + 0.001 * copy]
                })
                .collect();
        }
    }

    /// The depth image's view with the Kinect's intrinsics (`None` for clouds).
    fn view(&self) -> Result<Option<DepthView<'_>>> {
        Ok(match &self.image {
            Some(i) => Some(DepthView::new(i, &kinect_camera(i.height as usize), None)?),
            None => None,
        })
    }
}

impl<'a> Input<'a> {
    /// The cloud, or the depth image's view where there is one.
    fn of(points: &'a [[f32; 3]], view: Option<&'a DepthView<'a>>) -> Self {
        view.map_or(Input::Cloud(points), Input::Depth)
    }
}

/// The table: each of `--sizes` on both backends, with the upload floor at `bandwidth` (B/s).
fn sizes(
    args: &BenchGpuArgs,
    timer: &mut Timer,
    inputs: &mut Inputs,
    bandwidth: f64,
) -> Result<Vec<GpuRow>> {
    let mut rows = Vec::new();
    println!(
        "{:>10} {:>24} {:>24} {:>24} {:>9} {:>8} {:>10}",
        "points",
        "CPU ms [p10, p90]",
        "GPU end-to-end ms",
        "GPU kernel ms",
        "upload ms",
        "CPU/GPU",
        "|Δd| m"
    );
    let show = |t: Spread| format!("{:.3} [{:.3}, {:.3}]", t.median, t.p10, t.p90);
    let work = |w: &WorkCounts| {
        format!(
            "{} of {} blocks culled, {} items, {} descents, {} nodes",
            w.blocks_culled, w.blocks, w.items, w.descents, w.nodes
        )
    };
    for &n in &args.sizes {
        inputs.make(n);
        let view = inputs.view()?;
        let input = Input::of(&inputs.points, view.as_ref());
        let (n, bytes) = (input.len(), input.bytes());
        let cpu = timer.time(input, Backend::Cpu, args.runs)?;
        let gpu = timer.time(input, Backend::Gpu, args.runs)?;
        let (dc, cpu_work) = (cpu.distance, cpu.work);
        let (dg, gpu_work, kernel, passes) = (gpu.distance, gpu.work, gpu.kernel, gpu.steps);
        let (cpu, gpu) = (cpu.wall, gpu.wall);
        let (cpu_ms, gpu_end_to_end_ms) = (Spread::of(cpu), Spread::of(gpu));
        let row = GpuRow {
            points: n,
            cpu_ms,
            gpu_end_to_end_ms,
            gpu_kernel_ms: (!kernel.is_empty()).then(|| Spread::of(kernel)),
            upload_floor_ms: bytes as f64 / bandwidth * 1e3,
            cpu_over_gpu: cpu_ms.median / gpu_end_to_end_ms.median,
            max_difference_m: (dc - dg).abs(),
            cpu_work,
            gpu_work,
        };
        println!(
            "{:>10} {:>24} {:>24} {:>24} {:>9.3} {:>8.2} {:>10.1e}",
            n,
            show(row.cpu_ms),
            show(row.gpu_end_to_end_ms),
            row.gpu_kernel_ms.map_or_else(|| "-".into(), show),
            row.upload_floor_ms,
            row.cpu_over_gpu,
            row.max_difference_m
        );
        println!("{:>10} CPU work: {}", "", work(&row.cpu_work));
        println!("{:>10} GPU work: {}", "", work(&row.gpu_work));
        if !passes.is_empty() {
            let each: Vec<String> = passes
                .iter()
                .map(|(n, t)| format!("{n} {:.1}", t.median * 1e3))
                .collect();
            println!("{:>10} GPU steps, µs: {}", "", each.join(", "));
        }
        rows.push(row);
    }
    Ok(rows)
}

/// The crossover sweep over `--crossover`, and the setting it gives.
///
/// The sweep alternates the two backends in rounds of a quarter of the runs each, so that the
/// machine's drift falls on both alike; the crossover is the smallest size from which the GPU
/// wins at every size of the sweep, not only the first it wins at (at parity the first win is
/// a coin's throw).
fn sweep(args: &BenchGpuArgs, timer: &mut Timer, inputs: &mut Inputs) -> Result<Option<usize>> {
    let (parameter, unit) = if args.depth {
        ("gpu_min_depth_pixels", "pixels")
    } else {
        ("gpu_min_points", "points")
    };
    let mut sweep = Vec::new();
    for &n in &args.crossover {
        inputs.make(n);
        let view = inputs.view()?;
        let input = Input::of(&inputs.points, view.as_ref());
        let n = input.len();
        let (mut cpu, mut gpu) = (Vec::new(), Vec::new());
        let round = args.runs.div_ceil(4);
        while cpu.len() < args.runs {
            cpu.extend(timer.time(input, Backend::Cpu, round)?.wall);
            gpu.extend(timer.time(input, Backend::Gpu, round)?.wall);
        }
        let (c, g) = (Spread::of(cpu).median, Spread::of(gpu).median);
        println!(
            "crossover sweep: {n:>9} {unit}: CPU {c:.3} ms, GPU {g:.3} ms, CPU/GPU {:.2}",
            c / g
        );
        sweep.push((n, g < c));
    }
    let crossover = crossover(&sweep);
    match crossover {
        Some(n) => println!(
            "the GPU wins end to end at every size of the sweep from {n} {unit} on: set {parameter} to {n}"
        ),
        None => println!(
            "the GPU does not win at the sweep's largest size: keep backend auto off the GPU here ({parameter} above it)"
        ),
    }
    Ok(crossover)
}

/// The smallest size of a sweep (`(size, GPU won)`, in ascending size) from which the GPU wins
/// at every size, or `None` where it loses at the largest.
fn crossover(sweep: &[(usize, bool)]) -> Option<usize> {
    let mut sorted = sweep.to_vec();
    sorted.sort_by_key(|&(n, _)| n);
    let losses = sorted.iter().rposition(|&(_, won)| !won);
    let from = losses.map_or(0, |k| k + 1);
    sorted.get(from).map(|&(n, _)| n)
}

#[cfg(test)]
mod tests {
    use super::crossover;

    #[test]
    fn the_crossover_is_where_the_gpu_wins_from_on() {
        let k = 1_000;
        // A win at parity below a loss is not the crossover.
        let level = [
            (k, false),
            (307 * k, true),
            (1_000 * k, false),
            (5_000 * k, true),
        ];
        assert_eq!(crossover(&level), Some(5_000 * k));
        // The sweep's order does not matter.
        let shuffled = [
            (5_000 * k, true),
            (k, false),
            (100 * k, true),
            (307 * k, true),
        ];
        assert_eq!(crossover(&shuffled), Some(100 * k));
        assert_eq!(crossover(&[(k, true), (10 * k, true)]), Some(k));
        assert_eq!(crossover(&[(k, true), (10 * k, false)]), None);
        assert_eq!(crossover(&[]), None);
    }
}
