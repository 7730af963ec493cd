//! The opening's two lattice passes on flags, without a distance transform: the erosion by a
//! small stencil of integer offsets, and the dilation by a box of cells.
//!
//! Stage: inside step 2 of the unseen pass (`opening` calls them); inputs and outputs are one
//! flag per lattice cell (`dims` as the lattice's, x fastest), offsets and widths in cells; no
//! frame, no metres.
//!
//! - [`stencil`]: the integer offsets `k ≠ 0` with `|k|² < erosion2`, nearest first, or `None`
//!   when there are more than [`MAX_STENCIL`] (then the caller erodes by the distance
//!   transform, whose cost does not grow with the radius).
//! - [`erode`]: a cell survives when it and every cell at a stencil offset is unseen; an offset
//!   beyond the lattice fails it (what lies outside the monitored volume is not watched: a body
//!   counts where a ball of the capability fits inside the volume). Only unseen cells are candidates, and a candidate stops at its first seen
//!   neighbour, nearest first; interior cells test precomputed linear offsets, border cells
//!   check each offset's bounds. z slabs in parallel (rayon). Cost: O(cells · stencil) at
//!   worst, about O(unseen cells) in practice (most candidates stop at a face neighbour).
//! - [`dilate_by_box`]: the cells within `m` cells of a survivor along every axis (the
//!   Chebyshev ball, the box of half-width `m`), as three separable 1-D passes: along x each
//!   flagged cell fills its window (each cell written once), then along y and z a sliding count
//!   of the flags in a window of `2m + 1` rows, whole rows and slabs at a time so that it
//!   vectorizes: O(cells) whatever `m`, in parallel.

use rayon::prelude::*;

/// The most offsets the erosion tests per cell before the caller falls back on the distance
/// transform: a ball of radius 4 cells (`|k|² ≤ 16`: 256 offsets besides the centre). Beyond,
/// the stencil's cost per surviving cell outgrows the transform's passes.
pub(super) const MAX_STENCIL: usize = 256;

/// The offsets `k ≠ 0` with `|k|² < erosion2`, sorted by `|k|²` (nearest first: a seen cell
/// near an unseen one is most likely a face neighbour); `None` past [`MAX_STENCIL`].
pub(super) fn stencil(erosion2: u64) -> Option<Vec<[i64; 3]>> {
    // A ball of radius r holds about 4.19·r³ offsets: skip the enumeration when it is far past
    // the limit (erosion2 can be as large as the capability over the resolution, squared).
    if erosion2 > 64 {
        return None;
    }
    let r = (erosion2 as f64).sqrt().ceil() as i64;
    let mut offsets = Vec::new();
    for a in -r..=r {
        for b in -r..=r {
            for c in -r..=r {
                let n2 = (a * a + b * b + c * c) as u64;
                if n2 > 0 && n2 < erosion2 {
                    offsets.push([a, b, c]);
                }
            }
        }
    }
    offsets.sort_by_key(|[a, b, c]| a * a + b * b + c * c);
    (offsets.len() <= MAX_STENCIL).then_some(offsets)
}

/// The erosion of `unseen` by `offsets` (see the module doc): a survivor is unseen and every
/// in-lattice cell at an offset from it is unseen.
pub(super) fn erode(unseen: &[bool], dims: [usize; 3], offsets: &[[i64; 3]]) -> Vec<bool> {
    let [n0, n1, n2] = dims;
    let slab = n0 * n1;
    // The stencil's reach along an axis: cells at least this far from every face are interior.
    let r = offsets
        .iter()
        .flat_map(|k| k.iter().map(|c| c.unsigned_abs() as usize))
        .max()
        .unwrap_or(0);
    let linear: Vec<isize> = offsets
        .iter()
        .map(|&[a, b, c]| (a + n0 as i64 * (b + n1 as i64 * c)) as isize)
        .collect();
    let inside = |i: usize, k: i64, n: usize| {
        let p = i as i64 + k;
        (p >= 0 && p < n as i64).then_some(p as usize)
    };
    let mut out = vec![false; unseen.len()];
    out.par_chunks_mut(slab).enumerate().for_each(|(k, out)| {
        let k_interior = k >= r && k + r < n2;
        for j in 0..n1 {
            let row_interior = k_interior && j >= r && j + r < n1;
            for i in 0..n0 {
                let cell = i + n0 * (j + n1 * k);
                if !unseen[cell] {
                    continue;
                }
                out[i + n0 * j] = if row_interior && i >= r && i + r < n0 {
                    linear.iter().all(|&o| unseen[cell.wrapping_add_signed(o)])
                } else {
                    offsets.iter().all(|&[a, b, c]| {
                        match (inside(i, a, n0), inside(j, b, n1), inside(k, c, n2)) {
                            (Some(x), Some(y), Some(z)) => unseen[x + n0 * (y + n1 * z)],
                            // Beyond the lattice: not watched, not unseen.
                            _ => false,
                        }
                    })
                };
            }
        }
    });
    out
}

