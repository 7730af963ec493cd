//! Command line: `build` (trees, quality table, cache, export), `poses` (forward kinematics),
//! `query` (one cloud against the posed robot), `replay` (a bag through the monitor), `node`
//! (the live ROS 2 node), `play` and `record` (DDS bag tools), `generate` (scenario bags),
//! `params` (the parameter table), and `bench packing`, `bench query` and `bench gpu` (in
//! `crate::bench`).
//! Every option is defined once here and validated into the library's typed options.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use serde::Serialize;

use crate::bag::{replay, writer::Compression};
use crate::cloud;
use crate::config::Config;
use crate::ist::cache::TreeCache;
use crate::ist::{self, validate::validate_link, BuildOptions, LinkTree, Origin, TreeBuilder};
use crate::monitor::Monitor;
use crate::packing::PackingParams;
use crate::query::{Backend, Engine, LinkSelection, Mode, Outcome, QueryOptions};
use crate::robot::{PackagePath, RobotModel};
use crate::scenario::{self, ScenarioParams, SceneKind};

/// The demo robot shipped in `urdf/`, the default of every command.
pub const DEMO_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/urdf/demo_arm.urdf");

#[derive(Parser)]
#[command(
    name = "ist_monitor",
    version,
    about = "Robot-to-point-cloud distance with inner sphere trees"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Pack every link with inner spheres, build the trees and print their quality.
    Build(BuildArgs),
    /// Print the pose of every link in the root frame for given joint values.
    Poses(PosesArgs),
    /// Minimum distance between the posed robot and one point cloud.
    Query(QueryArgs),
    /// Replay a rosbag2 MCAP bag through the monitor: one line per cloud and a summary.
    Replay(ReplayArgs),
    /// Run the live ROS 2 node.
    Node(NodeArgs),
    /// Publish a bag's clouds, joint states and transforms on DDS at their recorded pace.
    Play(PlayArgs),
    /// Record the node's outputs from DDS into an MCAP.
    Record(RecordArgs),
    /// Print the node's parameters (name, default, unit, meaning) as a Markdown table.
    Params,
    /// Make a bag: a simulated depth camera watching the robot and an obstacle, with the exact
    /// minimum distance of every frame.
    Generate(GenerateArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(Bench),
}

#[derive(Args)]
struct NodeArgs {
    /// ROS 2 parameters file (default: config/demo_arm.yaml).
    #[arg(long, default_value = DEMO_CONFIG)]
    config: PathBuf,
    /// `--ros-args -r __node:=NAME -r __ns:=/NS -p NAME:=VALUE ...`
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    ros_args: Vec<String>,
}

