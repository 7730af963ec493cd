//! The fault model and the self-filter's contract, through the monitor (what `replay` and the
//! node run): the level never falls on a frame that tells nothing, and what the self-filter
//! removes is counted per link and said.

mod common;

use std::path::Path;

use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::Config;
use ist_monitor::monitor::{Frame, Level, Monitor};
use ist_monitor::msg::{Header, Time};
use ist_monitor::robot::RobotModel;
use nalgebra::Point3;

const STAMP: i64 = 1_700_000_000_000_000_000;

/// The demo arm at rest, seen by a sensor `cam` at the root (`world`), joints fixed at 0; and
/// points on it: the centres of every inner sphere of every link, in the root frame.
fn arm_at_rest() -> (Monitor, Vec<[f32; 3]>) {
    let (m, robot, _) = arm_at_rest_with(&[]);
    (m, robot)
}

/// As [`arm_at_rest`], with more parameters set; also the top of the arm: the highest point of
/// its inner spheres, and that sphere's centre and radius.
fn arm_at_rest_with(extra: &[(&str, &str)]) -> (Monitor, Vec<[f32; 3]>, ([f32; 3], f32)) {
    let (model, trees) = common::demo_trees();
    let names = model.kinematics.variables().to_vec();
    let poses = model.kinematics.link_poses(&vec![0.0; names.len()]);
    let mut robot = Vec::new();
    let mut top = ([0.0f32; 3], 0.0f32);
    for tree in &trees {
        let pose = poses[model.kinematics.link_index(&tree.link).unwrap()];
        for s in &tree.spheres {
            let c = s.center.map(f64::from);
            let p = pose * Point3::new(c[0], c[1], c[2]);
            let p = [p.x as f32, p.y as f32, p.z as f32];
            if robot.is_empty() || p[2] + s.radius > top.0[2] + top.1 {
                top = (p, s.radius);
            }
            robot.push(p);
        }
    }
    let mut overrides = at_rest(&names);
    overrides.extend(extra.iter().map(|(k, v)| (k.to_string(), v.to_string())));
    let config = Config::from_overrides(&overrides).unwrap();
    (
        Monitor::with_trees(config, model, &trees).unwrap(),
        robot,
        top,
    )
}

/// The demo arm seen by a sensor `cam` at the root (`world`), its joints `names` fixed at 0, on
/// the CPU.
fn at_rest(names: &[String]) -> Vec<(String, String)> {
    vec![
        ("robot_description".into(), common::DEMO_URDF.into()),
        ("static_transforms".into(), "[cam]".into()),
        ("cam.parent_frame".into(), "world".into()),
        ("cam.child_frame".into(), "cam".into()),
        ("fixed_joint_state.names".into(), format!("{names:?}")),
        (
            "fixed_joint_state.positions".into(),
            format!("{:?}", vec![0.0; names.len()]),
        ),
        ("backend".into(), "cpu".into()),
    ]
}

fn frame(monitor: &mut Monitor, points: &[[f32; 3]]) -> Frame {
    let header = Header {
        stamp: Time::from_nanos(STAMP),
        frame_id: "cam".into(),
    };
    let layout = pointcloud2::Layout::unorganized(points.len() as u32);
    let m = pointcloud2::encode(header, points, &layout).unwrap();
    monitor.on_cloud(0, &m, std::time::Instant::now(), Some(STAMP))
}

