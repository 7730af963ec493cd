//! `ist_monitor bench query`: error against run time of the query modes over sphere budgets,
//! on real scenarios, with the peers measured in the same run.
//!
//! Scenarios (from `../shared`, read by path):
//! - `kinect`: the Panda and the real Kinect cloud of the MoveIt perception tutorial, at the
//!   joint configurations of its SCENARIO.md and five more reaching toward the table;
//! - `grabber`: the UR5e placed 0.35 m in front of the camera of PCL's three grabber frames
//!   (base 0.3 m below the optical axis, z up), at four configurations reaching toward the
//!   scene (5 to 27 cm from it).
//!
//! For every budget the trees are built (or loaded from the cache) and every mode is timed
//! (median of `runs` queries per pose, pooled over poses) with per-link minima on and off. The
//! peers take every point as an obstacle, so the engine runs here without its self-filter (and
//! with the default region of interest, 2 m, which holds every point of these scenes). The
//! error is taken against the exact distance of peer (a) (parry3d, every point and link, no
//! pruning): `upper − exact` for fast, `exact − lower` for certified (how conservative the
//! certified bound is), `|exact mode − exact|` for exact. The table goes to stdout, the rows to
//! JSON and the plot to a PNG (plotters; DejaVu Sans is read from the system's fonts).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::cli::median_and_spread;
use crate::cloud::{self, Cloud};
use crate::ist::{self, cache::TreeCache, BuildOptions, LinkTree};
use crate::query::{peers, Backend, Engine, LinkSelection, Mode, QueryOptions};
use crate::robot::RobotModel;

/// `../shared` beside the checkout.
pub const SHARED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared");

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ScenarioName {
    Kinect,
    Grabber,
}

#[derive(clap::Args)]
pub struct BenchQueryArgs {
    /// The shared data folder.
    #[arg(long, default_value = SHARED)]
    shared: PathBuf,
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ScenarioName::Kinect, ScenarioName::Grabber])]
    scenarios: Vec<ScenarioName>,
    /// Sphere budgets per link.
    #[arg(long, value_delimiter = ',', default_values_t = [64u32, 256, 1024, 4096, 8192, 16384])]
    budgets: Vec<u32>,
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Mode::Fast, Mode::Certified, Mode::Exact])]
    modes: Vec<Mode>,
    /// Timed queries per pose and setting (the median is reported).
    #[arg(long, default_value_t = 20)]
    runs: usize,
    /// Timed runs of the slow peers (a) and (c) per pose.
    #[arg(long, default_value_t = 3)]
    peer_runs: usize,
    /// Peer (c), brute force over all spheres, only up to this budget (its cost grows with it).
    #[arg(long, default_value_t = 1024)]
    brute_force_max_budget: u32,
    /// Skip the peers (quick profiling of the engine alone; errors then need no reference).
    #[arg(long)]
    no_peers: bool,
    /// Tree cache folder (default as for `build`).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// PNG plot per scenario: PREFIX_<scenario>.png.
    #[arg(long, default_value = "docs/error_vs_time")]
    plot: PathBuf,
    /// Write every row as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Where the engine's queries run (the peers always run on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    backend: Backend,
}

/// Arguments of `bench gpu`.
#[derive(clap::Args)]
pub struct BenchGpuArgs {
    /// The shared data folder.
    #[arg(long, default_value = SHARED)]
    shared: PathBuf,
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
    #[arg(long, default_value_t = 20)]
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
    cpu_ms: (f64, f64, f64),
    gpu_end_to_end_ms: (f64, f64, f64),
    gpu_kernel_ms: Option<(f64, f64, f64)>,
    cpu_over_gpu: f64,
    max_difference_m: f64,
}

