//! A source's view for the unseen space, made from what its frame measured: a depth image
//! through its camera model, or an organized cloud with the pinhole intrinsics fitted from its
//! own points (taken before the exclusion volumes drop theirs: an excluded point is still a
//! return), placed by the sensor's pose at the frame's stamp, with the source's range limits
//! (a ball nearer than the minimum range is not judged by it). An unorganized cloud, or one no
//! pinhole fits, observes nothing free, and says why.

use nalgebra::Isometry3;

use crate::cloud::depth::{DepthView, PinholeCamera};
use crate::cloud::RangeLimits;
use crate::unseen::RangeView;

/// The view of a depth image `depth` of `camera`, placed by `root_from_sensor`, with the
/// source's `range_noise_m` (its range limits are the image's); why it observes nothing free
/// otherwise.
pub fn depth_view(
    depth: &DepthView,
    camera: &PinholeCamera,
    root_from_sensor: &Isometry3<f64>,
    range_noise_m: f64,
) -> Result<RangeView, String> {
    RangeView::from_depth(depth, camera, *root_from_sensor, range_noise_m)
        .map_err(|e| e.to_string())
}

/// The view of an organized cloud `points` of `width` per row (`None`: one row), placed by
/// `root_from_sensor`, with the source's `limits` and `range_noise_m`; why it observes nothing
/// free otherwise. `known`: the camera of the source's previous view, kept where it still fits
/// the cloud.
pub fn cloud_view(
    points: &[[f32; 3]],
    width: Option<usize>,
    root_from_sensor: &Isometry3<f64>,
    limits: Option<RangeLimits>,
    range_noise_m: f64,
    known: Option<&PinholeCamera>,
) -> Result<RangeView, String> {
    let w = width.unwrap_or(points.len());
    let h = points.len().checked_div(w).unwrap_or(0);
    // Its points outside the range limits are NaN already (`measure`); the limits go with the
    // view, so that a ball nearer than the minimum range is not judged.
    RangeView::from_organized_cloud(
        points,
        w as u32,
        h as u32,
        *root_from_sensor,
        limits,
        range_noise_m,
        known,
    )
    .map_err(|e| e.to_string())
}
