//! The measure of a surface gap in f64, for `validate`: the largest distance from some
//! triangles (a link's packed surface, or a mesh file's own triangles outside the link's solid)
//! to its inner spheres, as a certified upper bound and the largest sample (with its triangle
//! and point). Input: triangles (link frame, m), the tree's nodes and spheres; output:
//! [`GapBound`].
//!
//! Branch and bound, as `packing::gap` in f32: g is 1-Lipschitz, so a triangle with longest
//! edge L is bounded by its largest corner gap + L/√3, and by the convex bound of one sphere
//! (largest corner distance to it less its radius, with the spheres nearest its corners). A
//! sub-triangle is done when its bound is at most the floor (a bound known already: the
//! packing's claim plus its accuracy, or the packed surface's h for a file's own triangles, so
//! that the two slacks do not add up), or within `eps_m` of the largest gap at any corner of the
//! input outside the solid (found first) or of what its own triangle sampled; never what other
//! threads found meanwhile, so the value has the same bits on any thread count. Otherwise its longest edge is split, down to
//! `tolerance` (see `validate`'s module doc for the leaves and the solid's inside).
//!
//! Cost: a nearest-sphere walk of the tree per corner visited (a midpoint's bounded from the
//! start by its corner's nearest sphere: the same answer, a few nodes opened instead of many);
//! where the floor is exceeded the triangles there refine to `eps_m`, each sub-triangle asking
//! the caller whether it lies deep inside the solid (issue 56: on a 0.3 m tube of slivers the
//! measure took 537 s while that question summed every triangle's solid angle at points on the
//! surface, and the walks started from nothing; 3.1 s now).

use rayon::prelude::*;

use super::link_tree::IstNode;
use crate::geometry::{dist, widen, P3};
use crate::packing::InnerSphere;

/// How finely h is measured.
#[derive(Debug, Clone, Copy)]
pub(super) struct Accuracy {
    /// A sub-triangle is done within this of the largest gap known, m.
    pub eps_m: f64,
    /// Smallest sub-triangle (L/√3), m.
    pub tolerance: f64,
}

/// Nearest-sphere queries through the tree's own nodes (checked by `validate::check_tree` to bound
/// their children within `slack`).
pub(super) struct SphereIndex<'a> {
    pub nodes: &'a [IstNode],
    pub spheres: &'a [InnerSphere],
    pub slack: f64,
}

impl SphereIndex<'_> {
    /// The smallest `|p − c| − r` over the spheres, and that sphere (the first in the tree's
    /// order among equals). `hint`: a sphere likely near (a neighbouring point's nearest),
    /// whose distance, just above, starts the bound: the same answer, fewer nodes opened (a
    /// node is left only when it cannot hold a sphere at or below that distance, and the
    /// hint itself is found in its place). `stack`: scratch.
    fn nearest(&self, p: P3, hint: Option<usize>, stack: &mut Vec<usize>) -> (f64, usize) {
        let seed = hint
            .and_then(|k| self.spheres.get(k))
            .map_or(f64::INFINITY, |s| {
                (dist(p, widen(s.center)) - s.radius as f64).next_up()
            });
        let mut best = (seed, 0usize);
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            let Some(n) = self.nodes.get(i) else { continue };
            if dist(p, widen(n.center)) - n.radius as f64 - self.slack >= best.0 {
                continue;
            }
            let range = n.first_child as usize..(n.first_child + n.child_count) as usize;
            if n.children_are_spheres == 1 {
                for (k, s) in self.spheres[range.clone()].iter().enumerate() {
                    let d = dist(p, widen(s.center)) - s.radius as f64;
                    if d < best.0 {
                        best = (d, range.start + k);
                    }
                }
            } else {
                stack.extend(range);
            }
        }
        if best.0 == seed && hint.is_some() {
            // Never so for a tree `validate::check_tree` passed (the hint is found in its
            // place); asked again without it otherwise.
            return self.nearest(p, None, stack);
        }
        best
    }

    /// Largest distance from the triangle's corners to sphere `k`'s ball.
    fn convex_bound(&self, corners: [P3; 3], k: usize) -> f64 {
        let s = self.spheres[k];
        corners
            .iter()
            .map(|&v| dist(v, widen(s.center)) - s.radius as f64)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

const INV_SQRT3: f64 = 0.577_350_269_189_625_8;

/// The gap of some triangles to the spheres: `upper_m` certified, `lower_m` the largest sampled
/// at a point outside the solid, `worst` (triangle index, point) where.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct GapBound {
    pub upper_m: f64,
    pub lower_m: f64,
    pub worst: Option<(usize, P3)>,
}

