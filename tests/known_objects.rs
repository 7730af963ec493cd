//! Known objects of the cell through the monitor (what `replay` and the node run): an exclusion
//! box around the generated table removes exactly the table's points, and an attached part in
//! the gripper is measured as a link of the robot, against the generator's exact truth.

mod common;

use std::path::Path;

use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::Config;
use ist_monitor::geometry::Primitive;
use ist_monitor::monitor::{Frame, Level, Monitor};
use ist_monitor::msg::{Header, JointState, Time};
use ist_monitor::robot::{AttachedObject, RobotModel};
use ist_monitor::scenario::{
    self, Hit, Mount, Renderer, ScenarioParams, SceneKind, TABLE_CENTER, TABLE_SIZE,
};
use nalgebra::Isometry3;

const STAMP: i64 = 1_700_000_000_000_000_000;
/// 1.5 s per frame.
const PERIOD: i64 = 1_500_000_000;
/// What the renderer labels the table's pixels.
const TABLE: Hit = Hit::Scene(2);

/// The demo config with the camera's optical frame given as a static transform (the frames
/// come straight from the renderer, without the bag's /tf_static), no latency budget, and
/// `extra`.
fn monitor(extra: &[(&str, String)]) -> Monitor {
    let optical = scenario::link_from_optical();
    let (t, q) = (optical.translation.vector, optical.rotation.coords);
    let mut o: Vec<(&str, String)> = vec![
        ("static_transforms", "[optical]".into()),
        ("optical.parent_frame", scenario::CAMERA_LINK.into()),
        ("optical.child_frame", scenario::OPTICAL_FRAME.into()),
        (
            "optical.translation",
            format!("[{}, {}, {}]", t.x, t.y, t.z),
        ),
        (
            "optical.rotation",
            format!("[{}, {}, {}, {}]", q.x, q.y, q.z, q.w),
        ),
        ("backend", "cpu".into()),
        // No frame runs past it: the tests compare levels, and a frame slowed by the tests
        // running beside it (or by a debug build) would otherwise WARN.
        ("latency_budget", "60".into()),
    ];
    o.extend(common::SEEN_ONLY_FLOORLESS.map(|(k, v)| (k, v.to_owned())));
    o.extend(extra.iter().cloned());
    let o: Vec<(String, String)> = o.into_iter().map(|(k, v)| (k.into(), v)).collect();
    let config = Config::load(Path::new(common::DEMO_CONFIG), &o).unwrap();
    Monitor::new(config, &|_| {}).unwrap()
}

/// Frame `k` of a render (joint values, organized points) through `m`.
fn feed(m: &mut Monitor, k: i64, joints: &[f64], points: &[[f32; 3]], width: u32) -> Frame {
    let stamp = STAMP + k * PERIOD;
    let header = |frame_id: &str| Header {
        stamp: Time::from_nanos(stamp),
        frame_id: frame_id.into(),
    };
    let js = JointState {
        header: header(""),
        name: m.model.kinematics.variables().to_vec(),
        position: joints.to_vec(),
        ..JointState::default()
    };
    m.on_joint_state("/joint_states", &js).unwrap();
    let layout = pointcloud2::Layout {
        width,
        height: points.len() as u32 / width,
        ..pointcloud2::Layout::unorganized(0)
    };
    let c = pointcloud2::encode(header(scenario::OPTICAL_FRAME), points, &layout).unwrap();
    m.on_cloud(0, &c, std::time::Instant::now(), Some(stamp))
}

