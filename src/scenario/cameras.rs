//! The cameras of a generated bag and what each records: the first on the URDF's `camera_link`
//! (its optical frame under it on `/tf_static`), and optionally a second one beside the arm (its
//! link placed under the robot's root on `/tf_static`, its optical frame under that), each a
//! [`Renderer`] of its own (its own noise stream) with its topics and optical frame. A frame is
//! recorded as an organized cloud with its CameraInfo, or as the CameraInfo then the depth
//! image (a driver latches the model before its images).

use super::error::ScenarioError;
use super::params::{
    ScenarioParams, CAMERA_INFO_TOPIC, CAMERA_LINK, CLOUD_TOPIC, DEPTH_TOPIC, OPTICAL_FRAME,
    SIDE_CAMERA_INFO_TOPIC, SIDE_CAMERA_LINK, SIDE_CLOUD_TOPIC, SIDE_DEPTH_TOPIC,
    SIDE_OPTICAL_FRAME, SIDE_SEED_MIX,
};
use super::renderer::{link_from_optical, root_from_side_link, Frame, Mount, Renderer};
use crate::bag::BagWriter;
use crate::cloud::pointcloud2::{encode, Colour, Layout};
use crate::cloud::CloudError;
use crate::msg::{Header, PointCloud2, PointField, Transform, TransformStamped};
use crate::robot::RobotModel;

/// One camera of the bag: its renderer, topics and optical frame.
pub(super) struct Camera<'a> {
    pub renderer: Renderer<'a>,
    cloud_topic: &'static str,
    info_topic: &'static str,
    depth_topic: &'static str,
    pub optical_frame: &'static str,
}

impl<'a> Camera<'a> {
    /// The first camera: on [`CAMERA_LINK`], the topics under `/camera`.
    pub fn first(model: &'a RobotModel, params: &ScenarioParams) -> Result<Self, ScenarioError> {
        Ok(Self {
            renderer: Renderer::new(model, params, &Mount::fixed())?,
            cloud_topic: CLOUD_TOPIC,
            info_topic: CAMERA_INFO_TOPIC,
            depth_topic: DEPTH_TOPIC,
            optical_frame: OPTICAL_FRAME,
        })
    }

    /// The second camera: beside the arm ([`Mount::side`]), the topics under `/side_camera`,
    /// its noise from the seed mixed with [`SIDE_SEED_MIX`].
    pub fn side(model: &'a RobotModel, params: &ScenarioParams) -> Result<Self, ScenarioError> {
        let params = ScenarioParams {
            seed: params.seed ^ SIDE_SEED_MIX,
            ..params.clone()
        };
        let root = model.kinematics.root_link().to_owned();
        Ok(Self {
            renderer: Renderer::new(model, &params, &Mount::side(&root))?,
            cloud_topic: SIDE_CLOUD_TOPIC,
            info_topic: SIDE_CAMERA_INFO_TOPIC,
            depth_topic: SIDE_DEPTH_TOPIC,
            optical_frame: SIDE_OPTICAL_FRAME,
        })
    }

    /// Records `frame` at `log_ns` under `header` (stamp and this camera's optical frame).
    pub fn write(
        &self,
        writer: &mut BagWriter,
        log_ns: u64,
        header: Header,
        params: &ScenarioParams,
        frame: &Frame,
    ) -> Result<(), ScenarioError> {
        match &frame.depth_image {
            // The camera model first, as a depth camera driver latches it before its images.
            Some(image) => {
                let info = self.renderer.camera_info(header.clone());
                writer.write(self.info_topic, log_ns, &info)?;
                let image = crate::msg::Image {
                    header,
                    ..image.clone()
                };
                writer.write(self.depth_topic, log_ns, &image)?;
            }
            None => {
                let cloud = cloud_message(&header, params, &frame.points)?;
                writer.write(self.cloud_topic, log_ns, &cloud)?;
                let info = self.renderer.camera_info(header);
                writer.write(self.info_topic, log_ns, &info)?;
            }
        }
        Ok(())
    }
}

/// The `/tf_static` transforms of the cameras: the first's optical frame under its link, and
/// with a second camera its link under the robot's root `root` and its optical frame under
/// that.
pub(super) fn static_transforms(
    root: &str,
    second_camera: bool,
    header: &Header,
) -> Vec<TransformStamped> {
    let under = |parent: &str, child: &str, pose| TransformStamped {
        header: Header {
            frame_id: parent.into(),
            ..header.clone()
        },
        child_frame_id: child.into(),
        transform: Transform::from_isometry(&pose),
    };
    let mut transforms = vec![under(CAMERA_LINK, OPTICAL_FRAME, link_from_optical())];
    if second_camera {
        transforms.push(under(root, SIDE_CAMERA_LINK, root_from_side_link()));
        transforms.push(under(
            SIDE_CAMERA_LINK,
            SIDE_OPTICAL_FRAME,
            link_from_optical(),
        ));
    }
    transforms
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
