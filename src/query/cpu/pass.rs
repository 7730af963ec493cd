//! Step 3 on the CPU, the main pass (the GPU's `blocks`, then `measure`): one sweep over the
//! cloud in groups of `GROUP` blocks, a rayon task each. [`Pass`] holds what every block of
//! the query reads — the shared bounds (atomics), the posed links and their root spheres eight
//! to a vector, the robot's box, the tiling, the self-filter's grids — and its rules: the
//! pruning threshold ([`Pass::threshold`]) and the recording of a minimum ([`Pass::record`]),
//! which the shader implements alike. A group is bounded and tested against the robot's box;
//! each block then against the robot's box and the links' root spheres (no square root), and
//! a block that survives is taken (`measure.rs`). Distances in metres, sensor frame.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use wide::{f32x8, CmpGe, CmpLe};

use super::blocks::{accumulate, robot_distances2, Block, Raw, GROUP};
use crate::query::bounds::{load_distance, load_f32, pack_minimum, threshold, threshold_x8};
use crate::query::layout::{Candidate, PosedLink, RobotBox, Tiling, Work, MAX_LINKS};
use crate::query::link::QueryLink;
use crate::query::options::Mode;
use crate::query::result::StageCounts;
use crate::query::self_grid::SelfGrid;
use crate::query::work;

/// The links' root spheres in the sensor frame, eight links to a vector (SIMD over links), with
/// their surface gaps: a block's box is tested against all of them at once. Lanes past the last
/// link have radius −∞ and take nothing.
pub(super) struct LinkRoots {
    pub(super) octets: usize,
    pub(super) center: [[f32x8; 3]; MAX_LINKS / 8],
    pub(super) radius: [f32x8; MAX_LINKS / 8],
    pub(super) gap: [f32x8; MAX_LINKS / 8],
}

impl LinkRoots {
    pub(super) fn new(posed: &[PosedLink]) -> Self {
        let mut center = [[[0.0f32; 8]; 3]; MAX_LINKS / 8];
        let mut radius = [[f32::NEG_INFINITY; 8]; MAX_LINKS / 8];
        let mut gap = [[0.0f32; 8]; MAX_LINKS / 8];
        for (l, p) in posed.iter().enumerate() {
            let (o, j) = (l / 8, l % 8);
            for (axis, &c) in center[o].iter_mut().zip(&p.center) {
                axis[j] = c;
            }
            radius[o][j] = p.radius;
            gap[o][j] = p.gap;
        }
        Self {
            octets: posed.len().div_ceil(8),
            center: center.map(|c| c.map(f32x8::from)),
            radius: radius.map(f32x8::from),
            gap: gap.map(f32x8::from),
        }
    }
}

/// Where one point of the main pass ended.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum PointStage {
    /// Farther than `max_distance` from the robot's box.
    OutsideRoi,
    /// Within the padding of this link's inner spheres.
    SelfFiltered(usize),
    Pruned,
    Evaluated {
        inside: bool,
    },
}

/// A point of a sub-block in phase 2 (one that is valid and not the robot): ended at a
/// stage, or waiting in lane `j` of the sub-block's packet.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Slot {
    Done(PointStage),
    Lane(usize),
}

pub(super) struct Pass<'a> {
    pub(super) links: &'a [QueryLink],
    pub(super) posed: &'a [PosedLink],
    pub(super) best: &'a [AtomicU64],
    pub(super) global: &'a AtomicU32,
    pub(super) global_lower: &'a AtomicU32,
    pub(super) candidates: &'a Mutex<Vec<Candidate>>,
    pub(super) self_filtered: &'a [AtomicU64],
    pub(super) points: &'a [[f32; 3]],
    pub(super) tiling: Tiling,
    pub(super) mode: Mode,
    pub(super) per_link: bool,
    /// The largest of the links' ranges (`PosedLink::range`, which `threshold` reads): the
    /// bound of the tests that look at every link at once.
    pub(super) per_link_range: f32,
    /// The largest surface gap of the links.
    pub(super) max_gap: f32,
    /// Self-filter padding; −∞ when off.
    pub(super) padding: f32,
    /// Per link, the self-filter's grid for this padding (empty when off).
    pub(super) grids: &'a [SelfGrid],
    /// The robot's box, the region of interest (`max_distance`) with it.
    pub(super) robot_box: RobotBox,
    /// The links' root spheres, eight to a vector, for the blocks' box test.
    pub(super) roots: LinkRoots,
}

