//! Steps 4 and 5 of a query, one code path for both backends: once [`Bounds`] holds the minima,
//! the exact candidates and the counts of the sweep (from the CPU traversal or read back from
//! the GPU), the exact candidates are refined (`exact.rs`) and the result is assembled: the
//! nearest point and link, the closest robot point (on the nearest inner sphere, or on the mesh
//! in exact mode), the per-link minima with their certified lower bounds, and the outcome.

use std::sync::atomic::Ordering::Relaxed;

use nalgebra::{Isometry3, Point3};

use super::bounds::{load_f32, threshold, unpack_minimum, Bounds, EMPTY};
use super::descent::{dist, nearest_sphere};
use super::exact;
use super::input::Input;
use super::link::QueryLink;
use super::options::{Backend, Mode, QueryOptions};
use super::result::{LinkDistance, Nearest, Outcome, QueryResult, StageCounts};

/// Exact refinement, then the result, from what `bounds` holds after `backend`'s sweep.
pub(super) fn finish(
    links: &[QueryLink],
    bounds: &mut Bounds,
    input: Input,
    mut counts: StageCounts,
    backend: Backend,
) -> QueryResult {
    let points = |i: u32| input.point(i);
    let Input {
        root_from_sensor,
        link_poses,
        options,
        ..
    } = input;
    // 4. Exact refinement.
    let refined = if options.mode == Mode::Exact {
        let upper = load_f32(&bounds.global);
        let posed = &bounds.posed;
        let candidates = bounds
            .candidates
            .get_mut()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        exact::refine(links, posed, candidates, &points, upper, &mut counts)
    } else {
        None
    };
    // 5. The result.
    let assembly = Assembly {
        links,
        bounds,
        points: &points,
        root_from_sensor,
        link_poses,
        options,
    };
    assembly.result(counts, refined, backend)
}

/// What the result is assembled from: the links, the bounds after the sweep, the query's
/// points (by index), its poses and options.
struct Assembly<'a> {
    links: &'a [QueryLink],
    bounds: &'a Bounds,
    points: &'a dyn Fn(u32) -> [f32; 3],
    root_from_sensor: &'a Isometry3<f64>,
    link_poses: &'a [Isometry3<f64>],
    options: &'a QueryOptions,
}

