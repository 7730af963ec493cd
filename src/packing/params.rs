//! Packing parameters of one link: the sphere budget (start, cap), the smallest radius, the
//! coverage and the surface gap h it packs for, and the prototypes' count and settling steps.

use serde::{Deserialize, Serialize};

/// Packing parameters (per link).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackingParams {
    /// Most spheres of one link (split among its collision elements by volume): its budget
    /// starts at `start_spheres` (or this, if smaller) and grows while the link's h stays above
    /// its target (`ist::build_link`).
    pub max_spheres: u32,
    /// The budget a link starts with.
    pub start_spheres: u32,
    /// Spheres smaller than this are not placed (the first sphere of an element always is), m.
    pub min_radius_m: f32,
    /// Stop once the spheres fill this fraction of the mesh volume.
    pub target_coverage: f64,
    /// Prototypes of the first grid, spread over the element's bounding box.
    pub prototypes: u32,
    /// Settling steps of a prototype.
    pub settle_iterations: u32,
    /// The surface gap h a link is packed for, m: the gap pass fills pockets under the surface
    /// until the samples put the whole surface this close to the spheres (or the budget is
    /// spent), and the budget grows until the certified h is at most this (or `max_spheres`).
    /// A large link is packed for the larger [`PackingParams::link_target_gap`].
    pub target_gap_m: f32,
    /// The surface gap a link is packed for per metre of its bounding box's diagonal: a link
    /// is packed for the larger of this share of its size and `target_gap_m` (0: `target_gap_m`
    /// on every link). A link of up to 0.6 m is packed for 1.5 mm at the defaults, one of 1.2 m
    /// for 3 mm: on a metre-long link a millimetre more h costs a monitor whose protective
    /// separation is a metre or more little, and a finer tree costs minutes of the first build.
    #[serde(default = "default_target_gap_per_m")]
    pub target_gap_per_m: f32,
}

fn default_target_gap_per_m() -> f32 {
    0.0025
}

impl PackingParams {
    /// The surface gap a link whose bounding box has the diagonal `size_m` is packed for, m:
    /// the larger of `target_gap_m` and `target_gap_per_m` × `size_m`.
    pub fn link_target_gap(&self, size_m: f64) -> f32 {
        self.target_gap_m
            .max((self.target_gap_per_m as f64 * size_m) as f32)
    }
}

impl Default for PackingParams {
    fn default() -> Self {
        Self {
            max_spheres: 65536,
            start_spheres: 8192,
            min_radius_m: 0.00015,
            target_coverage: 0.99,
            prototypes: 4096,
            settle_iterations: 24,
            target_gap_m: 0.0015,
            target_gap_per_m: default_target_gap_per_m(),
        }
    }
}
