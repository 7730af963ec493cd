//! The self-filter's grid: for one link and one padding, which cells of a regular grid in the
//! link frame lie wholly within the padding of the link's inner spheres, wholly beyond it, or
//! across it. The CPU's self-filter looks a point up in it and descends the tree only for a
//! point in a cell across the padding (a thin shell), instead of one descent per point near the
//! robot.
//!
//! The inner spheres' signed distance `d(x) = min_s |x − c_s| − r_s` is 1-Lipschitz, so for a
//! cell of centre `m` and half-diagonal `ρ`, every point `x` of it has `|d(x) − d(m)| ≤ ρ`:
//! - **self**: `d(m) + ρ ≤ padding` — every point of the cell is within the padding, the test the
//!   descent would make (so the filter stays as conservative as before: a point is filtered only
//!   if an inner sphere, which lies inside the mesh, is within the padding of it);
//! - **clear**: `d(m) − ρ > padding` — no point of the cell is within it;
//! - **shell**: otherwise; the point's own descent decides.
//!
//! Both tests take a margin of `1e-6 m + 1e-5 ρ` for f32 rounding (the cell a point falls in,
//! the distances), so a cell is `self` or `clear` only when the descent of each of its points
//! would say so. The grid covers the spheres' box grown by the padding and one cell; a point
//! outside it is farther than the padding from every sphere.
//!
//! Cells are 0.4 × padding wide (at most 2²⁰ per link, a byte each: coarser for a large link
//! or a tiny padding), so that a point on the mesh surface, within the link's gap h of its
//! spheres, falls in a `self` cell whenever `h + 2ρ ≤ padding` (h ≤ 3 mm at the default 1 cm
//! padding). The grid is built once per padding (two levels: bricks of 4³ cells that are all
//! `self` or all `clear` are settled with one test each), in parallel over slabs.

use rayon::prelude::*;

use super::descent::any_within;
use super::layout::{Cell, GridHeader};
use super::link::QueryLink;
use super::options::QueryOptions;

/// Most cells of one link's grid.
const MAX_CELLS: usize = 1 << 20;

/// Cell width as a fraction of the padding.
const CELL_PER_PADDING: f32 = 0.4;

/// Cells per brick edge (the build's coarse level).
const BRICK: usize = 4;

/// One link's grid for one padding.
pub(crate) struct SelfGrid {
    origin: [f32; 3],
    inv_cell: f32,
    dims: [usize; 3],
    cells: Vec<Cell>,
}

impl SelfGrid {
    /// The grid of `link` for `padding` (m, ≥ 0).
    pub fn new(link: &QueryLink, padding: f32) -> Self {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for s in &link.spheres {
            for k in 0..3 {
                lo[k] = lo[k].min(s.center[k] - s.radius);
                hi[k] = hi[k].max(s.center[k] + s.radius);
            }
        }
        if link.spheres.is_empty() {
            return Self {
                origin: [0.0; 3],
                inv_cell: 0.0,
                dims: [0; 3],
                cells: Vec::new(),
            };
        }
        let extent = |cell: f32| {
            std::array::from_fn::<usize, 3, _>(|k| {
                ((hi[k] - lo[k] + 2.0 * (padding + cell)) / cell).ceil() as usize
            })
        };
        let mut cell = (CELL_PER_PADDING * padding).max(1e-4);
        while extent(cell).iter().product::<usize>() > MAX_CELLS {
            cell *= 1.25;
        }
        let dims = extent(cell);
        let origin = std::array::from_fn(|k| lo[k] - padding - cell);
        let half_diagonal = |n: usize| 0.5 * 3f32.sqrt() * cell * n as f32;
        let classify = |centre: [f32; 3], rho: f32| {
            let margin = 1e-6 + 1e-5 * rho;
            if any_within(link, centre, &[0], padding - rho - margin).is_some() {
                Cell::SelfPoint
            } else if any_within(link, centre, &[0], padding + rho + margin).is_some() {
                Cell::Shell
            } else {
                Cell::Clear
            }
        };
        let centre = |i: [usize; 3], n: usize| -> [f32; 3] {
            std::array::from_fn(|k| origin[k] + cell * (i[k] as f32 + 0.5 * n as f32))
        };
        let slab = dims[0] * dims[1];
        let mut cells = vec![Cell::Clear; slab * dims[2]];
        // Slabs of BRICK z-layers in parallel; within one, brick by brick.
        cells
            .par_chunks_mut(slab * BRICK)
            .enumerate()
            .for_each(|(bz, out)| {
                let z0 = bz * BRICK;
                let nz = out.len() / slab;
                for y0 in (0..dims[1]).step_by(BRICK) {
                    for x0 in (0..dims[0]).step_by(BRICK) {
                        let n = [BRICK.min(dims[0] - x0), BRICK.min(dims[1] - y0), nz];
                        // The brick's bounding sphere (a full brick's, which holds a partial
                        // one).
                        let whole = classify(centre([x0, y0, z0], BRICK), half_diagonal(BRICK));
                        for z in 0..n[2] {
                            for y in 0..n[1] {
                                for x in 0..n[0] {
                                    let at = z * slab + (y0 + y) * dims[0] + x0 + x;
                                    out[at] = match whole {
                                        Cell::Shell => classify(
                                            centre([x0 + x, y0 + y, z0 + z], 1),
                                            half_diagonal(1),
                                        ),
                                        settled => settled,
                                    };
                                }
                            }
                        }
                    }
                }
            });
        Self {
            origin,
            inv_cell: 1.0 / cell,
            dims,
            cells,
        }
    }

