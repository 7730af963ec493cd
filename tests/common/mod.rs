//! Helpers shared by the integration tests: the shared data folder and small file writers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// `../shared` beside the checkout. In CI (CI set) it must exist; elsewhere a test may skip
/// with a printed reason when it is absent.
pub fn shared() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared");
    if dir.join("robots").is_dir() {
        return Some(dir);
    }
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but ../shared is missing: the shared robots are required in CI");
    }
    eprintln!("skipped: ../shared is absent and CI is not set");
    None
}

/// Writes a binary STL of `triangles` (vertex triples).
pub fn write_stl(path: &Path, triangles: &[[[f32; 3]; 3]]) {
    let mut out = vec![0u8; 80];
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for t in triangles {
        out.extend_from_slice(&[0u8; 12]);
        for v in t {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.extend_from_slice(&[0u8; 2]);
    }
    std::fs::write(path, out).expect("write stl");
}

/// The 12 outward triangles of an axis-aligned box from `lo` to `hi`.
pub fn box_triangles(lo: [f32; 3], hi: [f32; 3]) -> Vec<[[f32; 3]; 3]> {
    let v = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ]
    .iter()
    .map(|f: &[usize; 3]| [v(f[0]), v(f[1]), v(f[2])])
    .collect()
}

/// A one-link URDF whose collision is `geometry` (the XML of a `<geometry>` child).
pub fn one_link_urdf(geometry: &str) -> String {
    format!(
        r#"<robot name="t"><link name="body"><collision><geometry>{geometry}</geometry></collision></link></robot>"#
    )
}
