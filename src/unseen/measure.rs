//! The search's distance over a batch of hidden centres, best first: per link the least
//! certified lower bound over the batch (where it can still lower that link's best), and the
//! least over every link (where it can still lower the nearest), measured on the inner sphere
//! trees only where a cheaper bound says it may matter.
//!
//! Inputs: the monitored links ([`QueryLink`]: inner sphere trees and surface gaps h) at the
//! frame's poses (`root_from_link`, f64, rounded to f32 once per link), their bounds at those
//! poses ([`LinkBound`]: bounding sphere and covers, root frame), a batch of root-frame centres,
//! and per link the distance below which its minimum is still wanted. Output: a [`Batch`], the
//! answer the engine's query gives for these points with those per-link ranges (certified
//! mode, no self-filter): a pair (centre, link) is at `max(0, d − h)`, `d` the distance from the
//! centre to the link's nearest inner sphere clamped at 0.
//!
//! **Why not the engine.** The engine measures clouds: hundreds of thousands of points in
//! blocks, one shared bound. The search asks of a few hundred centres, each link apart, most
//! links' minima still open to the per-link range: the engine then descends every link's tree
//! for nearly every centre (0.6 ms for the Kinect frame's first wave of 466 centres and 11
//! links). Here the pairs are taken in the order of a lower bound, refined lazily: the link's
//! bounding sphere first (one distance), then its covers (`robot::COVERS`), then its tree
//! ([`nearest_sphere`], bounded by what is still wanted). A pair is dropped as soon as its bound
//! cannot lower its link's best nor the nearest: a link's minimum is final after the few pairs
//! whose bounds lie below it.
//!
//! Exactness: a pair's bound never exceeds its distance, so every pair below a final best was
//! measured on the tree, and the results are those of measuring every pair (f32 arithmetic of
//! the engine's descent; the property test below against brute force in f64).
//!
//! Cost: per pair one distance (the bounding sphere), per pair within reach one per cover, per pair
//! that may matter a descent; a heap over the pairs within reach.

use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use nalgebra::Isometry3;
use rayon::prelude::*;

use crate::query::{nearest_sphere, QueryLink};

use super::least::Least;
use super::robot::{LinkBound, Rigid32};

/// The caller's certified distance over a batch of root-frame points.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// The least certified lower bound (m), `None` when none lies within the query's reach.
    pub lower_m: Option<f64>,
    /// The batch index of the point it was found at.
    pub nearest: Option<usize>,
    /// Per link (the engine's order), the least lower bound over the batch (m; a bound it
    /// exceeds where the query measured it no farther). Empty without per-link minima.
    pub per_link: Vec<f64>,
}

/// The links at a frame's poses, ready to measure batches of centres.
pub struct Measure<'a> {
    links: &'a [QueryLink],
    bounds: &'a [LinkBound],
    link_from_root: Vec<Rigid32>,
    /// Beyond this (m), nothing is measured: the query's reach (`max_distance`).
    max_m: f64,
    /// A best at or below this (m) is final: the search takes every distance there as 0 (the
    /// ball's margin).
    final_m: f32,
}

/// How far a pair's bound is refined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// The link's bounding sphere.
    Sphere,
    /// The link's covers.
    Covers,
}

/// A centre of the batch (its index) and the stage its lower bound from one link came from.
type Pair = Least<(u32, Stage)>;

impl<'a> Measure<'a> {
    /// `links` at `poses` (`root_from_link`, indexed by each link's `pose_index`), `bounds`
    /// their [`LinkBound`]s at the same poses (the same order), measured up to `max_m`.
    pub fn new(
        links: &'a [QueryLink],
        poses: &[Isometry3<f64>],
        bounds: &'a [LinkBound],
        max_m: f64,
        final_m: f64,
    ) -> Self {
        assert_eq!(links.len(), bounds.len(), "a bound per link");
        Self {
            links,
            bounds,
            link_from_root: (links.iter())
                .map(|l| Rigid32::of(&poses[l.pose_index].inverse()))
                .collect(),
            max_m,
            final_m: final_m as f32,
        }
    }

    /// The batch over `centres` (root frame): the least certified lower bound over every link
    /// where it is below `need` (and `max_m`), with its centre; per link (`needs`, the
    /// engine's order; empty: none), the least lower bound over the batch where it is below
    /// the link's need, else that need (a bound every pair of the link reaches); +∞ for a link
    /// whose need is −∞ (final: not measured). Links in parallel, the nearest shared between
    /// them (an atomic minimum of the distance's bits and the centre's index).
    pub fn batch(&self, centres: &[[f32; 3]], need: f64, needs: &[f64]) -> Batch {
        let overall = need.min(self.max_m) as f32;
        let own = |l: usize| needs.get(l).map_or(f32::NEG_INFINITY, |&n| n as f32);
        let nearest = AtomicU64::new(u64::MAX);
        let per_link: Vec<f32> = (0..self.links.len())
            .into_par_iter()
            .map(|l| self.link(l, centres, overall, own(l), &nearest))
            .collect();
        let v = nearest.load(Relaxed);
        let (best, index) = (f32::from_bits((v >> 32) as u32), v as u32);
        let found = v != u64::MAX && best < overall;
        Batch {
            lower_m: found.then_some(f64::from(best)),
            nearest: found.then_some(index as usize),
            per_link: (0..needs.len())
                .map(|l| match own(l) {
                    f32::NEG_INFINITY => f64::INFINITY,
                    n => f64::from(per_link[l].min(n)),
                })
                .collect(),
        }
    }

