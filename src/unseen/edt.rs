//! The exact squared Euclidean distance transform of the lattice (Felzenszwalb & Huttenlocher,
//! "Distance Transforms of Sampled Functions", 2012): for every cell, the squared distance (in
//! cells², exact integers in f64) to the nearest feature cell, ∞ where there is none.
//!
//! Separable: the 1-D transform (the lower envelope of the parabolas `(q − p)² + f(p)` rooted at
//! the finite samples) along x, then y, then z, each O(n) per line: O(cells) in all, against
//! O(cells · ball) for a scan of a ball around every cell. Lines run in parallel (rayon): x
//! lines are contiguous, y lines are gathered inside each z slab, z lines through a column
//! buffer (gathered, transformed, scattered back slab by slab). Two grid-sized f64 buffers.
//! Cells beyond the lattice are not features: what lies outside is taken as unknown.

use rayon::prelude::*;

/// Replaces `grid` (0 at the features, ∞ elsewhere; `dims` as the lattice's, x fastest) by the
/// squared distance of each cell to the nearest feature, in cells².
pub(super) fn squared_distance_transform(grid: &mut [f64], dims: [usize; 3]) {
    let [n0, n1, n2] = dims;
    let slab = n0 * n1;
    grid.par_chunks_mut(n0)
        .for_each_init(|| Lines::new(n0), |s, line| s.transform_in_place(line));
    grid.par_chunks_mut(slab).for_each_init(
        || Lines::new(n1),
        |s, slab| {
            for i in 0..n0 {
                for j in 0..n1 {
                    s.f[j] = slab[i + n0 * j];
                }
                s.envelope();
                for j in 0..n1 {
                    slab[i + n0 * j] = s.out[j];
                }
            }
        },
    );
    if n2 == 1 {
        return;
    }
    let mut columns = vec![0.0f64; grid.len()];
    {
        let grid = &*grid;
        columns.par_chunks_mut(n2).enumerate().for_each_init(
            || Lines::new(n2),
            |s, (column, out)| {
                for k in 0..n2 {
                    s.f[k] = grid[column + slab * k];
                }
                s.envelope();
                out.copy_from_slice(&s.out);
            },
        );
    }
    grid.par_chunks_mut(slab)
        .enumerate()
        .for_each(|(k, plane)| {
            for (column, d) in plane.iter_mut().enumerate() {
                *d = columns[column * n2 + k];
            }
        });
}

/// One line's buffers: its samples, its transform, the envelope's parabolas and boundaries.
struct Lines {
    f: Vec<f64>,
    out: Vec<f64>,
    roots: Vec<usize>,
    bounds: Vec<f64>,
}

impl Lines {
    fn new(n: usize) -> Self {
        Self {
            f: vec![0.0; n],
            out: vec![0.0; n],
            roots: Vec::with_capacity(n),
            bounds: Vec::with_capacity(n),
        }
    }

    fn transform_in_place(&mut self, line: &mut [f64]) {
        self.f.copy_from_slice(line);
        self.envelope();
        line.copy_from_slice(&self.out);
    }

    /// `out[q] = min_p (q − p)² + f[p]` over the finite `f[p]` (∞ when none).
    fn envelope(&mut self) {
        let (f, roots, bounds) = (&self.f, &mut self.roots, &mut self.bounds);
        roots.clear();
        bounds.clear();
        let key = |p: usize| f[p] + (p * p) as f64;
        for (q, fq) in f.iter().enumerate() {
            if fq.is_infinite() {
                continue;
            }
            // Pop the parabolas that q's hides entirely; the first keeps its −∞ boundary.
            let mut s = f64::NEG_INFINITY;
            while let (Some(&p), Some(&b)) = (roots.last(), bounds.last()) {
                s = (key(q) - key(p)) / (2.0 * (q - p) as f64);
                if s <= b {
                    roots.pop();
                    bounds.pop();
                    s = f64::NEG_INFINITY;
                } else {
                    break;
                }
            }
            roots.push(q);
            bounds.push(s);
        }
        if roots.is_empty() {
            self.out.fill(f64::INFINITY);
            return;
        }
        let mut k = 0;
        for (q, out) in self.out.iter_mut().enumerate() {
            while k + 1 < roots.len() && bounds[k + 1] < q as f64 {
                k += 1;
            }
            let d = q as f64 - roots[k] as f64;
            *out = d * d + f[roots[k]];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

        /// The separable transform is the brute-force minimum over every feature, exactly.
        #[test]
        fn transform_is_the_brute_force_minimum(
            dims in prop::array::uniform3(1usize..9),
            density in 0.0f64..0.3,
            seed in any::<u64>(),
        ) {
            let n = dims[0] * dims[1] * dims[2];
            let mut s = seed | 1;
            let features: Vec<bool> = (0..n)
                .map(|_| {
                    s ^= s << 13; s ^= s >> 7; s ^= s << 17;
                    (s % 1000) as f64 / 1000.0 < density
                })
                .collect();
            let mut grid: Vec<f64> =
                features.iter().map(|&f| if f { 0.0 } else { f64::INFINITY }).collect();
            squared_distance_transform(&mut grid, dims);
            let ijk = |i: usize| [i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1])];
            for (i, &d) in grid.iter().enumerate() {
                let a = ijk(i);
                let brute = (0..n)
                    .filter(|&j| features[j])
                    .map(|j| {
                        let b = ijk(j);
                        (0..3).map(|x| (a[x] as f64 - b[x] as f64).powi(2)).sum::<f64>()
                    })
                    .fold(f64::INFINITY, f64::min);
                prop_assert_eq!(d, brute, "cell {:?}", a);
            }
        }
    }
}
