//! Min/max pyramids of a view's per-pixel images (free distance, distance to the robot), for
//! the footprint test's shortcuts: the largest and smallest value over a pixel rectangle from a
//! few texels.
//!
//! Level 0 is the image itself (the pyramid owns it: the view writes its pixels there); level
//! `k` holds, per texel, the minimum and maximum over the `2^k × 2^k` pixels it covers (clipped
//! at the image's edge). A rectangle is read at the level whose texels are a quarter of its
//! longer side (at most 5 × 5 texels): they cover a superset of it, a little larger, so the
//! maximum read is at least the true one and the minimum at most, which is the side each
//! shortcut needs (`footprint`).
//!
//! An image whose maxima are read only at its pixels (the 2 × 2 maxima of the free distances)
//! keeps its levels' minima alone ([`Pyramid::build_minima`]); a maximum over a wider
//! rectangle is then +∞, "or more" as the contract allows.
//!
//! Cost: a third of the image's pixels to build, rows in parallel where a level holds at least
//! 16,384 texels and on one thread below (a parallel pass costs more to start than a small
//! level's work); where only some rows of an image filled with one value were written, the
//! texels over them (`fill`, `build_rows`); up to 25 reads a query.

use rayon::prelude::*;

use super::camera::Rect;

/// The pyramids of a view's images (`prepared`): the free distance, the largest free distance of
/// each 2 × 2 pixels (by their top-left pixel), and the distance to the robot.
#[derive(Debug, Clone, Default)]
pub struct Pyramids {
    pub free: Pyramid,
    pub pairs: Pyramid,
    pub robot: Pyramid,
}

/// One level above the image: `width × height` texels.
#[derive(Debug, Clone, Default)]
struct Level {
    width: usize,
    height: usize,
    min: Vec<f32>,
    max: Vec<f32>,
}

/// The min/max pyramid of one image, which it holds.
#[derive(Debug, Clone, Default)]
pub struct Pyramid {
    width: usize,
    height: usize,
    base: Vec<f32>,
    levels: Vec<Level>,
    /// Built by [`Pyramid::build_minima`]: the levels hold minima only, and a maximum read
    /// above the image is +∞ (what "the largest value, or more" allows).
    minima_only: bool,
}

impl Pyramid {
    /// The image (`width × height`, row-major) to be written, its allocation reused.
    pub fn base_mut(&mut self, width: usize, height: usize) -> &mut Vec<f32> {
        self.width = width;
        self.height = height;
        self.base.resize(width * height, 0.0);
        &mut self.base
    }

    /// The image.
    pub fn base(&self) -> &[f32] {
        &self.base
    }

    /// The image's width and height in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The image's value at pixel `(u, v)`.
    #[inline]
    pub fn at(&self, u: usize, v: usize) -> f32 {
        self.base[v * self.width + u]
    }

    /// Builds the levels above the image as it now is.
    pub fn build(&mut self) {
        self.minima_only = false;
        self.reduce_levels(None);
    }

    /// Builds the levels' minima alone (half the work), for an image whose maxima are read
    /// only at the image itself ([`Pyramid::at`]): [`Pyramid::max`] then reads +∞ over any
    /// rectangle wider than a pixel, [`Pyramid::maxima`] nothing above the image.
    pub fn build_minima(&mut self) {
        self.minima_only = true;
        self.reduce_levels(None);
    }

    /// The image `width × height` and every level above it filled with `value`: what
    /// [`Pyramid::build`] would make of the filled image, without reading it.
    pub fn fill(&mut self, width: usize, height: usize, value: f32) {
        self.minima_only = false;
        self.base_mut(width, height).fill(value);
        let count = levels_for(width.max(height)) - 1;
        self.levels.resize_with(count, Level::default);
        let (mut w, mut h) = (width, height);
        for level in &mut self.levels {
            (w, h) = (w.div_ceil(2), h.div_ceil(2));
            level.width = w;
            level.height = h;
            for values in [&mut level.min, &mut level.max] {
                values.clear();
                values.resize(w * h, value);
            }
        }
    }

    /// Rebuilds the levels above the image's rows where `changed` (one flag a row) is set: the
    /// texels over them, from the level below. The rest of the image must be as it was at the
    /// last [`Pyramid::build`] or [`Pyramid::fill`]; the result is then what `build` makes.
    pub fn build_rows(&mut self, changed: &[bool]) {
        self.reduce_levels(Some(changed));
    }

