//! The unseen space through the monitor (what `replay` and the node run), on a synthetic
//! organized cloud of the demo arm at rest: a pinhole camera `cam` placed by a static transform,
//! each pixel's ray cast against the arm's collision meshes, lit and dark balls and a lit
//! background. Each test pins a rule of issue 55 that main broke:
//!
//! - a dark ball beside the arm is within the unseen distance (main dropped the space up to the
//!   padding, h and a cell diagonal beyond the padded arm);
//! - `protect` takes the unseen distance when every valid point is the robot's (main took it only
//!   beside a seen distance);
//! - a capability the config accepts never faults at run time (main refused some at run time);
//! - `~/unseen_distance` tells "nothing hidden" (+∞) from "the pass failed" (NaN);
//! - an organized cloud's view keeps its source's minimum range;
//! - the pass's time is in the frame's processing and the speed factor's reaction time, and a
//!   frame later than the latency budget is a fault under `protect`;
//! - between the thresholds, the speed factor holds each link to its unseen distance;
//! - the hidden places measured best first (certified) agree with the engine's exact query;
//! - the markers' hidden places only while someone reads `~/closest_points`.

mod common;

use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::Config;
use ist_monitor::monitor::{Frame, Level, Monitor};
use ist_monitor::msg::{Header, Marker, Time};
use ist_monitor::robot::solid::Solid;
use ist_monitor::robot::RobotModel;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

const STAMP: i64 = 1_700_000_000_000_000_000;

/// A synthetic pinhole camera `width × height` of focal length `f` px.
struct Camera {
    width: u32,
    height: u32,
    f: f64,
    /// `root_from_camera` (optical frame: z forward, x right, y down).
    pose: Isometry3<f64>,
}

impl Camera {
    /// A camera at `eye` looking at `target`, of horizontal field of view `hfov_deg`.
    fn looking(eye: [f64; 3], target: [f64; 3], width: u32, height: u32, hfov_deg: f64) -> Self {
        let (eye, target) = (Vector3::from(eye), Vector3::from(target));
        let forward = (target - eye).normalize();
        // Optical frame: z forward, y down (world z up).
        let down = (-Vector3::z() + forward * forward.z).normalize();
        let right = down.cross(&forward);
        let rotation = nalgebra::Rotation3::from_basis_unchecked(&[right, down, forward]);
        Self {
            width,
            height,
            f: 0.5 * f64::from(width) / (0.5 * hfov_deg.to_radians()).tan(),
            pose: Isometry3::from_parts(
                Translation3::from(eye),
                UnitQuaternion::from_rotation_matrix(&rotation),
            ),
        }
    }

    /// The static transform `world → cam` as parameters.
    fn transform(&self) -> Vec<(String, String)> {
        let t = self.pose.translation.vector;
        let q = self.pose.rotation;
        vec![
            ("static_transforms".into(), "[cam]".into()),
            ("cam.parent_frame".into(), "world".into()),
            ("cam.child_frame".into(), "cam".into()),
            (
                "cam.translation".into(),
                format!("[{}, {}, {}]", t.x, t.y, t.z),
            ),
            (
                "cam.rotation".into(),
                format!("[{}, {}, {}, {}]", q.i, q.j, q.k, q.w),
            ),
        ]
    }
}

/// What the camera sees: the arm (its links' solids at their poses), balls (centre, radius,
/// dark), and a lit background `background` m along each ray (`None`: no return beyond).
struct Scene {
    solids: Vec<(Isometry3<f64>, Solid)>,
    balls: Vec<([f64; 3], f64, bool)>,
    background: Option<f64>,
}

impl Scene {
    fn arm(model: &RobotModel) -> Self {
        let names = model.kinematics.variables().to_vec();
        let poses = model.kinematics.link_poses(&vec![0.0; names.len()]);
        let mut solids = Vec::new();
        for link in &model.links {
            let pose = poses[model.kinematics.link_index(&link.name).unwrap()];
            for e in &link.elements {
                solids.push((pose, Solid::new(&e.mesh)));
            }
        }
        Self {
            solids,
            balls: Vec::new(),
            background: Some(3.0),
        }
    }

