//! The ROS 2 commands: `node` (the live monitor), `play` (a bag onto DDS or zenoh, optionally
//! measuring the node), `record` (the node's outputs into an MCAP) and `zenoh-router` (a router
//! for rmw_zenoh-style sessions, where no `rmw_zenohd` runs).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use ist_monitor::config::ParameterSources;
use ist_monitor::node;

use crate::args::{parse_positive, parse_seconds};
use crate::choice::choice;
use crate::demo;

#[derive(Args)]
pub struct NodeArgs {
    /// Middleware: dds or zenoh (default: from RMW_IMPLEMENTATION, rmw_zenoh_cpp for zenoh;
    /// DDS when unset).
    #[arg(long, value_parser = choice::<node::Transport>())]
    transport: Option<node::Transport>,
    /// ROS 2 parameters file (default: config/demo_arm.yaml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// `--ros-args` as rcl takes them: `-r __node:=NAME -r __ns:=/NS -r FROM:=TO --params-file
    /// FILE -p NAME:=VALUE --log-level [NAME:=]LEVEL --enclave /ENCLAVE` (FROM:=TO remaps an input or
    /// an output, e.g. `~/speed_scaling:=/joint_trajectory_controller/speed_scaling_input`;
    /// the enclave is SROS2's, used with ROS_SECURITY_ENABLE=true: docs/security.md)
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    ros_args: Vec<String>,
}

#[derive(Args)]
pub struct PlayArgs {
    /// Middleware: dds or zenoh (default: from RMW_IMPLEMENTATION, rmw_zenoh_cpp for zenoh;
    /// DDS when unset).
    #[arg(long, value_parser = choice::<node::Transport>())]
    transport: Option<node::Transport>,
    /// Bag: a .mcap file or a rosbag2 folder (default: the bundled demo bag).
    bag: Option<PathBuf>,
    /// Playback rate (1 = recorded pace).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    rate: f64,
    /// How many times to play the bag (stamps are shifted to now at each start).
    #[arg(long, default_value_t = 1)]
    loops: usize,
    /// Seconds to wait for discovery before the first message.
    #[arg(long, default_value_t = 1.5, value_parser = parse_seconds)]
    wait: f64,
    /// Measure the node: match its outputs on this JointState topic (e.g.
    /// /ist_monitor/link_distances) to the clouds, and report rate and latency.
    #[arg(long)]
    measure: Option<String>,
    /// Seconds to wait for outputs after the last message.
    #[arg(long, default_value_t = 0.5, value_parser = parse_seconds)]
    linger: f64,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct RecordArgs {
    /// Middleware: dds or zenoh (default: from RMW_IMPLEMENTATION, rmw_zenoh_cpp for zenoh;
    /// DDS when unset).
    #[arg(long, value_parser = choice::<node::Transport>())]
    transport: Option<node::Transport>,
    /// Output MCAP (.mcap file, or a rosbag2 folder).
    #[arg(long)]
    out: PathBuf,
    /// The node whose outputs to record.
    #[arg(long, default_value = "/ist_monitor")]
    node: String,
    /// Seconds to record.
    #[arg(long, default_value_t = 10.0, value_parser = parse_positive)]
    duration: f64,
}

pub fn node(args: NodeArgs) -> Result<()> {
    let ros = node::parse_ros_args(&args.ros_args)?;
    for note in &ros.noted {
        log::info!("{note}");
    }
    // The demo's parameters unless a file is given (`--config`, or launch_ros's
    // `--params-file`s, which start from the declared defaults as a ROS node does).
    let config_file = match (&args.config, ros.params_files.is_empty()) {
        (Some(c), _) => Some(c.clone()),
        (None, true) => Some(demo::or_demo(&None, crate::demo::CONFIG)?),
        (None, false) => None,
    };
    let mut config = ist_monitor::config::Config::from_sources(&ParameterSources {
        config: config_file,
        params_files: ros.params_files.clone(),
        node: ros.node.clone(),
        namespace: ros.namespace.clone(),
        overrides: ros.params.clone(),
    })
    .context("parameters")?;
    config.remaps = ros.remaps_for(&config.node_name);
    config.rosout = ros.rosout.unwrap_or(true);
    config.enclave = ros.enclave.clone();
    // Signals first: the node answers them throughout, the tree build included.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())?;
    }
    let transport = node::Transport::choose(args.transport)?;
    Ok(node::run(config, stop, transport)?)
}

#[derive(Args)]
pub struct RouterArgs {
    /// Endpoint to listen on (default: from ZENOH_ROUTER_CONFIG_URI's file, else rmw_zenoh's
    /// tcp/localhost:7447).
    #[arg(long)]
    listen: Option<String>,
}

/// A zenoh router until SIGINT or SIGTERM.
pub fn zenoh_router(args: RouterArgs) -> Result<()> {
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())?;
    }
    Ok(node::rmw_zenoh::zenoh_router(
        args.listen.as_deref(),
        &stop,
    )?)
}

pub fn play(args: PlayArgs) -> Result<()> {
    let bag = demo::or_demo(&args.bag, demo::BAG)?;
    let options = node::play::PlayOptions {
        transport: node::Transport::choose(args.transport)?,
        rate: args.rate,
        loops: args.loops,
        wait_s: args.wait,
        measure: args.measure.clone(),
        linger_s: args.linger,
    };
    let s = node::play::play(&bag, &options)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        let ms = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        println!(
            "{} clouds and {} messages published; {} outputs received ({:.1} Hz); latency p50 {} ms, p99 {} ms, max {} ms",
            s.clouds_published,
            s.messages_published,
            s.outputs_received,
            s.output_rate_hz,
            ms(s.latency_p50_ms),
            ms(s.latency_p99_ms),
            ms(s.latency_max_ms),
        );
    }
    Ok(())
}

pub fn record(args: RecordArgs) -> Result<()> {
    let transport = node::Transport::choose(args.transport)?;
    let n = node::record::record(transport, &args.node, &args.out, args.duration)?;
    println!("{n} messages recorded to {}", args.out.display());
    let ms = node::record::distance_latencies(&args.out, &args.node)?;
    let at = |q: f64| ist_monitor::stats::percentile(&ms, q);
    if let (Some(p50), Some(p99), Some(max)) = (at(0.5), at(0.99), at(1.0)) {
        println!(
            "~/distance: {} frames, received − stamped: p50 {p50:.1} ms, p99 {p99:.1} ms, max \
             {max:.1} ms",
            ms.len()
        );
    }
    Ok(())
}
