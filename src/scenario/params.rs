//! The generator's settings: the scene, the camera (image size, field of view, range, noise and
//! dropped pixels), the seed, and how the bag is written (compression, point layout, clouds or
//! depth images), a dark obstacle, a second camera and a floor; and the topics, frames and
//! rates the bag uses.

use super::scene::SceneKind;
use crate::bag::writer::Compression;
use crate::cloud::depth::DepthEncoding;

/// Generator settings.
#[derive(Debug, Clone)]
pub struct ScenarioParams {
    pub scene: SceneKind,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f64,
    /// Range noise σ along the ray, m (clipped at 2.5 σ).
    pub noise_m: f64,
    /// Fraction of pixels dropped (NaN), each at random on its own.
    pub holes: f64,
    /// Fraction of pixels dropped as a depth camera drops them (`dropouts`): at depth edges,
    /// on the person's dark hair and shoes, and in clusters, on a stream of their own. 0 (the
    /// default): none, and the bag is byte for byte as before.
    pub camera_dropouts: f64,
    /// Farthest return, m.
    pub max_range_m: f64,
    pub seed: u64,
    pub compression: Compression,
    /// Bytes per point: 16 (x y z, padding) or 32 (x y z, padding, rgb, padding), as RGB-D
    /// drivers publish.
    pub point_step: u32,
    /// Record depth images in this encoding on [`DEPTH_TOPIC`] instead of clouds: the points
    /// (and the truth) are then those `depth_image_proc` makes from the recorded image.
    pub depth: Option<DepthEncoding>,
    /// The obstacle (person, forearm or box) returns no depth, as dark fabric to a ToF or
    /// structured-light camera: its pixels are NaN (0 in a 16UC1 image), drawn from the noise
    /// stream as before (the other pixels are the bright scene's). The truth is then the
    /// distance to the obstacle's whole shape.
    pub dark: bool,
    /// A second depth camera beside the arm ([`SIDE_CAMERA_LINK`], placed on `/tf_static`
    /// under the robot's root) that looks into the first one's shadow, recorded on its own
    /// topics ([`SIDE_CLOUD_TOPIC`], [`SIDE_CAMERA_INFO_TOPIC`], [`SIDE_DEPTH_TOPIC`]) 1 ms
    /// after the first, with the same image size, noise and holes from a stream of its own.
    /// The scene then has a side wall behind the arm as this camera sees it
    /// (`SIDE_WALL_CENTER`, an obstacle like the back wall, more than 1.4 m from the arm), so
    /// that its rays behind the arm return.
    pub second_camera: bool,
    /// A floor under the cell (`FLOOR_SIZE`, its top the plane z = 0 of the robot's root),
    /// seen by every camera, so that the rays below the arm return (a ray with no return
    /// observes nothing). Its points are not obstacles: the truth leaves them out, as the
    /// robot's own, and the monitor is told to drop them with an exclusion volume
    /// (docs/replay.md). Off by default: the bags without it are byte for byte as before.
    pub floor: bool,
}

impl ScenarioParams {
    /// The bundled demo bag's (`bags/demo`): the person walking up to the arm, seen by a
    /// 192 × 144 camera over a floor, 2 % of the pixels dropped, so that it can watch the space
    /// it does not see (`ist_monitor generate --width 192 --height 144 --floor`).
    pub fn demo() -> Self {
        Self {
            width: 192,
            height: 144,
            floor: true,
            ..Self::default()
        }
    }

    /// Whether the scene hides its obstacle from the first camera (dark, or in the arm's
    /// shadow): the truth is then taken to the obstacle's whole shape as well as to the points.
    /// (The camera-like dropouts hide only parts of it: the truth stays the distance to what
    /// the camera saw.)
    pub fn hides_obstacle(&self) -> bool {
        self.dark || self.scene == SceneKind::Shadow
    }
}

impl Default for ScenarioParams {
    fn default() -> Self {
        Self {
            scene: SceneKind::Person,
            frames: 30,
            width: 128,
            height: 96,
            hfov_deg: 62.0,
            noise_m: 0.001,
            holes: 0.02,
            camera_dropouts: 0.0,
            max_range_m: 4.0,
            seed: 1,
            compression: Compression::Zstd,
            point_step: 16,
            depth: None,
            dark: false,
            second_camera: false,
            floor: false,
        }
    }
}

pub const CLOUD_TOPIC: &str = "/camera/depth/points";
pub const CAMERA_INFO_TOPIC: &str = "/camera/depth/camera_info";
/// Where depth images are recorded (`ScenarioParams::depth`).
pub const DEPTH_TOPIC: &str = "/camera/depth/image_raw";
pub const CAMERA_LINK: &str = "camera_link";
pub const OPTICAL_FRAME: &str = "camera_optical_frame";
/// The second camera (`ScenarioParams::second_camera`): its topics, as the first one's under
/// `/side_camera`, its link (on `/tf_static` under the robot's root, [`SIDE_CAMERA_POSE`]) and
/// its optical frame (under its link, as the first camera's).
pub const SIDE_CLOUD_TOPIC: &str = "/side_camera/depth/points";
pub const SIDE_CAMERA_INFO_TOPIC: &str = "/side_camera/depth/camera_info";
pub const SIDE_DEPTH_TOPIC: &str = "/side_camera/depth/image_raw";
pub const SIDE_CAMERA_LINK: &str = "side_camera_link";
pub const SIDE_OPTICAL_FRAME: &str = "side_camera_optical_frame";
/// `root_from_side_camera_link`: x y z (m) and roll pitch yaw (rad, as a URDF origin). 1.4 m to
/// the side of the arm, 0.45 m towards the wall, 0.75 m up, looking along +y and 0.25 rad
/// down: it sees the space behind the upper arm that the first camera cannot.
pub const SIDE_CAMERA_POSE: ([f64; 3], [f64; 3]) = (
    [-0.45, -1.4, 0.75],
    [0.0, 0.25, std::f64::consts::FRAC_PI_2],
);
/// The second camera's noise stream is the seed mixed with this (not a shift of the first
/// one's SplitMix64 sequence).
pub(super) const SIDE_SEED_MIX: u64 = 0xD1B5_4A32_D192_ED03;
/// The camera-like dropouts' stream is the camera's seed mixed with this.
pub(super) const DROPOUT_SEED_MIX: u64 = 0x8CB9_2BA7_2F3D_8DD7;
pub(super) const CLOUD_RATE_HZ: f64 = 10.0;
/// Step in `s` of the central differences.
pub(super) const DS: f64 = 1e-6;
pub(super) const JOINT_RATE_HZ: f64 = 50.0;
/// Stamp of the first frame, ns (2023-11-14).
pub(super) const START_NS: i64 = 1_700_000_000_000_000_000;