    /// The organized cloud (camera frame, row-major, NaN: no return).
    fn render(&self, camera: &Camera) -> Vec<[f32; 3]> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let (cx, cy) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
        let o = camera.pose.translation.vector;
        (0..w * h)
            .map(|i| {
                let d_cam = Vector3::new(
                    ((i % w) as f64 - cx) / camera.f,
                    ((i / w) as f64 - cy) / camera.f,
                    1.0,
                );
                let d = camera.pose.rotation * d_cam.normalize();
                let mut best: Option<(f64, bool)> = self.background.map(|b| (b, false));
                for (pose, solid) in &self.solids {
                    let lo = pose.inverse_transform_point(&Point3::from(o));
                    let ld = pose.inverse_transform_vector(&d);
                    let max = best.map_or(10.0, |b| b.0) as f32;
                    let hit = solid.cast_ray(
                        [lo.x as f32, lo.y as f32, lo.z as f32],
                        [ld.x as f32, ld.y as f32, ld.z as f32],
                        max,
                    );
                    if let Some(t) = hit {
                        best = Some((f64::from(t), false));
                    }
                }
                for &(c, r, dark) in &self.balls {
                    let oc = o - Vector3::from(c);
                    let b = d.dot(&oc);
                    let disc = b * b - (oc.dot(&oc) - r * r);
                    if disc >= 0.0 {
                        let t = -b - disc.sqrt();
                        if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
                            best = Some((t, dark));
                        }
                    }
                }
                match best {
                    Some((t, false)) => {
                        let p = d_cam.normalize() * t;
                        [p.x as f32, p.y as f32, p.z as f32]
                    }
                    _ => [f32::NAN; 3],
                }
            })
            .collect()
    }
}

/// The demo arm at rest seen by `camera`, with `extra` parameters.
fn monitor(camera: &Camera, extra: &[(&str, &str)]) -> (Monitor, RobotModel) {
    let (model, trees) = common::demo_trees();
    let names = model.kinematics.variables().to_vec();
    let mut overrides: Vec<(String, String)> = vec![
        ("robot_description".into(), common::DEMO_URDF.into()),
        ("fixed_joint_state.names".into(), format!("{names:?}")),
        (
            "fixed_joint_state.positions".into(),
            format!("{:?}", vec![0.0; names.len()]),
        ),
        ("backend".into(), "cpu".into()),
        ("self_filter_padding".into(), "0.01".into()),
        // A volume the camera covers, beside and above the arm's base.
        ("monitored_volume.size".into(), "[0.8, 0.8, 0.6]".into()),
        (
            "monitored_volume.translation".into(),
            "[0.1, 0.0, 0.5]".into(),
        ),
        ("latency_budget".into(), "10.0".into()),
    ];
    overrides.extend(camera.transform());
    overrides.extend(extra.iter().map(|(k, v)| (k.to_string(), v.to_string())));
    let config = Config::from_overrides(&overrides).unwrap();
    let m = Monitor::with_trees(config, model.clone(), &trees).unwrap();
    (m, model)
}

/// One organized cloud of `camera`'s, stamped now.
fn frame(monitor: &mut Monitor, camera: &Camera, points: &[[f32; 3]]) -> Frame {
    let header = Header {
        stamp: Time::from_nanos(STAMP),
        frame_id: "cam".into(),
    };
    let layout = pointcloud2::Layout {
        width: camera.width,
        height: camera.height,
        ..pointcloud2::Layout::unorganized(points.len() as u32)
    };
    let m = pointcloud2::encode(header, points, &layout).unwrap();
    monitor.on_cloud(0, &m, std::time::Instant::now(), Some(STAMP))
}

/// The distance `~/unseen_distance` carries.
fn unseen(f: &Frame) -> f32 {
    f.outputs.unseen_distance.as_ref().expect("published").range
}

/// The camera of these tests: 1.2 m in front of the arm, looking at its middle.
fn front() -> Camera {
    Camera::looking([1.3, 0.15, 0.7], [0.0, 0.0, 0.45], 240, 180, 62.0)
}

/// The centre of a dark ball of 5 cm radius beside the arm, 15 cm from it.
const DARK_BALL: [f64; 3] = [0.25, 0.0, 0.45];

