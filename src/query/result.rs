//! Steps 4 and 5 of a query, one code path for both backends: once [`Bounds`] holds the minima,
//! the exact candidates and the counts of the sweep (from the CPU traversal or read back from
//! the GPU), the exact candidates are refined (`exact.rs`) and the result is assembled: the
//! nearest point and link, the closest robot point (on the nearest inner sphere, or on the mesh
//! in exact mode), the per-link minima with their certified lower bounds, and the outcome.

use std::sync::atomic::Ordering::Relaxed;

use nalgebra::{Isometry3, Point3};

use super::bounds::{load_f32, threshold, unpack_minimum, Bounds, EMPTY};
use super::descent::{dist, nearest_sphere};
use serde::Serialize;

use super::{exact, Backend, Input, Mode, QueryLink, QueryOptions};

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
    assemble(
        links,
        bounds,
        &points,
        root_from_sensor,
        link_poses,
        options,
        counts,
        refined,
        backend,
    )
}

#[allow(clippy::too_many_arguments)]
fn assemble(
    links: &[QueryLink],
    bounds: &Bounds,
    points: &dyn Fn(u32) -> [f32; 3],
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
    options: &QueryOptions,
    counts: StageCounts,
    refined: Option<exact::Refined>,
    backend: Backend,
) -> QueryResult {
    let certified = options.mode != Mode::Fast;
    // Finite: an empty minimum is +∞, which an infinite max_distance would let through.
    let within = |d: f32| d.is_finite() && d <= options.max_distance_m;
    let per_link: Vec<(f32, u32)> = bounds
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
        .collect();
    let mut nearest_link = None;
    for (l, &(d, _)) in per_link.iter().enumerate() {
        if within(d) && nearest_link.is_none_or(|n: usize| d < per_link[n].0) {
            nearest_link = Some(l);
        }
    }
    // Recorded by both backends with or without per-link minima: the smallest `d − h` of any
    // (point, link) pair, which is the minimum over the links (see `bounds::threshold`).
    let global_lower = load_f32(&bounds.global_lower);
    let to_root = |p: [f32; 3]| {
        let q = root_from_sensor * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        [q.x, q.y, q.z]
    };
    // The closest point of link `l`'s inner spheres to cloud point `p`, in the root frame.
    let sphere_point = |l: usize, p: [f32; 3]| {
        let link = &links[l];
        let q = bounds.posed[l].in_link(p);
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
        let r = link_poses[link.pose_index] * Point3::new(on[0] as f64, on[1] as f64, on[2] as f64);
        [r.x, r.y, r.z]
    };
    let link_results = if options.per_link {
        let (global, lower) = (load_f32(&bounds.global), load_f32(&bounds.global_lower));
        per_link
            .iter()
            .zip(links)
            .zip(&bounds.posed)
            .enumerate()
            .map(|(l, ((&(d, p), link), posed))| {
                // The final threshold: a link whose minimum lies above it was not measured, and
                // every point lies farther than it (the threshold only decreased).
                let t = threshold(
                    options.mode,
                    true,
                    options.per_link_range_m,
                    global,
                    lower,
                    d,
                    posed.gap,
                );
                let measured = d <= t && within(d);
                let farther = (!measured).then(|| t.min(options.max_distance_m));
                LinkDistance {
                    link: link.name.clone(),
                    distance_m: measured.then_some(d as f64),
                    lower_m: certified.then(|| (farther.unwrap_or(d) - link.gap_m).max(0.0) as f64),
                    farther_than_m: farther.map(f64::from),
                    exact_m: refined
                        .as_ref()
                        .filter(|r| r.link == l)
                        .map(|r| r.distance as f64),
                    point_index: measured.then_some(p),
                    // Both points of the link's minimum (where the separation monitor takes
                    // the link's approach speed).
                    witness: measured.then(|| {
                        let q = points(p);
                        (to_root(q), sphere_point(l, q))
                    }),
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    let nearest = match (&refined, nearest_link) {
        (Some(r), _) if within(r.distance) => {
            let link = &links[r.link];
            let p = points(r.point);
            let q = link_poses[link.pose_index]
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
                point_root: to_root(p),
                robot_point_root: [q.x, q.y, q.z],
            })
        }
        (None, Some(l)) => {
            let (d, i) = per_link[l];
            let link = &links[l];
            let p = points(i);
            Some(Nearest {
                distance_m: d as f64,
                lower_m: certified.then_some(global_lower as f64),
                link: link.name.clone(),
                point_index: i,
                point_sensor: p,
                point_root: to_root(p),
                robot_point_root: sphere_point(l, p),
            })
        }
        _ => None,
    };
    // Links packed as convex hulls: their inner spheres may lie outside the link, so only
    // their certified lower bound holds for the link, and it is their distance. Exact mode
    // measures the hull itself, which contains the link: already a lower bound.
    let hull = |l: &QueryLink| l.convex_hull && options.mode != Mode::Exact;
    let mut link_results = link_results;
    for (r, link) in link_results.iter_mut().zip(links).filter(|(_, l)| hull(l)) {
        // In fast mode too: the hull's bound is the only distance that holds for the link.
        r.lower_m = r
            .farther_than_m
            .or(r.distance_m)
            .map(|d| (d - link.gap_m as f64).max(0.0));
        if r.distance_m.is_some() {
            r.distance_m = r.lower_m;
        }
    }
    let mut nearest = nearest;
    if let Some(n) = nearest.as_mut().filter(|_| links.iter().any(hull)) {
        // The smallest lower bound of a hull link, measured or farther than a bound (every
        // link's, without per-link minima).
        let hull_lower = if options.per_link {
            link_results
                .iter()
                .zip(links)
                .filter(|(_, l)| hull(l))
                .filter_map(|(r, _)| r.lower_m.map(|d| (d, r)))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(d, r)| (d, Some(r)))
        } else {
            Some((global_lower.max(0.0) as f64, None))
        };
        if let Some((d, r)) = hull_lower.filter(|(d, _)| *d < n.distance_m) {
            n.distance_m = d;
            n.lower_m = Some(n.lower_m.map_or(d, |l| l.min(d)));
            if let Some(r) = r {
                n.link = r.link.clone();
                if let (Some(i), Some((p, q))) = (r.point_index, r.witness) {
                    n.point_index = i;
                    n.point_sensor = points(i);
                    n.point_root = p;
                    n.robot_point_root = q;
                }
            }
        }
    }
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
        self_filtered_by_link: links
            .iter()
            .zip(&bounds.self_filtered)
            .map(|(link, n)| (link.name.clone(), n.load(Relaxed)))
            .filter(|(_, n)| *n > 0)
            .collect(),
        // Set by the engine, which knows the cloud's frame.
        point_spacing_m: 0.0,
    }
}

