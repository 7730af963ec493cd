//! The packing's output unit: an inner sphere in its link's frame, and how a sphere's radius is
//! made from a clearance (the f32 climb's, shrunk by its roundings, then capped by the exact f64
//! one) so that no sphere reaches outside the solid or into a neighbour.

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

/// One inner sphere in its link's frame (metres). WGSL mirror: `Sphere { center: vec3<f32>,
/// radius: f32 }` in `shaders/traverse.wgsl`, checked member by member against
/// `query::layout::MIRRORS`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, Serialize, Deserialize)]
pub struct InnerSphere {
    pub center: [f32; 3],
    pub radius: f32,
}
const _: () = assert!(std::mem::size_of::<InnerSphere>() == 16);

/// A sphere radius from a clearance, shrunk by a few f32 roundings so that the sphere stays
/// inside the mesh and apart from its neighbours.
pub(super) fn shrink(clearance: f32) -> f32 {
    clearance * (1.0 - 4.0 * f32::EPSILON) - 2e-7
}

/// The largest f32 radius at most `radius` whose ball lies within `clearance` (f64) of its
/// centre.
pub(super) fn exact_radius(radius: f32, clearance: f64) -> f32 {
    let mut r = radius.min(clearance as f32);
    while r > 0.0 && r as f64 > clearance {
        r = r.next_down();
    }
    r
}