/// The arm with a dark ball at [`DARK_BALL`], as `camera` sees them.
fn dark_ball_beside_the_arm(model: &RobotModel, camera: &Camera) -> Vec<[f32; 3]> {
    let mut scene = Scene::arm(model);
    scene.balls.push((DARK_BALL, 0.05, true));
    scene.render(camera)
}

/// The distance from the arm (its inner spheres, less h: what the query certifies) to a ball.
fn distance_to(model: &RobotModel, c: [f64; 3], r: f64) -> f64 {
    let (_, trees) = common::demo_trees();
    let names = model.kinematics.variables().to_vec();
    let poses = model.kinematics.link_poses(&vec![0.0; names.len()]);
    let mut best = f64::INFINITY;
    for tree in &trees {
        let pose = poses[model.kinematics.link_index(&tree.link).unwrap()];
        for s in &tree.spheres {
            let p = pose * Point3::from(s.center.map(f64::from));
            best = best.min((p - Point3::from(c)).norm() - f64::from(s.radius));
        }
    }
    (best - r).max(0.0)
}

/// A dark ball of the capability 3 mm from the arm, on the camera's side of it and beside it, is within the unseen distance even with the robot's shadow apart (the arm
/// hides none of it); without it the same scene leaves nothing hidden there.
#[test]
fn a_dark_ball_beside_the_arm_is_within_the_unseen_distance() {
    let camera = front();
    let apart = [
        ("unobserved", "report"),
        ("unobserved_self_shadow", "apart"),
    ];
    let (mut m, model) = monitor(&camera, &apart);
    let clear = frame(&mut m, &camera, &Scene::arm(&model).render(&camera));
    assert_eq!(unseen(&clear), f32::INFINITY, "{:?}", clear.unseen_nearest);
    // Where the arm is: the top of its inner spheres.
    let r = 0.035;
    for (dir, label) in [
        ([1.0, 0.25, 0.0], "camera side"),
        ([0.1, 1.0, 0.0], "beside"),
    ] {
        // Out from the arm's axis along `dir` until the ball is 3 mm from the arm.
        let at = |t: f64| [dir[0] * t, dir[1] * t, 0.42];
        let (mut lo, mut hi) = (0.0, 0.5);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if distance_to(&model, at(mid), r) > 0.003 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let c = at(hi);
        let truth = distance_to(&model, c, r);
        assert!(truth < 0.004, "{label}: the ball is {truth} m from the arm");
        let mut scene = Scene::arm(&model);
        scene.balls.push((c, r, true));
        let f = frame(&mut m, &camera, &scene.render(&camera));
        let d = unseen(&f);
        assert!(
            f64::from(d) <= truth + 1e-4,
            "{label}: unseen {d} m > truth {truth} m ({:?})",
            f.unseen_nearest
        );
    }
}

/// Every valid point on the robot (the self-filter takes them all: no seen distance) and nothing
/// returned beyond it: under `protect` the unseen distance, 0 beside the arm, sets the level
/// (ERROR), where `report` gives the self-filter's WARN.
#[test]
fn protect_takes_the_unseen_distance_when_every_point_is_the_robot() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let mut scene = Scene::arm(&model);
    scene.background = None;
    let points = scene.render(&camera);
    for (policy, want) in [("report", Level::Warn), ("protect", Level::Error)] {
        let (mut m, _) = monitor(&camera, &[("unobserved", policy)]);
        let f = frame(&mut m, &camera, &points);
        assert!(
            f.outputs.min_distance.is_none(),
            "{policy}: a seen distance"
        );
        assert_eq!(unseen(&f), 0.0, "{policy}");
        assert_eq!(f.outputs.level, want, "{policy}");
        assert_eq!(f.outputs.safety_stop.data, want == Level::Error, "{policy}");
    }
}

/// The smallest capability the config accepts at a 2 cm lattice (just over the cell diagonal)
/// with a coarse camera: the pass runs and never refuses at run time (under `protect`, a refusal
/// would be a permanent fault); the balls too small for the camera count as outside its view.
#[test]
fn a_capability_the_config_accepts_never_faults_at_run_time() {
    let camera = Camera::looking([1.3, 0.15, 0.7], [0.0, 0.0, 0.45], 64, 48, 62.0);
    let (model, _) = common::demo_trees();
    let (mut m, _) = monitor(
        &camera,
        &[
            ("unobserved", "protect"),
            ("detection_capability", "0.0347"),
        ],
    );
    let f = frame(&mut m, &camera, &Scene::arm(&model).render(&camera));
    let unseen = m.unseen().expect("a pass");
    assert!(unseen.outcome.is_ok(), "{:?}", unseen.outcome);
    assert!(f.unseen_nearest.is_some());
}

