//! The `ist_monitor` command: a thin shell over [`ist_monitor::cli`].

fn main() -> std::process::ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(
        "warn,wgpu_hal=error,wgpu_core=error,naga=error,rustdds=error,ros2_client=error",
    ))
    .format_timestamp(None)
    .init();
    match ist_monitor::cli::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