/// The cells within `m` cells of a flagged cell of `cells` along every axis (the dilation by the
/// box of half-width `m`).
pub(super) fn dilate_by_box(cells: &[bool], dims: [usize; 3], m: usize) -> Vec<bool> {
    let [n0, n1, n2] = dims;
    let slab = n0 * n1;
    let mut a = vec![false; cells.len()];
    let mut b = vec![false; cells.len()];
    // x: each row on its own, the window of every flagged cell filled (survivors are sparse;
    // a cell is written at most once).
    a.par_chunks_mut(n0)
        .zip(cells.par_chunks(n0))
        .for_each(|(dst, src)| {
            let mut filled = 0;
            for (i, _) in src.iter().enumerate().filter(|(_, &s)| s) {
                let end = (i + m + 1).min(n0);
                let start = i.saturating_sub(m).max(filled);
                dst[start..end].fill(true);
                filled = end;
            }
        });
    // y: inside each z slab, whole x rows at a time.
    b.par_chunks_mut(slab)
        .zip(a.par_chunks(slab))
        .for_each_init(Vec::new, |count, (dst, src)| {
            or_window(src, dst, n0, 0, m, count)
        });
    // z: whole slabs at a time, the output slabs cut into a few runs per thread.
    let per_run = n2.div_ceil(4 * rayon::current_num_threads()).max(1);
    let b = &b;
    a.par_chunks_mut(per_run * slab)
        .enumerate()
        .for_each_init(Vec::new, |count, (run, dst)| {
            or_window(b, dst, slab, run * per_run, m, count)
        });
    a
}

/// `dst`'s rows (of `row_len` flags), which are `src`'s rows `first ..`, each set to the OR of
/// `src`'s rows within `m` of it (those that exist), by a count per column slid along the rows.
fn or_window(
    src: &[bool],
    dst: &mut [bool],
    row_len: usize,
    first: usize,
    m: usize,
    count: &mut Vec<u32>,
) {
    let rows = src.len() / row_len;
    let row = |r: usize| &src[r * row_len..(r + 1) * row_len];
    count.clear();
    count.resize(row_len, 0);
    for r in first.saturating_sub(m)..(first + m + 1).min(rows) {
        for (c, &s) in count.iter_mut().zip(row(r)) {
            *c += u32::from(s);
        }
    }
    for (local, out) in dst.chunks_mut(row_len).enumerate() {
        let g = first + local;
        if local > 0 {
            if g + m < rows {
                for (c, &s) in count.iter_mut().zip(row(g + m)) {
                    *c += u32::from(s);
                }
            }
            if g > m {
                for (c, &s) in count.iter_mut().zip(row(g - m - 1)) {
                    *c -= u32::from(s);
                }
            }
        }
        for (o, &c) in out.iter_mut().zip(count.iter()) {
            *o = c > 0;
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// xorshift64*, in [0, 1): deterministic draws without a dependency (the opening's tests
    /// use it too).
    pub(in crate::unseen) struct Rng(pub u64);

    impl Rng {
        pub fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }

        pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    fn flags(seed: u64, n: usize, density: f64) -> Vec<bool> {
        let mut rng = Rng(seed | 1);
        (0..n).map(|_| rng.next() < density).collect()
    }

    fn at(dims: [usize; 3], p: [i64; 3]) -> Option<usize> {
        (0..3)
            .all(|a| p[a] >= 0 && p[a] < dims[a] as i64)
            .then(|| p[0] as usize + dims[0] * (p[1] as usize + dims[1] * p[2] as usize))
    }

    fn ijk(dims: [usize; 3], i: usize) -> [i64; 3] {
        [
            (i % dims[0]) as i64,
            (i / dims[0] % dims[1]) as i64,
            (i / (dims[0] * dims[1])) as i64,
        ]
    }

    #[test]
    fn the_stencil_is_the_offsets_inside_the_ball() {
        // 70 mm at 2 cm: the six face neighbours.
        let six = stencil(2).unwrap();
        assert_eq!(six.len(), 6);
        assert!(six
            .iter()
            .all(|k| k.iter().map(|c| c * c).sum::<i64>() == 1));
        assert_eq!(stencil(1).unwrap().len(), 0);
        assert_eq!(stencil(3).unwrap().len(), 18);
        assert_eq!(stencil(16).unwrap().len(), 250);
        assert_eq!(stencil(17).unwrap().len(), 256);
        assert!(stencil(18).is_none());
        assert!(stencil(1 << 40).is_none());
    }

    #[test]
    fn erosion_and_box_dilation_match_brute_force() {
        for (t, dims) in [[7, 5, 6], [1, 9, 4], [12, 1, 1], [6, 6, 6]]
            .into_iter()
            .enumerate()
        {
            let n = dims.iter().product::<usize>();
            let unseen = flags(t as u64 + 3, n, 0.8);
            for erosion2 in [1, 2, 3, 5, 9] {
                let offsets = stencil(erosion2).unwrap();
                let fast = erode(&unseen, dims, &offsets);
                for (i, &got) in fast.iter().enumerate() {
                    let p = ijk(dims, i);
                    let brute = unseen[i]
                        && offsets.iter().all(|k| {
                            at(dims, [p[0] + k[0], p[1] + k[1], p[2] + k[2]])
                                .is_some_and(|q| unseen[q])
                        });
                    assert_eq!(got, brute, "dims {dims:?} erosion2 {erosion2} cell {p:?}");
                }
            }
            let cells = flags(t as u64 + 9, n, 0.05);
            for m in [0, 1, 2, 5] {
                let fast = dilate_by_box(&cells, dims, m);
                for (i, &got) in fast.iter().enumerate() {
                    let p = ijk(dims, i);
                    let brute = (0..n).any(|q| {
                        let c = ijk(dims, q);
                        cells[q] && (0..3).all(|a| (c[a] - p[a]).unsigned_abs() as usize <= m)
                    });
                    assert_eq!(got, brute, "dims {dims:?} m {m} cell {p:?}");
                }
            }
        }
    }
}
