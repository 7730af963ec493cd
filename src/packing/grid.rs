//! A multi-level uniform grid over the inner spheres of one link, for "nearest sphere surface
//! below a bound" queries during packing and gap measurement.
//!
//! Level k has cells of size `cell₀·2ᵏ` and holds the spheres whose radius is at most half a
//! cell, each in the one cell that holds its centre (a linked list through `next`), so an
//! insertion is O(1). A query at p with bound b visits, on each level, the cells within
//! `b + max_radius(level)` of p: spheres of very different sizes each stay cheap to find.
//! Cost per query: a few dozen cells per non-empty level once b is of the order of the spheres.

use super::sphere::InnerSphere;

const NONE: u32 = u32::MAX;

struct Level {
    cell: f32,
    inv_cell: f32,
    dims: [usize; 3],
    heads: Vec<u32>,
    max_radius: f32,
}

/// Inner spheres of a link with a grid for nearest-surface queries.
pub struct SphereGrid {
    origin: [f32; 3],
    levels: Vec<Level>,
    next: Vec<u32>,
    spheres: Vec<InnerSphere>,
}

/// Finest cells per axis: bounds the memory of the finest level to 128³ heads (8 MiB).
const MAX_CELLS_PER_AXIS: f32 = 128.0;

impl SphereGrid {
    /// A grid over the box `lo..hi` whose finest cells are at least `finest_cell` wide.
    pub fn new(lo: [f32; 3], hi: [f32; 3], finest_cell: f32) -> Self {
        let size = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        let extent = size.iter().copied().fold(f32::MIN_POSITIVE, f32::max);
        let mut cell = finest_cell.max(extent / MAX_CELLS_PER_AXIS);
        let mut levels = Vec::new();
        loop {
            let dims = size.map(|s| (s / cell).floor() as usize + 1);
            levels.push(Level {
                cell,
                inv_cell: 1.0 / cell,
                dims,
                heads: vec![NONE; dims[0] * dims[1] * dims[2]],
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

    fn cell_of(&self, level: &Level, p: [f32; 3]) -> [usize; 3] {
        std::array::from_fn(|k| {
            (((p[k] - self.origin[k]) * level.inv_cell).max(0.0) as usize).min(level.dims[k] - 1)
        })
    }

    pub fn insert(&mut self, sphere: InnerSphere) {
        let index = self.spheres.len() as u32;
        let last = self.levels.len() - 1;
        let k = self
            .levels
            .iter()
            .position(|l| sphere.radius <= 0.5 * l.cell)
            .unwrap_or(last);
        let c = self.cell_of(&self.levels[k], sphere.center);
        let level = &mut self.levels[k];
        let slot = (c[2] * level.dims[1] + c[1]) * level.dims[0] + c[0];
        self.next.push(level.heads[slot]);
        level.heads[slot] = index;
        level.max_radius = level.max_radius.max(sphere.radius);
        self.spheres.push(sphere);
    }

    /// The sphere whose surface is nearest to `p` (signed: negative inside it), if that distance
    /// is below `bound`.
    pub fn nearest(&self, p: [f32; 3], bound: f32) -> Option<(f32, u32)> {
        let mut best = bound;
        let mut found = None;
        for level in &self.levels {
            if level.max_radius == 0.0 {
                continue;
            }
            let reach = best + level.max_radius;
            if reach <= 0.0 {
                continue;
            }
            let lo = self.cell_of(level, p.map(|x| x - reach));
            let hi = self.cell_of(level, p.map(|x| x + reach));
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    let row = (z * level.dims[1] + y) * level.dims[0];
                    for x in lo[0]..=hi[0] {
                        let mut i = level.heads[row + x];
                        while i != NONE {
                            let s = &self.spheres[i as usize];
                            let d = distance(p, s.center) - s.radius;
                            if d < best {
                                best = d;
                                found = Some(i);
                            }
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
        let mut bound = self.levels[0].cell;
        let limit = self.levels[self.levels.len() - 1].cell * 4.0;
        loop {
            if let Some(found) = self.nearest(p, bound) {
                return Some(found);
            }
            if bound > limit {
                return self.nearest(p, f32::INFINITY);
            }
            bound *= 2.0;
        }
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
    }
}