/// A frame in which the self-filter removed every valid point says so at WARN, publishes no
/// distance, and keeps a stop that was raised: an obstacle touching the robot looks the same.
#[test]
fn a_frame_the_self_filter_empties_never_releases_the_stop() {
    let (mut m, robot) = arm_at_rest();
    assert!(robot.len() > 100);
    // Far away: OK.
    let f = frame(&mut m, &[[5.0, 5.0, 5.0]]);
    assert_eq!(f.outputs.level, Level::Ok);
    // Only the robot: WARN, no distance, the reason said; counted per link.
    let f = frame(&mut m, &robot);
    assert_eq!(f.outputs.level, Level::Warn);
    assert!(f.outputs.min_distance.is_none());
    let message = &f.outputs.diagnostics.status[0].message;
    assert!(
        message.contains("self-filter removed every valid point"),
        "{message}"
    );
    let per_link: u64 = f.outputs.diagnostics.status[0]
        .values
        .iter()
        .filter(|kv| kv.key.starts_with("points_self_filtered."))
        .map(|kv| kv.value.parse::<u64>().unwrap())
        .sum();
    assert_eq!(per_link, robot.len() as u64);
    assert_eq!(
        common::status_value(&f, "points_self_filtered"),
        Some(&*robot.len().to_string())
    );
    // An obstacle above the arm, moved down until it raises the stop; the robot alone next
    // keeps the stop.
    let near = {
        let top = robot
            .iter()
            .copied()
            .max_by(|a, b| a[2].total_cmp(&b[2]))
            .unwrap();
        [top[0], top[1], top[2] + 0.2]
    };
    let f = frame(&mut m, &[near]);
    let d = f.outputs.min_distance.as_ref().map(|d| d.data);
    assert!(d.is_some_and(|d| d < 0.2), "{d:?}");
    let mut closer = near;
    let mut level = f.outputs.level;
    while level != Level::Error {
        closer[2] -= 0.01;
        level = frame(&mut m, &[closer]).outputs.level;
        assert!(closer[2] > near[2] - 0.2, "never reached the stop");
    }
    let f = frame(&mut m, &robot);
    assert_eq!(f.outputs.level, Level::Error, "the stop was released");
    assert!(f.outputs.min_distance.is_none());
    assert!(f.outputs.safety_stop.data);
}

/// The padding must stay below `stop_distance − hysteresis`: larger, a point at the stop
/// distance would be filtered as the robot and never raise the stop.
#[test]
fn the_self_filter_padding_is_bounded_by_the_stop_distance() {
    let e = Config::from_overrides(&[("self_filter_padding".into(), "10".into())])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("self_filter_padding") && e.contains("stop_distance"),
        "{e}"
    );
    let e = Config::from_overrides(&[("self_filter_padding".into(), "0.08".into())])
        .unwrap_err()
        .to_string();
    assert!(e.contains("0.08 m must stay below"), "{e}");
    assert!(Config::from_overrides(&[("self_filter_padding".into(), "0.079".into())]).is_ok());
    // Without the self-filter the padding is not used, so not checked.
    assert!(Config::from_overrides(&[
        ("self_filter_padding".into(), "10".into()),
        ("self_filter".into(), "false".into())
    ])
    .is_ok());
}

/// The robot description as a file, as the URDF text itself (what MoveIt's `robot_description`
/// parameter holds), or from a topic (only the node reads one); none is an error naming both
/// parameters.
#[test]
fn the_robot_comes_from_a_file_the_urdf_text_or_a_topic() {
    let dir = Path::new(common::DEMO_URDF).parent().unwrap();
    let text = std::fs::read_to_string(common::DEMO_URDF).unwrap().replace(
        "filename=\"meshes/",
        &format!("filename=\"file://{}/meshes/", dir.display()),
    );
    let from_text =
        Config::from_overrides(&[("robot_description".into(), format!("{text:?}"))]).unwrap();
    let m = Monitor::new(from_text, &|_| {}).unwrap();
    let from_file = Monitor::new(
        Config::from_overrides(&[("robot_description".into(), common::DEMO_URDF.into())]).unwrap(),
        &|_| {},
    )
    .unwrap();
    assert_eq!(m.model.name, from_file.model.name);
    assert_eq!(m.links(), from_file.links());
    let topic = Config::from_overrides(&[(
        "robot_description_topic".into(),
        "/robot_description".into(),
    )])
    .unwrap();
    let e = Monitor::new(topic, &|_| {}).err().unwrap().to_string();
    assert!(
        e.contains("only the live node reads the robot from a topic"),
        "{e}"
    );
    let e = Monitor::new(Config::default(), &|_| {})
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("robot_description") && e.contains("robot_description_topic"),
        "{e}"
    );
}

