//! A mesh exclusion volume: the solid of a mesh file (a fixture's or a conveyor's CAD export),
//! dilated by `padding`, tested per point in O(1) on a grid of signed distances.
//!
//! The file goes through the robot's intake (`robot::urdf::load_shape`: read, welded, closed,
//! filled where its shells leave gaps), so that a mesh a CAD tool exported is taken as a link's
//! would be. A grid of at most [`MAX_CELLS`] voxels along a side of the dilated box (and about [`MAX_VOXELS`] in all: a thin table gets small voxels) holds, at each voxel's
//! centre `c`, the signed distance `s(c)` to the solid's surface
//! (positive inside, the largest over its shells: the union), computed once in parallel.
//!
//! A point `p` is excluded when `s(c) − |p − c| ≥ −padding` for the centre `c` of its voxel.
//! The signed distance is 1-Lipschitz, so `s(p) ≥ s(c) − |p − c|`: every point excluded lies
//! inside the solid or within `padding` of it (never a point beyond), and every point within
//! `padding − √3·voxel` of the solid is excluded (`s(c) ≥ s(p) − |p − c|` and `|p − c|` is at
//! most half a diagonal). Between the two, in a band one voxel diagonal thick at the padding's
//! edge, a point may be kept: the safe side (a point kept is measured). Give `padding` at
//! least the voxel diagonal (reported in the log) for the mesh's own surface points to go.
//!
//! Cost: the grid (about 2 M floats, 8 MiB) and one signed-distance query per voxel at load
//! (about a second for a few thousand triangles on 2 cores); per point a lookup and a
//! distance.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::geometry::{Shape, P3};
use crate::robot::solid::Solid;

/// Voxels along a side of the grid, at most.
pub const MAX_CELLS: usize = 512;
/// Voxels in the grid, about: 8 MiB of signed distances.
pub const MAX_VOXELS: usize = 1 << 21;

/// The signed-distance grid of a mesh file's solid, dilated by `padding_m` (see the module doc).
pub struct MeshGrid {
    pub file: PathBuf,
    pub scale: P3,
    pub padding_m: f64,
    /// Edge of a voxel, m.
    pub voxel_m: f64,
    /// The grid's corner and size, in voxels, in the volume's frame.
    origin: [f32; 3],
    dims: [usize; 3],
    /// The signed distance at each voxel's centre (x fastest), positive inside.
    depth: Vec<f32>,
}

impl std::fmt::Debug for MeshGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshGrid")
            .field("file", &self.file)
            .field("scale", &self.scale)
            .field("padding_m", &self.padding_m)
            .field("voxel_m", &self.voxel_m)
            .field("dims", &self.dims)
            .finish()
    }
}