impl Assembly<'_> {
    /// The result: per-link minima, the nearest point, the convex-hull links' bounds over
    /// both, and the outcome.
    fn result(
        &self,
        counts: StageCounts,
        refined: Option<exact::Refined>,
        backend: Backend,
    ) -> QueryResult {
        let options = self.options;
        let per_link = self.minima();
        let mut link_results = if options.per_link {
            self.link_distances(&per_link, refined.as_ref())
        } else {
            Vec::new()
        };
        let mut nearest = self.nearest(&per_link, refined.as_ref());
        self.hull_bounds(&mut link_results, &mut nearest);
        let outcome = if counts.total == counts.invalid {
            Outcome::NoPoints
        } else if nearest.is_some() {
            Outcome::Nearest
        } else {
            Outcome::NothingWithinMaxDistance
        };
        QueryResult {
            mode: options.mode,
            backend,
            outcome,
            max_distance_m: options.max_distance_m,
            nearest,
            links: link_results,
            counts,
            stray_rejected: 0,
            excluded: Vec::new(),
            self_filtered_by_link: self
                .links
                .iter()
                .zip(&self.bounds.self_filtered)
                .map(|(link, n)| (link.name.clone(), n.load(Relaxed)))
                .filter(|(_, n)| *n > 0)
                .collect(),
            // Set by the engine, which knows the cloud's frame.
            point_spacing_m: 0.0,
        }
    }

    /// Whether a distance is a result: finite (an empty minimum is +∞, which an infinite
    /// max_distance would let through) and within max_distance.
    fn within(&self, d: f32) -> bool {
        d.is_finite() && d <= self.options.max_distance_m
    }

    /// Each link's minimum and its point (+∞ and `u32::MAX` for none).
    fn minima(&self) -> Vec<(f32, u32)> {
        self.bounds
            .best
            .iter()
            .map(|b| {
                let v = b.load(Relaxed);
                if v == EMPTY {
                    (f32::INFINITY, u32::MAX)
                } else {
                    unpack_minimum(v)
                }
            })
            .collect()
    }

    /// Recorded by both backends with or without per-link minima: the smallest `d − h` of any
    /// (point, link) pair, which is the minimum over the links (see `bounds::threshold`).
    fn global_lower(&self) -> f32 {
        load_f32(&self.bounds.global_lower)
    }

    /// A cloud point in the root frame.
    fn to_root(&self, p: [f32; 3]) -> [f64; 3] {
        let q = self.root_from_sensor * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        [q.x, q.y, q.z]
    }

    /// The closest point of link `l`'s inner spheres to cloud point `p`, in the root frame.
    fn sphere_point(&self, l: usize, p: [f32; 3]) -> [f64; 3] {
        let link = &self.links[l];
        let q = self.bounds.posed[l].in_link(p);
        // A tree has at least one sphere (checked when the engine is made), so an unbounded
        // descent always finds one; the sphere point is the fallback anyway.
        let s = nearest_sphere(link, q, f32::INFINITY)
            .map_or(link.spheres[0], |(_, s)| link.spheres[s as usize]);
        let v = [q[0] - s.center[0], q[1] - s.center[1], q[2] - s.center[2]];
        let n = dist(q, s.center);
        let on = if n <= s.radius {
            q
        } else {
            let f = s.radius / n;
            [
                s.center[0] + f * v[0],
                s.center[1] + f * v[1],
                s.center[2] + f * v[2],
            ]
        };
        let r = self.link_poses[link.pose_index]
            * Point3::new(on[0] as f64, on[1] as f64, on[2] as f64);
        [r.x, r.y, r.z]
    }

    /// Each link's distance (per-link minima): measured, or farther than its final threshold.
    fn link_distances(
        &self,
        per_link: &[(f32, u32)],
        refined: Option<&exact::Refined>,
    ) -> Vec<LinkDistance> {
        let options = self.options;
        let certified = options.mode != Mode::Fast;
        let (global, lower) = (
            load_f32(&self.bounds.global),
            load_f32(&self.bounds.global_lower),
        );
        per_link
            .iter()
            .zip(self.links)
            .zip(&self.bounds.posed)
            .enumerate()
            .map(|(l, ((&(d, p), link), posed))| {
                // The final threshold: a link whose minimum lies above it was not measured, and
                // every point lies farther than it (the threshold only decreased).
                let t = threshold(options.mode, true, posed.range, global, lower, d, posed.gap);
                let measured = d <= t && self.within(d);
                let farther = (!measured).then(|| t.min(options.max_distance_m));
                LinkDistance {
                    link: link.name.clone(),
                    distance_m: measured.then_some(d as f64),
                    lower_m: certified.then(|| (farther.unwrap_or(d) - link.gap_m).max(0.0) as f64),
                    farther_than_m: farther.map(f64::from),
                    exact_m: refined.filter(|r| r.link == l).map(|r| r.distance as f64),
                    point_index: measured.then_some(p),
                    // Both points of the link's minimum (where the separation monitor takes
                    // the link's approach speed).
                    witness: measured.then(|| {
                        let q = (self.points)(p);
                        (self.to_root(q), self.sphere_point(l, q))
                    }),
                }
            })
            .collect()
    }

    /// The nearest point: the exact one in exact mode, else the nearest link's minimum.
    fn nearest(
        &self,
        per_link: &[(f32, u32)],
        refined: Option<&exact::Refined>,
    ) -> Option<Nearest> {
        let mut nearest_link = None;
        for (l, &(d, _)) in per_link.iter().enumerate() {
            if self.within(d) && nearest_link.is_none_or(|n: usize| d < per_link[n].0) {
                nearest_link = Some(l);
            }
        }
        match (refined, nearest_link) {
            (Some(r), _) if self.within(r.distance) => {
                let link = &self.links[r.link];
                let p = (self.points)(r.point);
                let q = self.link_poses[link.pose_index]
                    * Point3::new(
                        r.robot_point[0] as f64,
                        r.robot_point[1] as f64,
                        r.robot_point[2] as f64,
                    );
                Some(Nearest {
                    distance_m: r.distance as f64,
                    lower_m: Some(r.distance as f64),
                    link: link.name.clone(),
                    point_index: r.point,
                    point_sensor: p,
                    point_root: self.to_root(p),
                    robot_point_root: [q.x, q.y, q.z],
                })
            }
            (None, Some(l)) => {
                let (d, i) = per_link[l];
                let link = &self.links[l];
                let p = (self.points)(i);
                Some(Nearest {
                    distance_m: d as f64,
                    lower_m: (self.options.mode != Mode::Fast)
                        .then_some(self.global_lower() as f64),
                    link: link.name.clone(),
                    point_index: i,
                    point_sensor: p,
                    point_root: self.to_root(p),
                    robot_point_root: self.sphere_point(l, p),
                })
            }
            _ => None,
        }
    }

    /// Links packed as convex hulls: their inner spheres may lie outside the link, so only
    /// their certified lower bound holds for the link, and it is their distance. Exact mode
    /// measures the hull itself, which contains the link: already a lower bound.
    fn hull_bounds(&self, link_results: &mut [LinkDistance], nearest: &mut Option<Nearest>) {
        let options = self.options;
        let hull = |l: &QueryLink| l.convex_hull && options.mode != Mode::Exact;
        for (r, link) in link_results
            .iter_mut()
            .zip(self.links)
            .filter(|(_, l)| hull(l))
        {
            // In fast mode too: the hull's bound is the only distance that holds for the link.
            r.lower_m = r
                .farther_than_m
                .or(r.distance_m)
                .map(|d| (d - link.gap_m as f64).max(0.0));
            if r.distance_m.is_some() {
                r.distance_m = r.lower_m;
            }
        }
        let Some(n) = nearest.as_mut().filter(|_| self.links.iter().any(hull)) else {
            return;
        };
        // The smallest lower bound of a hull link, measured or farther than a bound (every
        // link's, without per-link minima).
        let hull_lower = if options.per_link {
            link_results
                .iter()
                .zip(self.links)
                .filter(|(_, l)| hull(l))
                .filter_map(|(r, _)| r.lower_m.map(|d| (d, r)))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(d, r)| (d, Some(r)))
        } else {
            Some((self.global_lower().max(0.0) as f64, None))
        };
        if let Some((d, r)) = hull_lower.filter(|(d, _)| *d < n.distance_m) {
            n.distance_m = d;
            n.lower_m = Some(n.lower_m.map_or(d, |l| l.min(d)));
            if let Some(r) = r {
                n.link = r.link.clone();
                if let (Some(i), Some((p, q))) = (r.point_index, r.witness) {
                    n.point_index = i;
                    n.point_sensor = (self.points)(i);
                    n.point_root = p;
                    n.robot_point_root = q;
                }
            }
        }
    }
}
