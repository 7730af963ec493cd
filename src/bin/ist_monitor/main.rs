//! The `ist_monitor` command: the application on top of the `ist_monitor` library.
//!
//! - `cli/`: one module per group of subcommands (`build` and `poses`, `query`, `replay` and
//!   `generate`, the ROS 2 `node`, `play` and `record`); every option that is also a node
//!   parameter takes its name, default and meaning from the library's parameter table
//!   (`ist_monitor::config::PARAMETERS`).
//! - `bench/`: `bench packing`, `bench query` (error against run time, with its plots) and
//!   `bench gpu`, over the real scenes of `../shared` (`bench/scenes.rs`, which the criterion
//!   benches and the tests include too).
//! - `args.rs`, `choice.rs` and `setup.rs`: the options and parsers (a flag from a library
//!   `Choice`), and the tree build and monitor with their progress lines, that `cli/` and
//!   `bench/` share (neither imports the other's).
//! - `demo.rs`: where the demo robot, bag and config are found at run time (nothing about the
//!   checkout is compiled in).
//!
//! `main` prints one error chain and exits non-zero.

mod args;
mod bench;
mod choice;
mod cli;
mod demo;
mod setup;

fn main() -> std::process::ExitCode {
    runtime_dir();
    // Ours at info (the node's "up" line, a source's first cloud, the GPU found), the rest at
    // warn; the GPU and DDS crates only at error. RUST_LOG replaces all of it.
    // `--ros-args --log-level` sets ours (a launch file's `ros_arguments`).
    let args = cli::args();
    let ours = cli::ros_log_level(&args).unwrap_or(log::LevelFilter::Info);
    let filter = format!(
        "warn,ist_monitor={ours},wgpu_hal=error,wgpu_core=error,naga=error,rustdds=error,\
         ros2_client=error"
    )
    .to_lowercase();
    // stderr, and the node's own lines on /rosout once it runs (`node::rosout`).
    let logger =
        env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(filter))
            .format_timestamp(None)
            .build();
    let max = logger.filter();
    let _ = ist_monitor::node::rosout::install(Box::new(logger), max);
    match cli::run(args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each said once: our error types already print their
/// source (`"{path}: {source}"`), and a context that names a file is not repeated by a cause
/// that starts with the same file.
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let mut c = cause.to_string();
        if out.contains(&c) {
            continue;
        }
        if let Some(last) = out.rsplit(' ').next().filter(|w| !w.is_empty()) {
            if let Some(rest) = c.strip_prefix(last) {
                c = rest.trim_start_matches(':').trim_start().to_owned();
            }
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&c);
    }
    out
}

/// A private `XDG_RUNTIME_DIR` where none is set (services, containers, `sudo`), made before any
/// thread starts: the Vulkan driver's window-system code otherwise prints "error:
/// XDG_RUNTIME_DIR is invalid or not set" on every GPU probe, and a safety node must not teach
/// its operators to ignore error lines. Qt and systemd-less desktops fall back the same way.
fn runtime_dir() {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    let usable = |p: &std::path::Path| {
        std::fs::metadata(p).is_ok_and(|m| m.is_dir() && m.permissions().mode() & 0o077 == 0)
    };
    if std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| usable(std::path::Path::new(&d))) {
        return;
    }
    // Our uid: the owner of our own /proc entry.
    let Ok(uid) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return;
    };
    // runtime-UID, or one of this process where that name is taken by another user (inside a
    // user namespace, for one).
    for name in [
        format!("runtime-{uid}"),
        format!("runtime-{uid}-{}", std::process::id()),
    ] {
        let dir = std::env::temp_dir().join(name);
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        if std::fs::metadata(&dir).is_ok_and(|m| m.uid() == uid) && usable(&dir) {
            // Sound: no other thread exists yet (edition 2021, where set_var is safe).
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
            return;
        }
    }
}
