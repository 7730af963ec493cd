//! A multi-level uniform grid over the inner spheres of one link, for "nearest sphere surface
//! below a bound" queries during packing and gap measurement.
//!
//! Level k has cells of size `cell₀·2ᵏ` (cell₀ = twice the smallest radius) and holds the
//! spheres whose radius is at most half a cell, each in the one cell that holds its centre (a
//! linked list through `next`), so an insertion is O(1) and a cell holds O(1) spheres of its
//! level. Coarse levels store their cells densely; a level with more than 2²² cells (the fine
//! levels of a large link: 0.3 mm cells on a metre) hashes its cells into a table twice the
//! size of its spheres (spatial hashing: two cells may share a list, which only adds candidates).
//!
//! A query at p with bound b visits, on each level, the cells within `b + max_radius(level)`
//! of p, or, where those cells outnumber twice the level's spheres, the level's spheres
//! themselves: never more than that. A small bound (under 16 finest cells: a point near the
//! surface) goes from the finest level to the coarsest, where its small spheres are; a larger
//! one from the coarsest to the finest, so that the few large spheres deep inside shrink b
//! before the fine levels, which hold most spheres, are searched. `nearest_any` tries the
//! small bound first, then an unbounded one.
//!
//! The spheres found are the same as with the earlier grid (finest cells capped at the link's
//! extent/128, 3 mm on a 0.4 m link, so every sphere under 1.5 mm shared level 0, searched
//! first with the full bound): the packings are identical, byte for byte, and their time fell by
//! up to a third, none on small links (docs/robots.md, "Where a first build's time goes").

use super::sphere::InnerSphere;

const NONE: u32 = u32::MAX;

/// Levels with more cells than this are hashed.
const DENSE_MAX_CELLS: usize = 1 << 22;

/// Below this many finest cells a bound is small (the fine levels are searched first), and
/// `nearest_any` tries it before an unbounded search.
const SMALL_BOUND_CELLS: f32 = 16.0;

/// The first table of a hashed level (slots; a power of two).
const HASHED_FIRST_SLOTS: usize = 1024;

struct Level {
    cell: f32,
    inv_cell: f32,
    dims: [usize; 3],
    /// Dense: one head per cell. Hashed: a power-of-two table, slot = hash(cell) & mask.
    heads: Vec<u32>,
    hashed: bool,
    /// The level's spheres, in insertion order.
    members: Vec<u32>,
    max_radius: f32,
}

