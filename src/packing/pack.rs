//! The packing's order of passes, and its entry points: the volume pass spends half the budget,
//! the gap pass fills the pockets under the surface, the volume pass spends the rest
//! ([`Packer::grow`], which a link grows with while its h is above the target); [`pack`] runs that
//! once, [`pack_sphere`] places a sphere primitive's inscribed sphere without a search.

use super::grid::SphereGrid;
use super::packer::{Packer, Packing};
use super::params::PackingParams;
use super::sphere::{shrink, InnerSphere};
use crate::robot::ClosedMesh;

/// Share of the budget the first volume pass may spend before the gap pass.
const VOLUME_SHARE: f64 = 0.5;

impl Packer<'_> {
    /// Packs to `budget` spheres: the volume pass to half of it, the gap pass until its samples
    /// are within `stop` (m; at least the gap that proves `target_gap_m`, which 0 asks for) or
    /// the packing has `gap_limit` spheres (at least `budget`), the volume pass to the rest of
    /// `budget`; a packing already past a step's limit skips it, and the gap pass goes on where
    /// the last call left it. Returns the largest gap from a gap-pass sample of the surface to
    /// the spheres, m: a point of the element's surface that far from every sphere (a lower
    /// bound of its h, which the link's budget decision may use instead of a whole gap
    /// estimate), or None when every sample lies within the proof target.
    pub fn grow(&mut self, budget: usize, gap_limit: usize, stop: f32) -> Option<f32> {
        self.volume_pass((budget as f64 * VOLUME_SHARE).ceil() as usize);
        self.gap_pass(gap_limit.max(budget), stop);
        self.volume_pass(budget);
        let grid = &self.grid;
        self.gap.as_mut().and_then(|state| state.worst(grid))
    }
}

/// Packs one closed mesh with at most `budget` spheres: the volume pass fills the solid with the
/// largest spheres first, the gap pass then fills the pockets under the surface where the gap is
/// above `target_gap_m`, and the volume pass spends what budget is left.
pub fn pack(mesh: &ClosedMesh, budget: usize, params: &PackingParams) -> Packing {
    let mut packer = Packer::new(mesh, params);
    packer.grow(budget, budget, 0.0);
    packer.finish()
}

/// The packing of a sphere primitive: its inscribed sphere about `center` (the exact f64
/// distance to the tessellation's faces, shrunk like every sphere's radius), which no packing
/// beats, so no search is run.
pub fn pack_sphere(mesh: &ClosedMesh, center: [f64; 3], params: &PackingParams) -> Packing {
    let radius = crate::geometry::distance_point_mesh(center, &mesh.vertices, &mesh.triangles);
    let (lo, hi) = mesh.bounds();
    let mut grid = SphereGrid::new(lo, hi, 2.0 * params.min_radius_m);
    grid.insert(InnerSphere {
        center: center.map(|x| x as f32),
        radius: shrink(radius as f32),
    });
    Packing { grid, settles: 0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::mesh::tessellate_box;
    use crate::robot::ClosedMesh;

    #[test]
    fn a_cube_gets_one_big_sphere_first_and_fills_up() {
        let t = tessellate_box([0.1, 0.1, 0.1]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "cube").expect("closed");
        let params = PackingParams::default();
        let one = pack(&mesh, 1, &params);
        let s = one.grid.spheres()[0];
        assert!((s.radius - 0.05).abs() < 5e-4, "first sphere {s:?}");
        let many = pack(&mesh, 500, &params);
        let spheres = many.grid.spheres();
        assert_eq!(spheres.len(), 500);
        let volume: f64 = spheres
            .iter()
            .map(|s| crate::geometry::ball_volume(s.radius as f64))
            .sum();
        assert!(
            volume / mesh.volume_m3 > 0.6,
            "coverage {}",
            volume / mesh.volume_m3
        );
    }
}
