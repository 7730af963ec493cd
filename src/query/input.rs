//! What one query asks, as both backends and the result read it: the cloud (points, or a depth
//! image whose points the GPU makes), where its sensor is (`root_from_sensor`, f64), how the
//! robot is posed (`root_from_link` per link, f64) and the options.

use nalgebra::Isometry3;

use super::options::QueryOptions;
use crate::cloud::depth::DepthView;

/// What one query asks: the cloud, where its sensor is, how the robot is posed, the options.
#[derive(Clone, Copy)]
pub(super) struct Input<'a> {
    /// The points the CPU sweeps; empty for a depth image unprojected on the GPU (`depth`).
    pub(super) points: &'a [[f32; 3]],
    /// A depth image whose points the GPU makes; the host unprojects the few the result needs
    /// ([`Input::point`]), exactly as the GPU did.
    pub(super) depth: Option<&'a DepthView<'a>>,
    /// Points per row of an organized cloud.
    pub(super) width: Option<usize>,
    pub(super) root_from_sensor: &'a Isometry3<f64>,
    pub(super) link_poses: &'a [Isometry3<f64>],
    pub(super) options: &'a QueryOptions,
}

impl Input<'_> {
    /// Points in the query.
    pub(super) fn len(&self) -> usize {
        self.depth.map_or(self.points.len(), |d| d.len())
    }

    /// Point `i`.
    pub(super) fn point(&self, i: u32) -> [f32; 3] {
        match self.depth {
            Some(d) => d.point(i as usize),
            None => self.points[i as usize],
        }
    }
}