/// `~/unseen_distance`: +∞ where nothing hidden can lie in the volume (a volume the camera sees
/// whole in front of the lit background, clear of the arm), NaN where the pass failed (its
/// volume's frame unknown), with the fault said in `/diagnostics`.
#[test]
fn nothing_hidden_and_a_failed_pass_are_told_apart() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let points = Scene::arm(&model).render(&camera);
    let clear = [
        ("unobserved", "report"),
        ("monitored_volume.size", "[0.3, 0.3, 0.3]"),
        ("monitored_volume.translation", "[0.7, 0.15, 0.5]"),
    ];
    let (mut m, _) = monitor(&camera, &clear);
    let f = frame(&mut m, &camera, &points);
    assert_eq!(unseen(&f), f32::INFINITY, "{:?}", f.unseen_nearest);
    let (mut m, _) = monitor(
        &camera,
        &[
            clear[0],
            clear[1],
            clear[2],
            ("monitored_volume.frame", "nowhere"),
        ],
    );
    let f = frame(&mut m, &camera, &points);
    assert!(unseen(&f).is_nan());
    let status = (f.outputs.diagnostics.status.iter())
        .find(|s| s.name.ends_with("unobserved space"))
        .expect("the status");
    assert!(status.message.contains("nowhere"), "{}", status.message);
}

/// A source's minimum range goes with its organized cloud's view: a volume nearer the camera
/// than it, in open space that every ray passes, is not seen free (outside the view), where
/// the same cloud without the limit sees it free.
#[test]
fn an_organized_clouds_view_keeps_its_minimum_range() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let points = Scene::arm(&model).render(&camera);
    // A 10 cm cube 40 cm in front of the camera.
    let ahead = camera.pose * Point3::new(0.0, 0.0, 0.4);
    let at = format!("[{}, {}, {}]", ahead.x, ahead.y, ahead.z);
    let with = |min_range: &str| {
        let extra = [
            ("unobserved", "report"),
            ("monitored_volume.size", "[0.1, 0.1, 0.1]"),
            ("monitored_volume.translation", at.as_str()),
            ("camera.min_range", min_range),
        ];
        let (mut m, _) = monitor(&camera, &extra);
        unseen(&frame(&mut m, &camera, &points))
    };
    assert_eq!(with("0.0"), f32::INFINITY);
    assert!(with("0.6").is_finite());
}

