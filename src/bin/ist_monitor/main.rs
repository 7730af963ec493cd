//! The `ist_monitor` command: the application on top of the `ist_monitor` library.
//!
//! - `cli/`: one module per group of subcommands (`build` and `poses`, `query`, `replay` and
//!   `generate`, the ROS 2 `node`, `play` and `record`); every option that is also a node
//!   parameter takes its name, default and meaning from the library's parameter table
//!   (`ist_monitor::config::PARAMETERS`).
//! - `bench/`: `bench packing`, `bench query` (error against run time, with its plots) and
//!   `bench gpu`, over the real scenes of `../shared` (`bench/scenes.rs`, which the criterion
//!   benches and the tests include too).
//! - `demo.rs`: where the demo robot, bag and config are found at run time (nothing about the
//!   checkout is compiled in).
//!
//! `main` prints one error chain and exits non-zero.

mod bench;
mod cli;
mod demo;

fn main() -> std::process::ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(
        "warn,wgpu_hal=error,wgpu_core=error,naga=error,rustdds=error,ros2_client=error",
    ))
    .format_timestamp(None)
    .init();
    match cli::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
