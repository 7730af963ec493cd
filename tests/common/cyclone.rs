//! The secured Cyclone DDS peer (tests/peers/cyclone_secure_peer.c) and the SROS2 keystore tool
//! (tools/sros2_keystore.py), for the security tests: the peer is compiled here, at test time,
//! with Cyclone's idlc and gcc against Debian's cyclonedds-dev (built with OpenSSL, with the
//! DDS-Security plugins); a machine without them skips (CI: fails, `.ci/run` installs them).

use std::path::{Path, PathBuf};
use std::process::Command;

/// Debian's folder of Cyclone's DDS-Security plugins (libddsc0debian).
pub const PLUGINS: &str = "/usr/lib/x86_64-linux-gnu/libddsc0debian";

/// `python3 tools/sros2_keystore.py ARGS`, asserted to succeed.
pub fn keystore_tool(args: &[&str]) {
    let out = keystore_command(args).output().unwrap();
    assert!(
        out.status.success(),
        "sros2_keystore.py {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `python3 tools/sros2_keystore.py ARGS`, to run.
pub fn keystore_command(args: &[&str]) -> Command {
    let mut c = Command::new("python3");
    c.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/sros2_keystore.py"));
    c.args(args);
    c
}

/// Builds the peer into `dir` and returns its path; None (after a printed skip) where Cyclone's
/// development files, idlc, gcc or the security plugins are missing and CI is unset.
pub fn build_peer(dir: &Path) -> Option<PathBuf> {
    let plugins = ["auth", "ac", "crypto"]
        .map(|p| Path::new(PLUGINS).join(format!("libdds_security_{p}.so")));
    let missing = if !plugins.iter().all(|p| p.is_file()) {
        Some("Cyclone's DDS-Security plugins (libddsc0debian)")
    } else if Command::new("idlc").arg("-v").output().is_err() {
        Some("Cyclone's idlc (cyclonedds-tools)")
    } else if Command::new("gcc").arg("--version").output().is_err() {
        Some("gcc")
    } else if !Path::new("/usr/include/dds/dds.h").is_file() {
        Some("Cyclone's headers (cyclonedds-dev)")
    } else {
        None
    };
    if let Some(what) = missing {
        if std::env::var_os("CI").is_some() {
            panic!("CI is set but {what} is missing: .ci/run installs it");
        }
        super::skip(&format!("{what} is absent and CI is not set"));
        return None;
    }
    let peers = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers");
    let idl = Command::new("idlc")
        .arg("-o")
        .arg(dir)
        .arg(peers.join("ros_msgs.idl"))
        .output()
        .unwrap();
    assert!(
        idl.status.success(),
        "idlc: {}",
        String::from_utf8_lossy(&idl.stderr)
    );
    let exe = dir.join("cyclone_secure_peer");
    let cc = Command::new("gcc")
        .args(["-O1", "-Wall", "-Werror", "-o"])
        .arg(&exe)
        .arg(peers.join("cyclone_secure_peer.c"))
        .arg(dir.join("ros_msgs.c"))
        .arg("-I")
        .arg(dir)
        .args(["-lddsc", "-lm"])
        .output()
        .unwrap();
    assert!(
        cc.status.success(),
        "gcc: {}",
        String::from_utf8_lossy(&cc.stderr)
    );
    Some(exe)
}

/// The peer's JSON line (its last line of standard output).
pub fn peer_json(out: &std::process::Output) -> serde_json::Value {
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().last().unwrap_or("");
    serde_json::from_str(line).unwrap_or_else(|e| {
        panic!(
            "peer output {text:?} ({e}); stderr: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}