#[derive(Args)]
struct PlayArgs {
    /// Bag: a .mcap file or a rosbag2 folder (default: the bundled demo bag).
    #[arg(default_value = DEMO_BAG)]
    bag: PathBuf,
    /// Playback rate (1 = recorded pace).
    #[arg(long, default_value_t = 1.0)]
    rate: f64,
    /// How many times to play the bag (stamps are shifted to now at each start).
    #[arg(long, default_value_t = 1)]
    loops: usize,
    /// Seconds to wait for discovery before the first message.
    #[arg(long, default_value_t = 1.5)]
    wait: f64,
    /// Measure the node: match its outputs on this JointState topic (e.g.
    /// /ist_monitor/link_distances) to the clouds, and report rate and latency.
    #[arg(long)]
    measure: Option<String>,
    /// Seconds to wait for outputs after the last message.
    #[arg(long, default_value_t = 0.5)]
    linger: f64,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct RecordArgs {
    /// Output MCAP (.mcap file, or a rosbag2 folder).
    #[arg(long)]
    out: PathBuf,
    /// The node whose outputs to record.
    #[arg(long, default_value = "/ist_monitor")]
    node: String,
    /// Seconds to record.
    #[arg(long, default_value_t = 10.0)]
    duration: f64,
}

#[derive(Args)]
struct GenerateArgs {
    #[command(flatten)]
    robot: RobotArgs,
    /// Output: a rosbag2 folder (or a .mcap file); it must not exist yet.
    #[arg(long)]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = SceneKind::Person)]
    scene: SceneKind,
    #[arg(long, default_value_t = ScenarioParams::default().frames)]
    frames: usize,
    #[arg(long, default_value_t = ScenarioParams::default().width)]
    width: u32,
    #[arg(long, default_value_t = ScenarioParams::default().height)]
    height: u32,
    /// Range noise σ, m (clipped at 2.5 σ).
    #[arg(long, default_value_t = ScenarioParams::default().noise_m)]
    noise: f64,
    /// Fraction of pixels dropped (NaN holes).
    #[arg(long, default_value_t = ScenarioParams::default().holes)]
    holes: f64,
    #[arg(long, default_value_t = ScenarioParams::default().seed)]
    seed: u64,
    #[arg(long, value_enum, default_value_t = Compression::Zstd)]
    compression: Compression,
    /// Bytes per point: 16 (x y z) or 32 (x y z, rgb), as RGB-D drivers publish.
    #[arg(long, default_value_t = 16)]
    point_step: u32,
}

/// The bundled demo bag and its config, the defaults of `replay`.
pub const DEMO_BAG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/demo");
pub const DEMO_CONFIG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/demo_arm.yaml");

#[derive(Args)]
pub(crate) struct ReplayArgs {
    /// Bag: a .mcap file or a rosbag2 folder (default: the bundled demo bag).
    #[arg(default_value = DEMO_BAG)]
    bag: PathBuf,
    /// ROS 2 parameters file (default: config/demo_arm.yaml).
    #[arg(long, default_value = DEMO_CONFIG)]
    config: PathBuf,
    /// Override a parameter, NAME:=VALUE (value in YAML); repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME:=VALUE", value_parser = crate::config::parse_override)]
    params: Vec<(String, String)>,
    /// Write the node's outputs to this MCAP (`.mcap` file, or a rosbag2 folder otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Chunk compression of --out.
    #[arg(long, value_enum, default_value_t = Compression::Zstd)]
    out_compression: Compression,
    /// Where the queries run (overrides the config's `backend`): cpu, gpu or auto.
    #[arg(long, value_enum)]
    backend: Option<Backend>,
    /// Print the frames and the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub(crate) struct RobotArgs {
    /// URDF file (default: the demo robot in urdf/).
    #[arg(long, default_value = DEMO_URDF)]
    pub(crate) urdf: PathBuf,
    /// Where package://NAME is found; repeatable.
    #[arg(long = "package-path", value_name = "NAME=DIR")]
    pub(crate) package_paths: Vec<PackagePath>,
}

impl RobotArgs {
    pub(crate) fn load(&self) -> Result<RobotModel> {
        RobotModel::load(&self.urdf, &self.package_paths)
            .with_context(|| format!("loading robot {}", self.urdf.display()))
    }
}

#[derive(Args)]
struct PackingArgs {
    /// Sphere budget per link.
    #[arg(long, default_value_t = PackingParams::default().max_spheres)]
    max_spheres: u32,
    /// Smallest sphere radius, m.
    #[arg(long, default_value_t = PackingParams::default().min_radius_m)]
    min_radius: f32,
    /// Stop packing a link at this volume coverage (0..1].
    #[arg(long, default_value_t = PackingParams::default().target_coverage)]
    target_coverage: f64,
    /// Prototypes of the first grid per collision element.
    #[arg(long, default_value_t = PackingParams::default().prototypes)]
    prototypes: u32,
    /// The gap pass fills pockets under the surface until every sample is this close to the spheres, m.
    #[arg(long, default_value_t = PackingParams::default().target_gap_m)]
    target_gap: f32,
    /// Hierarchy build.
    #[arg(long, value_enum, default_value_t = BuildOptions::default().tree)]
    tree: TreeBuilder,
}

impl PackingArgs {
    fn options(&self) -> Result<BuildOptions> {
        if self.max_spheres == 0 {
            bail!("--max-spheres must be at least 1");
        }
        if !(self.min_radius > 0.0 && self.min_radius.is_finite()) {
            bail!("--min-radius must be a positive number of metres");
        }
        if !(self.target_coverage > 0.0 && self.target_coverage <= 1.0) {
            bail!("--target-coverage must lie in (0, 1]");
        }
        if self.prototypes == 0 {
            bail!("--prototypes must be at least 1");
        }
        if !(self.target_gap > 0.0 && self.target_gap.is_finite()) {
            bail!("--target-gap must be a positive number of metres");
        }
        Ok(BuildOptions {
            packing: PackingParams {
                max_spheres: self.max_spheres,
                min_radius_m: self.min_radius,
                target_coverage: self.target_coverage,
                prototypes: self.prototypes,
                target_gap_m: self.target_gap,
                ..PackingParams::default()
            },
            tree: self.tree,
            ..BuildOptions::default()
        })
    }
}

#[derive(Args)]
struct BuildArgs {
    #[command(flatten)]
    robot: RobotArgs,
    #[command(flatten)]
    packing: PackingArgs,
    /// Cache folder (default: $IST_MONITOR_CACHE, $XDG_CACHE_HOME/ist_monitor or ~/.cache/ist_monitor).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Build everything anew and store nothing.
    #[arg(long)]
    no_cache: bool,
    /// Print the table as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Write {"<link>": [[x, y, z, r], ...]} (link frames, metres) to this file.
    #[arg(long, value_name = "FILE")]
    export_spheres: Option<PathBuf>,
    /// Check every sphere and node against the meshes (exact, in f64).
    #[arg(long)]
    validate: bool,
}

#[derive(Args)]
struct PosesArgs {
    #[command(flatten)]
    robot: RobotArgs,
    /// Joint values, NAME=VALUE,... (radians or metres); joints not named are 0.
    #[arg(long, value_delimiter = ',', value_parser = parse_joint)]
    joints: Vec<(String, f64)>,
}

#[derive(Subcommand)]
enum Bench {
    /// Coverage, surface gap and build time against the sphere budget; cache load time; tree
    /// builders compared by the sum of node volumes.
    Packing(BenchPackingArgs),
    /// Error against run time of the query modes over sphere budgets, with the peers, on the
    /// real scenarios of ../shared; prints a table and writes a PNG plot.
    Query(crate::bench::BenchQueryArgs),
    /// The GPU backend against the CPU on the Panda and the Kinect cloud, for clouds of 307k to
    /// 5M points: end-to-end and kernel time, and the crossover for `--backend auto`.
    Gpu(crate::bench::BenchGpuArgs),
}

#[derive(Args)]
pub(crate) struct QueryArgs {
    #[command(flatten)]
    robot: RobotArgs,
    #[command(flatten)]
    packing: PackingArgs,
    /// Cache folder of the trees (default as for `build`).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Joint values, NAME=VALUE,... (radians or metres); joints not named are 0.
    #[arg(long, value_delimiter = ',', value_parser = parse_joint)]
    joints: Vec<(String, f64)>,
    /// Cloud: .pcd (ascii, binary, binary_compressed), .ply, or a rosbag2 bag (.mcap or folder).
    #[arg(long)]
    cloud: PathBuf,
    /// Which PointCloud2 message of a bag (0 first).
    #[arg(long, default_value_t = 0)]
    msg: usize,
    /// Pose of the cloud's frame in the robot's root link frame: "x y z qx qy qz qw".
    #[arg(long, value_parser = parse_pose, default_value = "0 0 0 0 0 0 1")]
    sensor_pose: nalgebra::Isometry3<f64>,
    #[arg(long, value_enum, default_value_t = Mode::Fast)]
    mode: Mode,
    /// Drop points farther than this from the robot's bounding box, m (inf keeps all).
    #[arg(long, default_value_t = QueryOptions::default().max_distance_m)]
    max_distance: f32,
    /// Self-filter padding, m: points this close to the robot are the robot itself.
    #[arg(long, default_value_t = QueryOptions::default().self_filter_padding_m.unwrap_or(0.0))]
    self_filter_padding: f32,
    /// Take every point as an obstacle, even on the robot.
    #[arg(long)]
    no_self_filter: bool,
    /// Only the global minimum (one shared bound; faster).
    #[arg(long)]
    no_per_link: bool,
    /// Only these links (comma separated).
    #[arg(long, value_delimiter = ',')]
    links: Vec<String>,
    /// Leave these links out (comma separated).
    #[arg(long, value_delimiter = ',')]
    exclude_links: Vec<String>,
    #[command(flatten)]
    backend: BackendArgs,
    /// Print the result object as JSON.
    #[arg(long)]
    json: bool,
}

/// Where queries run.
#[derive(Args, Clone, Copy)]
pub(crate) struct BackendArgs {
    /// cpu, gpu, or auto (the GPU from --gpu-min-points points on, on a hardware GPU).
    #[arg(long, value_enum, default_value_t = QueryOptions::default().backend)]
    pub(crate) backend: Backend,
    /// Crossover of --backend auto, in points.
    #[arg(long, default_value_t = QueryOptions::default().gpu_min_points)]
    pub(crate) gpu_min_points: usize,
}

/// Parses "x y z qx qy qz qw" (the quaternion is normalized; it must not be zero).
pub(crate) fn parse_pose(s: &str) -> Result<nalgebra::Isometry3<f64>, String> {
    let v: Vec<f64> = s
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|w| !w.is_empty())
        .map(|w| w.parse::<f64>().map_err(|e| format!("'{w}': {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() != 7 || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "expected 7 finite numbers \"x y z qx qy qz qw\", got '{s}'"
        ));
    }
    let q = nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]);
    if q.norm() < 1e-9 {
        return Err("the quaternion is zero".into());
    }
    Ok(nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(v[0], v[1], v[2]),
        nalgebra::UnitQuaternion::from_quaternion(q),
    ))
}

