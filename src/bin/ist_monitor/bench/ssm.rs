//! `bench ssm`: the speed and separation monitor over the generated approach scene (a person
//! walks up to the swinging demo arm and back, `generate --scene approach`): the cost of the
//! separation stage against the query of the same frames, measured in the same replays, and
//! with `--plot` the distance, the protective separation distance and the factor over time.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::monitor::replay::{self, Clock, ReplayFrame};
use ist_monitor::scenario::{self, ScenarioParams, SceneKind};
use ist_monitor::stats::Spread;

use crate::args::ConfigArgs;
use crate::setup::monitor_from_config;

#[derive(Args)]
pub struct BenchSsmArgs {
    #[command(flatten)]
    config: ConfigArgs,
    /// Clouds of the generated approach (10 Hz).
    #[arg(long, default_value_t = 60, value_parser = crate::args::parse_count)]
    frames: usize,
    /// Depth image width and height, pixels.
    #[arg(long, default_value_t = 128)]
    width: u32,
    #[arg(long, default_value_t = 96)]
    height: u32,
    /// Replays of the bag timed (every frame of every replay is a sample).
    #[arg(long, default_value_t = 5, value_parser = crate::args::parse_count)]
    runs: usize,
    /// Write the plot of the first replay to this PNG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// TrueType font of the plot (default: DejaVu Sans or another sans-serif found).
    #[arg(long)]
    font: Option<PathBuf>,
}

pub fn bench_ssm(args: BenchSsmArgs) -> Result<()> {
    if args.width == 0 || args.height == 0 {
        bail!("--width and --height must be at least 1");
    }
    let config = args.config.load(crate::demo::CONFIG, &[])?;
    if !config.ssm.enabled {
        bail!("speed_scaling.enabled is false: nothing to measure");
    }
    let mut monitor = monitor_from_config(config)?;
    let dir = tempfile::tempdir().context("creating a temporary folder")?;
    let bag = dir.path().join("approach");
    let params = ScenarioParams {
        scene: SceneKind::Approach,
        frames: args.frames,
        width: args.width,
        height: args.height,
        ..ScenarioParams::default()
    };
    scenario::generate(&monitor.model, &params, &bag)?;
    let mut first: Vec<ReplayFrame> = Vec::new();
    let (mut query_ms, mut ssm_ms, mut share) = (Vec::new(), Vec::new(), Vec::new());
    for run in 0..args.runs {
        replay::replay(&mut monitor, &bag, None, Clock::Log, &mut |f| {
            if run == 0 {
                first.push(f.clone());
            }
            if let Some(s) = f.ssm_ms {
                query_ms.push(f.processing_ms);
                ssm_ms.push(s);
                share.push(s / f.processing_ms);
            }
        })?;
    }
    println!(
        "generated approach: {} frames of {}×{}, {} replays, {} threads",
        args.frames,
        args.width,
        args.height,
        args.runs,
        rayon::current_num_threads()
    );
    println!(
        "{:>5} {:>10} {:>10} {:>10} {:>7} {:>7} {:>10} {:>10} {:<16}",
        "frame",
        "truth [m]",
        "lower [m]",
        "S_p [m]",
        "allowed",
        "factor",
        "v_r [m/s]",
        "truth v_r",
        "limiting link"
    );
    let m = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    for f in &first {
        println!(
            "{:>5} {:>10} {:>10} {:>10} {:>7} {:>7} {:>10} {:>10} {:<16}",
            f.index,
            m(f.truth_m),
            m(f.min_distance_m),
            m(f.protective_m),
            f.allowed_factor
                .map_or_else(|| "-".into(), |k| format!("{k:.3}")),
            f.speed_scaling
                .map_or_else(|| "-".into(), |k| format!("{k:.3}")),
            m(f.nearest_approach_mps),
            m(f.truth_approach_mps),
            f.ssm_link.as_deref().unwrap_or("-"),
        );
    }
    let (q, s, r) = (Spread::of(query_ms), Spread::of(ssm_ms), Spread::of(share));
    println!(
        "decode + poses + query per cloud: {:.3} ms [{:.3}, {:.3}]",
        q.median, q.p10, q.p90
    );
    println!(
        "separation stage per cloud:       {:.1} µs [{:.1}, {:.1}]",
        s.median * 1e3,
        s.p10 * 1e3,
        s.p90 * 1e3
    );
    println!(
        "its share of the query, per frame: {:.2} % [{:.2}, {:.2}] (target ≤ 5 %)",
        r.median * 100.0,
        r.p10 * 100.0,
        r.p90 * 100.0
    );
    if let Some(path) = &args.plot {
        super::plot::separation(path, args.font.as_deref(), &first)?;
        println!("plot written to {}", path.display());
    }
    Ok(())
}
