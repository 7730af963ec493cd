//! Every input the fuzzers found a fault with (`fuzz/regressions/<target>/`), run through the
//! same target body on stable, so that CI keeps them fixed without nightly. A target passes when
//! the decoder returns; a panic fails the test and names the input.

#[path = "../fuzz/targets.rs"]
mod targets;

use std::path::Path;

/// A fuzz target's body.
type Target = fn(&[u8]);

const TARGETS: &[(&str, Target)] = &[
    ("pointcloud2", targets::pointcloud2),
    ("messages", targets::messages),
    ("pcd", targets::pcd),
    ("ply", targets::ply),
    ("mcap", targets::mcap),
    ("params", targets::params),
    ("urdf", targets::urdf),
    ("mesh", targets::mesh),
];

#[test]
fn fuzz_findings_stay_fixed() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions");
    let mut ran = 0;
    for (name, target) in TARGETS {
        let dir = root.join(name);
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let data = std::fs::read(entry.path()).unwrap();
            let outcome = std::panic::catch_unwind(|| target(&data));
            assert!(outcome.is_ok(), "{name}: {} panics", entry.path().display());
            ran += 1;
        }
    }
    // Every folder holds what it says: a target name of the list.
    for entry in std::fs::read_dir(&root).unwrap().flatten() {
        let name = entry.file_name();
        assert!(
            TARGETS.iter().any(|(t, _)| name == *t),
            "fuzz/regressions/{name:?} is not a fuzz target"
        );
    }
    assert!(ran > 0, "no regression input in {}", root.display());
}
