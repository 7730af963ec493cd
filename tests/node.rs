//! The live node over DDS, inside a private network namespace with only loopback
//! (`../shared/tools/netns-run`): the test re-executes itself there, then starts the node, a
//! recorder of its outputs and `ist_monitor play` of the demo bag as separate processes.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::Duration;

use std::path::Path;

use common::ist_monitor;
use ist_monitor::bag::read_messages;
use ist_monitor::monitor::outputs::OutputTopic;
use ist_monitor::msg::{self, DiagnosticArray, DiagnosticStatus, Float64};
use ist_monitor::query::{Backend, Engine, LinkSelection, Mode, QueryOptions};

/// The node with `args`, its output and log kept (read them with `wait_with_output`).
fn spawn_node(args: &[&str]) -> Child {
    ist_monitor()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn spawn(args: &[&str]) -> Child {
    ist_monitor()
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap()
}

/// `play --json --wait WAIT --measure MEASURE [BAG]` run by `command` (an `ist_monitor()` with
/// the environment it needs): the summary it prints.
fn play_measured(
    mut command: Command,
    wait: &str,
    measure: &str,
    bag: Option<&Path>,
) -> serde_json::Value {
    command.args(["play", "--json", "--wait", wait, "--measure", measure]);
    if let Some(bag) = bag {
        command.arg(bag);
    }
    common::json_output(&mut command)
}

/// A play published `published` clouds (or images) and at least `at_least` were answered.
fn assert_answered(run: &serde_json::Value, published: u64, at_least: u64) {
    assert_eq!(run["clouds_published"], published);
    let received = run["outputs_received"].as_u64().unwrap();
    assert!(
        received >= at_least,
        "only {received} of {published} answered: {run}"
    );
}

/// Stops `node` with SIGTERM; it exits 0. Its log.
fn stop(node: Child) -> String {
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    let out = node.wait_with_output().unwrap();
    assert!(out.status.success());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A normal start and stop logs no error line (an operator must not learn to ignore them).
fn assert_no_error_lines(log: &str) {
    for line in log.lines() {
        assert!(
            !line.starts_with("[ERROR") && !line.to_lowercase().starts_with("error"),
            "an error line in a normal run: {line}"
        );
    }
}

/// The node serves the demo bag: every cloud gets its outputs, with `--ros-args` remappings;
/// when the source stops, an ERROR diagnostic comes within `source_timeout` (0.5 s here), and
/// when it plays again, the node recovers.
#[test]
fn node_serves_clouds_and_reports_a_stopped_source() {
    if !common::in_private_network("node_serves_clouds_and_reports_a_stopped_source") {
        return;
    }
    common::demo_trees();
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("outputs.mcap");
    let record_arg = record.to_str().unwrap();
    let node = spawn_node(&[
        "node",
        "--ros-args",
        "-r",
        "__node:=watch",
        "-r",
        "__ns:=/robot1",
        "-p",
        "camera.source_timeout:=0.5",
        // Every distance is counted below: none withheld as late on a loaded machine.
        "-p",
        "latency_budget:=10.0",
    ]);
    let mut recorder = spawn(&[
        "record",
        "--node",
        "/robot1/watch",
        "--duration",
        "11",
        "--out",
        record_arg,
    ]);
    // The node builds or loads its trees first; the player waits for discovery.
    std::thread::sleep(Duration::from_secs(2));
    let play =
        |wait: &str| play_measured(ist_monitor(), wait, "/robot1/watch/link_distances", None);
    let first = play("1.5");
    std::thread::sleep(Duration::from_millis(1500));
    let second = play("0.2");
    assert!(recorder.wait().unwrap().success());
    // SIGTERM: the node stops cleanly.
    let log = stop(node);
    assert!(log.contains("up: node /robot1/watch"), "{log}");
    assert_no_error_lines(&log);
    for run in [&first, &second] {
        assert_answered(run, 30, 27);
    }
    // What the node published, in order: every topic of the output table, as the node, replay
    // and record all take it from `OutputTopic`.
    let messages = read_messages(&record, &|_, _| true).unwrap();
    for topic in [
        OutputTopic::MinDistance,
        OutputTopic::LinkDistances,
        OutputTopic::ClosestPoints,
        OutputTopic::Diagnostics,
        OutputTopic::SafetyStop,
    ] {
        let name = topic.topic("/robot1/watch");
        assert!(
            messages.iter().any(|m| *m.topic == *name),
            "nothing recorded on {name}"
        );
    }
    let diagnostics: Vec<(u64, DiagnosticStatus)> = messages
        .iter()
        .filter(|m| &*m.topic == "/diagnostics")
        .map(|m| {
            let d: DiagnosticArray = msg::decode(&m.data).unwrap();
            (m.log_time_ns, d.status[0].clone())
        })
        .collect();
    let stale = |s: &DiagnosticStatus| s.message.contains("no cloud for");
    let first_stale = diagnostics
        .iter()
        .position(|(_, s)| stale(s))
        .expect("a stale-source ERROR");
    let (t_stale, status) = &diagnostics[first_stale];
    assert_eq!(status.level, DiagnosticStatus::ERROR);
    assert_eq!(status.name, "watch: camera");
    assert!(status
        .values
        .iter()
        .any(|kv| kv.key == "fault" && kv.value == "stale_source"));
    // The last distance before it, and how long the node took to report the silence.
    let (t_last, _) = diagnostics[..first_stale]
        .iter()
        .rev()
        .find(|(_, s)| s.message.starts_with("min distance"))
        .expect("distances before the source stopped");
    let reported_after = (t_stale - t_last) as f64 * 1e-9;
    assert!(
        reported_after <= 0.1 + 0.5 + 0.3,
        "stale source reported {reported_after:.2} s after the last cloud"
    );
    // The node's own counts ride along.
    assert!(status.values.iter().any(|kv| kv.key == "clouds_dropped"));
    // Recovery: distances again after the stale reports.
    assert!(diagnostics[first_stale..]
        .iter()
        .any(|(_, s)| s.message.starts_with("min distance")));
    // Distances: conservative values of a real approach, never published for the faults.
    let distances: Vec<f64> = messages
        .iter()
        .filter(|m| &*m.topic == "/robot1/watch/min_distance")
        .map(|m| msg::decode::<Float64>(&m.data).unwrap().data)
        .collect();
    // Both plays answered (27 of 30 at least, above); the recorder may join a little late.
    assert!(distances.len() >= 45, "{} distances", distances.len());
    assert!(distances.iter().all(|d| (0.0..1.3).contains(d)));
    assert!(distances.iter().any(|d| *d < 0.05));
}

/// Two cameras over DDS: the demo bag with a second camera that sees only a far wall, played to a
/// node watching both. Once the approach raised `~/safety_stop`, it is never released (the
/// wall camera's frames cannot clear it), and no published distance is the wall's.
#[test]
fn a_far_camera_never_releases_the_nodes_stop() {
    if !common::in_private_network("a_far_camera_never_releases_the_nodes_stop") {
        return;
    }
    common::demo_trees();
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("two_cameras.mcap");
    common::write_two_camera_bag(&bag, false);
    let record = dir.path().join("outputs.mcap");
    let wall_topic = format!("wall.topic:={}", common::SECOND_CAMERA_TOPIC);
    let node = spawn_node(&[
        "node",
        "--ros-args",
        "-p",
        "sources:=[camera, wall]",
        "-p",
        &wall_topic,
        "-p",
        "wall.max_range:=4.0",
        // The stop's fusion over the cameras is checked, not the machine's load: under
        // `protect` (the demo config) a frame over the budget is a fault that raises the stop
        // (tests/unseen_monitor.rs); CI's load once raised it between far frames.
        "-p",
        "latency_budget:=10.0",
    ]);
    let mut recorder = spawn(&[
        "record",
        "--duration",
        "7",
        "--out",
        record.to_str().unwrap(),
    ]);
    let _reap = common::Reap(vec![node.id(), recorder.id()]);
    std::thread::sleep(Duration::from_secs(2));
    let run = play_measured(
        ist_monitor(),
        "1.5",
        "/ist_monitor/link_distances",
        Some(&bag),
    );
    // The two cameras share their stamps: one answer per stamp is counted.
    assert_answered(&run, 60, 25);
    assert!(recorder.wait().unwrap().success());
    let log = stop(node);
    assert_no_error_lines(&log);
    let messages = read_messages(&record, &|_, _| true).unwrap();
    let stops: Vec<bool> = messages
        .iter()
        .filter(|m| &*m.topic == "/ist_monitor/safety_stop")
        .map(|m| msg::decode::<msg::Bool>(&m.data).unwrap().data)
        .collect();
    // Raised while the cell is not fully seen, released while the person is far, raised by the
    // approach: from there on, raised to the end.
    let raised = stops
        .windows(2)
        .position(|w| !w[0] && w[1])
        .map(|i| i + 1)
        .unwrap_or_else(|| panic!("the approach never raised the stop: {stops:?}"));
    assert!(
        stops[raised..].iter().all(|s| *s),
        "released after the approach: {stops:?}"
    );
    let distances: Vec<f64> = messages
        .iter()
        .filter(|m| &*m.topic == "/ist_monitor/min_distance")
        .map(|m| msg::decode::<Float64>(&m.data).unwrap().data)
        .collect();
    assert!(distances.len() >= 40, "{} distances", distances.len());
    assert!(distances.iter().all(|d| *d < 1.3), "{distances:?}");
}

/// The fault model through DDS: the bag with one fault of each kind, played to the node, gives
/// each as ERROR with its kind in the diagnostics, and the node answers the good clouds around
/// them.
#[test]
fn every_fault_kind_reaches_the_node_as_an_error() {
    if !common::in_private_network("every_fault_kind_reaches_the_node_as_an_error") {
        return;
    }
    common::demo_trees();
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("faults.mcap");
    common::write_fault_bag(&bag);
    let record = dir.path().join("outputs.mcap");
    let mut node = spawn(&["node"]);
    let mut recorder = spawn(&[
        "record",
        "--duration",
        "7",
        "--out",
        record.to_str().unwrap(),
    ]);
    std::thread::sleep(Duration::from_secs(2));
    let played = ist_monitor()
        .arg("play")
        .arg(&bag)
        .args(["--wait", "1.5"])
        .status()
        .unwrap();
    assert!(played.success());
    assert!(recorder.wait().unwrap().success());
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    assert!(node.wait().unwrap().success());
    let messages = read_messages(&record, &|_, _| true).unwrap();
    let mut kinds = std::collections::BTreeSet::new();
    let mut measured = 0;
    for m in messages.iter().filter(|m| &*m.topic == "/diagnostics") {
        let status = msg::decode::<DiagnosticArray>(&m.data).unwrap().status[0].clone();
        match status.values.iter().find(|kv| kv.key == "fault") {
            Some(kv) => {
                assert_eq!(status.level, DiagnosticStatus::ERROR, "{}", status.message);
                kinds.insert(kv.value.clone());
            }
            None => measured += 1,
        }
    }
    for (_, kind) in common::FAULTS {
        assert!(kinds.contains(*kind), "{kind} not reported; got {kinds:?}");
    }
    assert!(measured >= 20, "{measured} clouds measured");
}

/// While its trees are built (a cold cache: about 10 s for the demo arm on 2 cores) the node is
/// on the network and says it is not monitoring: ERROR with the reason, the safety stop, no
/// distance. SIGTERM during the build ends it at once, with status 0.
#[test]
fn a_node_building_its_trees_says_so_and_stops_at_once() {
    if !common::in_private_network("a_node_building_its_trees_says_so_and_stops_at_once") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("empty_cache");
    let record = dir.path().join("outputs.mcap");
    let mut node = spawn(&["node", "-p", &format!("cache_dir:={}", cache.display())]);
    let recorded = ist_monitor()
        .args(["record", "--duration", "2.5", "--out"])
        .arg(&record)
        .status()
        .unwrap();
    assert!(recorded.success());
    let asked = std::time::Instant::now();
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    let status = node.wait().unwrap();
    let took = asked.elapsed().as_secs_f64();
    assert!(status.success(), "{status:?}");
    assert!(took < 2.0, "SIGTERM answered after {took:.2} s");
    let messages = read_messages(&record, &|_, _| true).unwrap();
    let diagnostics: Vec<DiagnosticStatus> = messages
        .iter()
        .filter(|m| &*m.topic == "/diagnostics")
        .map(|m| msg::decode::<DiagnosticArray>(&m.data).unwrap().status[0].clone())
        .collect();
    assert!(diagnostics.len() >= 2, "{} diagnostics", diagnostics.len());
    // What must hold, however far the start-up got in the window: ERROR, "not monitoring",
    // the stop raised, no distance.
    for s in &diagnostics {
        assert_eq!(s.level, DiagnosticStatus::ERROR);
        assert!(s.message.starts_with("not monitoring: "), "{}", s.message);
    }
    let stops: Vec<bool> = messages
        .iter()
        .filter(|m| &*m.topic == "/ist_monitor/safety_stop")
        .map(|m| msg::decode::<msg::Bool>(&m.data).unwrap().data)
        .collect();
    assert!(!stops.is_empty() && stops.iter().all(|s| *s));
    assert!(!messages
        .iter()
        .any(|m| &*m.topic == "/ist_monitor/min_distance"));
}

/// Interop with an independent DDS implementation: the `cyclonedds` Python package publishes the
/// robot description on `/robot_description` (the node waits for it) and a
/// sensor_msgs/PointCloud2 under the ROS 2 naming (`rt/…`, `sensor_msgs::msg::dds_::PointCloud2_`)
/// and reads the node's `~/min_distance`, which must be the distance the library computes for
/// the same points, and its `~/speed_scaling`, remapped to `joint_trajectory_controller`'s input
/// and read with the QoS that controller asks.
#[test]
fn cyclonedds_feeds_the_node_and_reads_its_output() {
    if !common::in_private_network("cyclonedds_feeds_the_node_and_reads_its_output") {
        return;
    }
    let Some(python) = common::venv_python() else {
        return;
    };
    let (model, trees) = common::demo_trees();
    // The robot comes from the peer on /robot_description, as robot_state_publisher gives it.
    let mut node = ist_monitor()
        .args(common::at_rest_args())
        .args([
            "-p",
            "robot_description:=~",
            "-p",
            "robot_description_topic:=/robot_description",
            "-r",
            "~/speed_scaling:=/joint_trajectory_controller/speed_scaling_input",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/cyclonedds_interop.py");
    let out = common::json_output(Command::new(python).arg(script).arg(common::DEMO_URDF));
    Command::new("kill")
        .arg(node.id().to_string())
        .status()
        .unwrap();
    assert!(node.wait().unwrap().success());
    let received = out["min_distance"]
        .as_f64()
        .expect("a min_distance from the node");
    // The same cloud through the library: the patch 0.6 m ahead of camera_link, all joints 0.
    let mut engine = Engine::new(&model, &trees, &LinkSelection::default()).unwrap();
    let k = &model.kinematics;
    let poses = k.link_poses(&vec![0.0; k.variables().len()]);
    let camera = poses[k.link_index("camera_link").unwrap()];
    let points: Vec<[f32; 3]> = (0..20)
        .flat_map(|i| (0..20).map(move |j| [0.6, -0.2 + 0.02 * i as f32, -0.2 + 0.02 * j as f32]))
        .collect();
    let options = QueryOptions {
        mode: Mode::Certified,
        backend: Backend::Cpu,
        ..QueryOptions::default()
    };
    let r = engine.query(&points, &camera, &poses, &options).unwrap();
    let expected = r.nearest.unwrap().lower_m.unwrap();
    assert!(
        (received - expected).abs() < 1e-6,
        "{received} vs {expected}"
    );
    // The speed-scaling factor, remapped to joint_trajectory_controller's input, reached a reader
    // with that controller's QoS (reliable, transient local); the arm stands still (fixed joints) and the patch is beyond what a
    // stopped arm needs, so the factor rises from 0.
    let factor = out["speed_scaling"]
        .as_f64()
        .expect("a speed_scaling factor from the node");
    assert!((0.2..=1.0).contains(&factor), "{factor}");
}

/// A node at rest (factor remapped to joint_trajectory_controller's input, `env` set) and the
/// Cyclone DDS peer watching it with `peer_args`, once the peer says `watching` (the factor
/// has risen: the arm may move). Returns the node, the peer and the rest of its output to read.
fn node_and_watching_peer(
    python: &Path,
    env: &[(&str, &str)],
    peer_args: &[&str],
) -> (
    std::process::Child,
    std::process::Child,
    std::io::BufReader<std::process::ChildStdout>,
) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/cyclonedds_interop.py");
    let node = ist_monitor()
        .envs(env.iter().copied())
        .args(common::at_rest_args())
        .args([
            "-r",
            "~/speed_scaling:=/joint_trajectory_controller/speed_scaling_input",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut peer = Command::new(python)
        .arg(&script)
        .args(peer_args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = std::io::BufReader::new(peer.stdout.take().unwrap());
    let mut line = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut line).unwrap();
    assert_eq!(line.trim(), "watching", "the peer: {line}");
    (node, peer, stdout)
}

/// What the watching peer saw (its JSON line), once it ended well.
fn peer_report(
    peer: std::process::Child,
    mut stdout: std::io::BufReader<std::process::ChildStdout>,
) -> serde_json::Value {
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stdout, &mut rest).unwrap();
    let peer = peer.wait_with_output().unwrap();
    assert!(
        peer.status.success(),
        "the peer: {}",
        String::from_utf8_lossy(&peer.stderr)
    );
    serde_json::from_str(&rest).unwrap()
}

/// The node's last word, read by an independent DDS implementation (the Cyclone DDS peer): a
/// node serving a cloud at full speed that is stopped by SIGTERM, or that panics (a fault
/// injected after 40 frames), leaves `~/safety_stop` true and the speed-scaling factor 0 as the
/// last messages a controller and a safety PLC received.
#[test]
fn a_stopped_or_crashed_node_leaves_the_stop_raised_and_the_factor_at_zero() {
    if !common::in_private_network(
        "a_stopped_or_crashed_node_leaves_the_stop_raised_and_the_factor_at_zero",
    ) {
        return;
    }
    let Some(python) = common::venv_python() else {
        return;
    };
    common::demo_trees();
    for crash in [false, true] {
        let env: &[(&str, &str)] = if crash {
            &[(ist_monitor::node::PANIC_AFTER_ENV, "40")]
        } else {
            &[]
        };
        let watch = if crash { "8" } else { "4" };
        let (node, peer, stdout) = node_and_watching_peer(&python, env, &["--watch", watch]);
        let _reap = common::Reap(vec![node.id(), peer.id()]);
        if !crash {
            std::thread::sleep(Duration::from_millis(1500));
            Command::new("kill")
                .arg(node.id().to_string())
                .status()
                .unwrap();
        }
        let out = node.wait_with_output().unwrap();
        let log = String::from_utf8_lossy(&out.stderr);
        if crash {
            assert_eq!(out.status.code(), Some(101), "{log}");
            assert!(log.contains("stopped by a panic"), "{log}");
        } else {
            assert!(out.status.success(), "{log}");
        }
        let seen = peer_report(peer, stdout);
        let stops: Vec<bool> = serde_json::from_value(seen["stops"].clone()).unwrap();
        let factors: Vec<f64> = serde_json::from_value(seen["factors"].clone()).unwrap();
        // Running, the node allowed motion and raised no stop; its last word undid both.
        assert!(stops.contains(&false), "crash {crash}: {seen}");
        assert!(factors.iter().any(|&f| f >= 0.2), "crash {crash}: {seen}");
        assert_eq!(stops.last(), Some(&true), "crash {crash}: {seen}");
        assert_eq!(factors.last(), Some(&0.0), "crash {crash}: {seen}");
    }
}

/// A node killed outright (SIGKILL: no last word is possible) is still told apart from a quiet
/// one: the outputs offer the QoS deadline `output_deadline` (0.5 s) and automatic liveliness
/// with a 3 s lease, so an independent DDS subscriber (the Cyclone DDS peer) that requests them
/// is matched, sees no missed deadline and no lost liveliness while the node runs, and is told
/// by its own middleware within the deadline, then the lease, once the node is gone.
#[test]
fn a_killed_node_is_reported_by_the_offered_deadline() {
    if !common::in_private_network("a_killed_node_is_reported_by_the_offered_deadline") {
        return;
    }
    let Some(python) = common::venv_python() else {
        return;
    };
    common::demo_trees();
    let (node, peer, stdout) = node_and_watching_peer(
        &python,
        &[],
        &["--watch", "8", "--deadline", "0.5", "--lease", "3"],
    );
    let _reap = common::Reap(vec![node.id(), peer.id()]);
    std::thread::sleep(Duration::from_millis(1500));
    let killed_at = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    Command::new("kill")
        .args(["-KILL", &node.id().to_string()])
        .status()
        .unwrap();
    let out = node.wait_with_output().unwrap();
    assert!(!out.status.success());
    let seen = peer_report(peer, stdout);
    // Matched: a subscriber asking for a 0.5 s deadline received the stop topic.
    let samples = seen["deadline_samples"].as_u64().unwrap();
    assert!(samples >= 10, "{seen}");
    let missed: Vec<f64> = serde_json::from_value(seen["deadline_missed"].clone()).unwrap();
    assert!(
        missed.iter().all(|&t| t >= killed_at),
        "a deadline missed while the node ran: {seen} (killed at {killed_at})"
    );
    // Within the deadline, and a slack for a loaded machine (about 0.45 s when idle).
    let first = missed.first().copied();
    assert!(
        first.is_some_and(|t| t <= killed_at + 0.5 + 2.0),
        "no missed deadline within 2.5 s of the kill at {killed_at}: {seen}"
    );
    // Liveliness (a 3 s lease asked, 3 s offered): the writer was alive, stayed alive while
    // the node ran, and was lost within the lease after the kill (about 2.9 s when idle; 2 s
    // of slack for a loaded machine).
    let changes: Vec<(f64, u64)> = serde_json::from_value(seen["liveliness"].clone()).unwrap();
    assert!(changes.iter().any(|&(_, alive)| alive >= 1), "{seen}");
    assert!(
        changes
            .iter()
            .all(|&(t, alive)| alive >= 1 || t >= killed_at),
        "liveliness lost while the node ran: {seen} (killed at {killed_at})"
    );
    assert!(
        changes
            .last()
            .is_some_and(|&(t, alive)| alive == 0 && t <= killed_at + 3.0 + 2.0),
        "liveliness not lost within 5 s of the kill at {killed_at}: {seen}"
    );
}

/// Depth images over DDS: a generated 16UC1 bag (images and their CameraInfo) played to a node
/// whose source is a depth image; every image is answered, and each distance the node publishes
/// is bit for bit one that `replay` of the same bag gives.
#[test]
fn depth_images_feed_the_node() {
    if !common::in_private_network("depth_images_feed_the_node") {
        return;
    }
    use ist_monitor::cloud::depth::DepthEncoding;
    use ist_monitor::monitor::replay::{replay, Clock};
    use ist_monitor::scenario::{self, ScenarioParams, DEPTH_TOPIC};
    let (model, _) = common::demo_trees();
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("depth");
    let params = ScenarioParams {
        frames: 20,
        depth: Some(DepthEncoding::Millimetres16),
        ..ScenarioParams::default()
    };
    scenario::generate(&model, &params, &bag).unwrap();
    let type_param = "camera.type:=depth_image".to_string();
    let topic_param = format!("camera.topic:={DEPTH_TOPIC}");
    let node = ist_monitor()
        .args(["node", "--ros-args", "-p", &type_param, "-p", &topic_param])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let record = dir.path().join("outputs.mcap");
    let mut recorder = spawn(&[
        "record",
        "--duration",
        "5",
        "--out",
        record.to_str().unwrap(),
    ]);
    std::thread::sleep(Duration::from_secs(1));
    let run = play_measured(
        ist_monitor(),
        "1.5",
        "/ist_monitor/link_distances",
        Some(&bag),
    );
    assert!(recorder.wait().unwrap().success());
    let log = stop(node);
    assert!(
        log.contains("first depth image on /camera/depth/image_raw"),
        "{log}"
    );
    assert_answered(&run, 20, 18);
    // The library's answers on the same bag.
    let config = ist_monitor::config::Config::load(
        Path::new(common::DEMO_CONFIG),
        &[
            ("camera.type".into(), "depth_image".into()),
            ("camera.topic".into(), DEPTH_TOPIC.into()),
            // The library's every answer: none withheld as late on a loaded machine.
            ("latency_budget".into(), "60".into()),
        ],
    )
    .unwrap();
    let mut monitor = ist_monitor::monitor::Monitor::new(config, &|_| {}).unwrap();
    let mut library = Vec::new();
    replay(&mut monitor, &bag, None, Clock::Stamp, &mut |f| {
        library.extend(f.min_distance_m)
    })
    .unwrap();
    let published: Vec<f64> = read_messages(&record, &|t, _| t == "/ist_monitor/min_distance")
        .unwrap()
        .iter()
        .map(|m| msg::decode::<Float64>(&m.data).unwrap().data)
        .collect();
    assert!(
        published.len() >= 15,
        "{} distances recorded",
        published.len()
    );
    for d in &published {
        assert!(
            library.iter().any(|l| l.to_bits() == d.to_bits()),
            "the node published {d}, which replay never gives: {library:?}"
        );
    }
}

/// The zenoh transport, as rmw_zenoh speaks it, through a router (`ist_monitor zenoh-router`,
/// at rmw_zenoh's default endpoint): an independent zenoh peer (Python `eclipse-zenoh`) publishes
/// a PointCloud2, then a depth image with its CameraInfo, the rmw_zenoh way (keys with ROS 2's
/// type hashes, attachments), and receives the node's `~/min_distance` and `/diagnostics` by
/// their exact keys; the distances equal the library's answer on the same data, and the node,
/// its publishers and subscriptions are in the graph (liveliness tokens); then the demo
/// bag is played twice over zenoh (every cloud answered), the source's silence between the plays
/// is reported as ERROR and the node recovers; SIGTERM ends it cleanly.
#[test]
fn zenoh_transport_serves_the_node() {
    if !common::in_private_network("zenoh_transport_serves_the_node") {
        return;
    }
    let Some(python) = common::venv_python() else {
        return;
    };
    let has_zenoh = Command::new(&python)
        .args(["-c", "import zenoh"])
        .status()
        .is_ok_and(|s| s.success());
    if !has_zenoh {
        assert!(
            std::env::var_os("CI").is_none(),
            "eclipse-zenoh missing from the venv"
        );
        common::skip("the venv has no eclipse-zenoh (bash .ci/run installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (plan, expected_cloud, expected_depth) = zenoh_peer_plan(dir.path());
    let router = spawn(&["zenoh-router"]);
    std::thread::sleep(Duration::from_millis(500));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/zenoh_interop.py");
    let peer = Command::new(&python)
        .arg(script)
        .arg("tcp/localhost:7447")
        .args(["--set", "hysteresis=0.03"])
        .args(&plan)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    let mut node = ist_monitor();
    over_zenoh(&mut node);
    let node = node
        .args(common::at_rest_args())
        .args([
            "-p",
            "sources:=[camera, depth]",
            "-p",
            "camera.source_timeout:=0.5",
            "-p",
            "depth.type:=depth_image",
            "-p",
            "depth.topic:=/camera/depth/image_raw",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let _reap = common::Reap(vec![router.id(), node.id(), peer.id()]);
    let out = peer.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "zenoh_interop.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let peer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    check_zenoh_answers(&peer, expected_cloud, expected_depth);
    check_zenoh_graph(&peer);
    play_the_demo_over_zenoh(dir.path(), node, router);
}

/// `c` on the zenoh transport, as rmw_zenoh is chosen.
fn over_zenoh(c: &mut Command) {
    c.env("RMW_IMPLEMENTATION", "rmw_zenoh_cpp");
}

/// The zenoh peer's plan (a PointCloud2, a depth image with its CameraInfo, the optical frame
/// on a latched /tf_static; files written into `dir`) and the library's answers on the same
/// points: the cloud's and the depth image's certified lower bounds.
fn zenoh_peer_plan(dir: &Path) -> (Vec<String>, f64, f64) {
    use ist_monitor::cloud::depth::{
        encode_depth, points_from_depth, DepthEncoding, PinholeCamera,
    };
    use ist_monitor::cloud::pointcloud2::{encode, Layout};
    use ist_monitor::msg::{CameraInfo, Header, Time};
    let (model, trees) = common::demo_trees();
    let k = &model.kinematics;
    let poses = k.link_poses(&vec![0.0; k.variables().len()]);
    let camera_link = poses[k.link_index("camera_link").unwrap()];
    let optical = ist_monitor::scenario::link_from_optical();
    let header = |frame: &str| Header {
        stamp: Time::from_nanos(1),
        frame_id: frame.into(),
    };
    // A PointCloud2 in camera_link (x forward): a 20 × 20 patch 0.6 m ahead.
    let patch: Vec<[f32; 3]> = (0..20)
        .flat_map(|i| (0..20).map(move |j| [0.6, -0.2 + 0.02 * i as f32, -0.2 + 0.02 * j as f32]))
        .collect();
    let cloud = encode(header("camera_link"), &patch, &Layout::unorganized(400)).unwrap();
    // A 16UC1 depth image in the optical frame: a plane 0.7 m ahead, and its camera.
    let info = CameraInfo {
        header: header("camera_optical_frame"),
        width: 20,
        height: 20,
        k: [100.0, 0.0, 9.5, 0.0, 100.0, 9.5, 0.0, 0.0, 1.0],
        p: [
            100.0, 0.0, 9.5, 0.0, 0.0, 100.0, 9.5, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        ..CameraInfo::default()
    };
    let image = encode_depth(
        header("camera_optical_frame"),
        20,
        20,
        &[0.7; 400],
        DepthEncoding::Millimetres16,
    );
    let files = [
        (
            "/camera/depth/points",
            "sensor_msgs::msg::dds_::PointCloud2_",
            msg::encode(&cloud).unwrap(),
        ),
        (
            "/camera/depth/camera_info",
            "sensor_msgs::msg::dds_::CameraInfo_",
            msg::encode(&info).unwrap(),
        ),
        (
            "/camera/depth/image_raw",
            "sensor_msgs::msg::dds_::Image_",
            msg::encode(&image).unwrap(),
        ),
    ];
    // The optical frame, from the peer's transient-local /tf_static, published before the
    // node starts: the node has it only if it fetches the history, as rmw_zenoh does.
    let tf_static = ist_monitor::msg::TfMessage {
        transforms: vec![ist_monitor::msg::TransformStamped {
            header: header("camera_link"),
            child_frame_id: "camera_optical_frame".into(),
            transform: ist_monitor::msg::Transform::from_isometry(&optical),
        }],
    };
    let tf_path = dir.join("tf_static.cdr");
    std::fs::write(&tf_path, msg::encode(&tf_static).unwrap()).unwrap();
    let mut plan = vec![
        "--latched".to_string(),
        format!(
            "/tf_static={},tf2_msgs::msg::dds_::TFMessage_",
            tf_path.display()
        ),
        "--delay".into(),
        "3".into(),
        // Both sources at once: the node publishes the cell's fused distance, which needs
        // every enabled source.
        "--together".into(),
    ];
    for (i, (topic, ty, bytes)) in files.iter().enumerate() {
        let path = dir.join(format!("{i}.cdr"));
        std::fs::write(&path, bytes).unwrap();
        plan.push(format!("{topic}={},{ty}", path.display()));
    }
    // The library's answers on the same points.
    let mut engine = Engine::new(&model, &trees, &LinkSelection::default()).unwrap();
    let options = QueryOptions {
        mode: Mode::Certified,
        backend: Backend::Cpu,
        ..QueryOptions::default()
    };
    let mut lower = |points: &[[f32; 3]], sensor| {
        let r = engine.query(points, &sensor, &poses, &options).unwrap();
        r.nearest.expect("the points are seen").lower_m.unwrap()
    };
    let expected_cloud = lower(&patch, camera_link);
    let mut depth_points = Vec::new();
    let camera = PinholeCamera::from_camera_info(&info).unwrap();
    points_from_depth(&image, &camera, None, &mut depth_points).unwrap();
    let expected_depth = lower(&depth_points, camera_link * optical);

    (plan, expected_cloud, expected_depth)
}

/// What the zenoh peer received: each source's own measure and the cell's fused distance as the
/// library's, by the exact keys, with rmw_zenoh's attachments; the cached speed factor.
fn check_zenoh_answers(peer: &serde_json::Value, expected_cloud: f64, expected_depth: f64) {
    // Each source measured on its own, as its own status in /diagnostics says (6 decimals)...
    for (status, expected) in [
        ("ist_monitor: camera", expected_cloud),
        ("ist_monitor: depth", expected_depth),
    ] {
        let got = peer["lower_m"][status]
            .as_f64()
            .unwrap_or_else(|| panic!("no lower_m of {status}: {peer}"));
        assert!(
            (got - expected).abs() < 1e-6,
            "{status}: the node measured {got}, the library gives {expected}"
        );
    }
    // ... and the cell's distance is the nearer of the two.
    let fused = expected_cloud.min(expected_depth);
    let got: Vec<f64> = peer["distances"]["together"]
        .as_array()
        .unwrap_or_else(|| panic!("{peer}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(got.len() >= 10, "{} distances: {peer}", got.len());
    for d in &got {
        assert!(
            (d - fused).abs() < 1e-6,
            "the node published {d}, the nearer source is at {fused}"
        );
    }
    // The peer subscribed by the exact keys, with ROS 2's type hashes, as rmw_zenoh does: the
    // distances above reached it that way, and so did the diagnostics.
    assert!(peer["diagnostics"].as_u64().unwrap() >= 10, "{peer}");
    // Every distance carried rmw_zenoh's 32-byte attachment, its sequence numbers rising.
    let seqs: Vec<i64> = peer["attachments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| {
            assert_eq!(a[0].as_u64(), Some(32), "{a}");
            a[1].as_i64().unwrap()
        })
        .collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    // A late-joining transient-local subscriber of the speed-scaling factor gets the last one
    // from the node's cache (0: the node had faults, e.g. the depth source before its images).
    let cached = peer["speed_scaling"].as_array().unwrap();
    assert_eq!(cached.len(), 1, "{peer}");
    assert!((0.0..=1.0).contains(&cached[0].as_f64().unwrap()), "{peer}");
}

/// The node in the ROS graph as the zenoh peer saw it: its liveliness tokens, `ros2 param list`
/// and `ros2 param set` with its /parameter_events.
fn check_zenoh_graph(peer: &serde_json::Value) {
    // The node, its publishers and its subscriptions are in the ROS graph (liveliness tokens),
    // with their types' hashes and QoS.
    let tokens: Vec<&str> = peer["liveliness"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap())
        .collect();
    for (kind, tail) in [
        ("NN", "/%/%/ist_monitor"),
        (
            "MP",
            "/%/%/ist_monitor/%ist_monitor%min_distance/std_msgs::msg::dds_::Float64_/\
             RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a/",
        ),
        (
            "MS",
            "/%/%/ist_monitor/%camera%depth%points/sensor_msgs::msg::dds_::PointCloud2_/\
             RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5/2::,1:,:,:,,",
        ),
    ] {
        assert!(
            tokens
                .iter()
                .any(|k| k.starts_with("@ros2_lv/0/") && k.contains(&format!("/{kind}{tail}"))),
            "no {kind} token ending {tail}: {tokens:#?}"
        );
    }
    // `ros2 param list` over zenoh, asked as an rmw_zenoh client asks: every declared parameter
    // of this node's configuration, the reply paired to the request by its sequence number.
    let listed: Vec<&str> = (peer["parameters"].as_array())
        .unwrap_or_else(|| panic!("no answer from list_parameters: {peer}"))
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    let overrides: Vec<(String, String)> = common::at_rest_args()
        .iter()
        .map(String::as_str)
        .chain([
            "-p",
            "sources:=[camera, depth]",
            "-p",
            "depth.type:=depth_image",
        ])
        .collect::<Vec<_>>()
        .windows(2)
        .filter(|w| w[0] == "-p")
        .map(|w| ist_monitor::config::parse_override(w[1]).unwrap())
        .collect();
    let config =
        ist_monitor::config::Config::load(Path::new(common::DEMO_CONFIG), &overrides).unwrap();
    let expected = config.parameters();
    assert_eq!(listed.len(), expected.len(), "{listed:?}");
    for p in &expected {
        assert!(listed.contains(&p.name.as_str()), "{} not listed", p.name);
    }
    assert_eq!(peer["parameters_reply_sequence"], 41, "{peer}");
    assert!(
        tokens.iter().any(|k| k.contains(
            "/SS/%/%/ist_monitor/%ist_monitor%list_parameters/\
             rcl_interfaces::srv::dds_::ListParameters_/\
             RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d/"
        )),
        "no list_parameters service token: {tokens:#?}"
    );
    // `ros2 param set` over zenoh: taken, and announced on /parameter_events (with ROS 2's
    // type hash in the key) as the one parameter changed, stamped now.
    assert_eq!(peer["set"], serde_json::json!([[true, ""]]), "{peer}");
    let events = peer["parameter_events"].as_array().unwrap();
    assert_eq!(events.len(), 1, "{peer}");
    let event = &events[0];
    assert_eq!(event["node"], "/ist_monitor", "{event}");
    assert_eq!(
        event["changed"],
        serde_json::json!([["hysteresis", 3, 0.03]]),
        "{event}"
    );
    assert_eq!(event["new"], serde_json::json!([]), "{event}");
    assert_eq!(event["deleted"], serde_json::json!([]), "{event}");
    let age_ns = ist_monitor::msg::Time::now_nanos() - event["stamp_ns"].as_i64().unwrap();
    assert!((0..60_000_000_000).contains(&age_ns), "{event}");
}

/// The demo bag played twice over zenoh to `node` (through `router`) and recorded over zenoh:
/// every cloud answered, the silence between the plays an ERROR, then distances again; SIGTERM
/// ends the node and the router cleanly.
fn play_the_demo_over_zenoh(dir: &Path, node: Child, mut router: Child) {
    // The demo bag over zenoh, twice, recorded over zenoh.
    let record = dir.join("outputs.mcap");
    let mut recorder = ist_monitor();
    over_zenoh(&mut recorder);
    let mut recorder = recorder
        .args([
            "record",
            "--duration",
            "9",
            "--out",
            record.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    let play = |wait: &str| {
        let mut c = ist_monitor();
        over_zenoh(&mut c);
        play_measured(c, wait, "/ist_monitor/link_distances", None)
    };
    let first = play("1.0");
    std::thread::sleep(Duration::from_millis(1500));
    let second = play("0.3");
    assert!(recorder.wait().unwrap().success());
    for run in [&first, &second] {
        assert_answered(run, 30, 29);
    }
    let log = stop(node);
    assert!(
        log.contains("zenoh (rmw_zenoh)") && log.contains("1 router(s)"),
        "{log}"
    );
    assert_no_error_lines(&log);
    Command::new("kill")
        .arg(router.id().to_string())
        .status()
        .unwrap();
    assert!(router.wait().unwrap().success());
    // Between the plays the source was silent: ERROR, then distances again.
    let diagnostics: Vec<DiagnosticStatus> = read_messages(&record, &|t, _| t == "/diagnostics")
        .unwrap()
        .iter()
        .map(|m| msg::decode::<DiagnosticArray>(&m.data).unwrap().status[0].clone())
        .filter(|s| s.name.ends_with(": camera"))
        .collect();
    let stale = diagnostics
        .iter()
        .position(|s| s.message.contains("no cloud for"))
        .expect("a stale-source ERROR between the plays");
    assert_eq!(diagnostics[stale].level, DiagnosticStatus::ERROR);
    assert!(diagnostics[stale..]
        .iter()
        .any(|s| s.message.starts_with("min distance")));
}
