//! Helpers shared by the integration tests: the shared data folder and small file writers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

pub mod capture;
pub mod cyclone;

/// Says that the running test skips, and why, on the process's standard error itself: the
/// test harness captures `eprintln!`, so a skip would otherwise be invisible. `.ci/run` counts
/// these lines (`SKIPPED <test>: <reason>`).
pub fn skip(reason: &str) {
    use std::io::Write;
    let name = std::thread::current().name().unwrap_or("?").to_owned();
    let _ = std::io::stderr().write_all(format!("SKIPPED {name}: {reason}\n").as_bytes());
}

/// The demo robot, bag and parameters file of this checkout.
pub const DEMO_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/urdf/demo_arm.urdf");
pub const DEMO_BAG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/demo");
pub const DEMO_CONFIG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/demo_arm.yaml");

/// Overrides of the demo config for the generator's floorless scenes
/// (`ScenarioParams::default()`) in tests of what the cameras see: the space no camera sees
/// is not watched (without a floor every ray behind the scene returns nothing, and all of it is
/// hidden), and the demo config's floor exclusion is moved 1 m under the cell, where it removes
/// none of their points (a shoe's lowest points lie within the floor's centimetre).
pub const SEEN_ONLY_FLOORLESS: [(&str, &str); 2] = [
    ("unobserved", "ignore"),
    ("floor.translation", "[0.0, 0.0, -1.0]"),
];

/// The `ist_monitor` binary built for these tests.
pub fn ist_monitor() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ist_monitor"))
}

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
    skip("../shared is absent and CI is not set");
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
    let size = std::array::from_fn(|k| (hi[k] - lo[k]) as f64);
    let t = ist_monitor::robot::mesh::tessellate_box(size);
    let place = |v: [f32; 3]| std::array::from_fn(|k| v[k] + 0.5 * (lo[k] + hi[k]));
    t.triangles
        .iter()
        .map(|f| f.map(|i| place(t.vertices[i as usize])))
        .collect()
}

/// A one-link URDF whose collision is `geometry` (the XML of a `<geometry>` child).
pub fn one_link_urdf(geometry: &str) -> String {
    format!(
        r#"<robot name="t"><link name="body"><collision><geometry>{geometry}</geometry></collision></link></robot>"#
    )
}

/// The Python of the project's venv (`.ci/run` makes it, with `rosbags`), for the interop tests.
/// In CI it must exist; elsewhere a test may skip with a printed reason.
pub fn venv_python() -> Option<PathBuf> {
    venv_python_with("rosbags")
}

/// The venv's Python where it can import `module`. In CI it must; elsewhere a test may skip
/// with a printed reason.
fn venv_python_with(module: &str) -> Option<PathBuf> {
    let python = Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python");
    let ok = python.exists()
        && Command::new(&python)
            .args(["-c", &format!("import {module}")])
            .status()
            .is_ok_and(|s| s.success());
    if ok {
        return Some(python);
    }
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but .venv/bin/python with {module} is missing: .ci/run installs it");
    }
    skip(&format!(
        ".venv/bin/python with {module} is absent and CI is not set"
    ));
    None
}

/// Runs `command`, checks that it succeeded and parses its standard output as JSON.
pub fn json_output(command: &mut Command) -> serde_json::Value {
    let out = command.output().expect("run command");
    assert!(
        out.status.success(),
        "{:?}: {}",
        command,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on standard output")
}

/// Whether `engine` has a GPU backend. In CI one must exist (Mesa's lavapipe, which `.ci/run`
/// installs); elsewhere a GPU test may skip with a printed reason.
pub fn has_gpu(engine: &mut ist_monitor::query::Engine) -> bool {
    if engine.gpu().is_some() {
        return true;
    }
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but no GPU adapter (lavapipe: mesa-vulkan-drivers) was found");
    }
    skip("no GPU adapter and CI is not set");
    false
}

/// The faults every frame may have, one each, made from the demo bag (each edit keeps the
/// message decodable as CDR, so that `play` can publish it): `(cloud index, fault kind)`.
pub const FAULTS: &[(usize, &str)] = &[
    (3, "no_valid_points"),
    (6, "no_stamp"),
    (9, "stale_cloud"),
    (12, "future_cloud"),
    (15, "tf"),
    (18, "decode"),
    (24, "stale_joint_state"),
];

/// The demo bag's cloud topic.
pub const DEMO_CLOUD_TOPIC: &str = "/camera/depth/points";

/// One message's edit for [`edit_demo_bag`]: (topic, log time, cloud index, payload) → the
/// payload to write, or `None` to leave it out.
pub type Edit<'a> = dyn Fn(&str, u64, Option<usize>, &[u8]) -> Option<Vec<u8>> + 'a;

