//! The surface gap h of a packing: the largest distance from any point of the mesh surface to
//! the union of the inner spheres. For a point x outside the link, with s the closest surface
//! point, `d_spheres(x) ≤ |x − s| + d_spheres(s) ≤ d_mesh(x) + h`, so `d_spheres − h` is a
//! certified lower bound of the distance to the mesh.
//!
//! Two upper bounds of g(s) = distance from s to the union of spheres over a triangle:
//! - g is 1-Lipschitz; every point of a triangle with longest edge L lies within L/√3 of a
//!   vertex, so `g ≤ max(gₐ, g_b, g_c) + L/√3`;
//! - for any one sphere k, g ≤ |s − c_k| − r_k, which is convex in s, so its maximum over the
//!   triangle is at a vertex: `g ≤ min_k max_v (|v − c_k| − r_k)`, with k among the vertices'
//!   nearest spheres. This one is tight where one sphere faces the whole triangle.
//!
//! Branch and bound over the mesh triangles with the smaller of the two:
//! a triangle whose bound is within `tolerance` of the largest g known (at any mesh vertex, or
//! sampled on the triangle itself; never what other threads found meanwhile, so the result
//! does not depend on their timing) is done; any other is split in four. The result is an
//! upper bound of h, at most `tolerance` above the largest sampled value.

use rayon::prelude::*;

use super::grid::{distance, midpoint, SphereGrid};
use crate::robot::ClosedMesh;

/// The measured gap: `lower` is the largest sampled distance, attained at `worst_point`, and
/// `upper` the certified bound.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceGap {
    pub lower_m: f32,
    pub upper_m: f32,
    pub worst_point: [f32; 3],
}

const INV_SQRT3: f32 = 0.577_350_26;

/// Branch and bound of the surface gap (see the module doc). Deterministic: a triangle prunes
/// against the largest gap at any mesh vertex and what it sampled itself, never against what
/// other threads found meanwhile, so the same packing gives the same bits on any thread count.
pub fn surface_gap(mesh: &ClosedMesh, grid: &SphereGrid, tolerance_m: f32) -> SurfaceGap {
    let spheres = grid.spheres();
    // g at a point, and its nearest sphere.
    let g = |p: [f32; 3]| -> (f32, u32) {
        let (d, k) = grid.nearest_any(p).unwrap_or((f32::INFINITY, 0));
        (d.max(0.0), k)
    };
    let at_vertices = mesh
        .vertices
        .par_iter()
        .map(|&v| g(v).0)
        .reduce(|| 0.0, f32::max);
    let convex_bound = |corners: [[f32; 3]; 3], k: u32| -> f32 {
        let s = spheres.get(k as usize).map_or([0.0; 4], |s| {
            [s.center[0], s.center[1], s.center[2], s.radius]
        });
        corners
            .iter()
            .map(|v| distance(*v, [s[0], s[1], s[2]]) - s[3])
            .fold(f32::NEG_INFINITY, f32::max)
    };
    // Per triangle: (upper bound, (largest sampled gap, its point)); the largest, ties to the
    // lowest point, so that the reduction's shape does not matter.
    let largest = |x: (f32, (f32, [f32; 3])), y: (f32, (f32, [f32; 3]))| {
        let worst = match y.1 .0.total_cmp(&x.1 .0).then_with(|| {
            x.1 .1
                .iter()
                .zip(&y.1 .1)
                .map(|(a, b)| a.total_cmp(b))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        }) {
            std::cmp::Ordering::Greater => y.1,
            _ => x.1,
        };
        (x.0.max(y.0), worst)
    };
    let (upper, (lower, worst_point)) = mesh
        .triangles
        .par_iter()
        .map(|t| {
            let corner = |i: usize| mesh.vertices[t[i] as usize];
            let (a, b, c) = (corner(0), corner(1), corner(2));
            let mut stack = vec![(a, b, c, g(a), g(b), g(c))];
            let mut upper = 0.0f32;
            let mut worst = (0.0f32, a);
            while let Some((a, b, c, ga, gb, gc)) = stack.pop() {
                for (v, gv) in [(a, ga), (b, gb), (c, gc)] {
                    if gv.0 > worst.0 {
                        worst = (gv.0, v);
                    }
                }
                let longest = distance(a, b).max(distance(b, c)).max(distance(c, a));
                let lipschitz = ga.0.max(gb.0).max(gc.0) + longest * INV_SQRT3;
                let convex = [ga.1, gb.1, gc.1]
                    .iter()
                    .map(|&k| convex_bound([a, b, c], k))
                    .fold(f32::INFINITY, f32::min);
                // Round the bound up a little: it must stay above the true value in f32.
                let bound = lipschitz.min(convex.max(0.0)) * (1.0 + 1e-6) + 1e-9;
                let seen = at_vertices.max(worst.0);
                if bound <= seen + tolerance_m || longest * INV_SQRT3 <= tolerance_m {
                    upper = upper.max(bound);
                    continue;
                }
                let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
                let (gab, gbc, gca) = (g(ab), g(bc), g(ca));
                stack.push((a, ab, ca, ga, gab, gca));
                stack.push((ab, b, bc, gab, gb, gbc));
                stack.push((ca, bc, c, gca, gbc, gc));
                stack.push((ab, bc, ca, gab, gbc, gca));
            }
            (upper, worst)
        })
        .reduce(|| (0.0, (0.0, [0.0; 3])), largest);
    SurfaceGap {
        lower_m: lower,
        upper_m: upper,
        worst_point,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packing::InnerSphere;
    use crate::robot::mesh::tessellate_box;

    #[test]
    fn gap_of_a_cube_around_its_inscribed_ball() {
        let t = tessellate_box([2.0, 2.0, 2.0]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "cube").expect("closed");
        let mut grid = SphereGrid::new([-1.0; 3], [1.0; 3], 0.01);
        grid.insert(InnerSphere {
            center: [0.0; 3],
            radius: 1.0,
        });
        let gap = surface_gap(&mesh, &grid, 1e-4);
        // The corners are √3 from the centre.
        let exact = 3f32.sqrt() - 1.0;
        assert!((gap.lower_m - exact).abs() < 1e-5, "{gap:?}");
        assert!(
            gap.upper_m >= exact && gap.upper_m <= exact + 2e-4,
            "{gap:?}"
        );
    }
}
