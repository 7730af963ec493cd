//! Writing a scenario's bag: `/tf_static` (the cameras' frames), `/joint_states` at 50 Hz with
//! velocities, each camera's cloud (or depth image) with its CameraInfo at 10 Hz, stamped at
//! joint-state sample times (the second camera's logged 1 ms after the first's), and at each
//! camera's log time the truth topics of the frame (the exact distance over every camera's
//! obstacle points and, where the scene hides its obstacle, its whole shape; the approach
//! speed; the separation margin with the default SSM parameters).

use std::path::Path;

use super::cameras::{static_transforms, Camera};
use super::error::ScenarioError;
use super::params::{ScenarioParams, CLOUD_RATE_HZ, JOINT_RATE_HZ, START_NS};
use super::renderer::{Frame, Hit};
use crate::bag::{BagWriter, APPROACH_TRUTH_TOPIC, GROUND_TRUTH_TOPIC, MARGIN_TRUTH_TOPIC};
use crate::msg::{Float64, Header, JointState, TfMessage, Time};
use crate::robot::RobotModel;
use crate::separation::SsmParams;

/// What the generator wrote.
#[derive(Debug, Clone)]
pub struct Generated {
    pub frames: usize,
    /// Exact minimum distance per frame, m (`None`: no obstacle point): over every camera's
    /// obstacle points and, where the scene hides its obstacle (dark, shadow), its whole shape.
    pub truth_m: Vec<Option<f64>>,
    /// The truth of the separation monitor per frame: the robot's approach speed at its
    /// closest point (m/s) and the separation margin with the default SSM parameters (m).
    pub separation: Vec<Option<(f64, f64)>>,
    /// Obstacle and robot points per frame (the first camera).
    pub obstacle_points: Vec<usize>,
    pub robot_points: Vec<usize>,
    /// The first camera's valid points on the scene's obstacle itself (the person, the
    /// forearm, the box; not the wall or the table) per frame.
    pub target_points: Vec<usize>,
    /// The same for the second camera (empty without one).
    pub side_target_points: Vec<usize>,
}

/// Generates a bag at `out` (a rosbag2 folder, or a `.mcap` file).
pub fn generate(
    model: &RobotModel,
    params: &ScenarioParams,
    out: &Path,
) -> Result<Generated, ScenarioError> {
    let k = &model.kinematics;
    let mut cameras = vec![Camera::first(model, params)?];
    if params.second_camera {
        cameras.push(Camera::side(model, params)?);
    }
    let mut writer = BagWriter::create(out, params.compression)?;
    let stamp = |ns: i64| Header {
        stamp: Time::from_nanos(ns),
        frame_id: String::new(),
    };
    let transforms = static_transforms(k.root_link(), params.second_camera, &stamp(START_NS));
    writer.write("/tf_static", START_NS as u64, &TfMessage { transforms })?;
    let duration_s = (params.frames.max(1) - 1) as f64 / CLOUD_RATE_HZ;
    let joint_samples = (duration_s * JOINT_RATE_HZ).round() as usize;
    let per_cloud = (JOINT_RATE_HZ / CLOUD_RATE_HZ).round() as usize;
    let mut result = Generated {
        frames: params.frames,
        truth_m: Vec::new(),
        separation: Vec::new(),
        obstacle_points: Vec::new(),
        robot_points: Vec::new(),
        target_points: Vec::new(),
        side_target_points: Vec::new(),
    };
    let s_at = |i: usize| {
        if joint_samples == 0 {
            0.0
        } else {
            i as f64 / joint_samples as f64
        }
    };
    let ds_dt = if duration_s > 0.0 {
        1.0 / duration_s
    } else {
        0.0
    };
    let ssm = SsmParams::default();
    for j in 0..=joint_samples {
        let t_ns = START_NS + (j as f64 * 1e9 / JOINT_RATE_HZ).round() as i64;
        let renderer = &cameras[0].renderer;
        writer.write(
            "/joint_states",
            (t_ns + 1_000_000) as u64,
            &JointState {
                header: stamp(t_ns),
                name: k.variables().to_vec(),
                position: renderer.joints(s_at(j))?,
                velocity: renderer.joint_velocities(s_at(j), ds_dt)?,
                ..JointState::default()
            },
        )?;
        if j % per_cloud != 0 {
            continue;
        }
        let frames = (cameras.iter_mut())
            .map(|c| c.renderer.frame(s_at(j), true))
            .collect::<Result<Vec<Frame>, _>>()?;
        // The scene's truth: the nearest over the cameras (each already holds the hidden
        // shape's distance where there is one).
        let nearest = (frames.iter())
            .filter_map(|f| Some((f.truth_m?, f.truth_witness?, f)))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let mut separation = None;
        if let Some((_, w, f)) = nearest {
            // The separation margin with the default SSM parameters, the cloud seen at once
            // (T_r = reaction_time) and the exact distance (Z_d = the sensor's uncertainty).
            let (approach, speed) = cameras[0].renderer.approach(s_at(j), ds_dt, f, &w)?;
            let d = f.truth_m.unwrap_or(f64::INFINITY);
            let margin = d - ssm.protective_distance(
                ssm.reaction_time_s,
                approach,
                speed,
                ssm.sensor_uncertainty_m,
            );
            separation = Some((d, approach, margin));
        }
        for (i, (camera, frame)) in cameras.iter().zip(&frames).enumerate() {
            let log_ns = (t_ns + 20_000_000 + 1_000_000 * i as i64) as u64;
            let header = Header {
                frame_id: camera.optical_frame.into(),
                ..stamp(t_ns)
            };
            camera.write(&mut writer, log_ns, header, params, frame)?;
            if let Some((d, approach, margin)) = separation {
                writer.write(GROUND_TRUTH_TOPIC, log_ns, &Float64 { data: d })?;
                writer.write(APPROACH_TRUTH_TOPIC, log_ns, &Float64 { data: approach })?;
                writer.write(MARGIN_TRUTH_TOPIC, log_ns, &Float64 { data: margin })?;
            }
        }
        let target = |f: &Frame| f.hits.iter().filter(|h| **h == Hit::Scene(1)).count();
        result.truth_m.push(separation.map(|s| s.0));
        result.separation.push(separation.map(|s| (s.1, s.2)));
        result.obstacle_points.push(frames[0].obstacle_points);
        result.robot_points.push(frames[0].robot_points);
        result.target_points.push(target(&frames[0]));
        if let Some(side) = frames.get(1) {
            result.side_target_points.push(target(side));
        }
    }
    writer.finish()?;
    Ok(result)
}
