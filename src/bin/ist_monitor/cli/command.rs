//! The command line's subcommands and their dispatch, and how `ros2 run` and a launch file's
//! arguments (`--ros-args …` with no subcommand) are understood as `node`.

use anyhow::Result;
use clap::{Parser, Subcommand};

use super::{build, query, replay, ros};

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
    Build(build::BuildArgs),
    /// Print the pose of every link in the root frame for given joint values.
    Poses(build::PosesArgs),
    /// Minimum distance between the posed robot and one point cloud.
    Query(query::QueryArgs),
    /// Replay a rosbag2 MCAP bag through the monitor: one line per cloud and a summary.
    Replay(replay::ReplayArgs),
    /// Run the live ROS 2 node.
    Node(ros::NodeArgs),
    /// Publish a bag's clouds, depth images, joint states and transforms on DDS or zenoh at their
    /// recorded pace.
    Play(ros::PlayArgs),
    /// Record the node's outputs from DDS or zenoh into an MCAP.
    Record(ros::RecordArgs),
    /// Run a zenoh router (as rmw_zenohd does) for nodes on the zenoh transport.
    ZenohRouter(ros::RouterArgs),
    /// Print the node's parameters (name, default, unit, meaning) as a Markdown table.
    Params,
    /// Make a bag: a simulated depth camera watching the robot and an obstacle, with the exact
    /// minimum distance of every frame.
    Generate(replay::GenerateArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(crate::bench::Bench),
}

/// The command line, with `node` understood where it starts with `--ros-args` (as `ros2 run
/// ist_monitor ist_monitor --ros-args …` and a launch file's `Node(executable='ist_monitor')`
/// start it).
pub fn args() -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if args.get(1).is_some_and(|a| a == "--ros-args") {
        args.insert(1, "node".into());
    }
    args
}

/// The level `--ros-args --log-level` sets for the node's own log (`None`: not set, or the
/// arguments do not parse, which the node then reports).
pub fn ros_log_level(args: &[std::ffi::OsString]) -> Option<log::LevelFilter> {
    let at = args.iter().position(|a| a == "--ros-args")?;
    let ros: Vec<String> = args[at..]
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let ros = ist_monitor::node::parse_ros_args(&ros).ok()?;
    let name = ros.node.clone().unwrap_or_else(|| "ist_monitor".into());
    let ns = ros.namespace.clone().unwrap_or_default();
    ros.log_level_for(&name, &ns)
}

pub fn run(args: Vec<std::ffi::OsString>) -> Result<()> {
    match Cli::parse_from(args).command {
        Command::Build(args) => build::build(args),
        Command::Poses(args) => build::poses(args),
        Command::Query(args) => query::query(args),
        Command::Replay(args) => replay::replay(args),
        Command::Generate(args) => replay::generate(args),
        Command::Node(args) => ros::node(args),
        Command::Play(args) => ros::play(args),
        Command::Record(args) => ros::record(args),
        Command::ZenohRouter(args) => ros::zenoh_router(args),
        Command::Params => {
            print!("{}", ist_monitor::config::markdown_table());
            Ok(())
        }
        Command::Bench(bench) => crate::bench::run(bench),
    }
}
