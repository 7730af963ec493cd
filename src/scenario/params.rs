//! The generator's settings: the scene, the camera (image size, field of view, range, noise and
//! dropped pixels), the seed, and how the bag is written (compression, point layout, clouds or
//! depth images); and the topics, frames and rates the bag uses.

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
    /// Fraction of pixels dropped (NaN).
    pub holes: f64,
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
            max_range_m: 4.0,
            seed: 1,
            compression: Compression::Zstd,
            point_step: 16,
            depth: None,
        }
    }
}

pub const CLOUD_TOPIC: &str = "/camera/depth/points";
pub const CAMERA_INFO_TOPIC: &str = "/camera/depth/camera_info";
/// Where depth images are recorded (`ScenarioParams::depth`).
pub const DEPTH_TOPIC: &str = "/camera/depth/image_raw";
pub const CAMERA_LINK: &str = "camera_link";
pub const OPTICAL_FRAME: &str = "camera_optical_frame";
pub(super) const CLOUD_RATE_HZ: f64 = 10.0;
/// Step in `s` of the central differences.
pub(super) const DS: f64 = 1e-6;
pub(super) const JOINT_RATE_HZ: f64 = 50.0;
/// Stamp of the first frame, ns (2023-11-14).
pub(super) const START_NS: i64 = 1_700_000_000_000_000_000;