#[derive(Args)]
struct BenchPackingArgs {
    #[command(flatten)]
    robot: RobotArgs,
    /// Sphere budgets per link to sweep.
    #[arg(long, value_delimiter = ',', default_values_t = [1000u32, 4000, 16000])]
    budgets: Vec<u32>,
    /// Repetitions of the timed cache load.
    #[arg(long, default_value_t = 20)]
    runs: usize,
}

fn parse_joint(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME=VALUE, got '{s}'"))?;
    let value: f64 = value
        .parse()
        .map_err(|e| format!("joint {name}: '{value}' is not a number: {e}"))?;
    if !value.is_finite() {
        return Err(format!("joint {name}: value must be finite"));
    }
    Ok((name.to_owned(), value))
}

pub fn run() -> Result<()> {
    match Cli::parse().command {
        Command::Build(args) => build(args),
        Command::Poses(args) => poses(args),
        Command::Query(args) => query(args),
        Command::Replay(args) => replay(args),
        Command::Generate(args) => generate(args),
        Command::Node(args) => node(args),
        Command::Play(args) => {
            if !(args.rate > 0.0 && args.rate.is_finite()) {
                bail!("--rate must be a positive number");
            }
            let options = crate::node::play::PlayOptions {
                rate: args.rate,
                loops: args.loops,
                wait_s: args.wait,
                measure: args.measure.clone(),
                linger_s: args.linger,
            };
            let s = crate::node::play::play(&args.bag, &options)?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&s)?);
            } else {
                println!(
                    "{} clouds and {} messages published; {} outputs received ({:.1} Hz); latency p50 {} ms, p99 {} ms, max {} ms",
                    s.clouds_published,
                    s.messages_published,
                    s.outputs_received,
                    s.output_rate_hz,
                    s.latency_p50_ms.map_or("-".into(), |v| format!("{v:.2}")),
                    s.latency_p99_ms.map_or("-".into(), |v| format!("{v:.2}")),
                    s.latency_max_ms.map_or("-".into(), |v| format!("{v:.2}")),
                );
            }
            Ok(())
        }
        Command::Record(args) => {
            let n = crate::node::record::record(&args.node, &args.out, args.duration)?;
            println!("{n} messages recorded to {}", args.out.display());
            Ok(())
        }
        Command::Params => {
            print!("{}", crate::config::markdown_table());
            Ok(())
        }
        Command::Bench(Bench::Packing(args)) => bench_packing(args),
        Command::Bench(Bench::Query(args)) => crate::bench::bench_query(args),
        Command::Bench(Bench::Gpu(args)) => crate::bench::bench_gpu(args),
    }
}

