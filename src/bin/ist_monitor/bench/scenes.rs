//! The scenes the benchmarks and some tests run on:
//! - `kinect`: the Panda and the real Kinect cloud of the MoveIt perception tutorial
//!   (`../shared`), at the joint configurations of its SCENARIO.md and five more reaching toward
//!   the table;
//! - `kinect_far`: the same cloud stored in a frame 10 km from the camera (a map-frame cloud:
//!   every point moved by (8000, −5000, 3000) m in f64 and rounded to f32 there, the sensor pose
//!   moved to match), which the query runs in a working frame near the robot;
//! - `grabber`: the UR5e placed 0.35 m in front of the camera of PCL's three grabber frames
//!   (base 0.3 m below the optical axis, z up), at four configurations reaching toward the
//!   scene (5 to 27 cm from it);
//! - `robot_in_view`: the demo arm seen by the scenario generator's fixed 640×480 camera while
//!   the person walks up to it (10 frames along the scene, the arm's own points in view), with
//!   the generator's exact truth per frame;
//! - `wrist`: a 640×480 camera on the demo arm's gripper, the fingers in view, over the shelf
//!   scene (10 frames, exact truth);
//! - `near_blob`: the worst case a monitor exists for, something large right at the arm: 250,000
//!   points on a 10 cm-radius ball 5 cm from the demo arm's forearm, in image order (a 500×500
//!   grid of the ball's surface, as a depth camera would give it);
//! - `duplicates`: one point 3 cm from the forearm repeated 10⁶ times (a driver that repeats a
//!   reading).
//!
//! One definition for three targets: the `bench` subcommand (`mod scenes`), the criterion
//! benches and the integration tests (`#[path = ...] mod scenes`). It uses only the library.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use std::sync::Arc;

use anyhow::{Context, Result};
use std::f64::consts::FRAC_PI_2;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use ist_monitor::cloud::{self, Cloud};
use ist_monitor::robot::RobotModel;
use ist_monitor::scenario::{Mount, Renderer, ScenarioParams, SceneKind};

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ScenarioName {
    Kinect,
    KinectFar,
    Grabber,
    RobotInView,
    Wrist,
    NearBlob,
    Duplicates,
}

impl ScenarioName {
    /// Whether the scene needs `../shared`.
    pub fn needs_shared(self) -> bool {
        matches!(
            self,
            ScenarioName::Kinect | ScenarioName::KinectFar | ScenarioName::Grabber
        )
    }
}

/// One query to time: a cloud, where its sensor is, how the robot is posed.
pub struct Case {
    pub name: String,
    pub points: Arc<Vec<[f32; 3]>>,
    /// Points per row of an organized cloud.
    pub width: Option<usize>,
    pub root_from_sensor: Isometry3<f64>,
    pub link_poses: Vec<Isometry3<f64>>,
    /// The exact minimum distance over the obstacle points, when the scene knows it (the
    /// generator's truth); the benchmark otherwise takes peer (a)'s.
    pub truth_m: Option<f64>,
}

/// A robot, a cloud and the poses to query.
pub struct Scenario {
    pub name: ScenarioName,
    pub model: RobotModel,
    /// Joint configurations (name, joint values by name) of the real scenes, for the tests.
    pub poses: Vec<(String, Vec<(String, f64)>)>,
    pub cases: Vec<Case>,
    /// Whether the cloud holds the robot's own points (the peers, which take every point as an
    /// obstacle, then do not apply).
    pub robot_in_view: bool,
}

/// The Kinect camera of the perception tutorial: `static_transform_publisher 0.115 0.427 0.570
/// 0 0.2 1.92 camera_rgb_optical_frame world`, i.e. `p_cam = R·p_world + t` with
/// `R = Rz(0)·Ry(0.2)·Rx(1.92)`; the robot root (`panda_link0`) is `world`.
pub fn kinect_root_from_sensor() -> Isometry3<f64> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.0)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.92);
    let camera_from_world = Isometry3::from_parts(Translation3::new(0.115, 0.427, 0.570), r);
    camera_from_world.inverse()
}

