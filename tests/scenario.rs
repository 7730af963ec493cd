//! The real scenario of ../shared/bags/moveit_perception_tutorial/SCENARIO.md: the Panda and the
//! real Kinect cloud, through the library and through `ist_monitor query`.

mod common;

use common::ist_monitor;
#[path = "../src/bin/ist_monitor/bench/scenes.rs"]
mod scenes;

use ist_monitor::cloud;
use ist_monitor::ist::{build_robot, cache::TreeCache, BuildOptions};
use ist_monitor::query::layout::Minima;
use ist_monitor::query::{
    Backend, Engine, LinkSelection, Mode, Outcome, QueryOptions, QueryResult,
};
use ist_monitor::robot::RobotModel;
use nalgebra::Isometry3;
use scenes::{kinect_poses, kinect_root_from_sensor};

/// The Panda's engine (a small sphere budget), the bag's first Kinect cloud, the camera's pose
/// and the link poses of SCENARIO.md's named joint values.
struct Kinect {
    model: RobotModel,
    engine: Engine,
    points: Vec<[f32; 3]>,
    sensor: Isometry3<f64>,
}

impl Kinect {
    fn load(shared: &std::path::Path) -> Self {
        let model = RobotModel::load(
            &shared.join("robots/panda/robot.urdf"),
            &[],
            &Default::default(),
        )
        .unwrap();
        let cache_dir = tempfile::tempdir().unwrap();
        let mut options = BuildOptions::default();
        options.packing.max_spheres = 1024;
        let trees: Vec<_> = build_robot(
            &model,
            &options,
            Some(&TreeCache::new(cache_dir.path().to_owned())),
            &|_| {},
        )
        .unwrap()
        .into_iter()
        .map(|(t, _)| t)
        .collect();
        let engine = Engine::new(&model, &trees, &LinkSelection::default()).unwrap();
        let bag = shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap");
        let points = cloud::load(&bag, 0).unwrap().points;
        Self {
            model,
            engine,
            points,
            sensor: kinect_root_from_sensor(),
        }
    }

    /// The link poses of SCENARIO.md's pose `name`.
    fn pose(&self, name: &str) -> Vec<Isometry3<f64>> {
        let k = &self.model.kinematics;
        let (_, joints) = kinect_poses().into_iter().find(|(n, _)| n == name).unwrap();
        k.link_poses(&k.values_from_names(&joints, Some(0.0)).unwrap())
    }

    fn query(&mut self, poses: &[Isometry3<f64>], options: &QueryOptions) -> QueryResult {
        (self.engine)
            .query(&self.points, &self.sensor, poses, options)
            .unwrap()
    }
}

/// Exact mode within 1 mm of the reference distances, on the reference links and points; the
/// certified per-link intervals hold the reference per-link minima. Exact mode does not depend
/// on the sphere budget, so a small one keeps the build short.
#[test]
fn kinect_panda_reference_distances() {
    let Some(shared) = common::shared() else {
        return;
    };
    let mut kinect = Kinect::load(&shared);
    let exact = QueryOptions {
        mode: Mode::Exact,
        ..QueryOptions::default()
    };
    // Every link measured (the node's default measures only links within per_link_range).
    let certified = QueryOptions {
        mode: Mode::Certified,
        per_link_range_m: f32::INFINITY,
        ..QueryOptions::default()
    };
    let ready = kinect.pose("ready");
    let nearest = ready_nearest_is_the_reference(&mut kinect, &ready, &exact);
    ready_per_link_minima_in_their_intervals(&mut kinect, &ready, &certified, &nearest);
    let reach = kinect.pose("reach_table");
    let global = reach_table_nearest_is_the_reference(&mut kinect, &reach, &exact);
    // The GPU backend on the real scene (lavapipe in CI).
    if !common::has_gpu(&mut kinect.engine) {
        return;
    }
    let cases = [(&ready, &certified), (&reach, &exact), (&reach, &global)];
    gpu_agrees_on_the_real_scene(&mut kinect, &cases);
}