/// Writes the demo bag to `path` with `edit` applied to each message: it gets the topic, the
/// log time, the message's index among the clouds (`None` for other topics) and the payload,
/// and returns the payload to write (`None`: the message is left out).
pub fn edit_demo_bag(
    path: &Path,
    mut edit: impl FnMut(&str, u64, Option<usize>, &[u8]) -> Option<Vec<u8>>,
) {
    use ist_monitor::bag::{read_messages, writer::Compression, BagWriter};
    let messages = read_messages(Path::new(DEMO_BAG), &|_, _| true).unwrap();
    let mut w = BagWriter::create(path, Compression::None).unwrap();
    let mut clouds = 0;
    for m in &messages {
        let cloud = (&*m.topic == DEMO_CLOUD_TOPIC).then(|| {
            clouds += 1;
            clouds - 1
        });
        if let Some(data) = edit(&m.topic, m.log_time_ns, cloud, &m.data) {
            w.write_cdr(&m.topic, &m.schema, m.log_time_ns, &data)
                .unwrap();
        }
    }
    w.finish().unwrap();
}

/// A PointCloud2 payload with `change` applied.
pub fn edit_cloud(
    payload: &[u8],
    change: impl FnOnce(&mut ist_monitor::msg::PointCloud2<'_>),
) -> Vec<u8> {
    let mut c = ist_monitor::cloud::pointcloud2::decode(payload).unwrap();
    change(&mut c);
    ist_monitor::msg::encode(&c).unwrap()
}

/// The second camera's topic in [`write_two_camera_bag`].
pub const SECOND_CAMERA_TOPIC: &str = "/wall/points";

/// Writes the demo bag with a second camera on [`SECOND_CAMERA_TOPIC`] to `path`: 1 ms after
/// each demo cloud, a cloud with the same header that sees only a wall 3.5 m ahead (nothing
/// near the arm), or (`blinded`) one whose every point is NaN.
pub fn write_two_camera_bag(path: &Path, blinded: bool) {
    use ist_monitor::bag::{read_messages, writer::Compression, BagWriter};
    use ist_monitor::cloud::pointcloud2;
    let messages = read_messages(Path::new(DEMO_BAG), &|_, _| true).unwrap();
    let mut w = BagWriter::create(path, Compression::None).unwrap();
    let wall: Vec<[f32; 3]> = (0..400)
        .map(|i| {
            let (u, v) = ((i % 20) as f32 / 19.0, (i / 20) as f32 / 19.0);
            if blinded {
                [f32::NAN; 3]
            } else {
                [2.0 * u - 1.0, 2.0 * v - 1.0, 3.5]
            }
        })
        .collect();
    for m in &messages {
        w.write_cdr(&m.topic, &m.schema, m.log_time_ns, &m.data)
            .unwrap();
        if &*m.topic == DEMO_CLOUD_TOPIC {
            let c = pointcloud2::decode(&m.data).unwrap();
            let layout = pointcloud2::Layout::unorganized(wall.len() as u32);
            let second = pointcloud2::encode(c.header.clone(), &wall, &layout).unwrap();
            w.write_cdr(
                SECOND_CAMERA_TOPIC,
                &m.schema,
                m.log_time_ns + 1_000_000,
                &ist_monitor::msg::encode(&second).unwrap(),
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
}

/// Writes the demo bag with the [`FAULTS`] to `path`: an all-NaN cloud, a stamp of 0, a stamp
/// 1 s old and one 1 s ahead of the log time, a frame no transform reaches, a height the data
/// does not hold, and no joint state in the 0.15 s before a cloud.
pub fn write_fault_bag(path: &Path) {
    use ist_monitor::msg::Time;
    let clouds =
        ist_monitor::bag::read_messages(Path::new(DEMO_BAG), &|t, _| t == DEMO_CLOUD_TOPIC)
            .unwrap();
    let gap = clouds[24].log_time_ns;
    edit_demo_bag(path, |topic, t, cloud, data| {
        if topic == "/joint_states" && t > gap - 150_000_000 && t <= gap + 50_000_000 {
            return None;
        }
        let log = t as i64;
        Some(match cloud {
            Some(3) => edit_cloud(data, |c| c.data = vec![0xFF; c.data.len()].into()),
            Some(6) => edit_cloud(data, |c| c.header.stamp = Time::from_nanos(0)),
            Some(9) => edit_cloud(data, |c| {
                c.header.stamp = Time::from_nanos(log - 1_000_000_000)
            }),
            Some(12) => edit_cloud(data, |c| {
                c.header.stamp = Time::from_nanos(log + 1_000_000_000)
            }),
            Some(15) => edit_cloud(data, |c| c.header.frame_id = "nowhere".into()),
            Some(18) => edit_cloud(data, |c| c.height *= 2),
            _ => data.to_vec(),
        })
    });
}

/// The demo arm's trees as the node started with the demo config builds them (its sphere
/// budget), into the default cache (so that a node started after loads them in milliseconds).
pub fn demo_trees() -> (
    ist_monitor::robot::RobotModel,
    Vec<ist_monitor::ist::LinkTree>,
) {
    use ist_monitor::ist::{build_robot, cache::TreeCache};
    let model =
        ist_monitor::robot::RobotModel::load(Path::new(DEMO_URDF), &[], &Default::default())
            .unwrap();
    let config = ist_monitor::config::Config::load(Path::new(DEMO_CONFIG), &[]).unwrap();
    let trees = build_robot(&model, &config.build, Some(&TreeCache::at(None)), &|_| {})
        .unwrap()
        .into_iter()
        .map(|(t, _)| t)
        .collect();
    (model, trees)
}

/// The value of `key` in a monitor frame's first diagnostic status.
pub fn status_value<'a>(f: &'a ist_monitor::monitor::Frame, key: &str) -> Option<&'a str> {
    (f.outputs.diagnostics.status[0].values.iter())
        .find(|kv| kv.key == key)
        .map(|kv| kv.value.as_str())
}

/// True inside the private network; outside, runs `test` of this binary there and returns false.
pub fn in_private_network(test: &str) -> bool {
    if std::env::var_os("IST_NETNS_INSIDE").is_some() {
        return true;
    }
    let Some(shared) = shared() else {
        return false;
    };
    let out = Command::new(shared.join("tools/netns-run"))
        .arg(std::env::current_exe().unwrap())
        .args(["--exact", test, "--nocapture", "--test-threads=1"])
        .output()
        .unwrap();
    // The inner run's output, shown as it is (a skip inside too) but for its own summary
    // line, which would count the test twice in `.ci/run`'s summary.
    {
        use std::io::Write;
        let mut err = std::io::stderr();
        let _ = err.write_all(&out.stderr);
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            if !line.starts_with("test result:") {
                let _ = writeln!(err, "{line}");
            }
        }
    }
    let status = out.status;
    // 77: netns-run cannot make a namespace (not root, and no unprivileged user namespaces).
    if status.code() == Some(77) && std::env::var_os("CI").is_none() {
        skip("no private network namespace for this user (netns-run said why)");
        return false;
    }
    assert!(status.success(), "{test} inside the private network failed");
    false
}

/// Kills the processes it names when dropped during a panic: a failed assertion must not leave
/// a node or a router holding the test's pipes (the outer test would wait for them forever).
pub struct Reap(pub Vec<u32>);

impl Drop for Reap {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            return;
        }
        for pid in &self.0 {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
        }
    }
}

