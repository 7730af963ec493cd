//! Writing a scenario's bag: `/tf_static` (the optical frame under the camera link),
//! `/joint_states` at 50 Hz with velocities, a cloud (or a depth image) with its CameraInfo at
//! 10 Hz, stamped at joint-state sample times, and the truth topics of each frame (the exact
//! distance, the approach speed, the separation margin with the default SSM parameters).

use std::path::Path;

use super::error::ScenarioError;
use super::params::{
    ScenarioParams, CAMERA_INFO_TOPIC, CAMERA_LINK, CLOUD_RATE_HZ, CLOUD_TOPIC, DEPTH_TOPIC,
    JOINT_RATE_HZ, OPTICAL_FRAME, START_NS,
};
use super::renderer::{link_from_optical, Mount, Renderer};
use crate::bag::{BagWriter, APPROACH_TRUTH_TOPIC, GROUND_TRUTH_TOPIC, MARGIN_TRUTH_TOPIC};
use crate::cloud::pointcloud2::{encode, Colour, Layout};
use crate::cloud::CloudError;
use crate::msg::{
    Float64, Header, JointState, PointCloud2, PointField, TfMessage, Time, Transform,
    TransformStamped,
};
use crate::robot::RobotModel;
use crate::separation::SsmParams;

/// What the generator wrote.
#[derive(Debug, Clone)]
pub struct Generated {
    pub frames: usize,
    /// Exact minimum distance per frame, m (`None`: no obstacle point).
    pub truth_m: Vec<Option<f64>>,
    /// The truth of the separation monitor per frame: the robot's approach speed at its
    /// closest point (m/s) and the separation margin with the default SSM parameters (m).
    pub separation: Vec<Option<(f64, f64)>>,
    /// Obstacle and robot points per frame.
    pub obstacle_points: Vec<usize>,
    pub robot_points: Vec<usize>,
}

/// Generates a bag at `out` (a rosbag2 folder, or a `.mcap` file).
pub fn generate(
    model: &RobotModel,
    params: &ScenarioParams,
    out: &Path,
) -> Result<Generated, ScenarioError> {
    let k = &model.kinematics;
    let mut renderer = Renderer::new(model, params, &Mount::fixed())?;
    let mut writer = BagWriter::create(out, params.compression)?;
    let stamp = |ns: i64| Header {
        stamp: Time::from_nanos(ns),
        frame_id: String::new(),
    };
    writer.write(
        "/tf_static",
        START_NS as u64,
        &TfMessage {
            transforms: vec![TransformStamped {
                header: Header {
                    frame_id: CAMERA_LINK.into(),
                    ..stamp(START_NS)
                },
                child_frame_id: OPTICAL_FRAME.into(),
                transform: Transform::from_isometry(&link_from_optical()),
            }],
        },
    )?;
    let duration_s = (params.frames.max(1) - 1) as f64 / CLOUD_RATE_HZ;
    let joint_samples = (duration_s * JOINT_RATE_HZ).round() as usize;
    let per_cloud = (JOINT_RATE_HZ / CLOUD_RATE_HZ).round() as usize;
    let mut result = Generated {
        frames: params.frames,
        truth_m: Vec::new(),
        separation: Vec::new(),
        obstacle_points: Vec::new(),
        robot_points: Vec::new(),
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
        let frame = renderer.frame(s_at(j), true)?;
        let log_ns = (t_ns + 20_000_000) as u64;
        let header = Header {
            frame_id: OPTICAL_FRAME.into(),
            ..stamp(t_ns)
        };
        match &frame.depth_image {
            // The camera model first, as a depth camera driver latches it before its images.
            Some(image) => {
                let info = renderer.camera_info(header.clone());
                writer.write(CAMERA_INFO_TOPIC, log_ns, &info)?;
                let image = crate::msg::Image {
                    header,
                    ..image.clone()
                };
                writer.write(DEPTH_TOPIC, log_ns, &image)?;
            }
            None => {
                let cloud = cloud_message(&header, params, &frame.points)?;
                writer.write(CLOUD_TOPIC, log_ns, &cloud)?;
                writer.write(CAMERA_INFO_TOPIC, log_ns, &renderer.camera_info(header))?;
            }
        }
        let mut separation = None;
        if let (Some(d), Some(w)) = (frame.truth_m, frame.truth_witness) {
            writer.write(GROUND_TRUTH_TOPIC, log_ns, &Float64 { data: d })?;
            // The separation margin with the default SSM parameters, the cloud seen at once
            // (T_r = reaction_time) and the exact distance (Z_d = the sensor's uncertainty).
            let (approach, speed) = renderer.approach(s_at(j), ds_dt, &frame, &w)?;
            let margin = d - ssm.protective_distance(
                ssm.reaction_time_s,
                approach,
                speed,
                ssm.sensor_uncertainty_m,
            );
            writer.write(APPROACH_TRUTH_TOPIC, log_ns, &Float64 { data: approach })?;
            writer.write(MARGIN_TRUTH_TOPIC, log_ns, &Float64 { data: margin })?;
            separation = Some((approach, margin));
        }
        result.truth_m.push(frame.truth_m);
        result.separation.push(separation);
        result.obstacle_points.push(frame.obstacle_points);
        result.robot_points.push(frame.robot_points);
    }
    writer.finish()?;
    Ok(result)
}

/// An organized PointCloud2: x y z FLOAT32 and zero padding per point (16 bytes), or with a
/// grey `rgb` by depth at offset 16 (32 bytes, as RGB-D drivers publish).
fn cloud_message(
    header: &Header,
    params: &ScenarioParams,
    points: &[[f32; 3]],
) -> Result<PointCloud2<'static>, CloudError> {
    fn grey(p: [f32; 3]) -> [u8; 3] {
        [(255.0 - (p[2] * 60.0).clamp(0.0, 255.0)) as u8; 3]
    }
    let layout = Layout {
        width: params.width,
        height: params.height,
        datatype: PointField::FLOAT32,
        big_endian: false,
        point_step: params.point_step,
        row_padding: 0,
        rgb: (params.point_step == 32).then_some((16, grey as Colour)),
        pad: 0,
    };
    encode(header.clone(), points, &layout)
}
