//! The `ist_monitor` binary on the demo robot: the README's main command, JSON, sphere export,
//! and a corrupt cache that is rebuilt with a warning.

mod common;

use common::ist_monitor;

#[test]
fn build_demo_robot_json_export_and_cache() {
    let cache = tempfile::tempdir().expect("tmp");
    let export = cache.path().join("spheres.json");
    let run = |extra: &[&str]| {
        let out = ist_monitor()
            .args(["build", "--max-spheres", "200", "--json", "--cache-dir"])
            .arg(cache.path())
            .args(extra)
            .output()
            .expect("runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        (json, String::from_utf8_lossy(&out.stderr).into_owned())
    };
    // --validate: every sphere and node of every demo link checked exactly (primitives, a
    // two-element link, meshes).
    let (first, _) = run(&[
        "--validate",
        "--export-spheres",
        export.to_str().expect("utf8"),
    ]);
    let links = first["links"].as_array().expect("links");
    assert_eq!(links.len(), 9);
    for l in links {
        for field in ["name", "spheres", "coverage", "gap_m", "build_s"] {
            assert!(l.get(field).is_some(), "missing {field} in {l}");
        }
        assert_eq!(l["origin"], "built");
    }
    // A sphere primitive is its own best packing: one sphere, inscribed in the tessellation.
    let wrist = links
        .iter()
        .find(|l| l["name"] == "wrist_2_link")
        .expect("sphere link");
    assert_eq!(wrist["spheres"], 1);
    assert!(wrist["coverage"].as_f64().expect("coverage") > 0.99);
    let exported: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&export).expect("export")).expect("json");
    let gripper = exported["gripper_link"]
        .as_array()
        .expect("gripper spheres");
    assert_eq!(
        gripper.len() as u64,
        links
            .iter()
            .find(|l| l["name"] == "gripper_link")
            .expect("link")["spheres"]
            .as_u64()
            .expect("n")
    );
    assert_eq!(gripper[0].as_array().expect("sphere").len(), 4);

    let (second, _) = run(&[]);
    assert!(second["links"]
        .as_array()
        .expect("links")
        .iter()
        .all(|l| l["origin"] == "cache"));

    // Corrupt one cache file: it is rebuilt with a warning, never trusted.
    let file = std::fs::read_dir(cache.path())
        .expect("dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|e| e == "ist"))
        .expect("a cache file");
    let mut bytes = std::fs::read(&file).expect("read");
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0xff;
    std::fs::write(&file, bytes).expect("write");
    let (third, stderr) = run(&[]);
    assert!(
        stderr.contains("checksum mismatch") && stderr.contains("rebuilding"),
        "{stderr}"
    );
    let built = third["links"]
        .as_array()
        .expect("links")
        .iter()
        .filter(|l| l["origin"] == "built")
        .count();
    assert_eq!(built, 1);
    // The rebuilt link has the same spheres; its gap bound may differ within the branch and
    // bound's tolerance (5e-5 m), since threads prune against a shared bound.
    for (rebuilt, cached) in third["links"]
        .as_array()
        .expect("a")
        .iter()
        .zip(second["links"].as_array().expect("a"))
    {
        assert_eq!(rebuilt["spheres"], cached["spheres"]);
        assert_eq!(rebuilt["coverage"], cached["coverage"]);
        let gap = |l: &serde_json::Value| l["gap_m"].as_f64().expect("gap");
        assert!((gap(rebuilt) - gap(cached)).abs() <= 5e-5);
    }
}

#[test]
fn bad_options_are_refused_with_their_name() {
    let out = ist_monitor()
        .args(["build", "--max-spheres", "0"])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-spheres"));
}
