//! The exact inside test and clearance of a collision solid, in f64 and apart from parry3d's f32
//! queries that the packing climbs with: a closed mesh's inside by the ray winding number of its
//! surface (`surface`), a filled solid's by the intake's flood fill (`fill`); distances to the
//! triangles that bound it. Used where a wrong answer would put a sphere outside its link: the
//! packing checks each sphere before it keeps it (`packing`), and `ist::validate` checks every
//! tree before it is used or cached.

use std::sync::Arc;

use super::fill::Fill;
use super::mesh::ClosedMesh;
pub use super::surface::ExactSurface;
use crate::geometry::P3;

/// A collision solid for exact checks: inside by the ray winding number of a closed mesh, or by
/// the intake's flood fill for a filled one (`robot::fill`: there "inside" is the intake's
/// decision); distances to the triangles that bound it.
pub struct ExactSolid {
    pub surface: ExactSurface,
    fill: Option<Arc<Fill>>,
}

impl ExactSolid {
    pub fn new(mesh: &ClosedMesh) -> Self {
        Self {
            surface: ExactSurface::new(&mesh.vertices, &mesh.triangles),
            fill: mesh.fill.clone(),
        }
    }

    /// Whether `p` is inside (a point the fill cannot place counts as outside).
    pub fn contains(&self, p: P3) -> bool {
        match &self.fill {
            Some(fill) => fill.contains(p, false),
            None => self.surface.contains(p),
        }
    }

    /// The clearance of a ball: the distance from its centre to the surface less its radius
    /// (≥ 0 when the ball lies inside), or None when its centre is outside.
    pub fn ball_clearance(&self, center: P3, radius: f64) -> Option<f64> {
        self.contains(center)
            .then(|| self.surface.distance(center).0 - radius)
    }
}