/// The pass's time is in the frame's processing, and under `protect` in the speed factor's
/// reaction time (a tiny cloud, a large volume: the pass outweighs the query), on the first
/// frame (no pass before it: the pass runs before any output) and on the next (its seen outputs
/// go first, the last word waits for the pass). Under `report` the pass moves neither the level
/// nor the factor: the seen outputs go first with both, without the pass's topics, and the
/// last word keeps them. Under `protect` a frame later than the latency budget with its pass is
/// a fault of the cell (ERROR, said), under `report` a WARN.
#[test]
fn the_pass_is_counted_and_a_late_pass_is_a_fault_under_protect() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let points = Scene::arm(&model).render(&camera);
    let (mut m, _) = monitor(
        &camera,
        &[("unobserved", "protect"), ("speed_scaling.enabled", "true")],
    );
    for k in 0..2 {
        let f = frame(&mut m, &camera, &points);
        assert_eq!(f.first.is_some(), k == 1, "frame {k}");
        let pass = f.unseen_s.expect("the pass ran");
        assert!(f.processing_s >= pass, "{} < {pass}", f.processing_s);
        let separation = f.speed.as_ref().unwrap().separation.as_ref().unwrap();
        let reaction = m.config.ssm.reaction_time_s;
        assert!(
            separation.reaction_s >= reaction + pass,
            "frame {k}: reaction {} s leaves out the pass's {pass} s",
            separation.reaction_s
        );
    }
    let (mut m, _) = monitor(
        &camera,
        &[("unobserved", "report"), ("speed_scaling.enabled", "true")],
    );
    let f = frame(&mut m, &camera, &points);
    let (first, first_s) = f.first.as_ref().expect("the seen outputs went first");
    assert!(*first_s <= f.processing_s);
    assert!(first.unseen_distance.is_none() && f.outputs.unseen_distance.is_some());
    assert_eq!(first.level, f.outputs.level);
    let factor = |o: &ist_monitor::monitor::Outputs| o.speed_scaling.as_ref().map(|s| s.factor);
    assert_eq!(factor(first), factor(&f.outputs));
    for (policy, want) in [("report", Level::Warn), ("protect", Level::Error)] {
        let (mut m, _) = monitor(
            &camera,
            &[
                ("unobserved", policy),
                ("latency_budget", "0.000001"),
                // Far from everything: only lateness can raise the level.
                ("monitored_volume.size", "[0.3, 0.3, 0.3]"),
                ("monitored_volume.translation", "[0.7, 0.15, 0.5]"),
                ("warn_distance", "0.2"),
                ("stop_distance", "0.1"),
            ],
        );
        let f = frame(&mut m, &camera, &Scene::arm(&model).render(&camera));
        assert_eq!(f.outputs.level, want, "{policy}");
        if policy == "protect" {
            let cell = f.outputs.diagnostics.status.last().unwrap();
            assert!(cell.message.contains("latency_budget"), "{}", cell.message);
        }
    }
}

/// A dark ball 15 cm from the arm, between the thresholds, the seen distance far: under
/// `protect` the speed factor is held to the unseen distance (the limiting link's constraint
/// is the unseen one), under `report` it is the seen distance's.
#[test]
fn protect_holds_the_speed_factor_to_the_unseen_distance() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let points = dark_ball_beside_the_arm(&model, &camera);
    let truth = distance_to(&model, DARK_BALL, 0.05);
    assert!(truth > 0.1 && truth < 0.3, "{truth}");
    let mut factors = Vec::new();
    for policy in ["report", "protect"] {
        let (mut m, _) = monitor(
            &camera,
            &[
                ("unobserved", policy),
                ("unobserved_self_shadow", "apart"),
                ("speed_scaling.enabled", "true"),
            ],
        );
        let f = frame(&mut m, &camera, &points);
        let d = unseen(&f);
        assert!(
            f64::from(d) <= truth + 1e-4 && d < 0.3,
            "{policy}: unseen {d}"
        );
        let s = f.speed.as_ref().unwrap();
        let separation = s.separation.as_ref().unwrap();
        assert_eq!(separation.unseen, policy == "protect", "{policy}");
        factors.push(separation.allowed);
    }
    assert!(factors[1] < factors[0], "factors {factors:?}");
}

/// Under `protect` a frame's seen outputs go before its pass, with the previous frame's pass:
/// they raise the level at once (a body seen near) but never lower it nor count towards
/// lowering it; a release is the frame's own last word, once its pass has run. A dark ball near
/// the arm stops the cell; it leaves: with `release_frames: 2` the first clear frame keeps the
/// stop, and the second's seen outputs still do though they and the previous pass are both
/// clear (counted there, the release would come before the frame's own pass confirmed it); its
/// last word releases. A lit ball then comes near: the seen outputs stop the cell before the
/// pass.
#[test]
fn protect_releases_only_on_the_frames_own_pass() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let near = DARK_BALL;
    let scene = |ball: Option<bool>| {
        let mut scene = Scene::arm(&model);
        if let Some(dark) = ball {
            scene.balls.push((near, 0.05, dark));
        }
        scene.render(&camera)
    };
    let truth = distance_to(&model, near, 0.05);
    let (mut m, _) = monitor(
        &camera,
        &[
            ("unobserved", "protect"),
            ("unobserved_self_shadow", "apart"),
            ("speed_scaling.enabled", "true"),
            ("stop_distance", "0.3"),
            ("warn_distance", "0.4"),
            ("release_frames", "2"),
        ],
    );
    assert!(truth < 0.3, "{truth}");
    let f = frame(&mut m, &camera, &scene(Some(true)));
    assert!(f.first.is_none(), "no pass before the first frame");
    assert_eq!(f.outputs.level, Level::Error, "unseen {}", unseen(&f));
    let f = frame(&mut m, &camera, &scene(None));
    assert!(unseen(&f) > 0.32, "unseen {}", unseen(&f));
    assert_eq!(f.outputs.level, Level::Error, "one clear frame of two");
    let f = frame(&mut m, &camera, &scene(None));
    let (first, _) = f.first.as_ref().expect("the seen outputs went first");
    assert_eq!(
        first.level,
        Level::Error,
        "released only by the frame's pass"
    );
    assert!(first.safety_stop.data);
    assert_eq!(first.speed_scaling.as_ref().map(|s| s.factor), Some(0.0));
    assert!(f.outputs.level < Level::Error, "released on its own pass");
    assert!(!f.outputs.safety_stop.data);
    let f = frame(&mut m, &camera, &scene(Some(false)));
    let (first, _) = f.first.as_ref().expect("the seen outputs went first");
    assert_eq!(first.level, Level::Error, "a body seen near stops at once");
    assert!(first.safety_stop.data && f.outputs.safety_stop.data);
}