/// A robot with more links than the engine handles (129 > 128), or a link selection naming a
/// link it does not have, is refused before a single tree is built.
#[test]
fn too_many_links_are_refused_before_any_tree_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let mut urdf = String::from("<robot name=\"many\"><link name=\"l0\"><collision><geometry><box size=\"0.1 0.1 0.1\"/></geometry></collision></link>");
    for i in 1..129 {
        urdf.push_str(&format!(
            "<link name=\"l{i}\"><collision><geometry><box size=\"0.1 0.1 0.1\"/></geometry></collision></link>\
             <joint name=\"j{i}\" type=\"fixed\"><parent link=\"l{}\"/><child link=\"l{i}\"/></joint>",
            i - 1
        ));
    }
    urdf.push_str("</robot>");
    let path = dir.path().join("many.urdf");
    std::fs::write(&path, urdf).unwrap();
    let built = std::sync::atomic::AtomicUsize::new(0);
    let count = |_: &str| {
        built.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    };
    let config = |extra: &[(&str, &str)]| {
        let mut o = vec![
            ("robot_description".to_string(), path.display().to_string()),
            (
                "cache_dir".to_string(),
                dir.path().join("cache").display().to_string(),
            ),
            // Small trees: the last case builds all 128.
            ("max_spheres".to_string(), "16".to_string()),
        ];
        o.extend(extra.iter().map(|(k, v)| (k.to_string(), v.to_string())));
        Config::from_overrides(&o).unwrap()
    };
    let e = Monitor::new(config(&[]), &count).err().unwrap().to_string();
    assert!(e.contains("129 links") && e.contains("at most 128"), "{e}");
    let e = Monitor::new(config(&[("links", "[l0, nope]")]), &count)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("nope"), "{e}");
    assert_eq!(built.load(std::sync::atomic::Ordering::Relaxed), 0);
    // Leaving one out is within the limit; only the selected links are built.
    let model = RobotModel::load(&path, &[], &Default::default()).unwrap();
    let c = config(&[("exclude_links", "[l128]")]);
    assert!(c.selection.check(&model).is_ok());
    let m = Monitor::new(config(&[("links", "[l3, l7]")]), &count).unwrap();
    assert_eq!(m.links(), 2);
    assert_eq!(built.load(std::sync::atomic::Ordering::Relaxed), 2);
}

const STRAY_FILTER: &[(&str, &str)] = &[
    ("stray_filter.min_points", "4"),
    ("stray_filter.cluster_radius", "0.02"),
];

/// A wall of points 2.5 m up, 5 mm apart: something far that every frame sees.
fn far_wall() -> Vec<[f32; 3]> {
    (0..400)
        .map(|i| [(i % 20) as f32 * 0.005, (i / 20) as f32 * 0.005, 2.5])
        .collect()
}