    /// Each level from the one below: whole, or (`changed`: the image's rows) only the texels
    /// over the rows flagged.
    fn reduce_levels(&mut self, changed: Option<&[bool]>) {
        let count = levels_for(self.width.max(self.height)) - 1;
        self.levels.resize_with(count, Level::default);
        let mut dirty = changed.map(<[bool]>::to_vec);
        for k in 0..count {
            let (done, rest) = self.levels.split_at_mut(k);
            let (min, max, w, h) = match done.last() {
                None => (&self.base[..], &self.base[..], self.width, self.height),
                Some(from) => (&from.min[..], &from.max[..], from.width, from.height),
            };
            // A texel row is over two rows of the level below.
            dirty = dirty.map(|d| {
                (0..h.div_ceil(2))
                    .map(|j| d[2 * j] || d.get(2 * j + 1).copied().unwrap_or(false))
                    .collect()
            });
            reduce(
                min,
                max,
                w,
                h,
                &mut rest[0],
                dirty.as_deref(),
                self.minima_only,
            );
        }
    }

    /// Level `k`'s maxima (`k = 0`: the image), row-major, and its width in texels; `None`
    /// above the top.
    pub fn maxima(&self, k: usize) -> Option<(&[f32], usize)> {
        match k {
            0 => Some((&self.base, self.width)),
            _ if self.minima_only => None,
            k => {
                let level = self.levels.get(k - 1)?;
                Some((&level.max, level.width))
            }
        }
    }

    /// The largest value over `rect`, or more.
    pub fn max(&self, rect: Rect) -> f32 {
        if self.minima_only && self.level_for(rect) > 0 {
            return f32::INFINITY;
        }
        self.extreme(rect, f32::NEG_INFINITY, |l| &l.max, f32::max)
    }

    /// The smallest value over `rect`, or less.
    pub fn min(&self, rect: Rect) -> f32 {
        self.extreme(rect, f32::INFINITY, |l| &l.min, f32::min)
    }

    /// The level `rect` is read at: texels about a quarter of its longer side.
    fn level_for(&self, rect: Rect) -> usize {
        let side = (rect.u1 - rect.u0 + 1).max(rect.v1 - rect.v0 + 1);
        (levels_for(side) - 1)
            .saturating_sub(2)
            .min(self.levels.len())
    }

    fn extreme(
        &self,
        rect: Rect,
        start: f32,
        values: impl Fn(&Level) -> &Vec<f32>,
        pick: impl Fn(f32, f32) -> f32,
    ) -> f32 {
        let k = self.level_for(rect);
        let (data, width, height) = match k {
            0 => (&self.base, self.width, self.height),
            _ => {
                let level = &self.levels[k - 1];
                (values(level), level.width, level.height)
            }
        };
        let mut out = start;
        for j in (rect.v0 >> k)..=(rect.v1 >> k).min(height - 1) {
            for i in (rect.u0 >> k)..=(rect.u1 >> k).min(width - 1) {
                out = pick(out, data[j * width + i]);
            }
        }
        out
    }
}

/// Texels below which a level (or the rows of it rebuilt) is reduced on one thread, and the
/// least a task takes above: a parallel pass costs some 15 µs to start, more than a small
/// level's work (the robot's pyramid over the Kinect frame's 11 bands asked for the causes took
/// 0.19 ms over its 11 levels in parallel).
const PARALLEL_TEXELS: usize = 16_384;

/// The levels a side of `n` pixels needs: `k` from 0 while `2^k < n`, and one with `2^k ≥ n`.
fn levels_for(n: usize) -> usize {
    (usize::BITS - n.max(1).saturating_sub(1).leading_zeros()) as usize + 1
}

/// `to`, the level above the one of extremes `min`, `max` (`fw × fh`): each texel the extremes
/// of its (up to) four children (`minima_only`: the minima, the maxima left empty); only the
/// rows `rows` flags where given.
fn reduce(
    min: &[f32],
    max: &[f32],
    fw: usize,
    fh: usize,
    to: &mut Level,
    rows: Option<&[bool]>,
    minima_only: bool,
) {
    to.width = fw.div_ceil(2);
    to.height = fh.div_ceil(2);
    let n = to.width * to.height;
    to.min.resize(n, 0.0);
    to.max.resize(if minima_only { 0 } else { n }, 0.0);
    let w = to.width;
    let todo = |j: usize| rows.is_none_or(|r| r[j]);
    let row = |j: usize, lo_row: &mut [f32], hi_row: &mut [f32]| {
        let (r0, r1) = (2 * j * fw, (2 * j + 1).min(fh - 1) * fw);
        pairs(&min[r0..r0 + fw], &min[r1..r1 + fw], lo_row, f32::min);
        if !minima_only {
            pairs(&max[r0..r0 + fw], &max[r1..r1 + fw], hi_row, f32::max);
        }
    };
    // Minima only: each texel row with an empty row of maxima.
    let his: Vec<&mut [f32]> = match minima_only {
        true => (0..to.height).map(|_| &mut [][..]).collect(),
        false => to.max.chunks_mut(w).collect(),
    };
    let texels = w * (0..to.height).filter(|&j| todo(j)).count();
    if texels < PARALLEL_TEXELS {
        for ((j, lo_row), hi_row) in to.min.chunks_mut(w).enumerate().zip(his) {
            if todo(j) {
                row(j, lo_row, hi_row);
            }
        }
        return;
    }
    (to.min.par_chunks_mut(w).zip(his).enumerate())
        .with_min_len(PARALLEL_TEXELS.div_ceil(w))
        .filter(|(j, _)| todo(*j))
        .for_each(|(j, (lo_row, hi_row))| row(j, lo_row, hi_row));
}

