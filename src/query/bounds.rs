//! The shared bounds of one query, the state that either backend fills and the result assembly
//! (`result.rs`) reads: the posed links, each link's minimum with the point that attains it,
//! the global minimum and certified lower bound, and the exact-mode candidates.
//!
//! Each link's minimum is one `AtomicU64` holding the non-negative f32 distance bits above the
//! point index, so one `fetch_min` keeps both the minimum and the smallest point index that
//! attains it (non-negative f32 bits order like the floats). The GPU, which has no 64-bit
//! atomics, finds the index in its arg-min pass and its minima are packed here on readback.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use nalgebra::Isometry3;
use wide::f32x8;

use super::layout::{Candidate, PosedLink, RobotBox, WORK_COUNTERS};
use super::link::QueryLink;
use super::options::{Mode, QueryOptions};
use super::pose;

/// An empty per-link minimum.
pub(crate) const EMPTY: u64 = u64::MAX;

/// f32 distance and point index packed so that `fetch_min` keeps both.
#[inline]
pub(crate) fn pack_minimum(distance: f32, point: u32) -> u64 {
    ((distance.max(0.0).to_bits() as u64) << 32) | point as u64
}

#[inline]
pub(crate) fn unpack_minimum(v: u64) -> (f32, u32) {
    (f32::from_bits((v >> 32) as u32), v as u32)
}

/// The distance of a packed minimum (+∞ when empty).
#[inline]
pub(crate) fn load_distance(a: &AtomicU64) -> f32 {
    let v = a.load(Relaxed);
    if v == EMPTY {
        f32::INFINITY
    } else {
        unpack_minimum(v).0
    }
}

#[inline]
pub(crate) fn load_f32(a: &AtomicU32) -> f32 {
    f32::from_bits(a.load(Relaxed))
}

/// The largest inner-sphere distance of a link that can still change the result: the pruning
/// rule of both backends (the shader's `threshold` is the same), and, from the final values,
/// the bound a link not measured is known to exceed.
///
/// `global` and `global_lower` are the smallest inner-sphere distance and certified lower bound
/// found so far, `link_best` the link's own minimum so far, `gap` its surface gap h.
/// - Without per-link minima a point matters to a link only if it can lower the global minimum
///   (fast), the global lower bound `d − h` (certified), or be an exact candidate, `d − h ≤ U`
///   (exact).
/// - With per-link minima a point also matters while it can lower the link's own minimum, but
///   only below `range` (`QueryOptions::per_link_range_m`): beyond it a link's minimum cannot
///   change a decision, and the link is reported as "farther than" the final threshold.
///
/// Every input only decreases during a query, so the threshold only decreases: a point pruned
/// at any time lies farther than the final threshold.
#[inline(always)]
pub(crate) fn threshold(
    mode: Mode,
    per_link: bool,
    range: f32,
    global: f32,
    global_lower: f32,
    link_best: f32,
    gap: f32,
) -> f32 {
    let needed = match mode {
        Mode::Fast => global,
        Mode::Certified => global.max(global_lower + gap),
        Mode::Exact => global + gap,
    };
    if !per_link {
        return needed;
    }
    match mode {
        // Exact candidates are needed whatever the link's own minimum.
        Mode::Exact => needed.max(link_best.min(range)),
        // A point farther than the link's minimum changes neither it nor the global bounds
        // (the link's minimum is already in them).
        _ => link_best.min(needed.max(range)),
    }
}

/// [`threshold`] for eight links at once (lane by lane the same rule and the same arithmetic):
/// the CPU's test of a block against every link's root sphere.
#[inline(always)]
pub(crate) fn threshold_x8(
    mode: Mode,
    per_link: bool,
    range: f32,
    global: f32,
    global_lower: f32,
    link_best: f32x8,
    gap: f32x8,
) -> f32x8 {
    let global_v = f32x8::splat(global);
    let needed = match mode {
        Mode::Fast => global_v,
        Mode::Certified => global_v.max(f32x8::splat(global_lower) + gap),
        Mode::Exact => global_v + gap,
    };
    if !per_link {
        return needed;
    }
    let range = f32x8::splat(range);
    match mode {
        Mode::Exact => needed.max(link_best.min(range)),
        _ => link_best.min(needed.max(range)),
    }
}