/// One stray point 1.5 cm above the top of the arm (within the stop distance, outside the
/// self-filter padding), beside a mixed-pixel fringe on the arm's own surface that the
/// self-filter takes as the robot: without the filter it stops the cell; with it (4 points
/// within 2 cm), it is rejected (the robot's points are not its neighbours) and counted, and the
/// far wall is the distance. A real obstacle of 4 points at the same place stops the cell on
/// its first frame.
#[test]
fn a_stray_point_next_to_the_arm_stops_nothing_with_the_filter_on() {
    let (mut plain, _, (c, r)) = arm_at_rest_with(&[]);
    let (mut filtered, _, _) = arm_at_rest_with(STRAY_FILTER);
    let top = [c[0], c[1], c[2] + r];
    // Points on the top sphere's cap: the robot (distance 0 to an inner sphere).
    let fringe: Vec<[f32; 3]> = (0..12)
        .map(|k| {
            let a = k as f32 * 0.5;
            let (dx, dy) = (0.1 * r * a.cos(), 0.1 * r * a.sin());
            let dz = (r * r - dx * dx - dy * dy).sqrt();
            [c[0] + dx, c[1] + dy, c[2] + dz * 0.999]
        })
        .collect();
    let stray = [top[0], top[1], top[2] + 0.015];
    let mut cloud = far_wall();
    cloud.extend(&fringe);
    cloud.push(stray);
    let f = frame(&mut plain, &cloud);
    assert_eq!(
        f.outputs.level,
        Level::Error,
        "without the filter the stray stops"
    );
    let f = frame(&mut filtered, &cloud);
    assert_ne!(f.outputs.level, Level::Error);
    let d = f.outputs.min_distance.unwrap().data;
    assert!(d > 1.0, "the wall's distance, got {d}");
    assert_eq!(common::status_value(&f, "points_stray_rejected"), Some("1"));
    // A real obstacle: 4 points within 1 cm of each other at the stray's place.
    let (mut fresh, _, _) = arm_at_rest_with(STRAY_FILTER);
    let mut cloud = far_wall();
    cloud.extend((0..4).map(|k| [stray[0] + 0.003 * k as f32, stray[1], stray[2] + 0.002]));
    let f = frame(&mut fresh, &cloud);
    assert_eq!(
        f.outputs.level,
        Level::Error,
        "a real obstacle stops at once"
    );
    assert_eq!(common::status_value(&f, "points_stray_rejected"), Some("0"));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: 48,
        ..proptest::prelude::ProptestConfig::default()
    })]

    /// The filter never raises the distance above that of any cluster of `min_points` points
    /// within `cluster_radius` of each other, whatever strays lie around it.
    #[test]
    fn the_stray_filter_never_hides_a_cluster(
        strays in proptest::collection::vec(
            (-0.6f32..0.6, -0.6f32..0.6, 0.0f32..1.2), 0..24),
        centre in (-0.6f32..0.6, -0.6f32..0.6, 0.0f32..1.2),
        offsets in proptest::collection::vec(
            (-0.005f32..0.005, -0.005f32..0.005, -0.005f32..0.005), 4..8),
    ) {
        use std::cell::RefCell;
        thread_local! {
            static MONITORS: RefCell<Option<(Monitor, Monitor)>> = const { RefCell::new(None) };
        }
        MONITORS.with(|m| {
            let mut m = m.borrow_mut();
            let (plain, filtered) = m.get_or_insert_with(|| {
                (arm_at_rest_with(&[]).0, arm_at_rest_with(STRAY_FILTER).0)
            });
            let cluster: Vec<[f32; 3]> = offsets
                .iter()
                .map(|o| [centre.0 + o.0, centre.1 + o.1, centre.2 + o.2])
                .collect();
            let alone = frame(plain, &cluster);
            let counts = common::status_value(&alone, "points_self_filtered").unwrap().to_string();
            // A cluster that touches the robot is not an obstacle the property is about.
            proptest::prop_assume!(counts == "0");
            let Some(d_cluster) = alone.outputs.min_distance.map(|d| d.data) else {
                return Ok(());
            };
            let mut cloud: Vec<[f32; 3]> = strays.iter().map(|s| [s.0, s.1, s.2]).collect();
            cloud.extend(&cluster);
            let f = frame(filtered, &cloud);
            match f.outputs.min_distance {
                Some(d) => proptest::prop_assert!(
                    d.data <= d_cluster + 1e-9,
                    "filtered {} > the cluster's {d_cluster}", d.data
                ),
                // Every stray and the cluster point all self-filtered can leave no distance:
                // never a released stop (the level is held).
                None => proptest::prop_assert!(f.outputs.level >= Level::Warn),
            }
            Ok(())
        })?;
    }
}

/// An exclusion volume whose frame has no transform is a fault of the frame that names the
/// volume (its points would stop the cell, or be dropped in the wrong place); a cloud whose
/// every valid point lies in exclusion volumes is clear, not blind: the sensor sees, and what it
/// sees is known.
#[test]
fn exclusion_volumes_fault_without_their_frame_and_clear_when_all_is_known() {
    let wall = |m: &mut Monitor| frame(m, &far_wall());
    let volume = [
        ("exclusion_volumes", "[fixture]"),
        ("fixture.size", "[0.5, 0.5, 0.2]"),
        ("fixture.translation", "[0.05, 0.05, 2.5]"),
    ];
    let (mut unplaced, _, _) =
        arm_at_rest_with(&[volume[0], volume[1], ("fixture.frame", "nowhere")]);
    let f = wall(&mut unplaced);
    let e = f.result.as_ref().unwrap_err();
    assert_eq!(e.kind(), "exclusion_tf");
    assert!(e.to_string().contains("exclusion volume fixture"), "{e}");
    assert_eq!(f.outputs.level, Level::Error);
    assert!(f.outputs.min_distance.is_none());

    let mut placed: Vec<(&str, &str)> = volume.to_vec();
    placed.push(("fixture.frame", "cam"));
    let (mut m, _, _) = arm_at_rest_with(&placed);
    let f = wall(&mut m);
    let r = f.result.as_ref().unwrap();
    assert_eq!(r.excluded, vec![("fixture".to_string(), 400)]);
    assert_eq!(
        r.outcome,
        ist_monitor::query::Outcome::NothingWithinMaxDistance
    );
    assert_eq!(f.outputs.level, Level::Ok);
    assert_eq!(
        common::status_value(&f, "points_excluded.fixture"),
        Some("400")
    );
    // A volume for another source only leaves this one's points alone.
    placed.extend([("sources", "[cam0, cam1]"), ("fixture.sources", "[cam1]")]);
    let (mut other, _, _) = arm_at_rest_with(&placed);
    let r = wall(&mut other).result.unwrap();
    assert!(r.excluded.is_empty() && r.nearest.is_some());
}

