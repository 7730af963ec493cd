//! `ist_monitor query`: one cloud against the posed robot, with the per-link table and what
//! each stage of the query dropped.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use ist_monitor::cloud;
use ist_monitor::query::{Engine, Mode, Outcome};

use crate::args::{parse_joint, parse_pose, QueryParams, TreeArgs};
use crate::setup::cached_trees;

#[derive(Args)]
pub struct QueryArgs {
    #[command(flatten)]
    trees: TreeArgs,
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
    #[command(flatten)]
    params: QueryParams,
    /// Print the result object as JSON.
    #[arg(long)]
    json: bool,
}

pub fn query(args: QueryArgs) -> Result<()> {
    // Checked before the trees are built, by the rules a params file goes through.
    let config = args.params.config()?;
    let options = config.query.clone();
    let build = args.trees.packing.options()?;
    let model = args.trees.robot.load(&config.selection)?;
    let trees = cached_trees(&model, &build, args.trees.cache_dir.as_deref())?;
    let mut engine = Engine::new(&model, &trees, &config.selection)?;
    let q = model
        .kinematics
        .values_from_names(&args.joints, Some(0.0))?;
    let poses = model.kinematics.link_poses(&q);
    let cloud = cloud::load(&args.cloud, args.msg)
        .with_context(|| format!("reading cloud {}", args.cloud.display()))?;
    // The GPU probe of `gpu`, and of `auto` for a cloud that reaches gpu_min_points (device
    // creation, ~80 ms on a software driver), is done before the clock starts; the one query is
    // then timed as it comes (cold caches). `bench query` measures properly.
    if options.wants_gpu(cloud.points.len()) {
        engine.gpu();
    }
    let start = Instant::now();
    let width = (cloud.height > 1).then_some(cloud.width as usize);
    let result = engine.query_image(&cloud.points, width, &args.sensor_pose, &poses, &options)?;
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
                match (l.distance_m, l.farther_than_m) {
                    (None, Some(t)) => format!("> {t:.4}"),
                    (d, _) => f(d),
                },
                f(l.lower_m),
                l.point_index
                    .map(|p| p.to_string())
                    .unwrap_or_else(|| "-".into())
            );
        }
    }
    println!(
        "query time {:.3} ms (one cold query on the {:?} backend)",
        1e3 * elapsed,
        result.backend
    );
    Ok(())
}
