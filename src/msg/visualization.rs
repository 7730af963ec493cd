//! `visualization_msgs` (the ROS 2 Humble and later `Marker`, with texture and mesh fields).

use std::borrow::Cow;

use serde::{Deserialize, Serialize};

use super::builtin::{ColorRgba, Duration, Header};
use super::geometry::{Point, Pose, Vector3};
use super::message::ros_message;
use super::sensor::CompressedImage;

/// `visualization_msgs/msg/UVCoordinate`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UvCoordinate {
    pub u: f32,
    pub v: f32,
}
ros_message!(
    UvCoordinate,
    "visualization_msgs/msg/UVCoordinate",
    "float32 u\nfloat32 v\n"
);

/// `visualization_msgs/msg/MeshFile`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile<'a> {
    pub filename: String,
    #[serde(borrow, with = "serde_bytes")]
    pub data: Cow<'a, [u8]>,
}
ros_message!(
    MeshFile<'_>,
    "visualization_msgs/msg/MeshFile",
    "string filename\nuint8[] data\n"
);

/// `visualization_msgs/msg/Marker`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker<'a> {
    pub header: Header,
    pub ns: String,
    pub id: i32,
    pub r#type: i32,
    pub action: i32,
    pub pose: Pose,
    pub scale: Vector3,
    pub color: ColorRgba,
    pub lifetime: Duration,
    pub frame_locked: bool,
    pub points: Vec<Point>,
    pub colors: Vec<ColorRgba>,
    pub texture_resource: String,
    #[serde(borrow)]
    pub texture: CompressedImage<'a>,
    pub uv_coordinates: Vec<UvCoordinate>,
    pub text: String,
    pub mesh_resource: String,
    #[serde(borrow)]
    pub mesh_file: MeshFile<'a>,
    pub mesh_use_embedded_materials: bool,
}
ros_message!(
    Marker<'_>,
    "visualization_msgs/msg/Marker",
    "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\nstd_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\nvisualization_msgs/UVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\nvisualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n"
);

impl Marker<'_> {
    pub const ARROW: i32 = 0;
    pub const CUBE: i32 = 1;
    pub const SPHERE: i32 = 2;
    pub const CYLINDER: i32 = 3;
    pub const LINE_LIST: i32 = 5;
    pub const CUBE_LIST: i32 = 6;
    pub const SPHERE_LIST: i32 = 7;
    pub const TEXT_VIEW_FACING: i32 = 9;
    pub const MESH_RESOURCE: i32 = 10;
    pub const ADD: i32 = 0;
    pub const DELETE: i32 = 2;
    pub const DELETEALL: i32 = 3;
}

/// `visualization_msgs/msg/MarkerArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray<'a> {
    #[serde(borrow)]
    pub markers: Vec<Marker<'a>>,
}
ros_message!(
    MarkerArray<'_>,
    "visualization_msgs/msg/MarkerArray",
    "visualization_msgs/Marker[] markers\n"
);