/// How the query ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// A nearest obstacle point was found within `max_distance_m`.
    Nearest,
    /// The cloud had no valid point.
    NoPoints,
    /// Valid points, but none within `max_distance_m` (after the self-filter).
    NothingWithinMaxDistance,
}

/// How many points each stage dropped. `total = invalid + outside_roi + self_filtered + pruned
/// + evaluated`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StageCounts {
    pub total: u64,
    /// NaN, infinite or (0, 0, 0).
    pub invalid: u64,
    /// Farther than `max_distance_m` from the robot's bounding box.
    pub outside_roi: u64,
    /// The robot itself (within the self-filter padding).
    pub self_filtered: u64,
    /// Dropped by the shared bound before any tree descent.
    pub pruned: u64,
    /// Descended at least one tree.
    pub evaluated: u64,
    /// Obstacle points inside the robot (distance 0): inside an inner sphere (all modes), or
    /// inside a collision mesh among the exact candidates (exact mode).
    pub inside: u64,
    /// Exact point–mesh distances computed (exact mode).
    pub exact_refined: u64,
}

impl std::ops::Add for StageCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            total: self.total + o.total,
            invalid: self.invalid + o.invalid,
            outside_roi: self.outside_roi + o.outside_roi,
            self_filtered: self.self_filtered + o.self_filtered,
            pruned: self.pruned + o.pruned,
            evaluated: self.evaluated + o.evaluated,
            inside: self.inside + o.inside,
            exact_refined: self.exact_refined + o.exact_refined,
        }
    }
}

/// The nearest obstacle point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Nearest {
    /// The mode's distance: the inner-sphere upper bound (fast, certified) or the exact distance.
    pub distance_m: f64,
    /// The certified lower bound over all links (certified), or the exact distance (exact).
    pub lower_m: Option<f64>,
    pub link: String,
    pub point_index: u32,
    /// The cloud point, in the sensor frame.
    pub point_sensor: [f32; 3],
    /// The cloud point and the closest robot point, in the root frame.
    pub point_root: [f64; 3],
    pub robot_point_root: [f64; 3],
}

/// One link's minimum over the obstacle points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinkDistance {
    pub link: String,
    /// Inner-sphere distance (upper bound); `None` when the link was not measured: no point
    /// within `max_distance_m`, or the link lies beyond `per_link_range_m` (then
    /// `farther_than_m` says how far at least).
    pub distance_m: Option<f64>,
    /// Certified lower bound `max(0, d − h)` of the link's true distance (certified and exact
    /// modes); for a link not measured, `max(0, farther_than − h)`.
    pub lower_m: Option<f64>,
    /// For a link not measured: every obstacle point's inner-sphere distance to it exceeds this
    /// (at most `max_distance_m`).
    pub farther_than_m: Option<f64>,
    /// Exact distance, for the nearest link in exact mode.
    pub exact_m: Option<f64>,
    pub point_index: Option<u32>,
    /// For a measured link: the cloud point of its minimum and the closest point of its inner
    /// spheres to it, both in the root frame.
    pub witness: Option<([f64; 3], [f64; 3])>,
}

/// The result of one query.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QueryResult {
    pub mode: Mode,
    /// Where it ran.
    pub backend: Backend,
    pub outcome: Outcome,
    pub max_distance_m: f32,
    pub nearest: Option<Nearest>,
    /// Per-link minima (only when `per_link`), in the engine's link order.
    pub links: Vec<LinkDistance>,
    pub counts: StageCounts,
    /// The links the self-filtered points were taken as (a link within the padding: on the CPU
    /// the one that took the point before it if it does, else the first in engine order; on the
    /// GPU the first in engine order), with their counts; links with none are left out.
    pub self_filtered_by_link: Vec<(String, u64)>,
    /// The spacing of the cloud's f32 coordinates where the robot is, m: every point is known to
    /// within √3/2 of it, and the interval holds for the points as given.
    pub point_spacing_m: f32,
    /// Points the monitor's stray-point filter rejected (`config::StrayFilter`; 0 here).
    pub stray_rejected: u64,
    /// Points the monitor's exclusion volumes dropped before the query, per volume that applies
    /// to the source (`cloud::exclusion`; none here). They are among `counts.invalid`.
    pub excluded: Vec<(String, u64)>,
}
