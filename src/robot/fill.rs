//! The solid of a mesh whose shells together enclose space that no one shell does (a vendor's
//! visual mesh used for collision: a thin wall, closed at its ends by other parts), decided by
//! an exterior flood fill: the solid is everything the outside cannot reach.
//!
//! A grid of voxels (at most `MAX_VOXELS_PER_AXIS` along the longest side, with two layers of
//! margin) is laid over the mesh. A voxel that any triangle touches is *boundary* (exact
//! triangle–box overlap, separating axes in f64, on the voxel widened by a relative 1e-9); the
//! others are *pure*: no triangle crosses them, so each lies wholly in one component of space
//! minus the surface. The flood fill from the margin over face-adjacent pure voxels marks the
//! *exterior*; a pure voxel it does not reach is *interior*. A gap in the surface narrower than
//! a voxel cannot be crossed by the fill: such holes and slots are taken as closed (the voxel
//! size is reported).
//!
//! The solid's surface is the triangles that face the exterior: those touching a voxel with an
//! exterior voxel among its 26 neighbours. Triangles deep inside the solid (a wall's inner face,
//! the parts of overlapping shells inside each other) are dropped, so inner spheres grow across
//! them; a sphere's radius is bounded by the distance to the kept triangles, which is at most
//! the distance to the solid's boundary. Inside or outside for a point in a boundary voxel: the
//! label of a neighbouring pure voxel whose centre a segment reaches without crossing any
//! triangle; failing that, inside when the point is inside one of the closed shells the solid
//! was made of (their f64 winding number counted along rays, `robot::exact`: a wall thinner
//! than a voxel is still solid there, so spheres are packed into it); when neither decides (a
//! point on a shell's surface) the caller says which answer is safe (outside for the packing,
//! inside for a distance). A point in a boundary voxel with no exterior voxel among its 26
//! neighbours is inside without a test: any way from it to the outside passes through a gap
//! narrower than a voxel, which the fill takes as closed.
//!
//! Cost: O(voxels) memory (one byte each, ≤ 16.8 M) and time for the fill; a few triangle–box
//! tests per voxel a triangle's box covers.

use std::collections::VecDeque;

use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;

use super::surface::ExactSurface;
use crate::geometry::bounds_f64;

/// Voxels along the longest side of the mesh's box.
pub const MAX_VOXELS_PER_AXIS: usize = 256;
const MARGIN: usize = 2;

const EXTERIOR: u8 = 0;
const BOUNDARY: u8 = 1;
const INTERIOR: u8 = 2;
/// A boundary voxel with an exterior voxel among its 26 neighbours.
const FACING: u8 = 3;
/// Not yet reached by the fill.
const UNKNOWN: u8 = 4;

/// Voxel labels of a filled solid, and every triangle of its mesh for the segment tests.
pub struct Fill {
    origin: [f64; 3],
    pub voxel_m: f64,
    dims: [usize; 3],
    labels: Vec<u8>,
    surface: TriMesh,
    /// The closed, outward-oriented shells among the triangles: everything inside one of them
    /// is in the solid.
    shells: Vec<ExactSurface>,
}

impl std::fmt::Debug for Fill {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fill")
            .field("voxel_m", &self.voxel_m)
            .field("dims", &self.dims)
            .finish()
    }
}