/// `ready`, exact: the nearest point is SCENARIO.md's on panda_link0; its link's name.
fn ready_nearest_is_the_reference(
    kinect: &mut Kinect,
    ready: &[Isometry3<f64>],
    exact: &QueryOptions,
) -> String {
    let r = kinect.query(ready, exact);
    assert_eq!(r.outcome, Outcome::Nearest);
    let n = assert_nearest(
        &r,
        "ready",
        "panda_link0",
        0.0979,
        [-0.0087, 0.1782, 0.0680],
    );
    assert_eq!(r.counts.total, 307_200);
    assert_eq!(r.counts.invalid, 73_899);
    assert_eq!(r.counts.inside, 0);
    n.link.clone()
}

/// The nearest point of `r` (pose `what`) is SCENARIO.md's: on `link`, `distance` from the
/// robot (1 mm) at root-frame `point` (2 mm).
fn assert_nearest<'a>(
    r: &'a QueryResult,
    what: &str,
    link: &str,
    distance: f64,
    point: [f64; 3],
) -> &'a ist_monitor::query::Nearest {
    let n = r.nearest.as_ref().unwrap();
    assert_eq!(n.link, link);
    assert!(
        (n.distance_m - distance).abs() < 1e-3,
        "{what}: {}",
        n.distance_m
    );
    assert!(
        (0..3).all(|i| (n.point_root[i] - point[i]).abs() < 2e-3),
        "{:?}",
        n.point_root
    );
    n
}

/// SCENARIO.md's per-link minima for `ready` lie in the certified intervals (1 mm for the
/// reference's own rounding and tessellation); with the default range, a link farther than it
/// is bounded from below, correctly.
fn ready_per_link_minima_in_their_intervals(
    kinect: &mut Kinect,
    ready: &[Isometry3<f64>],
    certified: &QueryOptions,
    nearest: &str,
) {
    let c = kinect.query(ready, certified);
    let d = kinect.query(ready, &QueryOptions::default());
    for (link, reference) in [
        ("panda_link0", 0.0979),
        ("panda_link1", 0.1428),
        ("panda_link2", 0.2290),
        ("panda_link3", 0.3896),
        ("panda_link4", 0.5150),
        ("panda_link5", 0.5889),
        ("panda_hand", 0.4843),
        ("panda_leftfinger", 0.4758),
        ("panda_rightfinger", 0.4696),
    ] {
        let l = c.links.iter().find(|l| l.link == link).unwrap();
        let (lo, hi) = (l.lower_m.unwrap(), l.distance_m.unwrap());
        assert!(
            lo - 1e-3 <= reference && reference <= hi + 1e-3,
            "{link}: [{lo}, {hi}] does not hold {reference}"
        );
        let l = d.links.iter().find(|l| l.link == link).unwrap();
        let lower = l.lower_m.unwrap();
        assert!(
            lower <= reference + 1e-3,
            "{link}: lower {lower} above {reference}"
        );
        match (l.distance_m, l.farther_than_m) {
            (Some(_), None) => assert!(reference <= 0.32 + 1e-3 || link == nearest),
            (None, Some(t)) => assert!(t <= hi + 1e-6 && reference > 0.32 - 1e-3, "{link}: > {t}"),
            other => panic!("{link}: {other:?}"),
        }
    }
}

/// `reach_table`, exact: the nearest point is SCENARIO.md's on the left finger, and the
/// global-only query (one shared bound) gives the same exact answer; its options.
fn reach_table_nearest_is_the_reference(
    kinect: &mut Kinect,
    reach: &[Isometry3<f64>],
    exact: &QueryOptions,
) -> QueryOptions {
    let r = kinect.query(reach, exact);
    let n = assert_nearest(
        &r,
        "reach_table",
        "panda_leftfinger",
        0.0181,
        [0.0357, 0.6130, 0.0760],
    );
    let global = QueryOptions {
        per_link: false,
        ..exact.clone()
    };
    let g = kinect.query(reach, &global);
    assert_eq!(g.nearest.as_ref().unwrap().distance_m, n.distance_m);
    global
}

