//! The demo files, found at run time: `urdf/demo_arm.urdf`, `bags/demo` and
//! `config/demo_arm.yaml` of a checkout (or of a copy of its `urdf/`, `bags/` and `config/`
//! folders). Nothing about the checkout the binary was built in is compiled in, so an installed
//! binary looks in, in order: `$IST_MONITOR_DEMO_DIR`, the current folder, and the folders above
//! the executable (`target/release/ist_monitor` of a checkout). `../shared` is found beside the
//! demo folder, or at `$IST_MONITOR_SHARED`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

/// The demo robot, relative to the demo folder.
pub const URDF: &str = "urdf/demo_arm.urdf";
/// The bundled demo bag.
pub const BAG: &str = "bags/demo";
/// The demo arm's parameters file.
pub const CONFIG: &str = "config/demo_arm.yaml";

/// The folder that holds the demo files.
pub fn dir() -> Result<PathBuf> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(d) = std::env::var_os("IST_MONITOR_DEMO_DIR") {
        candidates.push(d.into());
    }
    if let Ok(d) = std::env::current_dir() {
        candidates.push(d);
    }
    if let Ok(exe) = std::env::current_exe() {
        candidates.extend(exe.ancestors().skip(1).take(4).map(Path::to_path_buf));
    }
    if let Some(d) = candidates.iter().find(|d| d.join(URDF).is_file()) {
        return Ok(d.clone());
    }
    bail!(
        "the demo files ({URDF}, {BAG}, {CONFIG}) were not found in {}: run from a checkout, \
         set IST_MONITOR_DEMO_DIR, or name your own files (--urdf, --config, a bag)",
        candidates
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// `path`, or the demo file `demo` when `path` is not given.
pub fn or_demo(path: &Option<PathBuf>, demo: &str) -> Result<PathBuf> {
    match path {
        Some(p) => Ok(p.clone()),
        None => Ok(dir()?.join(demo)),
    }
}

/// The shared data folder (`../shared` beside the demo folder, or `$IST_MONITOR_SHARED`).
pub fn shared(given: &Option<PathBuf>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p.clone());
    }
    if let Some(d) = std::env::var_os("IST_MONITOR_SHARED") {
        return Ok(d.into());
    }
    let d = dir()?.join("../shared");
    if !d.join("robots").is_dir() {
        bail!(
            "the shared data folder was not found at {} (give --shared DIR or set IST_MONITOR_SHARED)",
            d.display()
        );
    }
    Ok(d)
}
