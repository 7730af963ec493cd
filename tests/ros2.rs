//! The node against the real ROS 2 client: rclpy on rmw_fastrtps_cpp (Fast DDS, ROS 2 Jazzy's
//! default middleware, from the package index; `tests/python/rclpy_interop.py`), inside a
//! private network namespace with only loopback, as `ros2 param` and a ROS 2 node reach it.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::ist_monitor;

/// `ros2 param list/describe/get/set` through rclpy: every declared parameter is on the graph
/// with its type, meaning, unit and range; a read-only one and one that would weaken
/// protection while the stop is raised are refused with the reason; an exclusion volume added
/// at run time (atomically, with its parameters) drops exactly the cloud's points inside it,
/// counted in the diagnostics; a source disabled and enabled again is left and then heard
/// anew; an object attached at run time joins the robot (the rest of the cloud is measured to
/// it) and leaves it when released; each change is announced on `/parameter_events`.
#[test]
fn rclpy_lists_describes_and_sets_the_nodes_parameters() {
    if !common::in_private_network("rclpy_lists_describes_and_sets_the_nodes_parameters") {
        return;
    }
    let Some(python) = common::rclpy_python() else {
        return;
    };
    let node = ist_monitor()
        .args(common::at_rest_args())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let _reap = common::Reap(vec![node.id()]);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/rclpy_interop.py");
    let out = common::json_output(
        Command::new(python)
            .arg(script)
            .args(["params", "/ist_monitor"]),
    );
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    let log = node.wait_with_output().unwrap();
    assert!(log.status.success());

    // Every parameter of the declaration table, expanded for the one source.
    let listed: Vec<&str> = out["list"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let expected = ist_monitor::config::Config::default().parameters();
    assert_eq!(listed.len(), expected.len());
    for p in &expected {
        assert!(listed.contains(&p.name.as_str()), "{} not listed", p.name);
    }
    // Types as ROS 2 numbers them: double, integer, string, string array.
    assert_eq!(out["types"], serde_json::json!([3, 2, 4, 9]));
    let stop = &out["describe"][0];
    assert_eq!(
        stop["description"],
        ist_monitor::config::PARAMETERS
            .iter()
            .find(|d| d.name == "stop_distance")
            .unwrap()
            .doc
    );
    assert!(stop["constraints"].as_str().unwrap().contains("unit: m"));
    assert_eq!(stop["read_only"], false);
    assert_eq!(stop["range"][0], serde_json::json!([0.0, "inf"]));
    assert_eq!(out["describe"][1]["read_only"], true);
    assert_eq!(
        out["get"],
        serde_json::json!([0.1, 1, ["camera"], "/camera/depth/points"])
    );

    let refused = |key: &str, says: &str| {
        let r = &out[key][0];
        assert_eq!(r["successful"], false, "{key}: {r}");
        assert!(r["reason"].as_str().unwrap().contains(says), "{key}: {r}");
    };
    refused("set_read_only", "read-only");
    refused("set_weakening_while_stopped", "safety stop is raised");

    // With the cloud flowing and the stop released, the volume is taken whole and drops the
    // 10 of 20 columns of the plane that lie inside it.
    assert_eq!(out["released"], true, "{out}");
    assert_eq!(out["add_volume"]["successful"], true, "{out}");
    assert_eq!(out["points_excluded"], 200);
    assert_eq!(
        out["get_volume"],
        serde_json::json!([["patch"], [0.1, 0.2, 0.5], "box"])
    );
    assert_eq!(out["raise_stop"][0]["successful"], true);
    assert_eq!(out["remove_volume"][0]["successful"], true);
    assert_eq!(out["after"], serde_json::json!([0.25, [], null]));

    // The only source disabled: nothing watches the cell, ERROR; enabled again, the node
    // subscribes anew and its clouds release the stop.
    assert_eq!(out["disable"][0]["successful"], true, "{out}");
    assert_eq!(out["nothing_watches"], true, "{out}");
    assert_eq!(out["enable"][0]["successful"], true, "{out}");
    assert_eq!(out["released_again"], true, "{out}");

    // A shield attached around half the plane at run time: the monitor is rebuilt, the shield's
    // points are the robot's, and the rest of the plane is measured to it, within the stop
    // distance; released, the plane is far again.
    assert_eq!(out["attach"]["successful"], true, "{out}");
    assert_eq!(out["shield_nearest"], true, "{out}");
    assert_eq!(out["shield_status"]["level"], 2, "{out}");
    let d = out["shield_status"]["distance_m"].as_f64().unwrap();
    assert!((0.0..0.05).contains(&d), "{out}");
    assert_eq!(out["detach"][0]["successful"], true, "{out}");
    assert_eq!(out["released_after_detach"], true, "{out}");
    eprintln!(
        "attached at run time: link shield measured {:.3} s after the set",
        out["attach_s"]
    );

    // The seven changes taken, announced in order; nothing refused was.
    let events = out["events"].as_array().unwrap();
    assert_eq!(events.len(), 7, "{events:?}");
    assert!(events[0]["new"]
        .as_array()
        .unwrap()
        .contains(&serde_json::json!("patch.frame")));
    assert_eq!(
        events[1]["changed"],
        serde_json::json!({"stop_distance": 0.25})
    );
    assert!(events[2]["deleted"]
        .as_array()
        .unwrap()
        .contains(&serde_json::json!("patch.size")));
}

/// The node started as a launch file starts it, with simulated time: launch_ros's argument list
/// for `Node(package='ist_monitor', executable='ist_monitor', name='cell_monitor',
/// namespace='cell1', parameters=[package_file, {...}], remappings=[(cloud, realsense)],
/// ros_arguments=['--log-level', 'warn'])` — no subcommand, the package's file (`/**`) and the
/// dict launch_ros writes to a temporary file (the node's full name as key, lists tagged as
/// Python tuples), the cloud source remapped. rclpy then drives `/clock`: nothing on it yet is
/// ERROR naming it; clouds stamped with simulated time 1000 s (stale by the wall clock) are
/// answered OK, and the outputs carry simulated stamps; `/clock` silent is ERROR again; a
/// clock restarted 500 s back (a bag played again) is taken after the node forgets what it had.
#[test]
fn rclpy_runs_the_node_as_launch_does_on_simulated_time() {
    if !common::in_private_network("rclpy_runs_the_node_as_launch_does_on_simulated_time") {
        return;
    }
    let Some(python) = common::rclpy_python() else {
        return;
    };
    // The demo arm's trees in the cache (the parameters below pack as the demo's do).
    common::demo_trees();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let package_file = dir.path().join("cell.yaml");
    std::fs::write(
        &package_file,
        format!(
            "/**:\n  ros__parameters:\n    robot_description: {}\n    backend: cpu\n    \
             max_spheres: 8192\n    fixed_joint_state:\n      names: [shoulder_pan, \
             shoulder_lift, elbow, wrist_1, wrist_2, wrist_3, finger_left_joint]\n    \
             stop_distance: 0.1\n    camera:\n      min_range: 0.1\n",
            root.join("urdf/demo_arm.urdf").display()
        ),
    )
    .unwrap();
    let launch_file = dir.path().join("launch_params_x1");
    std::fs::write(
        &launch_file,
        "/cell1/cell_monitor:\n  ros__parameters:\n    use_sim_time: true\n    clock_timeout: \
         0.5\n    stop_distance: 0.12\n    fixed_joint_state.positions: !!python/tuple\n    \
         - 0.0\n    - 0.0\n    - 0.0\n    - 0.0\n    - 0.0\n    - 0.0\n    - 0.0\n",
    )
    .unwrap();
    let node = ist_monitor()
        .args(["--ros-args", "--log-level", "warn", "--ros-args"])
        .args(["-r", "__node:=cell_monitor", "-r", "__ns:=/cell1"])
        .arg("--params-file")
        .arg(&package_file)
        .arg("--params-file")
        .arg(&launch_file)
        .args(["-r", "/camera/depth/points:=/realsense/depth/points"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let _reap = common::Reap(vec![node.id()]);
    let script = root.join("tests/python/rclpy_interop.py");
    let out = common::json_output(Command::new(python).arg(script).args([
        "sim",
        "/cell1/cell_monitor",
        "/realsense/depth/points",
    ]));
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    let log = node.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&log.stderr);
    assert!(
        log.is_empty() || !log.contains("INFO"),
        "--log-level warn: {log}"
    );
    // The launch dict's value wins over the package file's; the rest is the file's.
    assert_eq!(
        out["get"],
        serde_json::json!([0.12, true, "cpu", 0.3]),
        "{out}"
    );
    assert_eq!(out["waits_for_clock"], true, "{out}");
    assert_eq!(out["ok_on_sim_time"], true, "{out}\n{log}");
    let stamp = out["stamp_s"].as_f64().unwrap();
    assert!((1000.0..1100.0).contains(&stamp), "{out}");
    assert_eq!(out["silent_clock"], true, "{out}");
    assert_eq!(out["ok_after_jump"], true, "{out}\n{log}");
    let stamp = out["stamp_after_jump_s"].as_f64().unwrap();
    assert!((500.0..600.0).contains(&stamp), "{out}");
    assert!(log.contains("/clock went back"), "{log}");
}