/// A first start whose trees are not cached (issue 47): the monitor comes on coarse trees (a
/// fixed budget of `start_spheres`, validated, their larger h certified and reported), and the
/// trees of the config's options, built meanwhile, are swapped in without a gap: the level,
/// the inputs and the sources stay, the certified interval narrows. A second start finds them
/// in the cache and needs no coarse trees; trees for other links are refused.
#[test]
fn a_first_start_monitors_on_coarse_trees_and_swaps_in_the_fine_ones() {
    let cache = tempfile::tempdir().unwrap();
    let model = RobotModel::load(Path::new(common::DEMO_URDF), &[], &Default::default()).unwrap();
    let names = model.kinematics.variables().to_vec();
    let mut overrides = at_rest(&names);
    overrides.extend([
        ("links".into(), "[wrist_1_link]".into()),
        ("start_spheres".into(), "1024".into()),
        ("max_spheres".into(), "8192".into()),
        ("cache_dir".into(), cache.path().display().to_string()),
    ]);
    let config = Config::from_overrides(&overrides).unwrap();
    let load = || Monitor::model(&config).unwrap();
    let (mut m, refinement) =
        Monitor::with_model_first(config.clone(), load(), &|_| {}, true).unwrap();
    let refinement = refinement.expect("nothing cached: coarse trees first");
    let coarse_h = m.link_gaps()[0].1;
    // A point 5 cm above the link's top sphere, in the root frame (the joints at 0).
    let poses = m.model.kinematics.link_poses(&vec![0.0; names.len()]);
    let link = m.model.kinematics.link_index("wrist_1_link").unwrap();
    let top = (m.model.links.iter())
        .find(|l| l.name == "wrist_1_link")
        .unwrap()
        .elements
        .iter()
        .flat_map(|e| e.mesh.vertices.iter())
        .map(|v| poses[link] * Point3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .unwrap();
    let top = [top.x as f32, top.y as f32, (top.z + 0.05) as f32];
    let width = |f: &Frame| {
        let upper: f64 = common::status_value(f, "distance_m")
            .unwrap()
            .parse()
            .unwrap();
        let lower: f64 = common::status_value(f, "lower_m").unwrap().parse().unwrap();
        upper - lower
    };
    let before = frame(&mut m, &[top]);
    assert!(before.outputs.min_distance.is_some());
    let level = before.outputs.level;
    // The trees of the config's options, built on the side, then swapped in.
    let trees = refinement.build(&|_| {}).unwrap();
    m.swap_trees(&trees, &refinement.attached).unwrap();
    let fine_h = m.link_gaps()[0].1;
    assert!(
        fine_h < coarse_h && fine_h <= 0.0015,
        "h {coarse_h} m coarse, {fine_h} m fine"
    );
    let after = frame(&mut m, &[top]);
    assert_eq!(after.outputs.level, level, "the level goes on");
    assert!(
        width(&after) < width(&before),
        "the certified interval narrows: {} m, then {} m",
        width(&before),
        width(&after)
    );
    assert!(width(&before) <= coarse_h + 1e-6 && width(&after) <= fine_h + 1e-6);
    // Trees without the monitored link are refused, and so are trees for other attached
    // objects; the monitor keeps its own.
    let other: Vec<_> = (common::demo_trees().1.into_iter())
        .filter(|t| t.link != "wrist_1_link")
        .collect();
    assert!(m.swap_trees(&other, &refinement.attached).is_err());
    let object = ist_monitor::robot::AttachedObject {
        name: "tool".into(),
        link: "wrist_1_link".into(),
        shape: ist_monitor::geometry::Primitive::Sphere { radius: 0.01 }.into(),
        link_from_object: nalgebra::Isometry3::identity(),
    };
    let e = m.swap_trees(&trees, &[object]).unwrap_err();
    assert!(e.to_string().contains("not for the monitored links"), "{e}");
    assert_eq!(m.link_gaps()[0].1, fine_h);
    // Started again: the config's trees are in the cache, no coarse ones.
    let (again, none) = Monitor::with_model_first(config.clone(), load(), &|_| {}, true).unwrap();
    assert!(none.is_none());
    assert_eq!(again.link_gaps(), m.link_gaps());
}
