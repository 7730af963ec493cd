//! Exact refinement: the inner-sphere pass as a filter for exact point–mesh distance.
//!
//! For a point p and link l, the inner-sphere distance d and the surface gap h bound the exact
//! distance e to the collision mesh: `max(0, d − h) ≤ e ≤ d`. The exact minimum E is therefore
//! at most the best sphere distance U, and only pairs with `d − h ≤ U` can attain it; the sphere
//! pass pruned with `U + h` and kept those pairs as candidates. Here they are sorted by lower
//! bound and refined with exact point–triangle distance (parry3d's BVH over the link's
//! triangles, a BVH descent bounded by the best exact value so far); a candidate whose lower
//! bound exceeds the best exact value is skipped. On real scenes a few hundred candidates remain
//! out of hundreds of thousands of points, and most of them are skipped.
//!
//! Candidates whose lower bound is 0 may be inside the mesh; they get the unbounded projection,
//! whose inside test (parry's pseudo-normals on the oriented closed mesh) is reliable at any
//! depth. The others are known to be outside, so the bounded projection is safe for them.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use rayon::prelude::*;

use super::bounds::{load_distance, pack_minimum, unpack_minimum, EMPTY};
use super::layout::{Candidate, PosedLink};
use super::link::QueryLink;
use super::result::StageCounts;
use crate::packing::Solid;

/// The exact minimum: distance, link, point and the closest mesh point (link frame).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Refined {
    pub distance: f32,
    pub link: usize,
    pub point: u32,
    pub robot_point: [f32; 3],
}

/// Exact distance from `p` (link frame) to a link made of `solids`, if at most `bound`.
pub fn link_distance(
    solids: &[Solid],
    p: [f32; 3],
    bound: f32,
    may_be_inside: bool,
) -> Option<(f32, [f32; 3])> {
    let mut best: Option<(f32, [f32; 3])> = None;
    for solid in solids {
        let b = best.map_or(bound, |b| b.0);
        let r = if may_be_inside {
            Some(solid.distance(p)).filter(|r| r.0 <= b)
        } else {
            solid.distance_within(p, b)
        };
        if let Some(r) = r {
            if best.is_none_or(|b| r.0 < b.0) {
                best = Some(r);
            }
        }
    }
    best
}

pub(crate) fn refine(
    links: &[QueryLink],
    posed: &[PosedLink],
    candidates: &mut Vec<Candidate>,
    points: &(dyn Fn(u32) -> [f32; 3] + Sync),
    upper: f32,
    counts: &mut StageCounts,
) -> Option<Refined> {
    candidates.retain(|c| c.lower <= upper);
    if candidates.is_empty() {
        return None;
    }
    // By lower bound, then link and coordinates, so that a point repeated in the cloud is
    // refined once (the copy with the smallest index is kept: same distance, and the smaller
    // index wins a tie), then index: the order, and the result, do not depend on the order
    // the sweep found the candidates in.
    let key = |c: &Candidate| {
        let p = points(c.point);
        (c.lower.to_bits(), c.link, p.map(f32::to_bits), c.point)
    };
    candidates.sort_unstable_by_key(key);
    candidates.dedup_by(|b, a| a.link == b.link && points(a.point) == points(b.point));
    let best = AtomicU64::new(EMPTY);
    let refined = AtomicU64::new(0);
    let inside = Mutex::new(Vec::new());
    let evaluate = |k: usize, c: &Candidate| {
        // Skipped when it cannot beat the best (distance, position): its exact distance is at
        // least its lower bound, and a tie goes to the earlier candidate. Candidates with
        // lower bound 0 are all refined: they may be inside the robot, which is counted.
        if c.lower > 0.0 && pack_minimum(c.lower, k as u32) > best.load(Relaxed) {
            return;
        }
        let bound = load_distance(&best);
        let l = c.link as usize;
        let q = posed[l].in_link(points(c.point));
        refined.fetch_add(1, Relaxed);
        if let Some((e, _)) = link_distance(&links[l].solids, q, bound, c.lower == 0.0) {
            if e == 0.0 {
                inside
                    .lock()
                    .unwrap_or_else(|poisoned| poisoned.into_inner())
                    .push(c.point);
            }
            best.fetch_min(pack_minimum(e, k as u32), Relaxed);
        }
    };
    // The first candidate alone, so that the parallel rest starts with a bound.
    evaluate(0, &candidates[0]);
    candidates[1..]
        .par_iter()
        .enumerate()
        .for_each(|(k, c)| evaluate(k + 1, c));
    counts.exact_refined = refined.into_inner();
    let mut inside = inside
        .into_inner()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    inside.sort_unstable();
    inside.dedup();
    counts.inside = inside.len() as u64;
    let v = best.into_inner();
    if v == EMPTY {
        return None;
    }
    let (distance, k) = unpack_minimum(v);
    let c = candidates[k as usize];
    let l = c.link as usize;
    let q = posed[l].in_link(points(c.point));
    let (_, robot_point) = link_distance(&links[l].solids, q, f32::INFINITY, true)?;
    Some(Refined {
        distance,
        link: l,
        point: c.point,
        robot_point,
    })
}