#[derive(Serialize)]
struct LinkRow<'a> {
    name: &'a str,
    spheres: usize,
    coverage: f64,
    gap_m: f64,
    gap_sampled_m: f64,
    build_s: f64,
    tree_volume_m3: f64,
    origin: Origin,
}

pub(crate) fn build_trees(
    model: &RobotModel,
    options: &BuildOptions,
    cache: Option<&TreeCache>,
) -> Result<Vec<(LinkTree, Origin)>> {
    let bar = indicatif::ProgressBar::new(model.links.len() as u64).with_message("links");
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} {pos}/{len} [{elapsed}] {wide_bar}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let trees = ist::build_robot(model, options, cache, &|_| bar.inc(1))?;
    bar.finish_and_clear();
    Ok(trees)
}

fn build(args: BuildArgs) -> Result<()> {
    let options = args.packing.options()?;
    let model = args.robot.load()?;
    if !model.skipped_links.is_empty() && !args.json {
        eprintln!(
            "links without collision geometry (skipped): {}",
            model.skipped_links.join(", ")
        );
    }
    let cache = (!args.no_cache).then(|| {
        TreeCache::new(
            args.cache_dir
                .clone()
                .unwrap_or_else(TreeCache::default_dir),
        )
    });
    let start = Instant::now();
    let trees = build_trees(&model, &options, cache.as_ref())?;
    let total_s = start.elapsed().as_secs_f64();
    if args.validate {
        for ((tree, _), geometry) in trees.iter().zip(&model.links) {
            validate_link(tree, geometry, 1e-6)?;
        }
    }
    let rows: Vec<LinkRow> = trees
        .iter()
        .map(|(t, origin)| LinkRow {
            name: &t.link,
            spheres: t.quality.spheres,
            coverage: t.quality.coverage,
            gap_m: t.quality.gap_m,
            gap_sampled_m: t.quality.gap_sampled_m,
            build_s: t.quality.build_s,
            tree_volume_m3: t.quality.tree_volume_m3,
            origin: *origin,
        })
        .collect();
    if let Some(path) = &args.export_spheres {
        export_spheres(path, &trees)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "links": rows }))?
        );
        return Ok(());
    }
    println!(
        "robot {} ({}), {} links",
        model.name,
        model.urdf_path.display(),
        rows.len()
    );
    println!(
        "{:<24} {:>8} {:>9} {:>8} {:>9} {:>7}",
        "link", "spheres", "coverage", "h [mm]", "build [s]", "from"
    );
    for r in &rows {
        println!(
            "{:<24} {:>8} {:>8.1}% {:>8.3} {:>9.2} {:>7}",
            r.name,
            r.spheres,
            100.0 * r.coverage,
            1e3 * r.gap_m,
            r.build_s,
            match r.origin {
                Origin::Built => "built",
                Origin::Cache => "cache",
            }
        );
    }
    println!(
        "total {total_s:.2} s{}",
        if args.validate { ", validated" } else { "" }
    );
    Ok(())
}

