//! Steps 4 and 5 of a query, one code path for both backends: once [`Bounds`] holds the minima,
//! the exact candidates and the counts of the sweep (from the CPU traversal or read back from
//! the GPU), the exact candidates are refined (`exact.rs`) and the result is assembled: the
//! nearest point and link, the closest robot point (on the nearest inner sphere, or on the mesh
//! in exact mode), the per-link minima with their certified lower bounds, and the outcome.

use std::sync::atomic::Ordering::Relaxed;

use nalgebra::{Isometry3, Point3};

use super::bounds::{load_f32, threshold, unpack_minimum, Bounds, EMPTY};
use super::descent::{dist, nearest_sphere};
use super::{
    exact, Backend, Input, LinkDistance, Mode, Nearest, Outcome, QueryLink, QueryOptions,
    QueryResult, StageCounts,
};

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
