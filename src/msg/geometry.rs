//! `geometry_msgs` and `tf2_msgs`, with the conversion to nalgebra's f64 isometries.

use nalgebra::{Isometry3, Quaternion as NaQuaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use super::builtin::Header;
use super::message::ros_message;

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}
ros_message!(
    Vector3,
    "geometry_msgs/msg/Vector3",
    "float64 x\nfloat64 y\nfloat64 z\n"
);

/// `geometry_msgs/msg/Point`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}
ros_message!(
    Point,
    "geometry_msgs/msg/Point",
    "float64 x\nfloat64 y\nfloat64 z\n"
);

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}
ros_message!(
    Quaternion,
    "geometry_msgs/msg/Quaternion",
    "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
);

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl Quaternion {
    /// The normalized rotation; `None` for a zero, near-zero or non-finite quaternion.
    pub fn to_unit(self) -> Option<UnitQuaternion<f64>> {
        let q = NaQuaternion::new(self.w, self.x, self.y, self.z);
        let norm = q.norm();
        (norm.is_finite() && norm > 1e-6).then(|| UnitQuaternion::new_unchecked(q / norm))
    }
    pub fn from_unit(q: &UnitQuaternion<f64>) -> Self {
        Self {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}
ros_message!(
    Pose,
    "geometry_msgs/msg/Pose",
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
);

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}
ros_message!(
    Transform,
    "geometry_msgs/msg/Transform",
    "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
);

impl Transform {
    /// The isometry, with the quaternion normalized; `None` when the quaternion is zero or the
    /// transform not finite.
    pub fn to_isometry(&self) -> Option<Isometry3<f64>> {
        let t = self.translation;
        let rotation = self.rotation.to_unit()?;
        [t.x, t.y, t.z]
            .iter()
            .all(|v| v.is_finite())
            .then(|| Isometry3::from_parts(Translation3::new(t.x, t.y, t.z), rotation))
    }
    pub fn from_isometry(pose: &Isometry3<f64>) -> Self {
        let t = pose.translation.vector;
        Self {
            translation: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            rotation: Quaternion::from_unit(&pose.rotation),
        }
    }
}

/// `geometry_msgs/msg/TransformStamped`: `header.frame_id` is the parent frame, the transform
/// is `parent_from_child`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}
ros_message!(
    TransformStamped,
    "geometry_msgs/msg/TransformStamped",
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"
);

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}
ros_message!(
    TfMessage,
    "tf2_msgs/msg/TFMessage",
    "geometry_msgs/TransformStamped[] transforms\n"
);