/// The Panda configurations of the Kinect scenario: SCENARIO.md's (its 1.5708, not π/2), then
/// five of ours in which the hand comes 7 to 50 mm from the table.
#[allow(clippy::approx_constant)]
pub fn kinect_poses() -> Vec<(String, Vec<(String, f64)>)> {
    let arm = |name: &str, q: [f64; 7], finger: f64| {
        let mut v: Vec<(String, f64)> = q
            .iter()
            .enumerate()
            .map(|(i, &x)| (format!("panda_joint{}", i + 1), x))
            .collect();
        v.push(("panda_finger_joint1".into(), finger));
        (name.to_string(), v)
    };
    vec![
        arm("ready", [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], 0.0),
        arm("extended", [0.0, 0.0, 0.0, 0.0, 0.0, 1.571, 0.785], 0.0),
        arm("zeros", [0.0; 7], 0.0),
        arm(
            "ready_j1_90",
            [1.5708, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
            0.0,
        ),
        arm(
            "reach_table",
            [1.5708, 0.5, 0.0, -2.0, 0.0, 2.5, 0.785],
            0.04,
        ),
        arm("reach_far", [1.5708, 0.7, 0.0, -1.6, 0.0, 2.4, 0.785], 0.02),
        arm("reach_low", [1.3, 0.9, 0.0, -1.3, 0.0, 2.3, 0.785], 0.02),
        arm("reach_side", [1.0, 0.6, 0.4, -1.9, 0.0, 2.6, 0.785], 0.02),
        arm("reach_out", [1.5708, 1.0, 0.0, -1.0, 0.0, 2.0, 0.785], 0.02),
        arm("near_contact", [1.4, 0.2, 0.0, -2.6, 0.0, 2.9, 0.0], 0.02),
    ]
}

/// The UR5e 0.35 m in front of the grabber camera, 0.3 m below its axis, z up, x along the
/// optical axis.
pub fn grabber_root_from_sensor() -> Isometry3<f64> {
    // Root axes in the camera frame (x right, y down, z forward): x_root = z_cam,
    // y_root = −x_cam, z_root = −y_cam.
    let m = Matrix3::from_columns(&[
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(-1.0, 0.0, 0.0),
        Vector3::new(0.0, -1.0, 0.0),
    ]);
    let sensor_from_root = Isometry3::from_parts(
        Translation3::new(0.0, 0.3, 0.35),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
    );
    sensor_from_root.inverse()
}

pub fn grabber_poses() -> Vec<(String, Vec<(String, f64)>)> {
    let names = [
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ];
    let arm = |name: &str, q: [f64; 6]| {
        (
            name.to_string(),
            names
                .iter()
                .zip(q)
                .map(|(n, v)| (n.to_string(), v))
                .collect(),
        )
    };
    vec![
        arm("home", [0.0, -1.571, 0.0, -1.571, 0.0, 0.0]),
        arm("reach_forward", [0.0, -1.2, 0.6, -1.2, -1.571, 0.0]),
        arm("reach_near", [0.0, -1.0, 0.9, -1.5, -1.571, 0.0]),
        arm("reach_left", [0.5, -1.3, 1.2, -1.5, -1.571, 0.0]),
    ]
}

/// Cases of fixed clouds at named joint configurations.
fn cases_of(
    model: &RobotModel,
    clouds: &[(String, Cloud)],
    root_from_sensor: Isometry3<f64>,
    poses: &[(String, Vec<(String, f64)>)],
) -> Result<Vec<Case>> {
    let k = &model.kinematics;
    let mut cases = Vec::new();
    for (cn, cloud) in clouds {
        let points = Arc::new(cloud.points.clone());
        for (pn, joints) in poses {
            cases.push(Case {
                name: format!("{cn} {pn}"),
                points: points.clone(),
                width: (cloud.height > 1).then_some(cloud.width as usize),
                root_from_sensor,
                link_poses: k.link_poses(&k.values_from_names(joints, Some(0.0))?),
                truth_m: None,
            });
        }
    }
    Ok(cases)
}

/// The demo robot of this repository (`urdf/demo_arm.urdf` in the demo folder `demo`).
pub fn demo_model(demo: &Path) -> Result<RobotModel> {
    Ok(RobotModel::load(
        &demo.join("urdf/demo_arm.urdf"),
        &[],
        &Default::default(),
    )?)
}

/// 10 generated 640×480 frames along `scene` seen from `mount`, with their truth.
fn generated(model: &RobotModel, scene: SceneKind, mount: &Mount) -> Result<Vec<Case>> {
    let params = ScenarioParams {
        scene,
        width: 640,
        height: 480,
        ..ScenarioParams::default()
    };
    let mut renderer = Renderer::new(model, &params, mount)?;
    (0..10)
        .map(|i| {
            let f = renderer.frame(i as f64 / 9.0, true)?;
            Ok(Case {
                name: format!("frame {i}"),
                points: Arc::new(f.points),
                width: Some(640),
                root_from_sensor: f.root_from_sensor,
                link_poses: f.link_poses,
                truth_m: f.truth_m,
            })
        })
        .collect()
}

/// The demo arm at the end of the person scene, and the forearm's pose: the stress scenes
/// are built around its collision cylinder (radius 0.04 m, axis z, centred at z = 0.175 m).
fn forearm_scene(model: &RobotModel) -> Result<(Vec<Isometry3<f64>>, Isometry3<f64>)> {
    let renderer = Renderer::new(model, &ScenarioParams::default(), &Mount::fixed())?;
    let link_poses = model.kinematics.link_poses(&renderer.joints(1.0)?);
    let forearm = model
        .kinematics
        .link_index("forearm_link")
        .context("the demo arm has a forearm_link")?;
    let pose = link_poses[forearm];
    Ok((link_poses, pose))
}

/// The scene `name`: from `shared` (`../shared`) for the real scenes, from the demo folder
/// `demo` (this repository) for the others.
pub fn load_scenario(shared: &Path, demo: &Path, name: ScenarioName) -> Result<Scenario> {
    let fixed = |name, model, clouds: Vec<(String, Cloud)>, sensor, poses: Vec<_>| {
        Ok::<_, anyhow::Error>(Scenario {
            name,
            cases: cases_of(&model, &clouds, sensor, &poses)?,
            model,
            poses,
            robot_in_view: false,
        })
    };
    Ok(match name {
        ScenarioName::Kinect => {
            let bag = shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap");
            fixed(
                name,
                RobotModel::load(
                    &shared.join("robots/panda/robot.urdf"),
                    &[],
                    &Default::default(),
                )?,
                vec![("kinect".into(), cloud::load(&bag, 0)?)],
                kinect_root_from_sensor(),
                kinect_poses(),
            )?
        }
        ScenarioName::KinectFar => {
            let mut scenario = load_scenario(shared, demo, ScenarioName::Kinect)?;
            let far_from_sensor = Translation3::new(8000.0, -5000.0, 3000.0);
            let points: Vec<[f32; 3]> = scenario.cases[0]
                .points
                .iter()
                .map(|p| {
                    let q = far_from_sensor
                        * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                    [q.x as f32, q.y as f32, q.z as f32]
                })
                .collect();
            let points = Arc::new(points);
            for case in &mut scenario.cases {
                case.points = points.clone();
                case.root_from_sensor *= far_from_sensor.inverse();
            }
            scenario.name = name;
            scenario
        }
        ScenarioName::Grabber => {
            let dir = shared.join("clouds/pcl_test/grabber_sequences");
            let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
                .with_context(|| format!("reading {}", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "pcd"))
                .collect();
            files.sort();
            let clouds = files
                .iter()
                .map(|f| {
                    Ok((
                        f.file_stem().unwrap().to_string_lossy().into_owned(),
                        cloud::load(f, 0)?,
                    ))
                })
                .collect::<Result<Vec<_>>>()?;
            fixed(
                name,
                RobotModel::load(
                    &shared.join("robots/ur5e/robot.urdf"),
                    &[],
                    &Default::default(),
                )?,
                clouds,
                grabber_root_from_sensor(),
                grabber_poses(),
            )?
        }
        ScenarioName::RobotInView | ScenarioName::Wrist => {
            let model = demo_model(demo)?;
            let cases = if name == ScenarioName::RobotInView {
                generated(&model, SceneKind::Person, &Mount::fixed())?
            } else {
                // 6 cm off the gripper's axis, looking along it, tilted 0.35 rad toward the
                // fingers (optical z forward = the gripper's z).
                let mount = Mount {
                    link: "gripper_link".into(),
                    link_from_optical: Isometry3::from_parts(
                        Translation3::new(0.06, 0.0, 0.0),
                        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -0.35)
                            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
                    ),
                };
                generated(&model, SceneKind::Shelf, &mount)?
            };
            Scenario {
                name,
                model,
                poses: Vec::new(),
                cases,
                robot_in_view: true,
            }
        }
        ScenarioName::NearBlob => {
            let model = demo_model(demo)?;
            let (link_poses, forearm) = forearm_scene(&model)?;
            // The ball's centre 0.04 + 0.05 + 0.10 m from the axis: its surface is 5 cm from the
            // cylinder. A 500×500 grid over the ball's surface, row by row.
            let (r, n) = (0.10, 500);
            let centre = Vector3::new(0.19, 0.0, 0.175);
            let mut points = Vec::with_capacity(n * n);
            for i in 0..n {
                let theta = std::f64::consts::PI * (i as f64 + 0.5) / n as f64;
                for j in 0..n {
                    let phi = std::f64::consts::TAU * j as f64 / n as f64;
                    let p = centre
                        + r * Vector3::new(
                            -theta.sin() * phi.cos(),
                            theta.sin() * phi.sin(),
                            theta.cos(),
                        );
                    let q = forearm * nalgebra::Point3::from(p);
                    points.push([q.x as f32, q.y as f32, q.z as f32]);
                }
            }
            stress(name, model, points, link_poses)
        }
        ScenarioName::Duplicates => {
            let model = demo_model(demo)?;
            let (link_poses, forearm) = forearm_scene(&model)?;
            let q = forearm * nalgebra::Point3::new(0.07, 0.0, 0.175);
            let points = vec![[q.x as f32, q.y as f32, q.z as f32]; 1_000_000];
            stress(name, model, points, link_poses)
        }
    })
}

/// A stress scene: one cloud in the root frame, one pose.
fn stress(
    name: ScenarioName,
    model: RobotModel,
    points: Vec<[f32; 3]>,
    link_poses: Vec<Isometry3<f64>>,
) -> Scenario {
    Scenario {
        name,
        model,
        poses: Vec::new(),
        cases: vec![Case {
            name: format!("{name:?}").to_lowercase(),
            points: Arc::new(points),
            width: (name == ScenarioName::NearBlob).then_some(500),
            root_from_sensor: Isometry3::identity(),
            link_poses,
            truth_m: None,
        }],
        robot_in_view: false,
    }
}