/// The table scene: a box 1 cm larger than the table on every side, in `world`, takes every
/// point of the table and nothing else — the result equals the one of the cloud with the
/// table's points (as the renderer labels them) removed by hand, on every frame, and the count
/// in the diagnostics is theirs. Without it the table holds the stop while the gripper passes
/// over it; with it the stop comes only from the person.
#[test]
fn an_exclusion_box_around_the_table_removes_exactly_its_points() {
    let model = RobotModel::load(Path::new(common::DEMO_URDF), &[], &Default::default()).unwrap();
    let params = ScenarioParams {
        scene: SceneKind::Table,
        ..ScenarioParams::default()
    };
    let mut renderer = Renderer::new(&model, &params, &Mount::fixed()).unwrap();
    let size = TABLE_SIZE.map(|e| e + 0.02);
    let at = TABLE_CENTER;
    let mut excluding = monitor(&[
        // The demo config's floor stays listed (moved under the cell: it drops nothing).
        ("exclusion_volumes", "[floor, table]".into()),
        ("table.frame", "world".into()),
        ("table.size", format!("{size:?}")),
        ("table.translation", format!("{at:?}")),
    ]);
    let mut by_hand = monitor(&[]);
    let mut plain = monitor(&[]);
    let (mut table_stops, mut person_stops) = (0, 0);
    for k in 0..15 {
        let f = renderer.frame(k as f64 / 14.0, false).unwrap();
        let table_points = f.hits.iter().filter(|h| **h == TABLE).count();
        assert!(table_points > 500, "frame {k}: the table is in view");
        let mut removed = f.points.clone();
        for (p, h) in removed.iter_mut().zip(&f.hits) {
            if *h == TABLE {
                *p = [f32::NAN; 3];
            }
        }
        let a = feed(&mut excluding, k, &f.joints, &f.points, params.width);
        let b = feed(&mut by_hand, k, &f.joints, &removed, params.width);
        let c = feed(&mut plain, k, &f.joints, &f.points, params.width);
        let (ra, rb) = (a.result.as_ref().unwrap(), b.result.as_ref().unwrap());
        assert_eq!(ra.nearest, rb.nearest, "frame {k}");
        assert_eq!(ra.links, rb.links, "frame {k}");
        // Which of the used points the shared bound prunes depends on the threads' timing.
        let stages = |c: &ist_monitor::query::StageCounts| {
            (
                c.total,
                c.invalid,
                c.outside_roi,
                c.self_filtered,
                c.pruned + c.evaluated,
            )
        };
        assert_eq!(stages(&ra.counts), stages(&rb.counts), "frame {k}");
        assert_eq!(
            ra.excluded,
            vec![
                ("floor".to_string(), 0),
                ("table".to_string(), table_points as u64)
            ]
        );
        assert_eq!(
            common::status_value(&a, "points_excluded.table"),
            Some(table_points.to_string().as_str())
        );
        assert_eq!(a.outputs.level, b.outputs.level, "frame {k}");
        let plain_level = c.outputs.level;
        if plain_level == Level::Error && a.outputs.level != Level::Error {
            table_stops += 1;
        }
        if a.outputs.level == Level::Error {
            person_stops += 1;
        }
        // The volume is drawn in RViz, in its frame.
        // The table's, after the floor's.
        let shape = (a.outputs.closest_points.markers.iter())
            .filter(|m| m.ns == "exclusion_volumes")
            .nth(1)
            .expect("the volume's marker");
        assert_eq!(shape.header.frame_id, "world");
        assert_eq!((shape.scale.x, shape.pose.position.z), (size[0], at[2]));
    }
    assert!(
        table_stops >= 3,
        "the table alone stopped {table_stops} frames"
    );
    assert!(person_stops >= 1, "the person still stops the arm");
}