    /// The cell of a link-frame point (`Clear` outside the grid).
    #[inline(always)]
    pub fn at(&self, q: [f32; 3]) -> Cell {
        let mut index = 0;
        let mut stride = 1;
        for ((&v, &o), &n) in q.iter().zip(&self.origin).zip(&self.dims) {
            let f = (v - o) * self.inv_cell;
            // Also false for NaN.
            if !(f >= 0.0 && f < n as f32) {
                return Cell::Clear;
            }
            index += (f as usize).min(n - 1) * stride;
            stride *= n;
        }
        self.cells[index]
    }

    /// The grid for the GPU: its header, with its cells appended to `words` (2 bits a cell, 16
    /// to a word, in the order `at` indexes them).
    pub fn pack(&self, words: &mut Vec<u32>) -> GridHeader {
        let base = words.len() as u32;
        words.extend(self.cells.chunks(16).map(|c| {
            c.iter()
                .enumerate()
                .fold(0u32, |w, (k, &cell)| w | (cell as u32) << (2 * k))
        }));
        GridHeader {
            origin: self.origin,
            inv_cell: self.inv_cell,
            dims: self.dims.map(|d| d as u32),
            base,
        }
    }

    /// Cells of each kind (clear, shell, self), for the tests and the log.
    pub fn census(&self) -> [usize; 3] {
        let mut n = [0; 3];
        for &c in &self.cells {
            n[c as usize] += 1;
        }
        n
    }
}

/// The links' grids for one padding, kept from query to query: built on the first query with a
/// padding (once; 43 ms for the demo arm, 90 ms for the Panda on 2 cores;
/// `Engine::prepare_self_filter` builds them ahead), for either backend's self-filter.
#[derive(Default)]
pub(super) struct SelfGrids(Option<(f32, Vec<SelfGrid>)>);

impl SelfGrids {
    /// Builds the grids for the padding of `options`, unless they are built already (nothing
    /// with the self-filter off).
    pub(super) fn prepare(&mut self, links: &[QueryLink], options: &QueryOptions) {
        let Some(padding) = options.self_filter_padding_m else {
            return;
        };
        if self.0.as_ref().is_none_or(|(p, _)| *p != padding) {
            let start = std::time::Instant::now();
            let grids: Vec<_> = links.iter().map(|l| SelfGrid::new(l, padding)).collect();
            let cells = grids
                .iter()
                .map(|g| g.census())
                .fold([0; 3], |a, c| [a[0] + c[0], a[1] + c[1], a[2] + c[2]]);
            log::debug!(
                "self-filter grids for padding {padding} m: {} cells ({} self, {} shell) in {:.0} ms",
                cells.iter().sum::<usize>(),
                cells[2],
                cells[1],
                start.elapsed().as_secs_f64() * 1e3
            );
            self.0 = Some((padding, grids));
        }
    }