impl GapBound {
    /// Both together: the larger bound, and the larger sample, ties to the lower triangle
    /// index and then the lower point, so that the reduction's shape does not matter.
    fn join(self, other: Self) -> Self {
        use std::cmp::Ordering;
        let points = |a: P3, b: P3| {
            (0..3)
                .map(|k| a[k].total_cmp(&b[k]))
                .find(|o| o.is_ne())
                .unwrap_or(Ordering::Equal)
        };
        let other_wins = match other.lower_m.total_cmp(&self.lower_m) {
            Ordering::Equal => match (self.worst, other.worst) {
                (None, w) => w.is_some(),
                (Some(_), None) => false,
                (Some((ts, ps)), Some((to, po))) => to.cmp(&ts).then(points(po, ps)).is_lt(),
            },
            o => o.is_gt(),
        };
        let best = if other_wins { other } else { self };
        Self {
            upper_m: self.upper_m.max(other.upper_m),
            ..best
        }
    }
}

/// Measures the gap of `triangles` (index in their source, corners) to the spheres (see the
/// module doc): `floor_m` is a bound already known for the whole (the packing's claim with its
/// accuracy, or the packed surface's measured h) at or below which nothing is refined; samples
/// above it are refined to within `eps_m`. With `inside`
/// (whether a point of the triangle with that index in its source lies inside the solid at
/// least a depth deep) points inside the solid are excused. `lower_m` is the largest gap sampled outside the solid, or at most `floor_m`
/// anywhere (whether those lie inside is not asked: on a file's own surface most do so within
/// rounding, which only the full winding number decides, at the cost of every triangle).
pub(super) fn measure(
    triangles: &[(usize, [P3; 3])],
    floor_m: f64,
    accuracy: Accuracy,
    index: &SphereIndex,
    inside: Option<&(dyn Fn(usize, P3, f64) -> bool + Sync)>,
) -> GapBound {
    let g = |p: P3, hint: Option<usize>, stack: &mut Vec<usize>| {
        let (d, k) = index.nearest(p, hint, stack);
        (d.max(0.0), k)
    };
    let outside = |n: usize, p: P3| inside.is_none_or(|f| !f(n, p, 0.0));
    let start: Vec<[(f64, usize); 3]> = (triangles.par_iter())
        .map_init(Vec::new, |stack, (_, t)| t.map(|p| g(p, None, stack)))
        .collect();
    // The largest gap at a corner outside the solid, found before any triangle is refined and
    // the same on any thread count. Corners below the floor do not move the threshold.
    let seed = triangles
        .par_iter()
        .zip(&start)
        .flat_map_iter(|(&(n, t), gs)| t.into_iter().zip(gs).map(move |(p, g)| (n, p, g)))
        .filter(|&(n, p, &(gap, _))| gap + accuracy.eps_m > floor_m && outside(n, p))
        .map(|(_, _, &(gap, _))| gap)
        .reduce(|| 0.0, f64::max);
    triangles
        .par_iter()
        .zip(&start)
        .map_init(Vec::new, |scratch, (&(n, corners), &gs)| {
            let mut out = GapBound::default();
            // A sample above the floor counts where it is outside the solid (asked only where
            // it would raise this triangle's largest).
            let note = |out: &mut GapBound, p: P3, gap: f64| {
                if gap > out.lower_m && (gap <= floor_m || outside(n, p)) {
                    out.lower_m = gap;
                    out.worst = Some((n, p));
                }
            };
            for (p, (gap, _)) in corners.iter().zip(gs) {
                note(&mut out, *p, gap);
            }
            let mut stack = vec![(corners, gs)];
            while let Some((t, gs)) = stack.pop() {
                let longest = dist(t[0], t[1]).max(dist(t[1], t[2])).max(dist(t[2], t[0]));
                let reach = longest * INV_SQRT3;
                let lipschitz = gs[0].0.max(gs[1].0).max(gs[2].0) + reach;
                let convex = gs
                    .iter()
                    .map(|&(_, k)| index.convex_bound(t, k))
                    .fold(f64::INFINITY, f64::min)
                    .max(0.0);
                let bound = lipschitz.min(convex);
                if bound <= floor_m.max(seed.max(out.lower_m) + accuracy.eps_m) {
                    out.upper_m = out.upper_m.max(bound);
                    continue;
                }
                if let Some(inside) = inside {
                    if t.iter().all(|&v| inside(n, v, reach)) {
                        continue;
                    }
                }
                if reach <= accuracy.tolerance {
                    // A corner inside the solid bounds its neighbourhood outside by the
                    // solid's boundary: the packed surface's h (the floor) + reach.
                    let leaf = t
                        .iter()
                        .zip(&gs)
                        .map(|(&v, &(gap, _))| {
                            if gap > floor_m && !outside(n, v) {
                                floor_m
                            } else {
                                gap
                            }
                        })
                        .fold(f64::NEG_INFINITY, f64::max)
                        + reach;
                    out.upper_m = out.upper_m.max(bound.min(leaf));
                    continue;
                }
                // Split the longest edge: slivers (a tessellated cylinder's faces) become
                // rounder pieces at once instead of four slivers.
                let k = (0..3)
                    .max_by(|&i, &j| {
                        dist(t[i], t[(i + 1) % 3]).total_cmp(&dist(t[j], t[(j + 1) % 3]))
                    })
                    .unwrap_or(0);
                let (p, q, r) = (k, (k + 1) % 3, (k + 2) % 3);
                let m: P3 = std::array::from_fn(|x| 0.5 * (t[p][x] + t[q][x]));
                let gm = g(m, Some(gs[p].1), scratch);
                note(&mut out, m, gm.0);
                stack.push(([t[p], m, t[r]], [gs[p], gm, gs[r]]));
                stack.push(([m, t[q], t[r]], [gm, gs[q], gs[r]]));
            }
            out
        })
        .reduce(GapBound::default, GapBound::join)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ist::build::{build_tree, TreeBuilder};
    use proptest::prelude::*;

    proptest! {
        /// A hint changes nothing: the same distance and sphere (the first in the tree's order
        /// among equals) as the plain descent and as brute force, spheres on a coarse grid
        /// so that equal distances occur.
        #[test]
        fn a_hinted_nearest_is_the_nearest(
            spheres in prop::collection::vec(
                (prop::array::uniform3(0u8..6), 1u8..4), 1..60),
            p in prop::array::uniform3(-0.05f64..0.35),
            hint in any::<prop::sample::Index>(),
            median in any::<bool>(),
        ) {
            let spheres: Vec<InnerSphere> = spheres
                .iter()
                .map(|(c, r)| InnerSphere {
                    center: c.map(|x| f32::from(x) * 0.05),
                    radius: f32::from(*r) * 0.01,
                })
                .collect();
            let builder = if median { TreeBuilder::MedianSplit } else { TreeBuilder::NeuralGas };
            let (nodes, spheres) = build_tree(spheres, builder);
            let index = SphereIndex { nodes: &nodes, spheres: &spheres, slack: 1e-6 };
            let mut stack = Vec::new();
            let plain = index.nearest(p, None, &mut stack);
            let hinted = index.nearest(p, Some(hint.index(spheres.len())), &mut stack);
            prop_assert_eq!(plain.0.to_bits(), hinted.0.to_bits());
            prop_assert_eq!(plain.1, hinted.1);
            let brute = spheres
                .iter()
                .map(|s| dist(p, widen(s.center)) - s.radius as f64)
                .fold(f64::INFINITY, f64::min);
            prop_assert_eq!(plain.0.to_bits(), brute.to_bits());
        }
    }
}