/// The GPU backend on the real scene: the same distances within 1e-5 m (rounding of the square
/// root only), per link too, and the same stage counts before pruning; as runs and as the
/// organized image (tiles), with the minima in 64-bit atomics (where the adapter has them) and
/// in the portable path. Its pruning is the CPU's: the same blocks culled within 2×, and with
/// 64-bit atomics no more than 2.5× the CPU's nodes expanded (measured 0.9–1.95× here, every
/// link measured to any range; 1.0–2.15× with packets, which expand a node for all eight points
/// of a packet; the portable path's arg-min pass descends again, about 1.6× more).
fn gpu_agrees_on_the_real_scene(
    kinect: &mut Kinect,
    cases: &[(&Vec<Isometry3<f64>>, &QueryOptions)],
) {
    // Both fast paths, then the portable one (neither 64-bit atomics nor subgroups), each point
    // descending on its own; then the fast paths with the sub-blocks' points in packets.
    for (int64_atomics, subgroups, packets) in [
        (true, true, false),
        (false, false, false),
        (true, true, true),
    ] {
        let gpu = (kinect.engine)
            .gpu_with(ist_monitor::query::gpu::GpuOptions {
                int64_atomics,
                subgroups,
                packets,
            })
            .unwrap();
        let path = format!("{:?} {:?} packets {packets}", gpu.minima, gpu.reduce);
        let packed = gpu.minima == Minima::Packed64;
        for &(joints, options) in cases {
            for width in [None, Some(640)] {
                let what = format!("{:?} width {width:?} {path}", options.mode);
                gpu_agrees_with_cpu_on(kinect, joints, options, width, packed, &what);
            }
        }
    }
}

/// One query of [`gpu_agrees_on_the_real_scene`] on both backends.
fn gpu_agrees_with_cpu_on(
    kinect: &mut Kinect,
    joints: &[Isometry3<f64>],
    options: &QueryOptions,
    width: Option<usize>,
    packed: bool,
    what: &str,
) {
    let on = |backend| QueryOptions {
        backend,
        ..options.clone()
    };
    let Kinect {
        engine,
        points,
        sensor,
        ..
    } = kinect;
    let c = engine
        .query_image(points, width, sensor, joints, &on(Backend::Cpu))
        .unwrap();
    let cw = engine.last_work();
    let g = engine
        .query_image(points, width, sensor, joints, &on(Backend::Gpu))
        .unwrap();
    let gw = engine.last_work();
    assert_eq!(g.backend, Backend::Gpu);
    let (cn, gn) = (c.nearest.unwrap(), g.nearest.unwrap());
    assert!(
        (cn.distance_m - gn.distance_m).abs() < 1e-5,
        "{what}: {cn:?} {gn:?}"
    );
    assert_eq!(cn.link, gn.link, "{what}");
    for (a, b) in c.links.iter().zip(&g.links) {
        let close = |x: Option<f64>, y: Option<f64>| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() < 1e-5,
            (x, y) => x == y,
        };
        assert!(close(a.distance_m, b.distance_m), "{what}: {a:?} {b:?}");
    }
    assert_eq!(
        (
            c.counts.invalid,
            c.counts.outside_roi,
            c.counts.self_filtered
        ),
        (
            g.counts.invalid,
            g.counts.outside_roi,
            g.counts.self_filtered
        ),
        "{what}"
    );
    eprintln!("{what}: CPU {cw:?}\n{what}: GPU {gw:?}");
    assert_eq!(cw.blocks, gw.blocks, "{what}");
    let within_2x = |a: u64, b: u64| a <= 2 * b && b <= 2 * a;
    assert!(
        within_2x(cw.blocks_culled, gw.blocks_culled),
        "{what}: {cw:?} {gw:?}"
    );
    if packed {
        assert!(2 * gw.nodes <= 5 * cw.nodes, "{what}: {cw:?} {gw:?}");
    }
}

