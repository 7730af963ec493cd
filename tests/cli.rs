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
        // The fingers share one file, the same solid in their frames: packed once.
        let shared = l["name"] == "finger_right";
        assert_eq!(l["origin"], if shared { "shared" } else { "built" }, "{l}");
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
        .all(|l| l["origin"]
            == if l["name"] == "finger_right" {
                "shared"
            } else {
                "cache"
            }));

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

/// Nothing about the checkout is compiled into the binary: a copy of it outside the checkout,
/// run from another folder, says where it looked for the demo files and how to name them, and
/// finds them through `IST_MONITOR_DEMO_DIR`. A config without `robot_description` is refused,
/// naming the parameter, instead of monitoring some robot.
#[test]
fn the_binary_finds_the_demo_at_run_time_only() {
    let dir = tempfile::tempdir().expect("tmp");
    let exe = dir.path().join("ist_monitor");
    std::fs::copy(env!("CARGO_BIN_EXE_ist_monitor"), &exe).expect("copy the binary");
    let run = |args: &[&str], demo: Option<&str>| {
        let mut c = std::process::Command::new(&exe);
        c.args(args)
            .current_dir(dir.path())
            .env_remove("IST_MONITOR_DEMO_DIR");
        if let Some(d) = demo {
            c.env("IST_MONITOR_DEMO_DIR", d);
        }
        c.output().expect("runs")
    };
    let out = run(&["poses"], None);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("demo files") && e.contains("--urdf"), "{e}");
    let out = run(&["poses"], Some(env!("CARGO_MANIFEST_DIR")));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("camera_link"));
    // A parameters file without robot_description.
    let config = dir.path().join("params.yaml");
    std::fs::write(
        &config,
        "ist_monitor:\n  ros__parameters:\n    mode: exact\n",
    )
    .unwrap();
    let out = run(
        &[
            "replay",
            common::DEMO_BAG,
            "--config",
            config.to_str().unwrap(),
        ],
        None,
    );
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("robot_description"), "{e}");
}

