//! `replay` (a bag through the monitor, one line per cloud) and `generate` (scenario bags with
//! the exact distance of every frame).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::bag::writer::Compression;
use ist_monitor::choice::Choice;
use ist_monitor::cloud::depth::DepthEncoding;
use ist_monitor::monitor::replay;
use ist_monitor::query::Backend;
use ist_monitor::scenario::{self, ScenarioParams, SceneKind};

use crate::args::{ConfigArgs, RobotArgs};
use crate::choice::choice;
use crate::demo;
use crate::setup::monitor_from_config;

#[derive(Args)]
pub struct ReplayArgs {
    /// Bag: a .mcap file or a rosbag2 folder (default: the bundled demo bag, bags/demo).
    bag: Option<PathBuf>,
    #[command(flatten)]
    config: ConfigArgs,
    /// Write the node's outputs to this MCAP (`.mcap` file, or a rosbag2 folder otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Chunk compression of --out.
    #[arg(long, value_parser = choice::<Compression>(), default_value = Compression::Zstd.name())]
    out_compression: Compression,
    /// Where the queries run: cpu, gpu or auto (the same as -p backend:=...).
    #[arg(long, value_parser = choice::<Backend>())]
    backend: Option<Backend>,
    /// What each cloud's stamp is checked against: the message's log time (as the node's
    /// clock), or the cloud's own stamp, which turns the stale/future check off — for bags whose
    /// log times are not when the data was taken.
    #[arg(long, value_parser = choice::<replay::Clock>(), default_value = replay::Clock::Log.name())]
    clock: replay::Clock,
    /// Print the frames and the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct GenerateArgs {
    #[command(flatten)]
    robot: RobotArgs,
    /// Output: a rosbag2 folder (or a .mcap file); it must not exist yet.
    #[arg(long)]
    out: PathBuf,
    /// The obstacle: a person walking up to the arm, a shelf the arm reaches over, or a forearm
    /// hidden in the arm's shadow.
    #[arg(
        long,
        value_parser = choice::<SceneKind>(),
        default_value = SceneKind::Person.name()
    )]
    scene: SceneKind,
    /// Clouds to record (10 Hz).
    #[arg(long, default_value_t = ScenarioParams::default().frames)]
    frames: usize,
    /// Depth image width, pixels.
    #[arg(long, default_value_t = ScenarioParams::default().width)]
    width: u32,
    /// Depth image height, pixels.
    #[arg(long, default_value_t = ScenarioParams::default().height)]
    height: u32,
    /// Range noise σ, m (clipped at 2.5 σ).
    #[arg(long, default_value_t = ScenarioParams::default().noise_m)]
    noise: f64,
    /// Fraction of pixels dropped (NaN holes), each at random on its own.
    #[arg(long, default_value_t = ScenarioParams::default().holes)]
    holes: f64,
    /// Fraction of pixels dropped as a depth camera drops them: at depth edges, on the
    /// person's dark hair and shoes, and in clusters (beside --holes; 0: none).
    #[arg(long, default_value_t = 0.0)]
    camera_dropouts: f64,
    /// Seed of the noise and the holes (the same seed gives the same bag, byte for byte).
    #[arg(long, default_value_t = ScenarioParams::default().seed)]
    seed: u64,
    /// Chunk compression of the bag.
    #[arg(long, value_parser = choice::<Compression>(), default_value = Compression::Zstd.name())]
    compression: Compression,
    /// Bytes per point: 16 (x y z) or 32 (x y z, rgb), as RGB-D drivers publish.
    #[arg(long, default_value_t = 16)]
    point_step: u32,
    /// Record depth images (sensor_msgs/Image, 16UC1 in millimetres or 32FC1 in metres) on
    /// /camera/depth/image_raw instead of clouds; the truth is then over the points
    /// depth_image_proc makes from them. Replay them with `-p camera.type:=depth_image -p
    /// camera.topic:=/camera/depth/image_raw`.
    #[arg(long, value_name = "ENCODING")]
    depth: Option<String>,
    /// The obstacle returns no depth (dark fabric to a ToF or structured-light camera): its
    /// pixels are NaN, 0 in a 16UC1 image; the truth is the distance to its whole shape.
    #[arg(long)]
    dark: bool,
    /// Record a second depth camera beside the arm that sees into the first one's shadow, on
    /// /side_camera/depth/{points,camera_info,image_raw}, its frames side_camera_link (on
    /// /tf_static under the root) and side_camera_optical_frame. Replay with
    /// config/demo_arm_two_cameras.yaml. The scene then has a side wall behind the arm (y =
    /// 1.6 m), an obstacle like the back wall, that the second camera sees.
    #[arg(long)]
    second_camera: bool,
    /// Add a floor (8 × 8 m, its top the plane z = 0 of the robot's root) that every camera
    /// sees, so that the rays below the arm return. Its points are not obstacles (left out of
    /// the truth): drop them in the monitor with an exclusion volume (docs/replay.md).
    #[arg(long)]
    floor: bool,
}