    /// Link `l`'s least lower bound over `centres` where below `own` or below the nearest
    /// (`overall` and `nearest`, which it lowers): its pairs best first.
    fn link(
        &self,
        l: usize,
        centres: &[[f32; 3]],
        overall: f32,
        own: f32,
        nearest: &AtomicU64,
    ) -> f32 {
        let (b, link) = (&self.bounds[l], &self.links[l]);
        // A final best (at or below the margin) wants nothing more.
        let open = |x: f32| {
            if x > self.final_m {
                x
            } else {
                f32::NEG_INFINITY
            }
        };
        let wanted = |best: f32| {
            let all = f32::from_bits((nearest.load(Relaxed) >> 32) as u32);
            open(overall.min(all)).max(open(own.min(best)))
        };
        // Beyond the bounding sphere's reach of what is wanted: not a pair (squared first).
        let first = open(overall).max(open(own));
        let mut heap: BinaryHeap<Pair> = (centres.iter().enumerate())
            .filter(|(_, &p)| b.sphere_within(p, first))
            .map(|(i, &p)| Pair {
                bound: b.sphere_bound(p),
                item: (i as u32, Stage::Sphere),
            })
            .collect();
        let mut best = f32::INFINITY;
        while let Some(pair) = heap.pop() {
            let limit = wanted(best);
            if pair.bound >= limit {
                break;
            }
            let (centre, stage) = pair.item;
            let p = centres[centre as usize];
            if stage == Stage::Sphere && !b.covers.is_empty() {
                // Two lower bounds: the larger holds.
                let bound = b.covers_bound(p).max(pair.bound);
                if bound < limit {
                    heap.push(Pair {
                        bound,
                        item: (centre, Stage::Covers),
                    });
                }
                continue;
            }
            let q = self.link_from_root[l].apply(p);
            if let Some((d, _)) = nearest_sphere(link, q, limit + link.gap_m) {
                let lower = (d - link.gap_m).max(0.0);
                best = best.min(lower);
                nearest.fetch_min(
                    ((lower.to_bits() as u64) << 32) | u64::from(centre),
                    Relaxed,
                );
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ist::IstNode;
    use crate::packing::InnerSphere;
    use crate::unseen::robot::link_bounds;
    use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
    use proptest::prelude::*;

    /// The test's own draws (xorshift).
    struct Draw(u64);

    impl Draw {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }

        fn pick<T: Copy>(&mut self, from: &[T]) -> T {
            from[(self.next() * from.len() as f64) as usize % from.len()]
        }
    }

    /// The bounding sphere of spheres (centroid, largest reach), a little grown.
    fn enclosing(spheres: &[([f32; 3], f32)]) -> ([f32; 3], f32) {
        let n = spheres.len() as f32;
        let c: [f32; 3] = std::array::from_fn(|k| spheres.iter().map(|s| s.0[k]).sum::<f32>() / n);
        let r = (spheres.iter())
            .map(|s| (0..3).map(|k| (s.0[k] - c[k]).powi(2)).sum::<f32>().sqrt() + s.1)
            .fold(0.0f32, f32::max);
        (c, r * 1.001 + 1e-5)
    }

    /// A link of up to 16 spheres in a two-level tree (a root over groups of up to four).
    fn link(draw: &mut Draw, pose_index: usize) -> QueryLink {
        let groups = 1 + (draw.next() * 4.0) as usize % 4;
        let (mut nodes, mut spheres) = (Vec::new(), Vec::new());
        let mut group_spheres = Vec::new();
        for _ in 0..groups {
            let centre = [0; 3].map(|_| draw.range(-0.15, 0.15) as f32);
            let count = 1 + (draw.next() * 4.0) as usize % 4;
            let members: Vec<([f32; 3], f32)> = (0..count)
                .map(|_| {
                    let c = centre.map(|x| x + draw.range(-0.05, 0.05) as f32);
                    (c, draw.range(0.005, 0.06) as f32)
                })
                .collect();
            let (c, r) = enclosing(&members);
            nodes.push(IstNode {
                center: c,
                radius: r,
                first_child: spheres.len() as u32,
                child_count: count as u32,
                children_are_spheres: 1,
                pad: 0,
            });
            group_spheres.push((c, r));
            spheres.extend(
                members
                    .iter()
                    .map(|&(center, radius)| InnerSphere { center, radius }),
            );
        }
        let (c, r) = enclosing(&group_spheres);
        let root = IstNode {
            center: c,
            radius: r,
            first_child: 1,
            child_count: groups as u32,
            children_are_spheres: 0,
            pad: 0,
        };
        nodes.insert(0, root);
        let gap = draw.pick(&[0.0f32, 0.002, 0.01]);
        QueryLink::new(
            format!("link{pose_index}"),
            pose_index,
            nodes,
            spheres,
            gap,
            Vec::new(),
        )
    }

    /// The certified lower bound from `p` (root frame) to `link` at `pose`, in f64.
    fn certified(link: &QueryLink, pose: &Isometry3<f64>, p: [f32; 3]) -> f64 {
        let q = pose.inverse() * Point3::from(p.map(f64::from));
        let d = (link.spheres.iter())
            .map(|s| (q - Point3::from(s.center.map(f64::from))).norm() - f64::from(s.radius))
            .fold(f64::INFINITY, f64::min);
        (d.max(0.0) - f64::from(link.gap_m)).max(0.0)
    }

    proptest! {
        /// Against every pair measured in f64: each link's minimum where below its need (else
        /// the need, which every pair reaches; +∞ when final), the nearest where below the
        /// overall need, both at most the truth and never below what is wanted of them; a
        /// minimum or a need at or below the margin only said to be there.
        #[test]
        fn best_first_against_every_pair(seed in 1u64.., n in 1usize..300) {
            let mut draw = Draw(seed);
            let count = 1 + (draw.next() * 4.0) as usize % 4;
            let links: Vec<QueryLink> = (0..count).map(|i| link(&mut draw, i)).collect();
            let poses: Vec<Isometry3<f64>> = (0..count)
                .map(|_| {
                    let t = Vector3::from_fn(|_, _| draw.range(-0.3, 0.3));
                    let axis = Vector3::from_fn(|_, _| draw.range(-2.0, 2.0));
                    Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(axis))
                })
                .collect();
            let bounds = link_bounds(&links, &poses);
            let centres: Vec<[f32; 3]> = (0..n).map(|_| [0; 3].map(|_| draw.range(-0.6, 0.6) as f32)).collect();
            let needs_from = [f64::NEG_INFINITY, 0.02, 0.1, 0.3, f64::INFINITY];
            let needs: Vec<f64> = match draw.next() < 0.8 {
                true => (0..count).map(|_| draw.pick(&needs_from)).collect(),
                false => Vec::new(),
            };
            let need = draw.pick(&needs_from);
            let max_m = draw.pick(&[0.25, f64::INFINITY]);
            let final_m = draw.pick(&[0.0, 0.01, 0.04]);
            let got = Measure::new(&links, &poses, &bounds, max_m, final_m).batch(&centres, need, &needs);
            let tol = 1e-5;
            // The truth, per link and over them.
            let truth: Vec<f64> = (0..count)
                .map(|l| (centres.iter()).map(|&p| certified(&links[l], &poses[l], p)).fold(f64::INFINITY, f64::min))
                .collect();
            let nearest = |i: usize| (0..count).map(|l| certified(&links[l], &poses[l], centres[i])).fold(f64::INFINITY, f64::min);
            let all = truth.iter().copied().fold(f64::INFINITY, f64::min);
            prop_assert_eq!(got.per_link.len(), needs.len());
            for (l, (&g, &own)) in got.per_link.iter().zip(&needs).enumerate() {
                let t = truth[l];
                if own == f64::NEG_INFINITY {
                    prop_assert_eq!(g, f64::INFINITY);
                    continue;
                }
                if t > final_m + tol && own > final_m {
                    prop_assert!(g <= t + tol, "link {l}: {g} above the truth {t}");
                    prop_assert!(g >= t.min(own) - tol, "link {l}: {g} below the truth {t} and the need {own}");
                } else {
                    prop_assert!(g <= final_m + tol, "link {l}: {g}, the truth {t} or the need {own} final");
                }
            }
            let overall = need.min(max_m);
            match (got.lower_m, got.nearest) {
                (Some(d), Some(i)) => {
                    prop_assert!(d >= all - tol && d < overall + tol, "nearest {d}: truth {all}, need {overall}");
                    prop_assert!(nearest(i) <= d + tol, "nearest {d} at a centre {} from the robot", nearest(i));
                    if all > final_m + tol {
                        prop_assert!((d - all).abs() < tol, "nearest {d}, truth {all}");
                    } else {
                        prop_assert!(d <= final_m + tol, "nearest {d}, the truth {all} final");
                    }
                }
                (None, None) => prop_assert!(all >= overall - tol || overall <= final_m,
                    "nothing found below {overall}; truth {all}"),
                other => prop_assert!(false, "{other:?}"),
            }
        }
    }
}