impl Level {
    fn slot(&self, c: [usize; 3]) -> usize {
        if self.hashed {
            let h = (c[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                ^ (c[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
                ^ (c[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
            ((h ^ (h >> 29)) as usize) & (self.heads.len() - 1)
        } else {
            (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
        }
    }

    /// Puts sphere `i` at the head of its cell's list.
    fn link(&mut self, origin: [f32; 3], spheres: &[InnerSphere], next: &mut [u32], i: u32) {
        let slot = self.slot(self.cell_of(origin, spheres[i as usize].center));
        next[i as usize] = self.heads[slot];
        self.heads[slot] = i;
    }

    fn cell_of(&self, origin: [f32; 3], p: [f32; 3]) -> [usize; 3] {
        std::array::from_fn(|k| {
            (((p[k] - origin[k]) * self.inv_cell).max(0.0) as usize).min(self.dims[k] - 1)
        })
    }
}

/// Inner spheres of a link with a grid for nearest-surface queries.
pub struct SphereGrid {
    origin: [f32; 3],
    levels: Vec<Level>,
    next: Vec<u32>,
    spheres: Vec<InnerSphere>,
}

impl SphereGrid {
    /// A grid over the box `lo..hi` whose finest cells are `finest_cell` wide (at least 1e-6 of
    /// the box's extent).
    pub fn new(lo: [f32; 3], hi: [f32; 3], finest_cell: f32) -> Self {
        let size = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        let extent = size.iter().copied().fold(f32::MIN_POSITIVE, f32::max);
        let mut cell = finest_cell.max(extent * 1e-6);
        let mut levels = Vec::new();
        loop {
            let dims = size.map(|s| (s / cell).floor() as usize + 1);
            let cells = dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
            let hashed = cells.is_none_or(|n| n > DENSE_MAX_CELLS);
            levels.push(Level {
                cell,
                inv_cell: 1.0 / cell,
                dims,
                heads: vec![
                    NONE;
                    if hashed {
                        HASHED_FIRST_SLOTS
                    } else {
                        cells.unwrap_or(0)
                    }
                ],
                hashed,
                members: Vec::new(),
                max_radius: 0.0,
            });
            if cell >= extent {
                break;
            }
            cell *= 2.0;
        }
        Self {
            origin: lo,
            levels,
            next: Vec::new(),
            spheres: Vec::new(),
        }
    }

    pub fn spheres(&self) -> &[InnerSphere] {
        &self.spheres
    }

    pub fn into_spheres(self) -> Vec<InnerSphere> {
        self.spheres
    }

    pub fn insert(&mut self, sphere: InnerSphere) {
        let index = self.spheres.len() as u32;
        self.spheres.push(sphere);
        self.next.push(NONE);
        let last = self.levels.len() - 1;
        let k = self
            .levels
            .iter()
            .position(|l| sphere.radius <= 0.5 * l.cell)
            .unwrap_or(last);
        let origin = self.origin;
        let level = &mut self.levels[k];
        level.members.push(index);
        level.max_radius = level.max_radius.max(sphere.radius);
        if level.hashed && 2 * level.members.len() > level.heads.len() {
            // Twice the slots, every list relinked in insertion order (as if built anew).
            level.heads = vec![NONE; 2 * level.heads.len()];
            for m in 0..level.members.len() {
                level.link(origin, &self.spheres, &mut self.next, level.members[m]);
            }
        } else {
            level.link(origin, &self.spheres, &mut self.next, index);
        }
    }

    /// The sphere whose surface is nearest to `p` (signed: negative inside it), if that distance
    /// is below `bound`.
    pub fn nearest(&self, p: [f32; 3], bound: f32) -> Option<(f32, u32)> {
        let mut best = bound;
        let mut found = None;
        let mut consider = |i: u32, best: &mut f32| {
            let s = &self.spheres[i as usize];
            let d = distance(p, s.center) - s.radius;
            if d < *best {
                *best = d;
                found = Some(i);
            }
        };
        // A small bound: the fine levels first (near the surface, where the small spheres are);
        // a large one: the coarse levels first, whose few large spheres shrink it.
        let fine_first = bound < SMALL_BOUND_CELLS * self.levels[0].cell;
        let n = self.levels.len();
        for j in 0..n {
            let level = &self.levels[if fine_first { j } else { n - 1 - j }];
            let reach = best + level.max_radius;
            if level.members.is_empty() || reach <= 0.0 {
                continue;
            }
            let lo = level.cell_of(self.origin, p.map(|x| x - reach));
            let hi = level.cell_of(self.origin, p.map(|x| x + reach));
            let cells = (0..3).map(|k| hi[k] + 1 - lo[k]).product::<usize>();
            if cells > 2 * level.members.len() {
                // Fewer spheres than cells to visit: the spheres themselves.
                for &i in &level.members {
                    consider(i, &mut best);
                }
                continue;
            }
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let mut i = level.heads[level.slot([x, y, z])];
                        while i != NONE {
                            consider(i, &mut best);
                            i = self.next[i as usize];
                        }
                    }
                }
            }
        }
        found.map(|i| (best, i))
    }

    /// The sphere whose surface is nearest to `p`, at any distance (None without spheres).
    pub fn nearest_any(&self, p: [f32; 3]) -> Option<(f32, u32)> {
        // Most queries are near the surface, with a sphere within a few cells: that search first.
        (self.nearest(p, SMALL_BOUND_CELLS * self.levels[0].cell))
            .or_else(|| self.nearest(p, f32::INFINITY))
    }

    /// Distance from `p` to the union of the spheres (0 inside one), or +∞ without spheres.
    pub fn distance_to_union(&self, p: [f32; 3]) -> f32 {
        self.nearest_any(p)
            .map_or(f32::INFINITY, |(d, _)| d.max(0.0))
    }
}

#[inline]
pub fn midpoint(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|k| 0.5 * (a[k] + b[k]))
}

#[inline]
pub fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The grid finds exactly what a scan over all spheres finds.
        #[test]
        fn nearest_matches_brute_force(
            spheres in prop::collection::vec(
                (prop::array::uniform3(0.0f32..1.0), 0.0005f32..0.2), 1..200),
            queries in prop::collection::vec(prop::array::uniform3(-0.2f32..1.2), 1..20),
            bound in 0.001f32..2.0,
        ) {
            let mut grid = SphereGrid::new([0.0; 3], [1.0; 3], 0.001);
            for (center, radius) in &spheres {
                grid.insert(InnerSphere { center: *center, radius: *radius });
            }
            for q in queries {
                let brute = spheres
                    .iter()
                    .map(|(c, r)| distance(q, *c) - r)
                    .fold(f32::INFINITY, f32::min);
                match grid.nearest(q, bound) {
                    Some((d, _)) => prop_assert!((d - brute).abs() < 1e-6),
                    None => prop_assert!(brute >= bound - 1e-6),
                }
                prop_assert!((grid.distance_to_union(q) - brute.max(0.0)).abs() < 1e-6);
            }
        }

        /// The same on a hashed level that outgrows its table (1,500 spheres of the finest
        /// level, whose 0.3 mm cells on a 0.5 m box are hashed, rehashed twice), with queries
        /// near them and bounds from below their size to beyond the box.
        #[test]
        fn a_hashed_level_finds_what_a_scan_finds(
            seed in prop::collection::vec(prop::array::uniform3(0.0f32..0.5), 1500),
            queries in prop::collection::vec(
                (0usize..1500, prop::array::uniform3(-0.003f32..0.003)), 1..40),
            bound in prop::sample::select(vec![0.0002f32, 0.002, 0.02, f32::INFINITY]),
        ) {
            let mut grid = SphereGrid::new([0.0; 3], [0.5; 3], 0.0003);
            prop_assert!(grid.levels[0].hashed);
            for (i, center) in seed.iter().enumerate() {
                let radius = 0.0001 + 0.000025 * (i % 3) as f32;
                grid.insert(InnerSphere { center: *center, radius });
            }
            prop_assert!(grid.levels[0].heads.len() >= 2 * 1500);
            for (near, offset) in queries {
                let q = std::array::from_fn(|k| seed[near][k] + offset[k]);
                let brute = (grid.spheres().iter())
                    .map(|s| distance(q, s.center) - s.radius)
                    .fold(f32::INFINITY, f32::min);
                match grid.nearest(q, bound) {
                    Some((d, i)) => {
                        prop_assert!((d - brute).abs() < 1e-7);
                        let s = grid.spheres()[i as usize];
                        prop_assert!((distance(q, s.center) - s.radius - d).abs() < 1e-7);
                    }
                    None => prop_assert!(brute >= bound),
                }
            }
        }
    }
}