/// Memory reused from query to query by both backends.
pub(crate) struct Bounds {
    /// The links posed for this query (`node_base`, `sphere_base`: their offsets in the
    /// concatenated node and sphere arrays the GPU holds).
    pub posed: Vec<PosedLink>,
    /// Per link: the minimum and its point, packed.
    pub best: Vec<AtomicU64>,
    pub global: AtomicU32,
    pub global_lower: AtomicU32,
    pub candidates: Mutex<Vec<Candidate>>,
    /// Per link: the points the self-filter took as this link.
    pub self_filtered: Vec<AtomicU64>,
    /// The traversal's work, per `layout::Work`.
    pub work: [AtomicU64; WORK_COUNTERS],
}

impl Bounds {
    pub fn new(links: &[QueryLink]) -> Self {
        let mut posed = Vec::with_capacity(links.len());
        let (mut nodes, mut spheres) = (0u32, 0u32);
        for link in links {
            posed.push(PosedLink {
                node_base: nodes,
                sphere_base: spheres,
                ..PosedLink::default()
            });
            nodes += link.nodes.len() as u32;
            spheres += link.spheres.len() as u32;
        }
        Self {
            posed,
            best: links.iter().map(|_| AtomicU64::new(EMPTY)).collect(),
            global: AtomicU32::new(f32::INFINITY.to_bits()),
            global_lower: AtomicU32::new(f32::INFINITY.to_bits()),
            candidates: Mutex::new(Vec::new()),
            self_filtered: links.iter().map(|_| AtomicU64::new(0)).collect(),
            work: Default::default(),
        }
    }

    /// Step 1 of a query, for either backend: poses the links (f64, rounded once), resets the
    /// minima and returns the robot's box.
    pub fn prepare(
        &mut self,
        links: &[QueryLink],
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> RobotBox {
        pose::pose_links(links, &mut self.posed, root_from_sensor, link_poses);
        for (l, p) in self.posed.iter_mut().enumerate() {
            p.range = options.link_range(l);
        }
        for b in &self.best {
            b.store(EMPTY, Relaxed);
        }
        for s in self.self_filtered.iter().chain(&self.work) {
            s.store(0, Relaxed);
        }
        self.global.store(f32::INFINITY.to_bits(), Relaxed);
        self.global_lower.store(f32::INFINITY.to_bits(), Relaxed);
        self.candidates_mut().clear();
        pose::robot_box(links, root_from_sensor, link_poses, options)
    }

    /// The candidate list, with the query's exclusive access (a poisoned lock, from a panic in
    /// another query, still holds a usable vector).
    pub fn candidates_mut(&mut self) -> &mut Vec<Candidate> {
        self.candidates
            .get_mut()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eight-lane rule gives, lane by lane, what the rule for one link gives, in every mode,
    /// with and without per-link minima, over finite, zero and infinite inputs.
    #[test]
    fn eight_links_threshold_as_one() {
        let values = [0.0f32, 1e-4, 0.0123, 0.05, 0.31, 0.32, 2.5, f32::INFINITY];
        let mut state = 0x853c_49e6_748f_ea9bu64;
        let mut pick = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            values[(state % values.len() as u64) as usize]
        };
        for _ in 0..2000 {
            let (range, global, global_lower) = (pick(), pick(), pick());
            let best: [f32; 8] = std::array::from_fn(|_| pick());
            let gap: [f32; 8] = std::array::from_fn(|_| pick().min(0.01));
            for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
                for per_link in [false, true] {
                    let v = threshold_x8(
                        mode,
                        per_link,
                        range,
                        global,
                        global_lower,
                        f32x8::from(best),
                        f32x8::from(gap),
                    )
                    .to_array();
                    for j in 0..8 {
                        let one =
                            threshold(mode, per_link, range, global, global_lower, best[j], gap[j]);
                        assert_eq!(
                            v[j].to_bits(),
                            one.to_bits(),
                            "{mode:?} {per_link} lane {j}"
                        );
                    }
                }
            }
        }
    }
}