    /// The grids a query with `options` filters with, built first where needed: one per link,
    /// or none with the self-filter off.
    pub(super) fn for_query(&mut self, links: &[QueryLink], options: &QueryOptions) -> &[SelfGrid] {
        self.prepare(links, options);
        match (&self.0, options.self_filter_padding_m) {
            (Some((_, grids)), Some(_)) => grids.as_slice(),
            _ => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ist::IstNode;
    use crate::packing::InnerSphere;

    /// A link of a few spheres under one root (the tree shape the descent needs).
    fn link(spheres: &[([f32; 3], f32)]) -> QueryLink {
        let spheres: Vec<InnerSphere> = spheres
            .iter()
            .map(|&(center, radius)| InnerSphere { center, radius })
            .collect();
        let root = IstNode {
            center: [0.0; 3],
            radius: spheres
                .iter()
                .map(|s| super::super::descent::dist(s.center, [0.0; 3]) + s.radius)
                .fold(0.0, f32::max),
            first_child: 0,
            child_count: spheres.len() as u32,
            children_are_spheres: 1,
            ..IstNode::default()
        };
        QueryLink::new("l".into(), 0, vec![root], spheres, 0.0, Vec::new())
    }

    /// Every point of a self cell is within the padding, no point of a clear cell is: checked
    /// against the spheres directly at random points around the link.
    #[test]
    fn cells_agree_with_the_spheres() {
        let l = link(&[
            ([0.0; 3], 0.05),
            ([0.08, 0.0, 0.0], 0.03),
            ([0.0, 0.06, 0.01], 0.02),
        ]);
        for padding in [0.0, 0.004, 0.01, 0.03] {
            let grid = SelfGrid::new(&l, padding);
            let census = grid.census();
            if padding > 0.0 {
                assert!(census[2] > 0, "padding {padding}: no self cell");
            }
            assert!(census[0] > 0 && census[1] > 0);
            let mut state = 0x2545_f491_4f6c_dd1du64;
            let mut rand = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 40) as f32 / (1u64 << 24) as f32
            };
            let mut seen = [0usize; 3];
            for _ in 0..200_000 {
                let q = [
                    -0.1 + 0.25 * rand(),
                    -0.1 + 0.22 * rand(),
                    -0.1 + 0.2 * rand(),
                ];
                let d = l
                    .spheres
                    .iter()
                    .map(|s| super::super::descent::dist(q, s.center) - s.radius)
                    .fold(f32::INFINITY, f32::min);
                let cell = grid.at(q);
                seen[cell as usize] += 1;
                match cell {
                    Cell::SelfPoint => assert!(d <= padding, "{q:?}: d {d} > padding {padding}"),
                    Cell::Clear => assert!(d > padding, "{q:?}: d {d} ≤ padding {padding}"),
                    // The shell is thin: within two half-diagonals of the padding's level.
                    Cell::Shell => {
                        let rho = 0.5 * 3f32.sqrt() / grid.inv_cell;
                        assert!((d - padding).abs() <= 2.0 * rho + 1e-5, "{q:?}: d {d}");
                    }
                }
            }
            assert!(seen.iter().all(|&n| n > 0), "padding {padding}: {seen:?}");
        }
    }

    #[test]
    fn outside_the_grid_and_nan_are_clear() {
        let grid = SelfGrid::new(&link(&[([0.0; 3], 0.05)]), 0.01);
        assert_eq!(grid.at([1.0, 0.0, 0.0]), Cell::Clear);
        assert_eq!(grid.at([f32::NAN, 0.0, 0.0]), Cell::Clear);
        assert_eq!(grid.at([0.0; 3]), Cell::SelfPoint);
        // A link of metres: coarser cells, still at most MAX_CELLS, still right.
        let big = link(&[([0.0; 3], 2.0), ([3.0, 0.0, 0.0], 1.5)]);
        let grid = SelfGrid::new(&big, 0.01);
        assert!(grid.cells.len() <= MAX_CELLS);
        assert_eq!(grid.at([0.0; 3]), Cell::SelfPoint);
        assert_eq!(grid.at([0.0, 2.5, 0.0]), Cell::Clear);
    }
}