/// `bench gpu`: the Panda and the Kinect cloud at the `ready` pose on the CPU and the GPU, in
/// one process: end-to-end time (upload, kernels, readback, assembly) and kernel time
/// (timestamp queries, where the adapter has them) against the CPU path on the same machine,
/// for several cloud sizes, and the crossover that `gpu_min_points` should be set to.
pub fn bench_gpu(args: BenchGpuArgs) -> Result<()> {
    let scenario = load_scenario(&args.shared, ScenarioName::Kinect)?;
    let cache_dir = args
        .cache_dir
        .clone()
        .unwrap_or_else(TreeCache::default_dir);
    let trees = trees(&scenario.model, BuildOptions::default(), &cache_dir)?;
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
    let base = &scenario.clouds[0].1.points;
    let cloud = |n: usize| -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let p = base[i % base.len()];
                let copy = (i / base.len()) as f32;
                [p[0], p[1], p[2] + 0.001 * copy]
            })
            .collect()
    };
    let k = &scenario.model.kinematics;
    let (_, joints) = &scenario.poses[0];
    let poses = k.link_poses(&k.values_from_names(joints, Some(0.0))?);
    let sensor = scenario.root_from_sensor;
    let mut time = |points: &[[f32; 3]], backend: Backend| -> Result<(Vec<f64>, Vec<f64>, f64)> {
        let options = QueryOptions {
            mode: args.mode,
            backend,
            ..QueryOptions::default()
        };
        // One untimed query: shader compilation, buffer growth, caches.
        let first = engine.query(points, &sensor, &poses, &options)?;
        let (mut wall, mut kernel) = (Vec::new(), Vec::new());
        for _ in 0..args.runs {
            let start = Instant::now();
            let r = engine.query(points, &sensor, &poses, &options)?;
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
    let show = |t: (f64, f64, f64)| format!("{:.3} [{:.3}, {:.3}]", t.0, t.1, t.2);
    for &n in &args.sizes {
        let points = cloud(n);
        let (cpu, _, dc) = time(&points, Backend::Cpu)?;
        let (gpu, kernel, dg) = time(&points, Backend::Gpu)?;
        let (cpu_ms, gpu_end_to_end_ms) = (median_and_spread(cpu), median_and_spread(gpu));
        let row = GpuRow {
            points: n,
            cpu_ms,
            gpu_end_to_end_ms,
            gpu_kernel_ms: (!kernel.is_empty()).then(|| median_and_spread(kernel)),
            cpu_over_gpu: cpu_ms.0 / gpu_end_to_end_ms.0,
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
        let (c, g) = (median_and_spread(cpu).0, median_and_spread(gpu).0);
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

/// A robot, a cloud and the poses to query.
pub struct Scenario {
    pub name: ScenarioName,
    pub model: RobotModel,
    pub clouds: Vec<(String, Cloud)>,
    pub root_from_sensor: Isometry3<f64>,
    /// (name, joint values by name).
    pub poses: Vec<(String, Vec<(String, f64)>)>,
}

/// The Kinect camera of the perception tutorial: `static_transform_publisher 0.115 0.427 0.570
/// 0 0.2 1.92 camera_rgb_optical_frame world`, i.e. `p_cam = R·p_world + t` with
/// `R = Rz(0)·Ry(0.2)·Rx(1.92)`; the robot root (`panda_link0`) is `world`.
pub fn kinect_root_from_sensor() -> Isometry3<f64> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.0)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.92);
    let camera_from_world = Isometry3::from_parts(Translation3::new(0.115, 0.427, 0.570), r);
    camera_from_world.inverse()
}

/// The Panda configurations of the Kinect scenario: SCENARIO.md's (its 1.5708, not π/2), then
/// five of ours in which the hand comes 7 to 50 mm from the table.
#[allow(clippy::approx_constant)]
pub fn kinect_poses() -> Vec<(String, Vec<(String, f64)>)> {
    let arm = |name: &str, q: [f64; 7], finger: f64| {
        let mut v: Vec<(String, f64)> = q
            .iter()
            .enumerate()
            .map(|(i, &x)| (format!("panda_joint{}", i + 1), x))
            .collect();
        v.push(("panda_finger_joint1".into(), finger));
        (name.to_string(), v)
    };
    vec![
        arm("ready", [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], 0.0),
        arm("extended", [0.0, 0.0, 0.0, 0.0, 0.0, 1.571, 0.785], 0.0),
        arm("zeros", [0.0; 7], 0.0),
        arm(
            "ready_j1_90",
            [1.5708, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
            0.0,
        ),
        arm(
            "reach_table",
            [1.5708, 0.5, 0.0, -2.0, 0.0, 2.5, 0.785],
            0.04,
        ),
        arm("reach_far", [1.5708, 0.7, 0.0, -1.6, 0.0, 2.4, 0.785], 0.02),
        arm("reach_low", [1.3, 0.9, 0.0, -1.3, 0.0, 2.3, 0.785], 0.02),
        arm("reach_side", [1.0, 0.6, 0.4, -1.9, 0.0, 2.6, 0.785], 0.02),
        arm("reach_out", [1.5708, 1.0, 0.0, -1.0, 0.0, 2.0, 0.785], 0.02),
        arm("near_contact", [1.4, 0.2, 0.0, -2.6, 0.0, 2.9, 0.0], 0.02),
    ]
}

/// The UR5e 0.35 m in front of the grabber camera, 0.3 m below its axis, z up, x along the
/// optical axis.
pub fn grabber_root_from_sensor() -> Isometry3<f64> {
    // Root axes in the camera frame (x right, y down, z forward): x_root = z_cam,
    // y_root = −x_cam, z_root = −y_cam.
    let m = Matrix3::from_columns(&[
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(-1.0, 0.0, 0.0),
        Vector3::new(0.0, -1.0, 0.0),
    ]);
    let sensor_from_root = Isometry3::from_parts(
        Translation3::new(0.0, 0.3, 0.35),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
    );
    sensor_from_root.inverse()
}

pub fn grabber_poses() -> Vec<(String, Vec<(String, f64)>)> {
    let names = [
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ];
    let arm = |name: &str, q: [f64; 6]| {
        (
            name.to_string(),
            names
                .iter()
                .zip(q)
                .map(|(n, v)| (n.to_string(), v))
                .collect(),
        )
    };
    vec![
        arm("home", [0.0, -1.571, 0.0, -1.571, 0.0, 0.0]),
        arm("reach_forward", [0.0, -1.2, 0.6, -1.2, -1.571, 0.0]),
        arm("reach_near", [0.0, -1.0, 0.9, -1.5, -1.571, 0.0]),
        arm("reach_left", [0.5, -1.3, 1.2, -1.5, -1.571, 0.0]),
    ]
}

pub fn load_scenario(shared: &Path, name: ScenarioName) -> Result<Scenario> {
    Ok(match name {
        ScenarioName::Kinect => {
            let bag = shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap");
            Scenario {
                name,
                model: RobotModel::load(&shared.join("robots/panda/robot.urdf"), &[])?,
                clouds: vec![("kinect".into(), cloud::load(&bag, 0)?)],
                root_from_sensor: kinect_root_from_sensor(),
                poses: kinect_poses(),
            }
        }
        ScenarioName::Grabber => {
            let dir = shared.join("clouds/pcl_test/grabber_sequences");
            let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
                .with_context(|| format!("reading {}", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "pcd"))
                .collect();
            files.sort();
            let clouds = files
                .iter()
                .map(|f| {
                    Ok((
                        f.file_stem().unwrap().to_string_lossy().into_owned(),
                        cloud::load(f, 0)?,
                    ))
                })
                .collect::<Result<Vec<_>>>()?;
            Scenario {
                name,
                model: RobotModel::load(&shared.join("robots/ur5e/robot.urdf"), &[])?,
                clouds,
                root_from_sensor: grabber_root_from_sensor(),
                poses: grabber_poses(),
            }
        }
    })
}

/// One line of the table.
#[derive(Debug, Clone, Serialize)]
struct Row {
    scenario: ScenarioName,
    /// "fast", "certified", "exact", or a peer.
    method: String,
    per_link: bool,
    budget: Option<u32>,
    median_ms: f64,
    p10_ms: f64,
    p90_ms: f64,
    /// Against the exact reference, over poses (None without peers).
    max_error_mm: Option<f64>,
    mean_error_mm: Option<f64>,
    runs: usize,
}

fn time<T>(runs: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, T) {
    let mut out = f();
    let mut samples = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t = Instant::now();
        out = std::hint::black_box(f());
        samples.push(t.elapsed().as_secs_f64() * 1e3);
    }
    (samples, out)
}

fn row(
    scenario: ScenarioName,
    method: &str,
    per_link: bool,
    budget: Option<u32>,
    samples: Vec<f64>,
    errors: &[f64],
) -> Row {
    let runs = samples.len();
    let (m, lo, hi) = median_and_spread(samples);
    Row {
        scenario,
        method: method.into(),
        per_link,
        budget,
        median_ms: m,
        p10_ms: lo,
        p90_ms: hi,
        max_error_mm: (!errors.is_empty()).then(|| errors.iter().fold(0.0, |a: f64, &b| a.max(b))),
        mean_error_mm: (!errors.is_empty())
            .then(|| errors.iter().sum::<f64>() / errors.len() as f64),
        runs,
    }
}

pub fn bench_query(args: BenchQueryArgs) -> Result<()> {
    if args.runs == 0 || args.peer_runs == 0 {
        bail!("--runs and --peer-runs must be at least 1");
    }
    println!(
        "bench query: {} threads, {} runs per pose and setting, {} per slow peer",
        rayon::current_num_threads(),
        args.runs,
        args.peer_runs
    );
    let cache_dir = args
        .cache_dir
        .clone()
        .unwrap_or_else(TreeCache::default_dir);
    let mut rows = Vec::new();
    for &name in &args.scenarios {
        let scenario = load_scenario(&args.shared, name)?;
        let k = &scenario.model.kinematics;
        let poses: Vec<(String, Vec<_>)> = scenario
            .poses
            .iter()
            .map(|(n, j)| Ok((n.clone(), k.link_poses(&k.values_from_names(j, Some(0.0))?))))
            .collect::<Result<_>>()?;
        let valid: usize = scenario.clouds[0]
            .1
            .points
            .iter()
            .filter(|p| crate::query::is_valid_point(**p))
            .count();
        println!(
            "\n== {name:?}: {} ({} links), {} cloud(s) of {} points ({valid} valid in the first), {} poses",
            scenario.model.name,
            scenario.model.links.len(),
            scenario.clouds.len(),
            scenario.clouds[0].1.points.len(),
            poses.len()
        );
        let cases: Vec<(&str, &Cloud, &str, &[Isometry3<f64>])> = scenario
            .clouds
            .iter()
            .flat_map(|(cn, c)| {
                poses
                    .iter()
                    .map(move |(pn, p)| (cn.as_str(), c, pn.as_str(), p.as_slice()))
            })
            .collect();
        let mut scenario_rows = Vec::new();
        // The floor and the exact peers do not depend on the budget: measured with the
        // default trees (peer (b) uses only the meshes).
        let default_trees = trees(&scenario.model, BuildOptions::default(), &cache_dir)?;
        let engine = Engine::new(&scenario.model, &default_trees, &LinkSelection::default())?;
        let mut floor = Vec::new();
        for (_, cloud, _, _) in &cases {
            floor.extend(time(args.runs, || peers::touch_every_point(&cloud.points)).0);
        }
        scenario_rows.push(row(
            name,
            "floor (touch every point)",
            false,
            None,
            floor,
            &[],
        ));
        let mut reference = Vec::new();
        if !args.no_peers {
            let (mut ta, mut tb) = (Vec::new(), Vec::new());
            for (cn, cloud, pn, lp) in &cases {
                let (s, a) = time(args.peer_runs, || {
                    peers::exact_every_point(&engine, &cloud.points, &scenario.root_from_sensor, lp)
                });
                ta.extend(s);
                let (s, b) = time(args.runs, || {
                    peers::exact_shared_bound(
                        &engine,
                        &cloud.points,
                        &scenario.root_from_sensor,
                        lp,
                    )
                });
                tb.extend(s);
                let a = a.context("no valid point")?;
                let b = b.context("no valid point")?;
                println!(
                    "  {cn} {pn}: exact {:.4} m on {} (point {}); peer (b) {:.4} m",
                    a.distance,
                    engine.links()[a.link].name,
                    a.point,
                    b.distance
                );
                if (a.distance - b.distance).abs() > 1e-5 {
                    bail!(
                        "peer (b) {} differs from peer (a) {}",
                        b.distance,
                        a.distance
                    );
                }
                reference.push(a.distance as f64);
            }
            scenario_rows.push(row(
                name,
                "(a) parry exact, every point",
                false,
                None,
                ta,
                &[],
            ));
            scenario_rows.push(row(
                name,
                "(b) parry exact, shared bound",
                false,
                None,
                tb,
                &[],
            ));
        }
        for &budget in &args.budgets {
            let mut options = BuildOptions::default();
            options.packing.max_spheres = budget;
            let trees = trees(&scenario.model, options, &cache_dir)?;
            let mut engine = Engine::new(&scenario.model, &trees, &LinkSelection::default())?;
            for &mode in &args.modes {
                for per_link in [false, true] {
                    let options = QueryOptions {
                        mode,
                        per_link,
                        self_filter_padding_m: None,
                        backend: args.backend,
                        ..QueryOptions::default()
                    };
                    let mut samples = Vec::new();
                    let mut errors = Vec::new();
                    for (c, (_, cloud, _, lp)) in cases.iter().enumerate() {
                        let (s, r) = time(args.runs, || {
                            engine.query(&cloud.points, &scenario.root_from_sensor, lp, &options)
                        });
                        samples.extend(s);
                        let r = r?;
                        let n = r.nearest.context("no nearest point")?;
                        if let Some(&exact) = reference.get(c) {
                            let e = match mode {
                                Mode::Fast => n.distance_m - exact,
                                Mode::Certified => exact - n.lower_m.unwrap_or(0.0),
                                Mode::Exact => (n.distance_m - exact).abs(),
                            };
                            errors.push(1e3 * e);
                        }
                    }
                    scenario_rows.push(row(
                        name,
                        &format!("{mode:?}").to_lowercase(),
                        per_link,
                        Some(budget),
                        samples,
                        &errors,
                    ));
                }
            }
            if !args.no_peers && budget <= args.brute_force_max_budget {
                let mut samples = Vec::new();
                let mut errors = Vec::new();
                for (c, (_, cloud, _, lp)) in cases.iter().enumerate() {
                    let (s, r) = time(args.peer_runs, || {
                        peers::brute_force_spheres(
                            &engine,
                            &cloud.points,
                            &scenario.root_from_sensor,
                            lp,
                        )
                    });
                    samples.extend(s);
                    let r = r.context("no valid point")?;
                    errors.push(1e3 * (r.distance as f64 - reference[c]));
                }
                scenario_rows.push(row(
                    name,
                    "(c) brute force, all spheres",
                    false,
                    Some(budget),
                    samples,
                    &errors,
                ));
            }
        }
        print_table(&scenario_rows);
        let path = PathBuf::from(format!(
            "{}_{}.png",
            args.plot.display(),
            format!("{name:?}").to_lowercase()
        ));
        match plot(&path, name, &scenario_rows) {
            Ok(()) => println!("plot: {}", path.display()),
            Err(e) => eprintln!("warning: no plot written: {e:#}"),
        }
        rows.extend(scenario_rows);
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn trees(model: &RobotModel, options: BuildOptions, cache_dir: &Path) -> Result<Vec<LinkTree>> {
    let cache = TreeCache::new(cache_dir.to_owned());
    Ok(ist::build_robot(model, &options, Some(&cache), &|_| {})?
        .into_iter()
        .map(|(t, _)| t)
        .collect())
}

fn print_table(rows: &[Row]) {
    let floor = rows
        .iter()
        .find(|r| r.method.starts_with("floor"))
        .map(|r| r.median_ms);
    println!(
        "{:<32} {:>8} {:>6} {:>10} {:>17} {:>8} {:>13} {:>13}",
        "method",
        "per-link",
        "budget",
        "median ms",
        "[p10, p90] ms",
        "× floor",
        "max err mm",
        "mean err mm"
    );
    for r in rows {
        let f = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
        println!(
            "{:<32} {:>8} {:>6} {:>10.3} {:>17} {:>8.1} {:>13} {:>13}",
            r.method,
            if r.per_link { "yes" } else { "no" },
            r.budget
                .map(|b| b.to_string())
                .unwrap_or_else(|| "-".into()),
            r.median_ms,
            format!("[{:.3}, {:.3}]", r.p10_ms, r.p90_ms),
            floor.map_or(f64::NAN, |f| r.median_ms / f),
            f(r.max_error_mm),
            f(r.mean_error_mm)
        );
    }
}

/// Errors below this are drawn on the axis (log scale).
const ERROR_FLOOR_MM: f64 = 1e-4;

fn plot(path: &Path, name: ScenarioName, rows: &[Row]) -> Result<()> {
    use plotters::prelude::*;
    let font = ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"]
        .iter()
        .find_map(|p| std::fs::read(p).ok())
        .context("DejaVuSans.ttf not found (install fonts-dejavu-core)")?;
    let font: &'static [u8] = Box::leak(font.into_boxed_slice());
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, font);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).ok();
    }
    let pts: Vec<&Row> = rows.iter().filter(|r| r.max_error_mm.is_some()).collect();
    if pts.is_empty() {
        bail!("no errors measured (run with the peers)");
    }
    let xs = rows.iter().map(|r| r.median_ms);
    let (xmin, xmax) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    let ymax = pts
        .iter()
        .filter_map(|r| r.max_error_mm)
        .fold(ERROR_FLOOR_MM, f64::max);
    let root = BitMapBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{name:?}: error against query time (max over poses)"),
            ("sans-serif", 24),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (xmin * 0.7..xmax * 4.0).log_scale(),
            (ERROR_FLOOR_MM * 0.7..ymax * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("query time per cloud, ms (median)")
        .y_desc("error against exact distance, mm (below 1e-4 drawn at 1e-4)")
        .draw()?;
    let styles: [(&str, bool, RGBColor); 6] = [
        ("fast", false, RGBColor(31, 119, 180)),
        ("certified", false, RGBColor(255, 127, 14)),
        ("exact", false, RGBColor(44, 160, 44)),
        ("fast", true, RGBColor(120, 170, 220)),
        ("certified", true, RGBColor(255, 187, 120)),
        ("exact", true, RGBColor(152, 223, 138)),
    ];
    for (method, per_link, color) in styles {
        let series: Vec<(f64, f64, u32)> = pts
            .iter()
            .filter(|r| r.method == method && r.per_link == per_link)
            .map(|r| {
                (
                    r.median_ms,
                    r.max_error_mm.unwrap().max(ERROR_FLOOR_MM),
                    r.budget.unwrap_or(0),
                )
            })
            .collect();
        if series.is_empty() {
            continue;
        }
        let label = format!(
            "{method}{}",
            if per_link {
                ", per-link minima"
            } else {
                ", global minimum"
            }
        );
        chart
            .draw_series(LineSeries::new(
                series.iter().map(|&(x, y, _)| (x, y)),
                color.stroke_width(2),
            ))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(series.iter().map(|&(x, y, b)| {
            EmptyElement::at((x, y))
                + Circle::new((0, 0), 4, color.filled())
                + Text::new(b.to_string(), (6, -14), ("sans-serif", 12))
        }))?;
    }
    for r in rows
        .iter()
        .filter(|r| r.method.starts_with('(') || r.method.starts_with("floor"))
    {
        let y = r.max_error_mm.unwrap_or(ERROR_FLOOR_MM).max(ERROR_FLOOR_MM);
        let label = match r.budget {
            Some(b) => format!("{} {b}", &r.method[..3]),
            None => r.method.clone(),
        };
        chart.draw_series(std::iter::once(
            EmptyElement::at((r.median_ms, y))
                + TriangleMarker::new((0, 0), 6, BLACK.filled())
                + Text::new(label, (6, 4), ("sans-serif", 12)),
        ))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
