//! The real scenes the benchmarks and some tests run on, from `../shared` (read by path):
//! - `kinect`: the Panda and the real Kinect cloud of the MoveIt perception tutorial, at the
//!   joint configurations of its SCENARIO.md and five more reaching toward the table;
//! - `grabber`: the UR5e placed 0.35 m in front of the camera of PCL's three grabber frames
//!   (base 0.3 m below the optical axis, z up), at four configurations reaching toward the
//!   scene (5 to 27 cm from it).
//!
//! One definition for three targets: the `bench` subcommand (`mod scenes`), the criterion
//! benches and the integration tests (`#[path = ...] mod scenes`). It uses only the library.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use ist_monitor::cloud::{self, Cloud};
use ist_monitor::robot::RobotModel;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ScenarioName {
    Kinect,
    Grabber,
}

/// A robot, a cloud and the poses to query.
pub struct Scenario {
    pub name: ScenarioName,
    pub model: RobotModel,
    pub clouds: Vec<(String, Cloud)>,
    pub root_from_sensor: Isometry3<f64>,
    /// (name, joint values by name).
    pub poses: Vec<(String, Vec<(String, f64)>)>,
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

pub fn load_scenario(shared: &Path, name: ScenarioName) -> Result<Scenario> {
    Ok(match name {
        ScenarioName::Kinect => {
            let bag = shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap");
            Scenario {
                name,
                model: RobotModel::load(&shared.join("robots/panda/robot.urdf"), &[])?,
                clouds: vec![("kinect".into(), cloud::load(&bag, 0)?)],
                root_from_sensor: kinect_root_from_sensor(),
                poses: kinect_poses(),
            }
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
            Scenario {
                name,
                model: RobotModel::load(&shared.join("robots/ur5e/robot.urdf"), &[])?,
                clouds,
                root_from_sensor: grabber_root_from_sensor(),
                poses: grabber_poses(),
            }
        }
    })
}