fn export_spheres(path: &Path, trees: &[(LinkTree, Origin)]) -> Result<()> {
    let map: serde_json::Map<String, serde_json::Value> = trees
        .iter()
        .map(|(t, _)| {
            let spheres: Vec<[f32; 4]> = t
                .spheres
                .iter()
                .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
                .collect();
            (t.link.clone(), serde_json::json!(spheres))
        })
        .collect();
    std::fs::write(path, serde_json::to_string(&map)?)
        .with_context(|| format!("writing {}", path.display()))
}

fn query(args: QueryArgs) -> Result<()> {
    let build = args.packing.options()?;
    let model = args.robot.load()?;
    let options = QueryOptions {
        mode: args.mode,
        max_distance_m: args.max_distance,
        self_filter_padding_m: (!args.no_self_filter).then_some(args.self_filter_padding),
        per_link: !args.no_per_link,
        backend: args.backend.backend,
        gpu_min_points: args.backend.gpu_min_points,
    };
    // Checked before the trees are built, by the rule the engine applies.
    options
        .validate()
        .context("--max-distance or --self-filter-padding")?;
    let cache = TreeCache::new(
        args.cache_dir
            .clone()
            .unwrap_or_else(TreeCache::default_dir),
    );
    let trees: Vec<LinkTree> = build_trees(&model, &build, Some(&cache))?
        .into_iter()
        .map(|(t, _)| t)
        .collect();
    let selection = LinkSelection {
        include: args.links.clone(),
        exclude: args.exclude_links.clone(),
    };
    let mut engine = Engine::new(&model, &trees, &selection)?;
    let q = model
        .kinematics
        .values_from_names(&args.joints, Some(0.0))?;
    let poses = model.kinematics.link_poses(&q);
    let cloud = cloud::load(&args.cloud, args.msg)
        .with_context(|| format!("reading cloud {}", args.cloud.display()))?;
    // One query, timed as it comes (cold caches); `bench query` measures properly.
    let start = Instant::now();
    let result = engine.query(&cloud.points, &args.sensor_pose, &poses, &options)?;
    let elapsed = start.elapsed().as_secs_f64();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&result)?);
        return Ok(());
    }
    println!(
        "cloud {}: {} points ({}×{}){}",
        args.cloud.display(),
        cloud.points.len(),
        cloud.width,
        cloud.height,
        cloud
            .frame_id
            .as_ref()
            .map(|f| format!(", frame {f}"))
            .unwrap_or_default()
    );
    match (&result.outcome, &result.nearest) {
        (Outcome::Nearest, Some(n)) => {
            let lower = n
                .lower_m
                .filter(|_| options.mode == Mode::Certified)
                .map(|l| format!(" (certified ≥ {l:.4} m)"))
                .unwrap_or_default();
            println!(
                "{:?} minimum {:.4} m{lower} on {}: cloud point {} at ({:.4}, {:.4}, {:.4}), robot point ({:.4}, {:.4}, {:.4}) (root frame {})",
                options.mode,
                n.distance_m,
                n.link,
                n.point_index,
                n.point_root[0],
                n.point_root[1],
                n.point_root[2],
                n.robot_point_root[0],
                n.robot_point_root[1],
                n.robot_point_root[2],
                model.kinematics.root_link()
            );
        }
        (Outcome::NoPoints, _) => println!("no valid points in the cloud"),
        _ => println!("nothing within max_distance {} m", options.max_distance_m),
    }
    let c = &result.counts;
    println!(
        "points: {} total, {} invalid, {} outside the region of interest, {} self-filtered, {} pruned, {} evaluated, {} inside{}",
        c.total,
        c.invalid,
        c.outside_roi,
        c.self_filtered,
        c.pruned,
        c.evaluated,
        c.inside,
        if options.mode == Mode::Exact {
            format!(", {} exact refinements", c.exact_refined)
        } else {
            String::new()
        }
    );
    if !result.links.is_empty() {
        println!(
            "{:<24} {:>12} {:>12} {:>10}",
            "link", "upper [m]", "lower [m]", "point"
        );
        for l in &result.links {
            let f = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
            println!(
                "{:<24} {:>12} {:>12} {:>10}",
                l.link,
                f(l.distance_m),
                f(l.lower_m),
                l.point_index
                    .map(|p| p.to_string())
                    .unwrap_or_else(|| "-".into())
            );
        }
    }
    println!("query time {:.3} ms (one cold query)", 1e3 * elapsed);
    Ok(())
}

