//! Benchmarks: `bench packing` (`packing.rs`), `bench query` (`query.rs`, its rows in `rows.rs`, its plot in
//! `plot.rs`),
//! `bench gpu` (`gpu.rs`), `bench ssm` (`ssm.rs`, the separation monitor), `bench monitor`
//! (`monitor.rs`, fusion, the stray-point filter and the unseen space) and `bench unseen`
//! (`picture.rs`, a frame's unseen space drawn), over the real scenes of `scenes.rs`. Figures are medians with
//! the 10th and 90th percentiles ([`ist_monitor::stats::Spread`]), each beside a floor or a
//! peer measured in the same run.

mod gpu;
mod monitor;
mod packing;
mod picture;
mod plot;
mod query;
mod rows;
pub mod scenes;
mod ssm;

use anyhow::Result;
use clap::Subcommand;

#[derive(Subcommand)]
pub enum Bench {
    /// Coverage, surface gap and build time against the sphere budget; cache load time; tree
    /// builders compared by the sum of node volumes.
    Packing(packing::BenchPackingArgs),
    /// Error against run time of the query modes over sphere budgets, with the peers, on the
    /// real scenarios of ../shared; prints a table, and with --plot writes PNG plots.
    Query(query::BenchQueryArgs),
    /// The GPU backend against the CPU on the Panda and the Kinect cloud, for clouds of 307k to
    /// 5M points: end-to-end and kernel time, and the crossover for `--backend auto`.
    Gpu(gpu::BenchGpuArgs),
    /// The speed and separation monitor over the generated approach scene: its cost against
    /// the query of the same frames; with --plot, distance, S_p and the factor over time.
    Ssm(ssm::BenchSsmArgs),
    /// What the monitor adds to the query on the real Kinect cloud: the fusion across sources
    /// with the output messages, the stray-point filter and the unseen space, as ratios to the
    /// query.
    Monitor(monitor::BenchMonitorArgs),
    /// A picture of one frame's unseen space, drawn from a replay: the view with the hidden
    /// places nearest the robot coloured by cause, and the same places from above.
    Unseen(picture::BenchUnseenArgs),
}

pub fn run(bench: Bench) -> Result<()> {
    match bench {
        Bench::Packing(args) => packing::packing(args),
        Bench::Query(args) => query::bench_query(args),
        Bench::Gpu(args) => gpu::bench_gpu(args),
        Bench::Ssm(args) => ssm::bench_ssm(args),
        Bench::Monitor(args) => monitor::bench_monitor(args),
        Bench::Unseen(args) => picture::bench_unseen(args),
    }
}