/// `ist_monitor query` on the demo robot with a PLY cloud: the nearest point, the counts, the
/// "nothing within" and "no points" outcomes, and errors for a bad sensor pose or link name.
#[test]
fn query_demo_robot() {
    let dir = tempfile::tempdir().expect("tmp");
    // Four points in the camera frame: NaN, one 0.3 m in front of the camera, two far away.
    let ply = dir.path().join("cloud.ply");
    let points = [
        [f32::NAN; 3],
        [0.0, 0.0, 0.3],
        [0.0, 0.0, 9.0],
        [5.0, 5.0, 5.0],
    ];
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    for p in points {
        for v in p {
            bytes.extend(v.to_le_bytes());
        }
    }
    std::fs::write(&ply, bytes).expect("ply");
    let query = |extra: &[&str]| {
        let mut cmd = ist_monitor();
        cmd.args(["query", "--max-spheres", "200", "--json", "--cache-dir"])
            .arg(dir.path())
            .arg("--cloud")
            .arg(&ply)
            .args(extra);
        cmd.output().expect("runs")
    };
    // The cloud in the root frame, the camera at (1.2, 0, 0.8) looking along −x (as the demo
    // URDF's camera_link): the point 0.3 m ahead is at x = 0.9.
    let pose = ["--sensor-pose", "1.2 0 0.8 0 -0.7071068 0 0.7071068"];
    let out = query(&[&pose[..], &["--mode", "certified"]].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(json["outcome"], "nearest");
    assert_eq!(json["nearest"]["point_index"], 1);
    let p = &json["nearest"]["point_root"];
    assert!((p[0].as_f64().unwrap() - 0.9).abs() < 1e-6, "{p}");
    assert!((p[2].as_f64().unwrap() - 0.8).abs() < 1e-6, "{p}");
    let (d, lower) = (
        json["nearest"]["distance_m"].as_f64().unwrap(),
        json["nearest"]["lower_m"].as_f64().unwrap(),
    );
    assert!(lower <= d && d > 0.0, "{lower} {d}");
    assert_eq!(json["counts"]["invalid"], 1);
    assert_eq!(json["counts"]["outside_roi"], 2);
    assert_eq!(json["links"].as_array().unwrap().len(), 9);

    let out = query(&[&pose[..], &["--max-distance", "0.01"]].concat());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(json["outcome"], "nothing_within_max_distance");

    // The GPU backend gives the same answer. With no usable GPU (here: only Metal allowed, on
    // Linux), it falls back to the CPU with one message.
    let certified = &[&pose[..], &["--mode", "certified"]].concat();
    let gpu = query(&[&certified[..], &["--backend", "gpu"]].concat());
    let gpu_json: serde_json::Value = serde_json::from_slice(&gpu.stdout).expect("json");
    let d_gpu = gpu_json["nearest"]["distance_m"].as_f64().unwrap();
    assert!((d_gpu - d).abs() < 1e-5, "{d_gpu} {d}");
    let mut cmd = ist_monitor();
    cmd.env("WGPU_BACKEND", "metal")
        .args([
            "query",
            "--max-spheres",
            "200",
            "--json",
            "--backend",
            "gpu",
            "--cache-dir",
        ])
        .arg(dir.path())
        .arg("--cloud")
        .arg(&ply)
        .args(certified);
    let out = cmd.output().expect("runs");
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.matches("no usable GPU").count(), 1, "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(json["backend"], "cpu");
    assert_eq!(json["nearest"]["distance_m"].as_f64().unwrap(), d);

    let out = query(&["--sensor-pose", "1 2 3"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("7 finite numbers"));
    let out = query(&["--links", "no_such_link"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no_such_link"));
}

/// `config/README.md` shows the declared parameters as `ist_monitor params` prints them, and
/// every shipped config file loads.
#[test]
fn config_files_and_their_documentation() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("config/README.md")).unwrap();
    assert!(
        readme.contains(&ist_monitor::config::markdown_table()),
        "config/README.md is out of date: paste `ist_monitor params` into it"
    );
    let mut files = 0;
    for entry in std::fs::read_dir(root.join("config")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "yaml") {
            let c = ist_monitor::config::Config::load(&path, &[])
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(!c.sources.is_empty());
            // package:// descriptions resolve (to ../shared for the third-party robots).
            if common::shared().is_some() {
                let urdf = c
                    .robot_urdf()
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(urdf.exists(), "{}: {}", path.display(), urdf.display());
            }
            files += 1;
        }
    }
    assert!(files >= 2);
}

/// The ROS package: `package.xml` names the package, its licence (Cargo.toml's) and colcon's
/// `ament_cargo` build type; what Cargo.toml installs to share/ exists; the launch file
/// declares the arguments docs/launch.md names and defaults to a shipped parameters file.
#[test]
fn the_ros_package_is_declared() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let xml = std::fs::read_to_string(root.join("package.xml")).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let text = |tag: &str| {
        doc.descendants()
            .find(|n| n.has_tag_name(tag))
            .and_then(|n| n.text())
            .unwrap_or_default()
            .to_owned()
    };
    assert_eq!(doc.root_element().attribute("format"), Some("3"));
    assert_eq!(text("name"), env!("CARGO_PKG_NAME"));
    assert_eq!(text("version"), env!("CARGO_PKG_VERSION"));
    assert_eq!(text("license"), env!("CARGO_PKG_LICENSE"));
    assert_eq!(text("build_type"), "ament_cargo");
    let cargo = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let share = cargo
        .lines()
        .find_map(|l| l.strip_prefix("install_to_share = "))
        .expect("[package.metadata.ros] install_to_share");
    for dir in share.trim_matches(['[', ']']).split(',') {
        let dir = dir.trim().trim_matches('"');
        assert!(root.join(dir).is_dir(), "install_to_share: {dir}");
    }
    let launch = std::fs::read_to_string(root.join("launch/ist_monitor.launch.py")).unwrap();
    for arg in ["params_file", "namespace", "use_sim_time", "log_level"] {
        assert!(
            launch.contains(&format!("DeclareLaunchArgument(\"{arg}\"")),
            "{arg}"
        );
    }
    assert!(launch.contains("\"config\", \"ur5e.yaml\""));
    assert!(root.join("config/ur5e.yaml").exists());
    assert!(root.join("LICENSE").exists());
}

/// `bench monitor` on our own demo bag: each monitor replays the bag up to its first cloud
/// first, so the generated bag's joint states place the robot (it once measured a lone cloud
/// with no joint state, and the pass never ran). The rows follow the config: its volume, its
/// shadow and the other.
#[test]
fn bench_monitor_runs_on_the_demo_bag() {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = ist_monitor()
        .current_dir(root)
        .args(["bench", "monitor", "--unseen-only", "--runs", "2"])
        .args(["--config", "config/demo_arm.yaml", "bags/demo"])
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for row in [
        "unseen space, the config's volume, shadow apart (67500 cells)",
        "unseen space, the config's volume, shadow count (67500 cells)",
        "unseen space, 2 × 2 × 2 m at 2 cm, shadow apart",
    ] {
        assert!(stdout.contains(row), "no row {row:?}:\n{stdout}");
    }
}