/// `ist_monitor query` of the Panda at the `ready` pose against the bag's Kinect cloud
/// (SCENARIO.md's camera; 256 spheres a link, trees cached in `cache`), with `args` and the
/// environment `env`: its JSON.
fn query_the_bag(
    shared: &std::path::Path,
    cache: &std::path::Path,
    args: &[&str],
    env: &[(&str, &str)],
) -> serde_json::Value {
    // SCENARIO.md's camera as "x y z qx qy qz qw" (root_from_sensor).
    let s = kinect_root_from_sensor();
    let (t, q) = (s.translation.vector, s.rotation.coords);
    let pose = format!("{} {} {} {} {} {} {}", t.x, t.y, t.z, q.x, q.y, q.z, q.w);
    let mut command = ist_monitor();
    command
        .args(["query", "--urdf"])
        .arg(shared.join("robots/panda/robot.urdf"))
        .args(["--max-spheres", "256", "--cache-dir"])
        .arg(cache)
        .args([
            "--joints",
            "panda_joint2=-0.785,panda_joint4=-2.356,panda_joint6=1.571,panda_joint7=0.785",
            "--json",
            "--sensor-pose",
            &pose,
        ])
        .args(args)
        .arg("--cloud")
        .arg(shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap"));
    for (k, v) in env {
        command.env(k, v);
    }
    common::json_output(&mut command)
}

/// `ist_monitor query` on the bag folder, JSON out.
#[test]
fn query_command_on_the_bag() {
    let Some(shared) = common::shared() else {
        return;
    };
    let cache = tempfile::tempdir().unwrap();
    let json = query_the_bag(&shared, cache.path(), &["--mode", "exact"], &[]);
    assert_eq!(json["outcome"], "nearest");
    assert_eq!(json["nearest"]["link"], "panda_link0");
    let d = json["nearest"]["distance_m"].as_f64().unwrap();
    assert!((d - 0.0979).abs() < 1e-3, "{d}");
    assert_eq!(json["counts"]["invalid"], 73_899);
}

/// `ist_monitor query --backend gpu` on the real Kinect scene equals `--backend cpu` on every
/// vector width lavapipe runs the shader at (`LP_NATIVE_VECTOR_WIDTH` 128, 256, 512: subgroups
/// of four, eight and sixteen), with the minima in 64-bit atomics and the reductions by subgroup,
/// and on the portable path without either (`IST_MONITOR_GPU_NO_INT64`,
/// `IST_MONITOR_GPU_NO_SUBGROUPS`), and with the measure pass's packets
/// (`IST_MONITOR_GPU_PACKETS`), certified with per-link minima (the node's defaults, every
/// link measured): the same nearest link and point, distances within 1e-5 m, the same counts
/// that do not depend on the bounds' history. On a hardware GPU the width changes nothing.
#[test]
fn the_gpu_answers_the_kinect_scene_at_every_lavapipe_width_and_on_the_portable_path() {
    let Some(shared) = common::shared() else {
        return;
    };
    let cache = tempfile::tempdir().unwrap();
    let query = |backend: &str, env: &[(&str, &str)]| {
        let args = ["--per-link-range", ".inf", "--backend", backend];
        query_the_bag(&shared, cache.path(), &args, env)
    };
    let cpu = query("cpu", &[]);
    for width in ["128", "256", "512"] {
        for (portable, packets) in [("0", "0"), ("1", "0"), ("0", "1")] {
            let env = [
                ("LP_NATIVE_VECTOR_WIDTH", width),
                ("IST_MONITOR_GPU_NO_INT64", portable),
                ("IST_MONITOR_GPU_NO_SUBGROUPS", portable),
                ("IST_MONITOR_GPU_PACKETS", packets),
            ];
            let gpu = query("gpu", &env);
            let what = format!("width {width}, portable {portable}, packets {packets}");
            if gpu["backend"] != "gpu" {
                if std::env::var_os("CI").is_some() {
                    panic!("{what}: the query ran on {} in CI", gpu["backend"]);
                }
                common::skip("no GPU adapter and CI is not set");
                return;
            }
            assert_eq!(gpu["nearest"]["link"], cpu["nearest"]["link"], "{what}");
            assert_eq!(
                gpu["nearest"]["point_index"], cpu["nearest"]["point_index"],
                "{what}"
            );
            let d = |j: &serde_json::Value| j["nearest"]["distance_m"].as_f64().unwrap();
            assert!((d(&gpu) - d(&cpu)).abs() < 1e-5, "{what}: {gpu} {cpu}");
            for (a, b) in cpu["links"]
                .as_array()
                .unwrap()
                .iter()
                .zip(gpu["links"].as_array().unwrap())
            {
                let (x, y) = (a["distance_m"].as_f64(), b["distance_m"].as_f64());
                assert_eq!(x.is_some(), y.is_some(), "{what}: {a} {b}");
                if let (Some(x), Some(y)) = (x, y) {
                    assert!((x - y).abs() < 1e-5, "{what}: {a} {b}");
                }
            }
            for count in ["total", "invalid", "outside_roi", "self_filtered"] {
                assert_eq!(
                    gpu["counts"][count], cpu["counts"][count],
                    "{what}: {count}"
                );
            }
        }
    }
}

/// The generator's hidden-obstacle scenes (`dark`, `shadow`, the second camera): the demo arm,
/// `frames` frames of `scene` into a temporary bag, with `change` applied to the parameters.
fn generate_hidden(
    scene: ist_monitor::scenario::SceneKind,
    frames: usize,
    change: impl FnOnce(&mut ist_monitor::scenario::ScenarioParams),
) -> (
    tempfile::TempDir,
    std::path::PathBuf,
    ist_monitor::scenario::Generated,
) {
    let model = RobotModel::load(
        std::path::Path::new(common::DEMO_URDF),
        &[],
        &Default::default(),
    )
    .unwrap();
    let mut params = ist_monitor::scenario::ScenarioParams {
        scene,
        frames,
        ..Default::default()
    };
    change(&mut params);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bag");
    let g = ist_monitor::scenario::generate(&model, &params, &out).unwrap();
    (dir, out, g)
}

/// The payloads on `topic` of the bag at `bag`, in log-time order.
fn payloads(bag: &std::path::Path, topic: &str) -> Vec<Vec<u8>> {
    ist_monitor::bag::read_messages(bag, &|t, _| t == topic)
        .unwrap()
        .into_iter()
        .map(|m| m.data)
        .collect()
}

/// The clouds on `topic`, decoded.
fn clouds(bag: &std::path::Path, topic: &str) -> Vec<Vec<[f32; 3]>> {
    payloads(bag, topic)
        .iter()
        .map(|d| cloud::pointcloud2::cloud_from_cdr(d).unwrap().points)
        .collect()
}

/// A dark person (`ScenarioParams::dark`) is the person scene with the person's pixels blank:
/// the same draws elsewhere (every valid point of the dark bag is the person bag's, and the
/// points lost are exactly the person's), no valid point on the person, in a cloud and in a
/// 16UC1 image (0 there); its truth is the distance to the whole person, at most that to the
/// lit person's points (within their range noise), and falls below 0.1 m by the end.
#[test]
fn generated_dark_person_returns_nothing_and_keeps_its_truth() {
    use ist_monitor::scenario::{SceneKind, CLOUD_TOPIC, DEPTH_TOPIC};
    let frames = 10;
    let (_d1, lit, lit_g) = generate_hidden(SceneKind::Person, frames, |_| {});
    let (_d2, dark, g) = generate_hidden(SceneKind::Person, frames, |p| p.dark = true);
    assert!(
        g.target_points.iter().all(|&n| n == 0),
        "{:?}",
        g.target_points
    );
    // The person walks into view: seen on the last frames of the lit scene.
    assert!(lit_g.target_points[frames - 3..].iter().all(|&n| n > 500));
    let valid = |c: &[[f32; 3]]| c.iter().filter(|p| p[0].is_finite()).count();
    for (i, (a, b)) in clouds(&lit, CLOUD_TOPIC)
        .iter()
        .zip(clouds(&dark, CLOUD_TOPIC))
        .enumerate()
    {
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(&b) {
            assert!(q[0].is_nan() || p == q, "frame {i}: {p:?} {q:?}");
        }
        assert_eq!(valid(a) - valid(&b), lit_g.target_points[i], "frame {i}");
    }
    let truth: Vec<f64> = g.truth_m.iter().map(|t| t.unwrap()).collect();
    // The lit points carry the range noise (clipped at 2.5 σ = 2.5 mm), the shape does not.
    for (d, lit) in truth.iter().zip(&lit_g.truth_m) {
        assert!(*d <= lit.unwrap() + 0.0025 + 1e-5, "{d} > {lit:?}");
    }
    assert!(truth[0] > 0.5 && *truth.last().unwrap() < 0.1, "{truth:?}");
    // The same as 16UC1 images: 0 wherever the person is.
    let depth = Some(cloud::depth::DepthEncoding::Millimetres16);
    let (_d3, lit, _) = generate_hidden(SceneKind::Person, 3, |p| p.depth = depth);
    let (_d4, dark, g) = generate_hidden(SceneKind::Person, 3, |p| {
        p.depth = depth;
        p.dark = true
    });
    let zeros = |bag: &std::path::Path| -> Vec<usize> {
        payloads(bag, DEPTH_TOPIC)
            .iter()
            .map(|d| {
                let image = ist_monitor::msg::decode::<ist_monitor::msg::Image>(d).unwrap();
                assert_eq!(image.encoding, "16UC1");
                image.data.chunks(2).filter(|c| c == &[0, 0]).count()
            })
            .collect()
    };
    let (lit_zeros, dark_zeros) = (zeros(&lit), zeros(&dark));
    assert_eq!(dark_zeros.len(), 3);
    assert!((0..3).all(|i| dark_zeros[i] >= lit_zeros[i]));
    assert!(
        dark_zeros[2] > lit_zeros[2] + 500,
        "{dark_zeros:?} {lit_zeros:?}"
    );
    assert!(g.target_points.iter().all(|&n| n == 0));
}

/// The shadow scene: the forearm reaching in behind the upper arm is hidden from the first
/// camera on every frame while its truth falls from over 0.5 m to under 0.1 m; the second camera
/// (`ScenarioParams::second_camera`) sees it on every frame, recorded on its own topics and
/// optical frame with its CameraInfo, its link placed on /tf_static under the root, and the
/// truth at each camera's log time.
#[test]
fn generated_shadow_is_hidden_from_the_first_camera_and_seen_by_the_second() {
    use ist_monitor::bag::GROUND_TRUTH_TOPIC;
    use ist_monitor::msg::{CameraInfo, TfMessage};
    use ist_monitor::scenario::*;
    let frames = 10;
    let (_dir, bag, g) = generate_hidden(SceneKind::Shadow, frames, |p| p.second_camera = true);
    assert!(
        g.target_points.iter().all(|&n| n <= 2),
        "{:?}",
        g.target_points
    );
    assert!(
        g.side_target_points.iter().all(|&n| n > 50),
        "{:?}",
        g.side_target_points
    );
    // The first camera sees the arm the forearm hides behind.
    assert!(g.robot_points.iter().all(|&n| n > 100));
    let truth: Vec<f64> = g.truth_m.iter().map(|t| t.unwrap()).collect();
    assert!(truth[0] > 0.5 && *truth.last().unwrap() < 0.1, "{truth:?}");
    assert!(truth.windows(2).all(|w| w[1] <= w[0] + 1e-9), "{truth:?}");
    // The second camera's topics, frames and truths.
    let side = clouds(&bag, SIDE_CLOUD_TOPIC);
    assert_eq!(side.len(), frames);
    assert!(side.iter().all(|c| c.len() == 128 * 96));
    for d in payloads(&bag, SIDE_CAMERA_INFO_TOPIC) {
        let info = ist_monitor::msg::decode::<CameraInfo>(&d).unwrap();
        assert_eq!(info.header.frame_id, SIDE_OPTICAL_FRAME);
        assert_eq!((info.width, info.height), (128, 96));
    }
    assert_eq!(payloads(&bag, SIDE_CAMERA_INFO_TOPIC).len(), frames);
    assert_eq!(payloads(&bag, CLOUD_TOPIC).len(), frames);
    assert_eq!(payloads(&bag, GROUND_TRUTH_TOPIC).len(), 2 * frames);
    let tf = payloads(&bag, "/tf_static");
    assert_eq!(tf.len(), 1);
    let tf = ist_monitor::msg::decode::<TfMessage>(&tf[0]).unwrap();
    let pairs: Vec<(&str, &str)> = (tf.transforms.iter())
        .map(|t| (t.header.frame_id.as_str(), t.child_frame_id.as_str()))
        .collect();
    assert_eq!(
        pairs,
        [
            (CAMERA_LINK, OPTICAL_FRAME),
            ("world", SIDE_CAMERA_LINK),
            (SIDE_CAMERA_LINK, SIDE_OPTICAL_FRAME)
        ]
    );
    // config/demo_arm_two_cameras.yaml reads both cameras.
    let config = ist_monitor::config::Config::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/demo_arm_two_cameras.yaml"),
        &[],
    )
    .unwrap();
    let topics: Vec<&str> = config.sources.iter().map(|s| s.topic.as_str()).collect();
    assert_eq!(topics, [CLOUD_TOPIC, SIDE_CLOUD_TOPIC]);
}

