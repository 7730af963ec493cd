//! Where a sensor is in the robot: up from the sensor frame through TF to the first URDF link,
//! whose pose the joint states give by forward kinematics (so a camera on the wrist moves with
//! the arm), or else the TF path to the root frame. Output: `root_from_sensor` at a cloud's
//! stamp.

use nalgebra::Isometry3;

use super::buffer::{strip, TfBuffer, TfError};

/// `root_from_sensor` at `stamp_ns`: up from the sensor frame through TF to the first frame
/// that `link_pose` knows (a URDF link: `root_from_link` by forward kinematics), or else the
/// TF path to `root_frame`.
pub fn root_from_sensor(
    tf: &TfBuffer,
    sensor_frame: &str,
    root_frame: &str,
    stamp_ns: Option<i64>,
    tolerance_s: f64,
    link_pose: &dyn Fn(&str) -> Option<Isometry3<f64>>,
) -> Result<Isometry3<f64>, TfError> {
    let tolerance_ns = (tolerance_s * 1e9) as i64;
    let sensor_frame = strip(sensor_frame);
    for (frame, frame_from_sensor) in tf.chain(sensor_frame, stamp_ns, tolerance_ns)? {
        if let Some(root_from_frame) = link_pose(&frame) {
            return Ok(root_from_frame * frame_from_sensor);
        }
    }
    tf.lookup(root_frame, sensor_frame, stamp_ns, tolerance_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tf::buffer::tests::{pose, ts};

    #[test]
    fn sensor_frames_resolve_through_urdf_links_or_the_root() {
        let mut tf = TfBuffer::new(10.0);
        // Optical frame under a URDF link; a second camera that names the world as its child.
        tf.insert(&ts("camera_link", "optical", 0, pose(0.0, 1.0)), true)
            .unwrap();
        tf.insert(&ts("cam2", "world", 0, pose(3.0, 0.2)), true)
            .unwrap();
        tf.insert(&ts("world", "robot_root", 0, pose(0.5, 0.0)), true)
            .unwrap();
        let links = |name: &str| (name == "camera_link").then(|| pose(2.0, 0.0));
        let r = root_from_sensor(&tf, "optical", "robot_root", None, 0.0, &links).unwrap();
        assert!((r.translation.x - 2.0).abs() < 1e-12);
        let r = root_from_sensor(&tf, "cam2", "robot_root", None, 0.0, &links).unwrap();
        let expected = (pose(3.0, 0.2) * pose(0.5, 0.0)).inverse();
        assert!((r.to_homogeneous() - expected.to_homogeneous()).norm() < 1e-12);
    }
}