impl Fill {
    /// The fill of `triangles`, and for each triangle whether it faces the exterior. `shells`
    /// are the closed, outward-oriented shells among the triangles. `None` when parry3d
    /// refuses the triangles (none left).
    pub fn new(
        vertices: &[[f32; 3]],
        triangles: &[[u32; 3]],
        shells: Vec<ExactSurface>,
    ) -> Option<(Self, Vec<bool>)> {
        let (lo, hi) = bounds_f64(vertices);
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let voxel_m = extent / MAX_VOXELS_PER_AXIS as f64;
        let origin = lo.map(|x| x - MARGIN as f64 * voxel_m);
        let dims: [usize; 3] =
            std::array::from_fn(|k| ((hi[k] - lo[k]) / voxel_m).ceil() as usize + 1 + 2 * MARGIN);
        let surface = TriMesh::new(
            vertices
                .iter()
                .map(|v| Vector::new(v[0], v[1], v[2]))
                .collect(),
            triangles.to_vec(),
        )
        .ok()?;
        let mut fill = Self {
            origin,
            voxel_m,
            dims,
            labels: vec![UNKNOWN; dims[0] * dims[1] * dims[2]],
            surface,
            shells,
        };
        let corners = |t: &[u32; 3]| t.map(|i| vertices[i as usize].map(f64::from));
        for t in triangles {
            fill.touched(corners(t), |f, i| f.labels[i] = BOUNDARY);
        }
        fill.flood();
        let mut facing = vec![false; triangles.len()];
        for (t, f) in triangles.iter().zip(&mut facing) {
            fill.touched(corners(t), |fill, i| {
                if fill.labels[i] == FACING {
                    *f = true;
                }
            });
        }
        Some((fill, facing))
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    fn cell(&self, p: [f64; 3]) -> Option<[usize; 3]> {
        let mut c = [0; 3];
        for k in 0..3 {
            let x = ((p[k] - self.origin[k]) / self.voxel_m).floor();
            if x < 0.0 || x >= self.dims[k] as f64 {
                return None;
            }
            c[k] = x as usize;
        }
        Some(c)
    }

    fn centre(&self, c: [usize; 3]) -> [f64; 3] {
        std::array::from_fn(|k| self.origin[k] + (c[k] as f64 + 0.5) * self.voxel_m)
    }

    /// Calls `f` with every voxel the triangle touches.
    fn touched(&mut self, t: [[f64; 3]; 3], mut f: impl FnMut(&mut Self, usize)) {
        let lo: [f64; 3] = std::array::from_fn(|k| t[0][k].min(t[1][k]).min(t[2][k]));
        let hi: [f64; 3] = std::array::from_fn(|k| t[0][k].max(t[1][k]).max(t[2][k]));
        let a = self.cell(lo).unwrap_or([0; 3]);
        let b = self.cell(hi).unwrap_or(self.dims.map(|d| d - 1));
        let half = 0.5 * self.voxel_m * (1.0 + 1e-9);
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    let c = self.centre([x, y, z]);
                    if triangle_box_overlap(t, c, half) {
                        let i = self.index([x, y, z]);
                        f(self, i);
                    }
                }
            }
        }
    }

    /// Exterior from the margin over face-adjacent pure voxels; then interior and facing.
    fn flood(&mut self) {
        let [nx, ny, nz] = self.dims;
        let mut queue = VecDeque::new();
        self.labels[0] = EXTERIOR;
        queue.push_back([0usize, 0, 0]);
        while let Some(c) = queue.pop_front() {
            for (k, step) in [(0, -1i64), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1)] {
                let v = c[k] as i64 + step;
                if v < 0 || v >= self.dims[k] as i64 {
                    continue;
                }
                let mut n = c;
                n[k] = v as usize;
                let i = self.index(n);
                if self.labels[i] == UNKNOWN {
                    self.labels[i] = EXTERIOR;
                    queue.push_back(n);
                }
            }
        }
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let i = self.index([x, y, z]);
                    match self.labels[i] {
                        UNKNOWN => self.labels[i] = INTERIOR,
                        BOUNDARY if self.near_exterior([x, y, z]) => self.labels[i] = FACING,
                        _ => {}
                    }
                }
            }
        }
    }

    fn neighbours(&self, c: [usize; 3]) -> impl Iterator<Item = [usize; 3]> + '_ {
        (0..27).filter(|&n| n != 13).filter_map(move |n| {
            let d = [n % 3, (n / 3) % 3, n / 9];
            let mut m = [0; 3];
            for k in 0..3 {
                let v = c[k] as i64 + d[k] as i64 - 1;
                if v < 0 || v >= self.dims[k] as i64 {
                    return None;
                }
                m[k] = v as usize;
            }
            Some(m)
        })
    }

    fn near_exterior(&self, c: [usize; 3]) -> bool {
        self.neighbours(c)
            .any(|n| self.labels[self.index(n)] == EXTERIOR)
    }

    /// Whether `p` (link frame) is in the solid; `ambiguous` is the answer when `p` lies in a
    /// boundary voxel, no segment to a pure neighbour is free of triangles and no closed shell
    /// holds it.
    pub fn contains(&self, p: [f64; 3], ambiguous: bool) -> bool {
        let Some(c) = self.cell(p) else {
            return false;
        };
        match self.labels[self.index(c)] {
            EXTERIOR => false,
            INTERIOR => true,
            // No exterior voxel among its neighbours: any way out leads through a gap narrower
            // than a voxel, which the fill takes as closed.
            BOUNDARY => true,
            _ => {
                for n in self.neighbours(c) {
                    let label = self.labels[self.index(n)];
                    if label != EXTERIOR && label != INTERIOR {
                        continue;
                    }
                    let q = self.centre(n);
                    let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    let ray = Ray::new(
                        Vector::new(p[0] as f32, p[1] as f32, p[2] as f32),
                        Vector::new(
                            (d[0] / len) as f32,
                            (d[1] / len) as f32,
                            (d[2] / len) as f32,
                        ),
                    );
                    // A margin for the f32 ray: a hit just past the centre still blocks.
                    if self
                        .surface
                        .cast_local_ray(&ray, (len * (1.0 + 1e-4)) as f32, false)
                        .is_none()
                    {
                        return label == INTERIOR;
                    }
                }
                // On a shell's surface (no ray decides) the caller's answer stands.
                self.shells
                    .iter()
                    .any(|s| s.contains_by_rays(p) == Some(true))
                    || ambiguous
            }
        }
    }

    /// Volume of the solid: interior voxels and half the boundary ones, m³.
    pub fn volume_m3(&self) -> f64 {
        let (mut inside, mut boundary) = (0usize, 0usize);
        for &l in &self.labels {
            match l {
                INTERIOR => inside += 1,
                BOUNDARY | FACING => boundary += 1,
                _ => {}
            }
        }
        (inside as f64 + 0.5 * boundary as f64) * self.voxel_m.powi(3)
    }

    /// Whether no voxel is interior or deep boundary: the fill found nothing enclosed.
    pub fn encloses_nothing(&self) -> bool {
        !self.labels.iter().any(|&l| l == INTERIOR || l == BOUNDARY)
    }

    /// The labels, for the tree cache's key.
    pub fn labels(&self) -> &[u8] {
        &self.labels
    }
}