/// Points of `cloud` (in the optical frame `root_from_optical` places in the root) as root-frame
/// points, `None` where the point is invalid.
fn in_root(
    cloud: &[[f32; 3]],
    root_from_optical: &nalgebra::Isometry3<f64>,
) -> Vec<Option<nalgebra::Point3<f64>>> {
    (cloud.iter())
        .map(|p| {
            (!p[0].is_nan()).then(|| {
                root_from_optical * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)
            })
        })
        .collect()
}

/// The floor (`ScenarioParams::floor`) is a background, not an obstacle: the same seed gives the
/// same truth (distance, approach speed, margin) and the same obstacle and robot points frame for
/// frame, every valid point of the floorless bag is there bit for bit, and the rays that
/// returned nothing below and around the arm now return points on the plane z = 0 (within the
/// range noise, clipped at 2.5 σ = 2.5 mm along the ray).
#[test]
fn generated_floor_keeps_the_truth_and_fills_the_rays_below_the_arm() {
    use ist_monitor::scenario::{Mount, Renderer, SceneKind, CLOUD_TOPIC};
    let small = |p: &mut ist_monitor::scenario::ScenarioParams| {
        p.width = 64;
        p.height = 48;
    };
    let (_d1, plain, g) = generate_hidden(SceneKind::Person, 3, small);
    let (_d2, floored, gf) = generate_hidden(SceneKind::Person, 3, |p| {
        small(p);
        p.floor = true
    });
    assert_eq!(g.truth_m, gf.truth_m);
    assert_eq!(g.separation, gf.separation);
    assert_eq!(g.obstacle_points, gf.obstacle_points);
    assert_eq!(g.robot_points, gf.robot_points);
    assert!(g.truth_m.iter().all(|t| t.is_some()));
    // The first camera is fixed (camera_link under world): one pose for every frame.
    let model = RobotModel::load(
        std::path::Path::new(common::DEMO_URDF),
        &[],
        &Default::default(),
    )
    .unwrap();
    let params = ist_monitor::scenario::ScenarioParams {
        width: 64,
        height: 48,
        ..Default::default()
    };
    let root_from_optical = Renderer::new(&model, &params, &Mount::fixed())
        .unwrap()
        .frame(0.0, false)
        .unwrap()
        .root_from_sensor;
    let (a, b) = (clouds(&plain, CLOUD_TOPIC), clouds(&floored, CLOUD_TOPIC));
    assert_eq!((a.len(), b.len()), (3, 3));
    for (a, b) in a.iter().zip(&b) {
        let mut floor = 0;
        let mut below_arm = 0;
        for (p, q) in a.iter().zip(b) {
            if !p[0].is_nan() {
                assert_eq!(p.map(f32::to_bits), q.map(f32::to_bits));
            }
        }
        for (p, q) in in_root(a, &root_from_optical)
            .iter()
            .zip(in_root(b, &root_from_optical))
        {
            let (None, Some(q)) = (p, q) else { continue };
            assert!(q.z.abs() < 0.0026, "a new point off the floor: {q}");
            floor += 1;
            below_arm += usize::from(q.x.hypot(q.y) < 0.8);
        }
        assert!(floor > 500, "{floor} floor points");
        assert!(
            below_arm > 100,
            "{below_arm} floor points within 0.8 m of the base"
        );
    }
}