/// The monitor of a config, with a progress line while its trees are built or loaded.
fn monitor_from_config(config: Config) -> Result<Monitor> {
    let bar = indicatif::ProgressBar::new_spinner();
    let monitor = Monitor::new(config, &|link| {
        bar.set_message(format!("inner sphere trees: {link}"));
        bar.tick();
    });
    bar.finish_and_clear();
    monitor
}

fn node(args: NodeArgs) -> Result<()> {
    let ros = crate::node::parse_ros_args(&args.ros_args)?;
    let mut config = Config::load(&args.config, &ros.params)
        .with_context(|| format!("config {}", args.config.display()))?;
    if let Some(name) = ros.node {
        config.node_name = name;
    }
    if let Some(ns) = ros.namespace {
        config.namespace = ns;
    }
    // Signals first: a stop during the tree build ends the node cleanly once it is built.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())?;
    }
    let monitor = monitor_from_config(config)?;
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        return Ok(());
    }
    crate::node::run(monitor, stop)
}

fn generate(args: GenerateArgs) -> Result<()> {
    if args.out.exists() {
        bail!("{} exists already", args.out.display());
    }
    if args.point_step != 16 && args.point_step != 32 {
        bail!("--point-step must be 16 or 32");
    }
    if args.frames == 0 || args.width == 0 || args.height == 0 {
        bail!("--frames, --width and --height must be at least 1");
    }
    if !(args.noise >= 0.0 && args.noise.is_finite() && (0.0..=1.0).contains(&args.holes)) {
        bail!("--noise must be ≥ 0 and --holes in [0, 1]");
    }
    let model = args.robot.load()?;
    let params = ScenarioParams {
        scene: args.scene,
        frames: args.frames,
        width: args.width,
        height: args.height,
        noise_m: args.noise,
        holes: args.holes,
        seed: args.seed,
        compression: args.compression,
        point_step: args.point_step,
        ..ScenarioParams::default()
    };
    let g = scenario::generate(&model, &params, &args.out)?;
    println!(
        "{:>5} {:>10} {:>10} {:>10}",
        "frame", "truth [m]", "obstacle", "robot"
    );
    for i in 0..g.frames {
        println!(
            "{:>5} {:>10} {:>10} {:>10}",
            i,
            g.truth_m[i].map_or_else(|| "-".into(), |t| format!("{t:.4}")),
            g.obstacle_points[i],
            g.robot_points[i]
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

fn replay(args: ReplayArgs) -> Result<()> {
    let mut config = Config::load(&args.config, &args.params)
        .with_context(|| format!("config {}", args.config.display()))?;
    if let Some(backend) = args.backend {
        config.query.backend = backend;
    }
    let mut monitor = monitor_from_config(config)?;
    let out = args.out.as_deref().map(|p| (p, args.out_compression));
    let mut frames = Vec::new();
    let json = args.json;
    if !json {
        println!(
            "{:>5} {:>18} {:<7} {:>10} {:>10} {:>10} {:<20} {:>10} {:>8}",
            "frame",
            "stamp [s]",
            "level",
            "min [m]",
            "lower [m]",
            "upper [m]",
            "link",
            "truth [m]",
            "ms"
        );
    }
    let summary = replay::replay(&mut monitor, &args.bag, out, &mut |f| {
        if json {
            frames.push(f.clone());
            return;
        }
        let m = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
        println!(
            "{:>5} {:>18.6} {:<7} {:>10} {:>10} {:>10} {:<20} {:>10} {:>8.3}{}",
            f.index,
            f.stamp_ns as f64 * 1e-9,
            format!("{:?}", f.level).to_uppercase(),
            m(f.min_distance_m),
            m(f.lower_m),
            m(f.distance_m),
            f.link.as_deref().unwrap_or(match f.outcome {
                "nearest" => "-",
                other => other,
            }),
            m(f.truth_m),
            f.processing_ms,
            f.fault
                .as_ref()
                .map(|e| format!("  {e}"))
                .unwrap_or_default()
        );
    })?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(
                &serde_json::json!({"frames": frames, "summary": summary})
            )?
        );
        return Ok(());
    }
    let faults: usize = summary.faults.values().sum();
    println!(
        "{} frames, {} faults{}, {} dropped, {} input errors; processing p50 {:.3} ms, p99 {:.3} ms{}",
        summary.frames,
        faults,
        if faults > 0 {
            format!(" ({:?})", summary.faults)
        } else {
            String::new()
        },
        summary.dropped,
        summary.input_errors,
        summary.processing_p50_ms,
        summary.processing_p99_ms,
        summary
            .max_error_vs_truth_m
            .map(|e| format!("; max |min_distance − truth| {:.2} mm", e * 1e3))
            .unwrap_or_default()
    );
    if let Some(out) = &args.out {
        println!("outputs written to {}", out.display());
    }
    Ok(())
}

fn poses(args: PosesArgs) -> Result<()> {
    let model = args.robot.load()?;
    let k = &model.kinematics;
    let q = k.values_from_names(&args.joints, Some(0.0))?;
    let poses = k.link_poses(&q);
    println!(
        "{:<24} {:>9} {:>9} {:>9}   (root frame {}, m)",
        "link",
        "x",
        "y",
        "z",
        k.root_link()
    );
    for (name, pose) in k.link_names().iter().zip(&poses) {
        let t = pose.translation.vector;
        println!("{name:<24} {:>9.4} {:>9.4} {:>9.4}", t.x, t.y, t.z);
    }
    Ok(())
}

pub(crate) fn median_and_spread(mut samples: Vec<f64>) -> (f64, f64, f64) {
    samples.sort_by(f64::total_cmp);
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.1), at(0.9))
}