/// The hidden places' distances in certified mode (the pass measures them best first,
/// `unseen::Measure`) and in exact mode (the engine's query, refined on the meshes): per link,
/// the exact distance is at least the certified lower bound and within the link's h above it
/// (the pass's one rule either way; a dark ball 15 cm from the arm, the robot's shadow counted).
#[test]
fn the_best_first_measure_and_the_engine_agree_per_link() {
    let camera = front();
    let (model, trees) = common::demo_trees();
    let points = dark_ball_beside_the_arm(&model, &camera);
    let per_link = |mode: &str| {
        let (mut m, _) = monitor(
            &camera,
            &[
                ("unobserved", "report"),
                ("mode", mode),
                ("per_link_range", "0.5"),
            ],
        );
        frame(&mut m, &camera, &points);
        let facts = m.unseen().unwrap().outcome.as_ref().unwrap().clone();
        facts.per_link
    };
    let (certified, exact) = (per_link("certified"), per_link("exact"));
    assert_eq!(certified.len(), exact.len());
    let mut measured = 0;
    for ((name, c), (other, e)) in certified.iter().zip(&exact) {
        assert_eq!(name, other);
        let h = (trees.iter().find(|t| &t.link == name)).map_or(0.0, |t| t.quality.gap_m);
        assert!(e + 1e-5 >= *c, "{name}: exact {e} below certified {c}");
        if c.is_finite() {
            measured += 1;
            assert!(
                *e <= c + h + 1e-4,
                "{name}: exact {e} above certified {c} + h {h}"
            );
        }
    }
    assert!(measured >= 3, "{certified:?}");
}

/// Nobody reading `~/closest_points` (the node tells it from discovery): the pass keeps no
/// hidden places for the markers (a DELETE of namespace `unseen` goes out instead of the
/// cubes), with the same unseen distance; read again, the cubes come back.
#[test]
fn the_markers_only_while_someone_reads_them() {
    let camera = front();
    let (model, _) = common::demo_trees();
    let points = dark_ball_beside_the_arm(&model, &camera);
    let (mut m, _) = monitor(&camera, &[("unobserved", "report")]);
    let cubes = |f: &Frame| {
        (f.outputs.closest_points.markers.iter())
            .filter(|k| k.ns == "unseen" && k.action == Marker::ADD)
            .map(|k| k.points.len())
            .sum::<usize>()
    };
    let read = frame(&mut m, &camera, &points);
    assert!(cubes(&read) > 0, "no hidden places drawn");
    m.markers_read(|| Some(false));
    let unread = frame(&mut m, &camera, &points);
    assert_eq!(cubes(&unread), 0);
    assert!(unread
        .outputs
        .closest_points
        .markers
        .iter()
        .any(|k| k.ns == "unseen" && k.action == Marker::DELETE));
    assert_eq!(unseen(&unread), unseen(&read));
    m.markers_read(|| Some(true));
    let again = frame(&mut m, &camera, &points);
    assert_eq!(cubes(&again), cubes(&read));
}