pub fn replay(args: ReplayArgs) -> Result<()> {
    let backend = (args.backend.iter())
        .map(|b| ("backend".to_string(), b.name().to_owned()))
        .collect::<Vec<_>>();
    let config = args.config.load(demo::CONFIG, &backend)?;
    let bag = demo::or_demo(&args.bag, demo::BAG)?;
    let mut monitor = monitor_from_config(config)?;
    let out = args.out.as_deref().map(|p| (p, args.out_compression));
    let mut frames = Vec::new();
    let json = args.json;
    // The header with the first frame, so that a bag that replays nothing prints only its error.
    let header = || {
        println!(
            "{:>5} {:>18} {:<7} {:>10} {:>10} {:>10} {:<20} {:>10} {:>6} {:>10} {:>10} {:>10} {:>10} {:>8} {:>10} {:<10} {:>8}",
            "frame",
            "stamp [s]",
            "level",
            "min [m]",
            "lower [m]",
            "upper [m]",
            "link",
            "truth [m]",
            "factor",
            "margin [m]",
            "v_r [m/s]",
            "truth v_r",
            "truth mrg",
            "ms",
            "unseen [m]",
            "why",
            "unseen ms"
        )
    };
    if args.clock == replay::Clock::Stamp {
        log::warn!("--clock stamp: cloud stamps are not checked against the bag's clock");
    }
    let summary = replay::replay(&mut monitor, &bag, out, args.clock, &mut |f| {
        if json {
            frames.push(f.clone());
            return;
        }
        if f.index == 0 {
            header();
        }
        let m = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
        println!(
            "{:>5} {:>18.6} {:<7} {:>10} {:>10} {:>10} {:<20} {:>10} {:>6} {:>10} {:>10} {:>10} {:>10} {:>8.3} {:>10} {:<10} {:>8}{}",
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
            f.speed_scaling
                .map_or_else(|| "-".into(), |k| format!("{k:.3}")),
            m(f.separation_margin_m),
            m(f.nearest_approach_mps),
            m(f.truth_approach_mps),
            m(f.truth_margin_m),
            f.processing_ms,
            if f.unseen_all_seen {
                "inf".into()
            } else {
                m(f.unseen_m)
            },
            f.unseen_cause.map_or("-", short_cause),
            f.unseen_ms
                .map_or_else(|| "-".into(), |t| format!("{t:.1}")),
            f.fault
                .as_ref()
                .or(f.ssm_fault.as_ref())
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
    if let (Some(p50), Some(p99)) = (summary.unseen_p50_ms, summary.unseen_p99_ms) {
        println!(
            "unobserved space: pass p50 {p50:.1} ms, p99 {p99:.1} ms; frames with a truth where \
             min(min_distance, unseen_distance) exceeds it: {} of {} (promised for a body \
             inside the monitored volume)",
            summary.protected_above_truth, summary.protected_checked
        );
    }
    if let Some(out) = &args.out {
        println!("outputs written to {}", out.display());
    }
    Ok(())
}

pub fn generate(args: GenerateArgs) -> Result<()> {
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
    if !(0.0..1.0).contains(&args.camera_dropouts) {
        bail!("--camera-dropouts must be in [0, 1)");
    }
    let depth = match args.depth.as_deref() {
        None => None,
        Some(e) => Some(DepthEncoding::from_name(e).with_context(|| {
            format!("--depth {e}: expected 16UC1 (millimetres) or 32FC1 (metres)")
        })?),
    };
    let model = args.robot.load(&Default::default())?;
    let params = ScenarioParams {
        depth,
        scene: args.scene,
        frames: args.frames,
        width: args.width,
        height: args.height,
        noise_m: args.noise,
        holes: args.holes,
        camera_dropouts: args.camera_dropouts,
        seed: args.seed,
        compression: args.compression,
        point_step: args.point_step,
        dark: args.dark,
        second_camera: args.second_camera,
        floor: args.floor,
        ..ScenarioParams::default()
    };
    let g = scenario::generate(&model, &params, &args.out)?;
    println!(
        "{:>5} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "frame", "truth [m]", "v_r [m/s]", "margin [m]", "obstacle", "robot"
    );
    let m = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    for i in 0..g.frames {
        println!(
            "{:>5} {:>10} {:>10} {:>10} {:>10} {:>10}",
            i,
            m(g.truth_m[i]),
            m(g.separation[i].map(|s| s.0)),
            m(g.separation[i].map(|s| s.1)),
            g.obstacle_points[i],
            g.robot_points[i]
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// A cause's name in the replay table's narrow column.
fn short_cause(name: &str) -> &str {
    match name {
        "robot_shadow" => "robot",
        "another_body_shadow" => "occluded",
        "no_return" => "no return",
        "outside_every_view" => "outside",
        other => other,
    }
}