fn bench_packing(args: BenchPackingArgs) -> Result<()> {
    let model = args.robot.load()?;
    println!(
        "robot {} ({} links), {} threads",
        model.name,
        model.links.len(),
        rayon::current_num_threads()
    );
    let dir = tempfile_dir()?;
    for &budget in &args.budgets {
        let mut options = BuildOptions::default();
        options.packing.max_spheres = budget;
        let cache = TreeCache::new(dir.join(budget.to_string()));
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
            "{:<24} {:>8} {:>9} {:>8} {:>9}",
            "link", "spheres", "coverage", "h [mm]", "build [s]"
        );
        for (t, _) in &trees {
            let q = &t.quality;
            println!(
                "{:<24} {:>8} {:>8.1}% {:>8.3} {:>9.2}",
                t.link,
                q.spheres,
                100.0 * q.coverage,
                1e3 * q.gap_m,
                q.build_s
            );
        }
        // Cache load against its floor, reading the same files' bytes.
        let mut load = Vec::new();
        let mut read = Vec::new();
        for _ in 0..args.runs {
            let t = Instant::now();
            let loaded = ist::build_robot(&model, &options, Some(&cache), &|_| {})?;
            load.push(t.elapsed().as_secs_f64());
            if loaded.iter().any(|(_, o)| *o != Origin::Cache) {
                bail!("cache miss in the load benchmark");
            }
            let t = Instant::now();
            let mut bytes = 0;
            for link in &model.links {
                bytes += std::fs::read(cache.path(&ist::cache::key(link, &options)))?.len();
            }
            read.push(t.elapsed().as_secs_f64());
            std::hint::black_box(bytes);
        }
        let (m, lo, hi) = median_and_spread(load);
        let (rm, rlo, rhi) = median_and_spread(read);
        println!(
            "cache load (hash meshes, read, verify, decode; {} runs): median {:.2} ms [p10 {:.2}, p90 {:.2}]; \
             peer raw file read: {:.2} ms [{:.2}, {:.2}]; ratio {:.1}×",
            args.runs, 1e3 * m, 1e3 * lo, 1e3 * hi, 1e3 * rm, 1e3 * rlo, 1e3 * rhi, m / rm
        );
        // Tree builders on the same spheres.
        let mut sums = [0.0f64; 2];
        for (t, _) in &trees {
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
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}

fn tempfile_dir() -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("ist_monitor_bench_{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}
