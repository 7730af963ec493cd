//! `bench monitor`: what the monitor adds to the query on one real cloud (by default the Kinect
//! cloud of ../shared's MoveIt perception tutorial bag, with the Panda and
//! `config/panda_perception_tutorial.yaml`): the fusion across sources with the output messages
//! (one source, and two), and the stray-point filter, each as a ratio to the decode + poses +
//! query of the same frames. The variants are alternated frame by frame in one run, so the
//! machine's drift hits them alike.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::bag::read_messages;
use ist_monitor::monitor::Monitor;
use ist_monitor::stats::Spread;

use crate::cli::{monitor_from_config, ConfigArgs};

#[derive(Args)]
pub struct BenchMonitorArgs {
    /// Bag whose first cloud of the first source is measured (default: the Kinect bag of
    /// ../shared/bags/moveit_perception_tutorial).
    bag: Option<PathBuf>,
    #[command(flatten)]
    config: ConfigArgs,
    /// The shared data folder (default: ../shared beside the demo folder, or $IST_MONITOR_SHARED).
    #[arg(long)]
    shared: Option<PathBuf>,
    /// Timed frames per variant.
    #[arg(long, default_value_t = 200, value_parser = crate::cli::parse_count)]
    runs: usize,
}

/// The bench's default config.
const CONFIG: &str = "config/panda_perception_tutorial.yaml";

/// A monitor of the config with `extra` parameters.
fn monitor(args: &BenchMonitorArgs, extra: &[(&str, &str)]) -> Result<Monitor> {
    let extra: Vec<(String, String)> = (extra.iter())
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    monitor_from_config(args.config.load(CONFIG, &extra)?)
}

pub fn bench_monitor(args: BenchMonitorArgs) -> Result<()> {
    let bag = match &args.bag {
        Some(b) => b.clone(),
        None => crate::demo::shared(&args.shared)?
            .join("bags/moveit_perception_tutorial/perception_tutorial_mcap"),
    };
    let mut plain = monitor(&args, &[])?;
    let source = plain
        .config
        .sources
        .iter()
        .find(|s| s.enabled)
        .context("no enabled source")?;
    let (name, topic) = (source.name.clone(), source.topic.clone());
    let messages = read_messages(&bag, &|t, _| t == topic)
        .with_context(|| format!("reading {}", bag.display()))?;
    let Some(cloud) = messages.first() else {
        bail!("{}: no message on {topic}", bag.display());
    };
    let payload = &cloud.data;
    let sources = format!("[{name}, {name}_2]");
    let second_topic = format!("{name}_2.topic");
    let mut two = monitor(
        &args,
        &[("sources", &sources), (&second_topic, "/bench/second")],
    )?;
    let mut stray = monitor(&args, &[("stray_filter.min_points", "4")])?;
    // Warm-up: the GPU probe (backend auto), the caches and the self-filter's grids.
    for m in [&mut plain, &mut two, &mut stray] {
        for _ in 0..3 {
            m.on_cloud(0, payload, None);
        }
    }
    two.on_cloud(1, payload, None);
    let (mut query, mut outputs, mut query_two, mut outputs_two, mut query_stray) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut rejected = 0;
    for run in 0..args.runs {
        let f = plain.on_cloud(0, payload, None);
        if let Err(e) = &f.result {
            bail!("{}: the cloud is a fault: {e}", bag.display());
        }
        query.push(f.processing_s * 1e3);
        outputs.push(f.outputs_s * 1e3);
        let f = two.on_cloud(run % 2, payload, None);
        query_two.push(f.processing_s * 1e3);
        outputs_two.push(f.outputs_s * 1e3);
        let f = stray.on_cloud(0, payload, None);
        query_stray.push(f.processing_s * 1e3);
        rejected += f.result.as_ref().map_or(0, |r| r.stray_rejected);
    }
    let ratio = |a: &[f64], b: &[f64]| Spread::of(a.iter().zip(b).map(|(x, y)| x / y).collect());
    let ms = |s: Spread| format!("{:.3} ms [{:.3}, {:.3}]", s.median, s.p10, s.p90);
    let pct = |s: Spread| {
        format!(
            "{:.2} % [{:.2}, {:.2}]",
            s.median * 100.0,
            s.p10 * 100.0,
            s.p90 * 100.0
        )
    };
    println!(
        "{}: one cloud of {topic} ({} bytes), {} frames per variant, alternated, {} threads",
        bag.display(),
        payload.len(),
        args.runs,
        rayon::current_num_threads()
    );
    println!(
        "decode + poses + query, one source:          {}",
        ms(Spread::of(query.clone()))
    );
    println!(
        "fusion + outputs, one source:                {}  = {} of the query",
        ms(Spread::of(outputs.clone())),
        pct(ratio(&outputs, &query))
    );
    println!(
        "fusion + outputs, two sources:               {}  = {} of the query",
        ms(Spread::of(outputs_two.clone())),
        pct(ratio(&outputs_two, &query_two))
    );
    println!(
        "decode + poses + query + stray filter (4):   {}  = {} of the query alone",
        ms(Spread::of(query_stray.clone())),
        pct(ratio(&query_stray, &query))
    );
    println!(
        "points the stray filter rejected:            {rejected} in {} frames",
        args.runs
    );
    Ok(())
}