impl Pass<'_> {
    /// The largest inner-sphere distance of link `l` that can still change the result.
    #[inline(always)]
    pub(super) fn threshold(&self, l: usize) -> f32 {
        threshold(
            self.mode,
            self.per_link,
            self.posed[l].range,
            load_f32(self.global),
            load_f32(self.global_lower),
            if self.per_link {
                load_distance(&self.best[l])
            } else {
                f32::INFINITY
            },
            self.posed[l].gap,
        )
    }

    /// An upper bound of every link's threshold (the rule of [`threshold`] with the largest
    /// surface gap; with per-link minima, the range), without a look at each link.
    #[inline]
    pub(super) fn largest_threshold(&self) -> f32 {
        let needed = threshold(
            self.mode,
            false,
            self.per_link_range,
            load_f32(self.global),
            load_f32(self.global_lower),
            f32::INFINITY,
            self.max_gap,
        );
        if self.per_link {
            // The links' own minima bound it more tightly once they are known.
            let own = self
                .best
                .iter()
                .map(load_distance)
                .fold(f32::NEG_INFINITY, f32::max);
            needed.max(self.per_link_range.min(own))
        } else {
            needed
        }
    }

    #[inline]
    pub(super) fn record(&self, l: usize, point: u32, d: f32) {
        self.best[l].fetch_min(pack_minimum(d, point), Relaxed);
        self.global.fetch_min(d.to_bits(), Relaxed);
        let lower = (d - self.posed[l].gap).max(0.0);
        match self.mode {
            Mode::Certified => {
                self.global_lower.fetch_min(lower.to_bits(), Relaxed);
            }
            Mode::Exact => {
                if lower <= load_f32(self.global) {
                    self.candidates
                        .lock()
                        .unwrap_or_else(|poisoned| poisoned.into_inner())
                        .push(Candidate {
                            lower,
                            link: l as u32,
                            point,
                            pad: 0,
                        });
                }
            }
            Mode::Fast => {}
        }
    }

    /// Per eight links, how near to its root sphere's centre a block must come to hold a
    /// point that matters to the link: its threshold, or the self-filter's padding when that
    /// is larger, plus the root sphere's radius, widened for f32 rounding (lanes past the last
    /// link: −∞). Taken once per group of blocks: thresholds only fall, so for the group's
    /// later blocks it is an upper bound.
    pub(super) fn link_reach(&self) -> [f32x8; MAX_LINKS / 8] {
        let (global, global_lower) = (load_f32(self.global), load_f32(self.global_lower));
        let padding = f32x8::splat(self.padding);
        let mut reach = [f32x8::ZERO; MAX_LINKS / 8];
        for (o, r) in reach[..self.roots.octets].iter_mut().enumerate() {
            let best = if self.per_link {
                f32x8::from(std::array::from_fn(|j| {
                    self.best.get(8 * o + j).map_or(0.0, load_distance)
                }))
            } else {
                f32x8::splat(f32::INFINITY)
            };
            let limit = threshold_x8(
                self.mode,
                self.per_link,
                self.per_link_range,
                global,
                global_lower,
                best,
                self.roots.gap[o],
            )
            .max(padding);
            *r = (limit + self.roots.radius[o]) * f32x8::splat(1.0 + 1e-6) + f32x8::splat(1e-6);
        }
        reach
    }

    /// A box (a group's or a block's) at squared distances `near2` and `far2` from the robot's
    /// box: `Err` with the stage of all its points when it is outside the region of interest
    /// (`OutsideRoi`), or wholly inside it and beyond reach of the robot's box, a lower bound of
    /// every link's distance (`Pruned`); else `Ok(partial_roi)`, whether it straddles the
    /// region of interest's edge.
    #[inline(always)]
    pub(super) fn against_robot_box(&self, near2: f32, far2: f32) -> Result<bool, PointStage> {
        let roi2 = self.robot_box.max_distance * self.robot_box.max_distance;
        if near2 > roi2 {
            return Err(PointStage::OutsideRoi);
        }
        let partial_roi = far2 > roi2;
        let reach = self.padding.max(self.largest_threshold());
        if (reach < 0.0 || near2 > reach * reach) && !partial_roi {
            return Err(PointStage::Pruned);
        }
        Ok(partial_roi)
    }

    /// The links whose root sphere comes within `reach` ([`Pass::link_reach`]) of a block's box
    /// `lo..hi` (sensor frame): eight links at a time, in squared distances from each centre
    /// to the box's nearest point. The box lies inside the block's sphere, so this is tighter
    /// than the spheres' test.
    #[inline]
    pub(super) fn links_near_box(&self, reach: &[f32x8], lo: [f32; 3], hi: [f32; 3]) -> u128 {
        let lo = lo.map(f32x8::splat);
        let hi = hi.map(f32x8::splat);
        let zero = f32x8::ZERO;
        let mut mask = 0u128;
        for (o, &reach) in reach[..self.roots.octets].iter().enumerate() {
            let c = &self.roots.center[o];
            let e = [0, 1, 2].map(|k| (lo[k] - c[k]).max(c[k] - hi[k]).max(zero));
            let d2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            let within = reach.cmp_ge(zero) & d2.cmp_le(reach * reach);
            mask |= u128::from(within.move_mask() as u8) << (8 * o);
        }
        mask
    }

    /// Whether point `p` of a block that straddles the region of interest lies outside it.
    #[inline(always)]
    pub(super) fn outside(&self, p: [f32; 3], partial_roi: bool) -> bool {
        partial_roi && !self.robot_box.within(p, self.robot_box.max_distance)
    }

    /// One group of `GROUP` blocks (a rayon task): each block bounded; the group's box tested
    /// against the robot's box (most groups away from the robot end here, as one); else all
    /// its blocks tested against the robot's box at once ([`robot_distances2`]), then block by
    /// block ([`Pass::block`]). Within the group the last point measured is carried from block
    /// to block, so that a point repeated over many blocks is measured once per group.
    pub(super) fn group(
        &self,
        g: usize,
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
    ) -> StageCounts {
        let first = g * GROUP;
        let n = GROUP.min(self.tiling.blocks() - first);
        work::add(Work::Blocks, n as u64);
        let mut raw = [Raw::empty(); GROUP];
        let mut all = Raw::empty();
        for (k, r) in raw[..n].iter_mut().enumerate() {
            *r = accumulate(self.points, self.tiling.subs(first + k));
            all.merge(r);
        }
        // The counts of a group that ends as one.
        let mut whole = StageCounts {
            total: u64::from(all.valid + all.invalid),
            invalid: u64::from(all.invalid),
            ..Default::default()
        };
        if all.valid == 0 {
            work::add(Work::Culled, n as u64);
            return whole;
        }
        // The group's box first: a group outside the region of interest, or wholly beyond
        // reach of the robot's box, ends here, its blocks' lanes never folded.
        let group = all.fold();
        let (near, far) = self.robot_box.box_distances2(group.lo, group.hi);
        match self.against_robot_box(near, far) {
            Err(PointStage::OutsideRoi) => {
                whole.outside_roi = u64::from(all.valid);
                work::add(Work::Culled, n as u64);
                return whole;
            }
            Err(_) => {
                whole.pruned = u64::from(all.valid);
                work::add(Work::Culled, n as u64);
                return whole;
            }
            Ok(_) => {}
        }
        let mut blocks = [Block::EMPTY; GROUP];
        let (near2, far2) = if group.uniform() {
            // One point repeated over the group (each block's box is the group's): folds and
            // box tests once, and every block after the first repeats it.
            for (block, r) in blocks[..n].iter_mut().zip(&raw) {
                *block = Block {
                    valid: r.valid,
                    invalid: r.invalid,
                    ..group
                };
            }
            ([near; GROUP], [far; GROUP])
        } else {
            for (block, r) in blocks[..n].iter_mut().zip(&raw) {
                *block = r.fold();
            }
            robot_distances2(&self.robot_box, &blocks)
        };
        let link_reach = self.link_reach();
        let mut counts = StageCounts::default();
        let mut last = None;
        let mut taken = 0;
        for k in 0..n {
            let distances = (near2[k], far2[k], &link_reach[..]);
            taken += self.block(
                first + k,
                &blocks[k],
                distances,
                frontier,
                spans,
                &mut last,
                &mut counts,
            ) as u64;
        }
        work::add(Work::Culled, n as u64 - taken);
        counts
    }

    /// One block, whose box lies at squared distances `(near2, far2)` from the robot's box
    /// (`link_reach`: the links' reach, [`Pass::link_reach`]): dropped whole (region of
    /// interest, robot box, the links' root spheres), or taken ([`Pass::take`]). A block that
    /// repeats the point before it ends where that one ended, with no work (same distance,
    /// larger index: it cannot change a minimum). `last` is the last point measured in this
    /// run of blocks and where it ended. Returns whether the block was taken (the others are
    /// the work counters' culled blocks).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn block(
        &self,
        b: usize,
        block: &Block,
        (near2, far2, link_reach): (f32, f32, &[f32x8]),
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
        last: &mut Option<([f32; 3], PointStage)>,
        counts: &mut StageCounts,
    ) -> bool {
        counts.total += u64::from(block.valid + block.invalid);
        counts.invalid += u64::from(block.invalid);
        if block.valid == 0 {
            return false;
        }
        let valid = u64::from(block.valid);
        // A block that repeats the point before it (its box is that point).
        let uniform = block.uniform();
        if let Some((q, stage)) = *last {
            if uniform && q == block.lo {
                *counts = *counts + self.repeat(stage, valid);
                return false;
            }
        }
        let whole = |stage: PointStage, last: &mut Option<([f32; 3], PointStage)>| {
            *last = uniform.then_some((block.lo, stage));
        };
        // The robot's box against the block's, squared distances (no square root for the
        // blocks culled here, most of them).
        let partial_roi = match self.against_robot_box(near2, far2) {
            Ok(partial_roi) => partial_roi,
            Err(stage) => {
                match stage {
                    PointStage::OutsideRoi => counts.outside_roi += valid,
                    _ => counts.pruned += valid,
                }
                whole(stage, last);
                return false;
            }
        };
        // Then every link's root sphere against the block's box (no square root either): most
        // blocks near the robot's box but away from its links end here.
        let links = self.links_near_box(link_reach, block.lo, block.hi);
        if links == 0 && !partial_roi {
            counts.pruned += valid;
            whole(PointStage::Pruned, last);
            return false;
        }
        *counts = *counts + self.take(b, block, near2, partial_roi, links, frontier, spans, last);
        true
    }

    /// The counts of `valid` more copies of a point that ended at `stage` (the rest of a run of
    /// blocks that repeat one point).
    pub(super) fn repeat(&self, stage: PointStage, valid: u64) -> StageCounts {
        let mut c = StageCounts::default();
        match stage {
            PointStage::OutsideRoi => c.outside_roi = valid,
            PointStage::SelfFiltered(l) => {
                c.self_filtered = valid;
                self.self_filtered[l].fetch_add(valid, Relaxed);
            }
            PointStage::Pruned => c.pruned = valid,
            PointStage::Evaluated { inside } => {
                c.evaluated = valid;
                c.inside = if inside { valid } else { 0 };
            }
        }
        c
    }
}

/// The links of a mask, lowest first.
#[inline(always)]
pub(super) fn bits(mut mask: u128) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let l = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            l
        })
    })
}

#[inline(always)]
pub(super) fn starts<'a>(frontier: &'a [u32], spans: &[(u32, u32)], l: usize) -> &'a [u32] {
    let (s, n) = spans[l];
    &frontier[s as usize..(s + n) as usize]
}

/// Frontier node indices and, per link, their span.
type FrontierScratch = (Vec<u32>, Vec<(u32, u32)>);

thread_local! {
    /// Per-thread frontier memory (grows once, reused by every block of every query).
    static SCRATCH: std::cell::RefCell<FrontierScratch> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

pub(super) fn with_scratch<R>(
    links: usize,
    f: impl FnOnce(&mut Vec<u32>, &mut [(u32, u32)]) -> R,
) -> R {
    SCRATCH.with(|s| {
        let mut s = s.borrow_mut();
        let (frontier, spans) = &mut *s;
        if spans.len() < links {
            spans.resize(links, (0, 0));
        }
        f(frontier, spans)
    })
}