/// Triangle–box overlap by separating axes (Akenine-Möller): the box's 3 axes, the triangle's
/// normal and the 9 cross products of edges and axes.
fn triangle_box_overlap(t: [[f64; 3]; 3], centre: [f64; 3], half: f64) -> bool {
    let v: [[f64; 3]; 3] = t.map(|p| std::array::from_fn(|k| p[k] - centre[k]));
    let e: [[f64; 3]; 3] = std::array::from_fn(|i| {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
    });
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let separated = |axis: [f64; 3]| {
        let p = v.map(|x| dot(x, axis));
        let r = half * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        lo > r || hi < -r
    };
    let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if axes.iter().any(|&a| separated(a)) {
        return false;
    }
    if separated(cross(e[0], e[1])) {
        return false;
    }
    for edge in e {
        for a in axes {
            let axis = cross(edge, a);
            if dot(axis, axis) > 0.0 && separated(axis) {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_by_separating_axes() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(triangle_box_overlap(t, [0.2, 0.2, 0.0], 0.1));
        assert!(triangle_box_overlap(t, [0.2, 0.2, 0.09], 0.1));
        assert!(!triangle_box_overlap(t, [0.2, 0.2, 0.11], 0.1));
        // Beyond the hypotenuse, inside the triangle's bounding box.
        assert!(!triangle_box_overlap(t, [0.8, 0.8, 0.0], 0.1));
        assert!(triangle_box_overlap(t, [0.55, 0.55, 0.0], 0.1));
    }
}