/// `--ros-args` that start the node on the CPU with the demo arm's joints held at 0 (these tests
/// publish no `/joint_states`) and the unseen space off (their clouds, the real Kinect cloud and
/// small ones of their own, are not the demo camera's: what no camera sees is tested on its own,
/// `tests/node_unseen.rs`); more arguments follow.
pub fn at_rest_args() -> Vec<String> {
    let joints =
        "[shoulder_pan, shoulder_lift, elbow, wrist_1, wrist_2, wrist_3, finger_left_joint]";
    [
        "node",
        "--ros-args",
        "-p",
        "backend:=cpu",
        "-p",
        &format!("fixed_joint_state.names:={joints}"),
        "-p",
        "fixed_joint_state.positions:=[0, 0, 0, 0, 0, 0, 0]",
        "-p",
        "unobserved:=ignore",
    ]
    .map(String::from)
    .to_vec()
}

/// The venv's Python with the real ROS 2 client (`rclpy` on `rmw_fastrtps_cpp`, ROS 2 Jazzy
/// from the package index; `.ci/run` installs it).
pub fn rclpy_python() -> Option<PathBuf> {
    venv_python_with("rclpy")
}

/// A small deterministic generator (xorshift64*), so that a proptest seed gives a whole scene;
/// each test file adds the draws its scenes need (`impl Rng` there).
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// Waits (up to two minutes: the node loads its trees first) for the node logging to `log`
/// to say it is up.
pub fn wait_up(log: &Path) {
    for _ in 0..1200 {
        if std::fs::read_to_string(log).is_ok_and(|l| l.contains("up: node")) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    panic!(
        "the node never said it was up:\n{}",
        std::fs::read_to_string(log).unwrap_or_default()
    );
}