/// With a second camera the scene has a side wall behind the arm as that camera sees it
/// (`SIDE_WALL_CENTER`, its near face at y = 1.55 m): the side camera's rays behind the arm
/// return points on it, and with the floor the rest of its rays below the arm return too.
#[test]
fn generated_second_camera_sees_the_side_wall_behind_the_arm() {
    use ist_monitor::scenario::*;
    let (_dir, bag, g) = generate_hidden(SceneKind::Shadow, 2, |p| {
        p.width = 64;
        p.height = 48;
        p.second_camera = true;
        p.floor = true;
    });
    assert!(g.truth_m.iter().all(|t| t.is_some_and(|t| t < 1.0)));
    let root_from_optical = root_from_side_link() * link_from_optical();
    let near_face = SIDE_WALL_CENTER[1] - 0.5 * SIDE_WALL_SIZE[1];
    for cloud in clouds(&bag, SIDE_CLOUD_TOPIC) {
        let points = in_root(&cloud, &root_from_optical);
        let wall = (points.iter().flatten())
            .filter(|p| (p.y - near_face).abs() < 0.003 && p.z > 0.01)
            .count();
        let floor = (points.iter().flatten())
            .filter(|p| p.z.abs() < 0.0026)
            .count();
        assert!(wall > 64 * 48 / 4, "{wall} points on the side wall");
        assert!(floor > 64 * 48 / 10, "{floor} points on the floor");
    }
}