/// The same table given as a mesh file (an STL of its box, as a CAD tool would export it),
/// dilated by 9 mm: every table point goes (the padding is above the grid's voxel diagonal) and
/// nothing else does (nothing else lies within 1 cm of the table), so the result equals the one
/// of the cloud with the table's points removed by hand, on every frame.
#[test]
fn an_exclusion_mesh_of_the_table_removes_exactly_its_points() {
    let model = RobotModel::load(Path::new(common::DEMO_URDF), &[], &Default::default()).unwrap();
    let params = ScenarioParams {
        scene: SceneKind::Table,
        ..ScenarioParams::default()
    };
    let mut renderer = Renderer::new(&model, &params, &Mount::fixed()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("table.stl");
    let half = TABLE_SIZE.map(|e| 0.5 * e as f32);
    common::write_stl(&stl, &common::box_triangles(half.map(|h| -h), half));
    let mut excluding = monitor(&[
        // The demo config's floor stays listed (moved under the cell: it drops nothing).
        ("exclusion_volumes", "[floor, table]".into()),
        ("table.frame", "world".into()),
        ("table.shape", "mesh".into()),
        ("table.mesh", stl.display().to_string()),
        ("table.padding", "0.009".into()),
        ("table.translation", format!("{TABLE_CENTER:?}")),
    ]);
    let mut by_hand = monitor(&[]);
    for k in 0..15 {
        let f = renderer.frame(k as f64 / 14.0, false).unwrap();
        let table_points = f.hits.iter().filter(|h| **h == TABLE).count();
        let mut removed = f.points.clone();
        for (p, h) in removed.iter_mut().zip(&f.hits) {
            if *h == TABLE {
                *p = [f32::NAN; 3];
            }
        }
        let a = feed(&mut excluding, k, &f.joints, &f.points, params.width);
        let b = feed(&mut by_hand, k, &f.joints, &removed, params.width);
        let (ra, rb) = (a.result.as_ref().unwrap(), b.result.as_ref().unwrap());
        assert_eq!(
            ra.excluded,
            vec![
                ("floor".to_string(), 0),
                ("table".to_string(), table_points as u64)
            ],
            "frame {k}"
        );
        assert_eq!(ra.nearest, rb.nearest, "frame {k}");
        assert_eq!(a.outputs.level, b.outputs.level, "frame {k}");
        // Drawn in RViz from its file.
        // The table's, after the floor's.
        let shape = (a.outputs.closest_points.markers.iter())
            .filter(|m| m.ns == "exclusion_volumes")
            .nth(1)
            .expect("the volume's marker");
        assert!(
            shape.mesh_resource.ends_with("table.stl"),
            "{}",
            shape.mesh_resource
        );
    }
}

/// A 30 cm bar held in the gripper, sticking out sideways toward the person: rendered as part
/// of the robot, and configured as an attached object. Its points are self-filtered (the
/// distance is to the rest of the scene, never 0), the certified interval holds the exact
/// truth of robot-and-bar on every frame, and where the bar is what comes nearest the person
/// the nearest link is the bar. Without the attachment the bar's own points stop the arm, and
/// its approach to the person is missed (the arm's own distance is reported, which is larger).
#[test]
fn an_attached_part_is_measured_as_a_link_of_the_robot() {
    attached_bar_is_measured(&[("part.size", "[0.04, 0.3, 0.04]".into())]);
}

/// The same bar given as a mesh file (an STL of its box): taken in as a link's mesh is, and
/// measured the same way.
#[test]
fn an_attached_mesh_is_measured_as_a_link_of_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("bar.stl");
    common::write_stl(
        &stl,
        &common::box_triangles([-0.02, -0.15, -0.02], [0.02, 0.15, 0.02]),
    );
    attached_bar_is_measured(&[
        ("part.shape", "mesh".into()),
        ("part.mesh", stl.display().to_string()),
    ]);
}

