//! The cells that place the volume pass's prototypes: a first grid over the link's bounding box
//! (one prototype per cell, jittered), then, when the spheres become small against the cells,
//! each live cell split in eight, keeping the children that may still hold free space and
//! starting prototypes at those with room for a sphere. Sizes in metres, link frame.

use rayon::prelude::*;

use super::grid::SphereGrid;
use super::prototype::Prototype;
use crate::robot::solid::Solid;

/// Half the diagonal of a unit cube.
const HALF_DIAGONAL: f32 = 0.866_025_4;
/// Live cells kept per prototype allowed, when the cells are split.
const CELLS_PER_PROTOTYPE: usize = 2;

/// A deterministic offset in [-0.25, 0.25) of a cell, from its coordinates.
fn jitter(cell: [i64; 3], axis: usize) -> f32 {
    let mut h = (cell[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (cell[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (cell[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ (axis as u64).wrapping_mul(0x27D4_EB2F_1656_67C5);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h >> 40) as f32 / (1u64 << 24) as f32 * 0.5 - 0.25
}

/// The first grid over the box `lo`..`hi`, cells sized for about `count` prototypes: a
/// prototype at every cell centre (jittered) inside the solid, and the cells that reach the solid
/// (kept for refinement). Returns the cells, the prototypes and the cell size, m.
pub(super) fn first_grid(
    solid: &Solid,
    lo: [f32; 3],
    hi: [f32; 3],
    count: u32,
) -> (Vec<[f32; 3]>, Vec<Prototype>, f32) {
    let box_volume: f64 = (0..3).map(|k| (hi[k] - lo[k]) as f64).product();
    let cell = (box_volume / count.max(1) as f64).cbrt() as f32;
    let counts =
        std::array::from_fn::<usize, 3, _>(|k| ((hi[k] - lo[k]) / cell).ceil().max(1.0) as usize);
    let first: Vec<[i64; 3]> = (0..counts[2])
        .flat_map(|z| {
            (0..counts[1])
                .flat_map(move |y| (0..counts[0]).map(move |x| [x as i64, y as i64, z as i64]))
        })
        .collect();
    let centre = |c: [i64; 3], jittered: bool| -> [f32; 3] {
        std::array::from_fn(|k| {
            let offset = if jittered { jitter(c, k) } else { 0.0 };
            lo[k] + (c[k] as f32 + 0.5 + offset) * cell
        })
    };
    let seeded: Vec<([i64; 3], f32, [f32; 3])> = first
        .par_iter()
        .map(|&c| {
            let p = centre(c, true);
            (c, solid.signed_distance(p).0, p)
        })
        .collect();
    let mut cells = Vec::new();
    let mut prototypes = Vec::new();
    for (c, d, p) in seeded {
        if d > -cell * HALF_DIAGONAL {
            cells.push(centre(c, false));
        }
        if d > 0.0 {
            prototypes.push(Prototype::at(p));
        }
    }
    (cells, prototypes, cell)
}

/// Splits every live cell in eight, keeps the children that may still hold free space, and
/// returns the children whose centre has room for a sphere, largest room first.
pub(super) fn refine(
    solid: &Solid,
    grid: &SphereGrid,
    cells: &mut Vec<[f32; 3]>,
    size: f32,
    min_radius: f32,
    room: usize,
) -> Vec<(f32, [f32; 3])> {
    let half = size * 0.5;
    let half_diagonal = size * HALF_DIAGONAL;
    let children: Vec<(f32, [f32; 3])> = cells
        .par_iter()
        .flat_map_iter(|c| {
            (0..8).map(move |i| {
                std::array::from_fn::<f32, 3, _>(|k| {
                    c[k] + if i >> k & 1 == 1 { half } else { -half }
                })
            })
        })
        .map(|p| {
            let (d_mesh, _) = solid.signed_distance(p);
            let room = match grid.nearest(p, d_mesh) {
                Some((d, _)) => d,
                None => d_mesh,
            };
            (room, p)
        })
        .filter(|(room, _)| *room > -half_diagonal)
        .collect();
    // Keep the roomiest cells: no more than the remaining budget can use.
    let mut children = children;
    children.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    children.truncate(CELLS_PER_PROTOTYPE * room.max(1));
    *cells = children.iter().map(|(_, p)| *p).collect();
    children.retain(|(room, _)| *room > min_radius);
    children
}