/// `out[i]`: `pick` over columns `2i` and `2i + 1` (the last alone where the width is odd) of
/// rows `a` and `b`.
#[inline]
fn pairs(a: &[f32], b: &[f32], out: &mut [f32], pick: fn(f32, f32) -> f32) {
    let even = a.len() / 2;
    for ((o, x), y) in out.iter_mut().zip(a.chunks_exact(2)).zip(b.chunks_exact(2)) {
        *o = pick(pick(x[0], x[1]), pick(y[0], y[1]));
    }
    if a.len() % 2 == 1 {
        let last = a.len() - 1;
        out[even] = pick(a[last], b[last]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Pixel values in [−2, 8) from `seed` (xorshift).
    fn values(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 1000) as f32 / 100.0 - 2.0
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

        /// The four texels bound the brute-force extremes of any rectangle, and a single pixel
        /// reads itself; built for its minima alone, the same minima.
        #[test]
        fn extremes_bound_the_brute_force_ones(
            w in 1usize..40,
            h in 1usize..40,
            seed in any::<u64>(),
            corners in prop::array::uniform4(0.0f64..1.0),
        ) {
            let mut next = values(seed);
            let image: Vec<f32> = (0..w * h).map(|_| next()).collect();
            let mut p = Pyramid::default();
            p.base_mut(w, h).copy_from_slice(&image);
            p.build();
            let pick = |x: f64, n: usize| ((x * n as f64) as usize).min(n - 1);
            let (a, b) = (pick(corners[0], w), pick(corners[1], w));
            let (c, d) = (pick(corners[2], h), pick(corners[3], h));
            let rect = Rect { u0: a.min(b), u1: a.max(b), v0: c.min(d), v1: c.max(d) };
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for v in rect.v0..=rect.v1 {
                for u in rect.u0..=rect.u1 {
                    lo = lo.min(image[v * w + u]);
                    hi = hi.max(image[v * w + u]);
                }
            }
            prop_assert!(p.max(rect) >= hi && p.min(rect) <= lo);
            let one = Rect { u0: a, u1: a, v0: c, v1: c };
            prop_assert_eq!(p.max(one), image[c * w + a]);
            prop_assert_eq!(p.min(one), image[c * w + a]);
            // Its minima alone: the same minima, maxima still bounds (exact at a pixel).
            let mut minima = p.clone();
            minima.build_minima();
            prop_assert_eq!(minima.min(rect), p.min(rect));
            prop_assert!(minima.max(rect) >= hi);
            prop_assert_eq!(minima.max(one), image[c * w + a]);
        }

        /// A filled image with some rows rewritten, rebuilt over those rows, reads as the same
        /// image built whole, at every level and rectangle.
        #[test]
        fn rows_rebuilt_equal_a_whole_build(
            w in 1usize..40,
            h in 1usize..40,
            seed in any::<u64>(),
            rows in prop::collection::vec(any::<bool>(), 40),
        ) {
            let mut next = values(seed);
            let mut part = Pyramid::default();
            part.fill(w, h, f32::INFINITY);
            let changed = &rows[..h];
            let base = part.base_mut(w, h);
            for v in (0..h).filter(|&v| changed[v]) {
                for u in 0..w {
                    base[v * w + u] = next();
                }
            }
            let mut whole = part.clone();
            whole.build();
            part.build_rows(changed);
            prop_assert_eq!(part.levels.len(), whole.levels.len());
            for (a, b) in part.levels.iter().zip(&whole.levels) {
                prop_assert_eq!((a.width, a.height), (b.width, b.height));
                prop_assert_eq!(&a.min, &b.min);
                prop_assert_eq!(&a.max, &b.max);
            }
        }
    }

    #[test]
    fn levels_cover_the_side() {
        assert_eq!(levels_for(1), 1);
        assert_eq!(levels_for(2), 2);
        assert_eq!(levels_for(3), 3);
        assert_eq!(levels_for(4), 3);
        assert_eq!(levels_for(640), 11);
    }
}