/// The bar rendered with the robot and attached as `part` with the shape `shape` gives.
fn attached_bar_is_measured(shape: &[(&str, String)]) {
    let part = AttachedObject {
        name: "part".into(),
        link: "gripper_link".into(),
        shape: Primitive::Box {
            size: [0.04, 0.3, 0.04],
        }
        .into(),
        link_from_object: Isometry3::translation(0.0, -0.15, 0.16),
    };
    let mut model =
        RobotModel::load(Path::new(common::DEMO_URDF), &[], &Default::default()).unwrap();
    model.attach(&part).unwrap();
    let part_link = model.kinematics.link_index("part").unwrap();
    let params = ScenarioParams::default();
    let mut renderer = Renderer::new(&model, &params, &Mount::fixed()).unwrap();
    let mut attach = vec![
        ("attached_objects", "[part]".into()),
        ("part.link", "gripper_link".into()),
        ("part.translation", "[0.0, -0.15, 0.16]".into()),
    ];
    attach.extend(shape.iter().cloned());
    let mut holding = monitor(&attach);
    let mut unaware = monitor(&[]);
    let (mut bar_nearest, mut unaware_stops, mut unaware_misses, mut part_points) = (0, 0, 0, 0);
    for k in 0..15 {
        let f = renderer.frame(k as f64 / 14.0, true).unwrap();
        let truth = f.truth_m.unwrap();
        let a = feed(&mut holding, k, &f.joints, &f.points, params.width);
        let r = a.result.as_ref().unwrap();
        let n = r.nearest.as_ref().unwrap();
        let lower = n.lower_m.unwrap();
        assert!(
            lower - 1e-6 <= truth && truth <= n.distance_m + 1e-6,
            "frame {k}: truth {truth} outside [{lower}, {}]",
            n.distance_m
        );
        assert!(lower > 0.02, "frame {k}: {lower}");
        let part_filtered = (r.self_filtered_by_link.iter())
            .find(|(l, _)| l == "part")
            .map_or(0, |(_, c)| *c);
        if f.truth_witness.unwrap().link == part_link {
            bar_nearest += 1;
            assert_eq!(n.link, "part", "frame {k}");
        }
        let b = feed(&mut unaware, k, &f.joints, &f.points, params.width);
        if b.outputs.level == Level::Error && a.outputs.level != Level::Error {
            unaware_stops += 1;
        }
        part_points += part_filtered;
        if n.link == "part" {
            // What the unaware monitor misses: the bar is nearer the person than the arm.
            let unaware = b.result.as_ref().unwrap().nearest.as_ref().unwrap();
            if unaware.lower_m.unwrap() > truth + 0.005 {
                unaware_misses += 1;
            }
        }
        // Drawn in RViz on its link.
        let shape = (a.outputs.closest_points.markers.iter())
            .find(|m| m.ns == "attached_objects")
            .expect("the object's marker");
        assert_eq!(shape.header.frame_id, "gripper_link");
    }
    assert!(
        bar_nearest >= 3,
        "the bar was nearest on {bar_nearest} frames"
    );
    assert!(
        part_points > 1000,
        "{part_points} points self-filtered as the bar"
    );
    assert!(
        unaware_stops >= 3,
        "unaware, the bar stopped {unaware_stops} frames"
    );
    assert!(
        unaware_misses >= 2,
        "unaware, the bar's approach to the person was missed on {unaware_misses} frames"
    );
}

/// An attached object on a link the robot lacks, or named like one of its links, is refused
/// at start naming the parameter, the object and the link.
#[test]
fn an_attached_object_on_an_unknown_link_is_refused_naming_it() {
    for (name, link, expect) in [
        (
            "part",
            "grippr_link",
            "link grippr_link is not a link of robot",
        ),
        (
            "forearm_link",
            "gripper_link",
            "already has a link named forearm_link",
        ),
    ] {
        let o: Vec<(String, String)> = vec![
            ("attached_objects".into(), format!("[{name}]")),
            (format!("{name}.link"), link.into()),
            (format!("{name}.size"), "[0.1, 0.1, 0.1]".into()),
        ];
        let config = Config::load(Path::new(common::DEMO_CONFIG), &o).unwrap();
        let e = Monitor::new(config, &|_| {}).err().unwrap().to_string();
        assert!(
            e.contains("parameter attached_objects") && e.contains(expect),
            "{e}"
        );
    }
}