impl MeshGrid {
    /// The grid of `file` scaled by `scale`, dilated by `padding_m`; an error says why the
    /// file cannot be a volume (unreadable, or enclosing nothing).
    pub fn build(file: &Path, scale: P3, padding_m: f64) -> Result<Self, String> {
        let shape = Shape::Mesh {
            file: file.to_owned(),
            scale,
        };
        let (elements, _) = crate::robot::urdf::load_shape("exclusion volume", &shape.to_urdf())
            .map_err(|e| e.to_string())?;
        let solids: Vec<Solid> = elements
            .iter()
            .map(|e| Solid::try_new(&e.mesh))
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{}: {e}", file.display()))?;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for s in &solids {
            let (l, h) = s.bounds();
            for k in 0..3 {
                lo[k] = lo[k].min(f64::from(l[k]));
                hi[k] = hi[k].max(f64::from(h[k]));
            }
        }
        if solids.is_empty()
            || lo
                .iter()
                .zip(&hi)
                .any(|(l, h)| l.partial_cmp(h).is_none_or(|o| o.is_gt()))
        {
            return Err(format!("{}: no solid in the mesh", file.display()));
        }
        let extent: [f64; 3] = std::array::from_fn(|k| hi[k] - lo[k] + 2.0 * padding_m);
        let longest = extent.iter().copied().fold(0.0, f64::max);
        let voxel_m = ((extent
            .iter()
            .map(|e| e.max(longest * 1e-3))
            .product::<f64>()
            / MAX_VOXELS as f64)
            .cbrt())
        .max(longest / (MAX_CELLS - 2) as f64)
        .max(1e-6);
        // One voxel of margin beyond the padding on every side: a point within the padding
        // always has its voxel in the grid.
        let origin: [f64; 3] = std::array::from_fn(|k| lo[k] - padding_m - voxel_m);
        let dims: [usize; 3] = std::array::from_fn(|k| {
            (((hi[k] - lo[k] + 2.0 * padding_m) / voxel_m).ceil() as usize + 2).min(MAX_CELLS + 2)
        });
        let n = dims[0] * dims[1] * dims[2];
        let depth = (0..n)
            .into_par_iter()
            .map(|i| {
                let idx = [
                    i % dims[0],
                    (i / dims[0]) % dims[1],
                    i / (dims[0] * dims[1]),
                ];
                let c: [f32; 3] =
                    std::array::from_fn(|k| (origin[k] + (idx[k] as f64 + 0.5) * voxel_m) as f32);
                solids
                    .iter()
                    .map(|s| s.signed_distance(c).0)
                    .fold(f32::NEG_INFINITY, f32::max)
            })
            .collect();
        log::info!(
            "exclusion mesh {}: {} shells, grid {}×{}×{} of {:.1} mm voxels (points within {:.1} \
             mm of the padding's edge may be kept)",
            file.display(),
            solids.len(),
            dims[0],
            dims[1],
            dims[2],
            voxel_m * 1e3,
            voxel_m * 3f64.sqrt() * 1e3
        );
        Ok(Self {
            file: file.to_owned(),
            scale,
            padding_m,
            voxel_m,
            origin: origin.map(|x| x as f32),
            dims,
            depth,
        })
    }

    /// The grid's box in the volume's frame: a point outside it is never excluded.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let lo = self.origin.map(f64::from);
        let hi = std::array::from_fn(|k| lo[k] + self.dims[k] as f64 * self.voxel_m);
        (lo, hi)
    }

    /// Whether volume-frame point `q` is excluded (see the module doc); NaN is not.
    #[inline]
    pub fn contains(&self, q: [f32; 3]) -> bool {
        let v = self.voxel_m as f32;
        let mut i = 0usize;
        let mut stride = 1usize;
        let mut d2 = 0.0f32;
        for (k, &qk) in q.iter().enumerate() {
            let x = (qk - self.origin[k]) / v;
            // NaN and points off the grid fail here.
            if !(x >= 0.0 && x < self.dims[k] as f32) {
                return false;
            }
            let cell = (x as usize).min(self.dims[k] - 1);
            let off = (x - (cell as f32 + 0.5)) * v;
            d2 += off * off;
            i += cell * stride;
            stride *= self.dims[k];
        }
        self.depth[i] - d2.sqrt() >= -(self.padding_m as f32)
    }
}

impl PartialEq for MeshGrid {
    /// The same file, scale and padding: the same volume.
    fn eq(&self, other: &Self) -> bool {
        (&self.file, self.scale, self.padding_m) == (&other.file, other.scale, other.padding_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 0.4 × 0.3 × 0.2 m box as an STL file, dilated by 3 cm: every point excluded is within
    /// the padding of the box (never beyond), and every point within the padding less a voxel
    /// diagonal is excluded; checked against the box's exact distance on a lattice through it.
    #[test]
    fn a_mesh_volume_takes_the_dilated_solid_and_never_more() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("box.stl");
        let half = [0.2f32, 0.15, 0.1];
        let t = crate::robot::mesh::tessellate_box(half.map(|h| 2.0 * h as f64));
        std::fs::write(&file, t.to_ascii_stl()).unwrap();
        let padding = 0.03;
        let grid = MeshGrid::build(&file, [1.0; 3], padding).unwrap();
        let band = grid.voxel_m * 3f64.sqrt();
        let (mut excluded, mut checked) = (0, 0);
        for i in 0..60 {
            for j in 0..50 {
                for k in 0..40 {
                    let p = [
                        -0.3 + 0.01 * i as f64,
                        -0.25 + 0.01 * j as f64,
                        -0.2 + 0.01 * k as f64,
                    ]
                    .map(|x| x + 0.0013);
                    // Distance to the box (0 inside).
                    let out: f64 = (0..3)
                        .map(|a| (p[a].abs() - f64::from(half[a])).max(0.0).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    let taken = grid.contains(p.map(|x| x as f32));
                    assert!(!taken || out <= padding + 1e-4, "{p:?} at {out} m taken");
                    assert!(
                        taken || out > padding - band - 1e-4,
                        "{p:?} at {out} m kept"
                    );
                    excluded += usize::from(taken);
                    checked += 1;
                }
            }
        }
        assert!(excluded > 0 && excluded < checked);
        assert!(!grid.contains([f32::NAN, 0.0, 0.0]));
        let e = MeshGrid::build(&dir.path().join("none.stl"), [1.0; 3], 0.0).unwrap_err();
        assert!(e.contains("none.stl"), "{e}");
    }
}
