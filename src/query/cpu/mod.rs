//! The CPU backend's traversal, steps 2 and 3 of [`super::Engine::query`] (step 1, posing, is
//! `pose.rs`; steps 4 and 5, exact refinement and the result, are `exact.rs` and `result.rs`,
//! shared with the GPU).
//!
//! 2. **Seeds**: one pass over a sample of the cloud (every `SEED_STRIDE`-th point, eight
//!    links' root centres at a time) gives each link the `SEEDS` valid points nearest to its
//!    root sphere that are not the robot, in distinct blocks; those points are descended for
//!    that link, and with per-link minima their blocks too (in parallel), so that the shared
//!    bounds are tight before the main pass.
//! 3. **Main pass** (parallel over groups of blocks, rayon; the one sweep over the whole
//!    cloud). The cloud's hierarchy (`blocks`: the tiling and the blocks' SIMD bounds), bottom
//!    up: points; **sub-blocks** of `SUB` = 8 points;
//!    **blocks** of `BLOCK` = 32 points, runs of consecutive points or, for an organized cloud,
//!    tiles of 8 × 4 pixels ([`Tiling`]; a tile's sphere is about a third of a row run's);
//!    groups of 16 blocks, a rayon task. Each block gets its valid count and the bounding
//!    box of its valid points (eight lanes at a time, SIMD). A group, then a block, is dropped
//!    whole when its box lies outside the region of interest or farther from the robot's box
//!    than every link's bound (squared distances between the boxes, eight blocks at a time);
//!    a block, also when its box is beyond every link's root sphere by the link's bound (eight
//!    links at a time). No square root for the blocks dropped here, nearly all of them (on
//!    the Kinect scene, global: about 250 of 9600 blocks go further). Otherwise a block is
//!    taken, as the sphere around its box, in two phases:
//!    - **the robot** (self-filter), only for a block within the padding of some link's root
//!      sphere: each point is looked up in that link's self-filter grid ([`SelfGrid`]: cells
//!      wholly within the padding of the inner spheres, wholly beyond it, or across it), the
//!      link that took the point before it first; only a point in a cell across the padding
//!      descends the tree (stopping at the first sphere within the padding). A block that is
//!      all robot ends here.
//!    - **the obstacles**: each link's tree is cut at the block with the link's bound as the
//!      limit (the **frontier**: the nodes no larger than the block whose lower bound over the
//!      block is within the limit; most links end with an empty one and cost the block nothing
//!      more); each sub-block is tested against
//!      the frontier nodes, and a link it reaches only through them is confirmed by a descent
//!      of its centre that stops at the first inner sphere within the bound plus its radius:
//!      the links that remain are the only ones its points look at. Each point is tested
//!      against their frontier nodes; the points of a sub-block that pass descend from them
//!      together, a packet of up to eight (`descent::nearest_packet`, SIMD over the points;
//!      one point alone descends by itself, four children tested at once), depth first,
//!      nearest child first, pruning nodes whose lower bound `|p − c| − r` exceeds the bound
//!      of every point of the packet.
//!
//!    A point equal to the one before it (within a group, across blocks too) takes its result
//!    with no work. Minima go into the shared atomics with `fetch_min`, so every thread prunes
//!    with the best bound found by any.
//!
//! The pruning rule ([`Pass::threshold`]) and the recording rule ([`Pass::record`]) are the
//! ones the GPU shader implements per point; the blocks, frontiers and SIMD are the CPU's own.
//! Nothing is allocated per query once the scratch memory has grown (thread-local frontier
//! buffers, the exact candidates' vector), but the seed lists (a few hundred bytes per rayon
//! split).

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use rayon::prelude::*;
use wide::{f32x8, CmpGe, CmpLe, CmpLt};

mod blocks;

use super::bounds::{load_distance, load_f32, pack_minimum, threshold, threshold_x8, Bounds};
use super::descent::{
    any_within, dist, dist2, nearest_from, nearest_packet, nearest_sphere, valid, within_reach,
};
use super::layout::{Candidate, PosedLink, RobotBox, FRONTIER, SEED_STRIDE};
use super::self_grid::{Cell, SelfGrid};
use super::{result, Backend, Input, Mode, QueryLink, QueryResult, StageCounts, MAX_LINKS};
use blocks::{
    accumulate, bound_block, bound_sub, robot_distances2, Block, Raw, Sphere, Tiling, GROUP, SUB,
    TILE_ROWS,
};

/// Sample points read at once by the seeds' scan.
const GATHER: usize = 16;

/// Sample points (and their blocks) that seed each link.
const SEEDS: usize = 3;

/// Seed points of a global query descended on the query's own thread: up to this many cost less
/// than a parallel step (eleven links' 33: 11–12 µs against 15–22 µs in parallel, Kinect scene,
/// 2 cores). With per-link minima they stay parallel: on this thread the Kinect node defaults
/// measured 1.27 against 1.22 ms (the parallel step there is followed by the seeds' blocks).
const SERIAL_SEEDS: usize = 48;

/// Appends to `out` the frontier of a block (centre `c` in the link frame, radius `r`) in a
/// tree: a cut of the tree whose nodes' lower bound over the block, `|c − c_n| − r − r_n`, is at
/// most `limit`; every sphere within `limit` of a point of the block lies under one of them.
/// The cut is refined level by level, node by node, down to nodes no larger than the block or
/// holding spheres, as long as it stays within `FRONTIER` nodes (the coarser cut is kept
/// otherwise). Returns whether the frontier is not empty.
fn frontier(link: &QueryLink, c: [f32; 3], r: f32, limit: f32, out: &mut Vec<u32>) -> bool {
    let nodes = &link.nodes;
    let start = out.len();
    let root = &nodes[0];
    if dist(c, root.center) - r - root.radius > limit {
        return false;
    }
    out.push(0);
    loop {
        // One refinement round: every node larger than the block is replaced by its children
        // that pass the test, unless the cut would outgrow FRONTIER.
        let mut next = [0u32; FRONTIER];
        let mut n = 0;
        let mut refined = false;
        for &i in &out[start..] {
            let node = &nodes[i as usize];
            if node.children_are_spheres != 0 || node.radius <= r {
                if n == FRONTIER {
                    return true;
                }
                next[n] = i;
                n += 1;
                continue;
            }
            refined = true;
            let first = node.first_child as usize;
            let count = node.child_count as usize;
            let mut within = within_reach(&link.node_soa, c, first, count, limit + r);
            while within != 0 {
                let k = within.trailing_zeros() as usize;
                within &= within - 1;
                if n == FRONTIER {
                    return true;
                }
                next[n] = (first + k) as u32;
                n += 1;
            }
        }
        out.truncate(start);
        out.extend_from_slice(&next[..n]);
        if !refined || n == 0 {
            return n > 0;
        }
    }
}

/// The links' root spheres in the sensor frame, eight links to a vector (SIMD over links), with
/// their surface gaps: a block's box is tested against all of them at once. Lanes past the last
/// link have radius −∞ and take nothing.
struct LinkRoots {
    octets: usize,
    center: [[f32x8; 3]; MAX_LINKS / 8],
    radius: [f32x8; MAX_LINKS / 8],
    gap: [f32x8; MAX_LINKS / 8],
}

impl LinkRoots {
    fn new(posed: &[PosedLink]) -> Self {
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
enum PointStage {
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
enum Slot {
    Done(PointStage),
    Lane(usize),
}

struct Pass<'a> {
    links: &'a [QueryLink],
    posed: &'a [PosedLink],
    best: &'a [AtomicU64],
    global: &'a AtomicU32,
    global_lower: &'a AtomicU32,
    candidates: &'a Mutex<Vec<Candidate>>,
    self_filtered: &'a [AtomicU64],
    points: &'a [[f32; 3]],
    tiling: Tiling,
    mode: Mode,
    per_link: bool,
    per_link_range: f32,
    /// The largest surface gap of the links.
    max_gap: f32,
    /// Self-filter padding; −∞ when off.
    padding: f32,
    /// Per link, the self-filter's grid for this padding (empty when off).
    grids: &'a [SelfGrid],
    /// The robot's box, the region of interest (`max_distance`) with it.
    robot_box: RobotBox,
    /// The links' root spheres, eight to a vector, for the blocks' box test.
    roots: LinkRoots,
}

impl Pass<'_> {
    /// The largest inner-sphere distance of link `l` that can still change the result.
    #[inline(always)]
    fn threshold(&self, l: usize) -> f32 {
        threshold(
            self.mode,
            self.per_link,
            self.per_link_range,
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
    fn largest_threshold(&self) -> f32 {
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
    fn record(&self, l: usize, point: u32, d: f32) {
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
    fn link_reach(&self) -> [f32x8; MAX_LINKS / 8] {
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
    fn against_robot_box(&self, near2: f32, far2: f32) -> Result<bool, PointStage> {
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
    fn links_near_box(&self, reach: &[f32x8], lo: [f32; 3], hi: [f32; 3]) -> u128 {
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

    /// A link of `mask` with an inner sphere within the self-filter padding of `p`: `hint` (the
    /// link that took the point before it, kept up to date) first, then the others in engine
    /// order. Its grid settles most points ([`SelfGrid`]), a descent from its root the points in
    /// the grid's shell.
    #[inline]
    fn self_link(&self, p: [f32; 3], mask: u128, hint: &mut usize) -> Option<usize> {
        let takes = |l: usize| {
            let q = self.posed[l].in_link(p);
            match self.grids[l].at(q) {
                Cell::SelfPoint => true,
                Cell::Clear => false,
                Cell::Shell => any_within(&self.links[l], q, &[0], self.padding).is_some(),
            }
        };
        let first = 1u128.checked_shl(*hint as u32).unwrap_or(0) & mask;
        if first != 0 && takes(*hint) {
            return Some(*hint);
        }
        let l = bits(mask & !first).find(|&l| takes(l))?;
        *hint = l;
        Some(l)
    }

    /// Whether a block may hold points of the robot: a link of `near` has an inner sphere within
    /// the padding plus the block's radius of its centre (a descent that stops at the first).
    #[inline]
    fn may_be_robot(&self, block: &Sphere, near: u128) -> bool {
        let limit = self.padding + block.radius;
        bits(near).any(|l| {
            let c = self.posed[l].in_link(block.center);
            any_within(&self.links[l], c, &[0], limit).is_some()
        })
    }

    /// Whether `p` is the robot (within the padding of a link; false when the self-filter is
    /// off).
    fn is_robot(&self, p: [f32; 3]) -> bool {
        self.robot_box.within(p, self.padding)
            && self
                .self_link(p, self.near_links(p, 0.0), &mut { usize::MAX })
                .is_some()
    }

    /// The links whose root sphere comes within the padding of a block (centre `c`, radius
    /// `r`, sensor frame): the only ones that may take its points as the robot (none when the
    /// self-filter is off).
    #[inline]
    fn near_links(&self, c: [f32; 3], r: f32) -> u128 {
        let mut mask = 0u128;
        if self.padding < 0.0 {
            return mask;
        }
        for (l, pl) in self.posed.iter().enumerate() {
            let reach = self.padding + r + pl.radius;
            if dist2(c, pl.center) <= reach * reach {
                mask |= 1 << l;
            }
        }
        mask
    }

    /// Whether point `p` of a block that straddles the region of interest lies outside it.
    #[inline(always)]
    fn outside(&self, p: [f32; 3], partial_roi: bool) -> bool {
        partial_roi && !self.robot_box.within(p, self.robot_box.max_distance)
    }

    /// Descends the links of `mask` for an obstacle point and records its distances; returns
    /// whether the point is inside an inner sphere.
    #[inline]
    fn evaluate(
        &self,
        i: u32,
        p: [f32; 3],
        mask: u128,
        frontier: &[u32],
        spans: &[(u32, u32)],
    ) -> bool {
        let mut inside = false;
        for l in bits(mask) {
            let link = &self.links[l];
            let q = self.posed[l].in_link(p);
            let s = starts(frontier, spans, l);
            if let Some((d, _)) = nearest_from(link, q, s, self.threshold(l)) {
                inside |= d == 0.0;
                self.record(l, i, d);
            }
        }
        inside
    }

    /// The frontiers of a block in the links of `links` (in the main pass, the links whose root
    /// sphere its box comes near), cut at the link's threshold; returns the mask of links with
    /// a frontier.
    fn frontiers(
        &self,
        center: [f32; 3],
        radius: f32,
        links: u128,
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
    ) -> u128 {
        frontier.clear();
        let mut mask = 0u128;
        for l in bits(links) {
            let pl = &self.posed[l];
            let limit = self.threshold(l);
            let start = frontier.len() as u32;
            let c = pl.in_link(center);
            if self::frontier(&self.links[l], c, radius, limit, frontier) {
                spans[l] = (start, frontier.len() as u32 - start);
                mask |= 1 << l;
            }
        }
        mask
    }

    /// The links of `mask` that may hold a point of the sphere (`c`, `r`) within their
    /// threshold.
    #[inline]
    fn sub_mask(
        &self,
        c: [f32; 3],
        r: f32,
        mask: u128,
        frontier: &[u32],
        spans: &[(u32, u32)],
    ) -> u128 {
        let mut out = 0u128;
        for l in bits(mask) {
            let link = &self.links[l];
            let q = self.posed[l].in_link(c);
            let st = starts(frontier, spans, l);
            let reach = self.threshold(l) + r;
            let within = reaches(link, q, st, reach);
            // A sub-block only within the link's bound by its frontier nodes, which are as
            // large as the block, is confirmed by a descent of its centre that stops at the
            // first inner sphere within the bound plus its radius: most are dropped here, not
            // point by point.
            if within && any_within(link, q, st, reach).is_some() {
                out |= 1 << l;
            }
        }
        out
    }

    /// One group of `GROUP` blocks (a rayon task): each block bounded; the group's box tested
    /// against the robot's box (most groups away from the robot end here, as one); else all
    /// its blocks tested against the robot's box at once ([`robot_distances2`]), then block by
    /// block ([`Pass::block`]). Within the group the last point measured is carried from block
    /// to block, so that a point repeated over many blocks is measured once per group.
    fn group(&self, g: usize, frontier: &mut Vec<u32>, spans: &mut [(u32, u32)]) -> StageCounts {
        let first = g * GROUP;
        let n = GROUP.min(self.tiling.blocks() - first);
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
            return whole;
        }
        // The group's box first: a group outside the region of interest, or wholly beyond
        // reach of the robot's box, ends here, its blocks' lanes never folded.
        let group = all.fold();
        let (near, far) = self.robot_box.box_distances2(group.lo, group.hi);
        match self.against_robot_box(near, far) {
            Err(PointStage::OutsideRoi) => {
                whole.outside_roi = u64::from(all.valid);
                return whole;
            }
            Err(_) => {
                whole.pruned = u64::from(all.valid);
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
        for k in 0..n {
            let distances = (near2[k], far2[k], &link_reach[..]);
            self.block(
                first + k,
                &blocks[k],
                distances,
                frontier,
                spans,
                &mut last,
                &mut counts,
            );
        }
        counts
    }

    /// One block, whose box lies at squared distances `(near2, far2)` from the robot's box
    /// (`link_reach`: the links' reach, [`Pass::link_reach`]): dropped whole (region of
    /// interest, robot box, the links' root spheres), or taken ([`Pass::take`]). A block that
    /// repeats the point before it ends where that one ended, with no work (same distance,
    /// larger index: it cannot change a minimum). `last` is the last point measured in this
    /// run of blocks and where it ended.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn block(
        &self,
        b: usize,
        block: &Block,
        (near2, far2, link_reach): (f32, f32, &[f32x8]),
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
        last: &mut Option<([f32; 3], PointStage)>,
        counts: &mut StageCounts,
    ) {
        counts.total += u64::from(block.valid + block.invalid);
        counts.invalid += u64::from(block.invalid);
        if block.valid == 0 {
            return;
        }
        let valid = u64::from(block.valid);
        // A block that repeats the point before it (its box is that point).
        let uniform = block.uniform();
        if let Some((q, stage)) = *last {
            if uniform && q == block.lo {
                *counts = *counts + self.repeat(stage, valid);
                return;
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
                return;
            }
        };
        // Then every link's root sphere against the block's box (no square root either): most
        // blocks near the robot's box but away from its links end here.
        let links = self.links_near_box(link_reach, block.lo, block.hi);
        if links == 0 && !partial_roi {
            counts.pruned += valid;
            whole(PointStage::Pruned, last);
            return;
        }
        *counts = *counts + self.take(b, block, near2, partial_roi, links, frontier, spans, last);
    }

    /// A block that its box's tests did not drop (`near2`: its squared distance to the robot's
    /// box; `links`: the links within its reach): phase 1, the self-filter, then phase 2,
    /// sub-block by sub-block (each tested against the block's frontier, which also narrows the
    /// links its points descend), then its points, a packet per sub-block. A point equal to the
    /// one before it ends where that one ended.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn take(
        &self,
        b: usize,
        block: &Block,
        near2: f32,
        partial_roi: bool,
        links: u128,
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
        last: &mut Option<([f32; 3], PointStage)>,
    ) -> StageCounts {
        let mut counts = StageCounts::default();
        let uniform = block.uniform();
        let whole = |stage: PointStage, last: &mut Option<([f32; 3], PointStage)>| {
            *last = uniform.then_some((block.lo, stage));
        };
        let sphere = block.sphere();
        let subs = self.tiling.subs(b);
        // Phase 1, the self-filter, with frontiers cut at the padding (small, cheap): which
        // points are the robot. A block all robot ends here.
        let mut self_by_link = [0u32; MAX_LINKS];
        let mut robot = 0u32;
        // The robot box bounds every link from below: a block beyond the padding of it holds no
        // robot point.
        if self.padding >= 0.0 && near2 <= self.padding * self.padding {
            let near = self.near_links(sphere.center, sphere.radius);
            if near != 0 {
                let mut hint = usize::MAX;
                // Whether the block was found to lie beyond the padding of every link.
                let mut checked = false;
                'points: for (k, &(start, len)) in subs.iter().enumerate() {
                    for (i, &p) in self.points[start..start + len].iter().enumerate() {
                        if !valid(p) || self.outside(p, partial_roi) {
                            continue;
                        }
                        let l = match *last {
                            Some((q, stage)) if q == p => match stage {
                                PointStage::SelfFiltered(l) => Some(l),
                                _ => None,
                            },
                            _ => {
                                let l = self.self_link(p, near, &mut hint);
                                if let Some(l) = l {
                                    *last = Some((p, PointStage::SelfFiltered(l)));
                                } else if !checked {
                                    // The first point that is not the robot: one descent per
                                    // near link for the whole block, which clears most blocks
                                    // beside the robot (a near obstacle) at once.
                                    checked = true;
                                    if !self.may_be_robot(&sphere, near) {
                                        break 'points;
                                    }
                                }
                                l
                            }
                        };
                        if let Some(l) = l {
                            robot |= 1 << (SUB * k + i);
                            counts.self_filtered += 1;
                            self_by_link[l] += 1;
                        }
                    }
                }
            }
        }
        // Phase 2, the obstacle points: frontiers cut at each link's threshold, then
        // sub-block by sub-block, point by point.
        if counts.self_filtered < u64::from(block.valid) {
            let mask = self.frontiers(sphere.center, sphere.radius, links, frontier, spans);
            if mask == 0 && !partial_roi {
                // No link within reach: the rest of the block is pruned whole.
                counts.pruned = u64::from(block.valid) - counts.self_filtered;
                if counts.self_filtered == 0 {
                    whole(PointStage::Pruned, last);
                }
            } else {
                self.obstacles(
                    subs,
                    mask,
                    robot,
                    partial_roi,
                    frontier,
                    spans,
                    last,
                    &mut counts,
                );
            }
        }
        if counts.self_filtered > 0 {
            for (l, &n) in self_by_link[..self.links.len()].iter().enumerate() {
                if n > 0 {
                    self.self_filtered[l].fetch_add(u64::from(n), Relaxed);
                }
            }
        }
        counts
    }

    /// Phase 2 of a block: its points that are not the robot (bits of `robot`), sub-block by
    /// sub-block against the links of `mask`: each sub-block's points that pass its tests are
    /// measured together ([`Pass::packet`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn obstacles(
        &self,
        subs: [(usize, usize); TILE_ROWS],
        mask: u128,
        robot: u32,
        partial_roi: bool,
        frontier: &[u32],
        spans: &[(u32, u32)],
        last: &mut Option<([f32; 3], PointStage)>,
        counts: &mut StageCounts,
    ) {
        for (k, &(start, len)) in subs.iter().enumerate() {
            let chunk = &self.points[start..start + len];
            let mut sub = None;
            // Where each point ended, or the lane of the packet it waits in (a point equal to
            // the one before it ends where that one does); none for the points not measured.
            let mut slots = [None; SUB];
            let mut lanes = [(0u32, [0.0f32; 3]); SUB];
            let mut n = 0;
            let mut prev = last.map(|(q, stage)| (q, Slot::Done(stage)));
            for (i, &p) in chunk.iter().enumerate() {
                if !valid(p) || robot & (1 << (SUB * k + i)) != 0 {
                    continue;
                }
                slots[i] = Some(match prev {
                    Some((q, slot)) if q == p => slot,
                    _ => {
                        let slot = if self.outside(p, partial_roi) {
                            Slot::Done(PointStage::OutsideRoi)
                        } else {
                            let sub = *sub.get_or_insert_with(|| {
                                let (c, r) = bound_sub(chunk);
                                if mask == 0 || r < 0.0 {
                                    0
                                } else {
                                    self.sub_mask(c, r, mask, frontier, spans)
                                }
                            });
                            if sub == 0 {
                                Slot::Done(PointStage::Pruned)
                            } else {
                                lanes[n] = ((start + i) as u32, p);
                                n += 1;
                                Slot::Lane(n - 1)
                            }
                        };
                        prev = Some((p, slot));
                        slot
                    }
                });
            }
            let measured = if n > 0 {
                self.packet(&lanes[..n], sub.unwrap_or(0), frontier, spans)
            } else {
                [PointStage::Pruned; SUB]
            };
            let stage_of = |slot: Slot| match slot {
                Slot::Done(stage) => stage,
                Slot::Lane(j) => measured[j],
            };
            if let Some((q, slot)) = prev {
                *last = Some((q, stage_of(slot)));
            }
            for &slot in slots.iter().take(len).flatten() {
                match stage_of(slot) {
                    PointStage::OutsideRoi => counts.outside_roi += 1,
                    // A copy of a robot point of an earlier block, in a block whose phase 1 did
                    // not run.
                    PointStage::SelfFiltered(l) => {
                        counts.self_filtered += 1;
                        self.self_filtered[l].fetch_add(1, Relaxed);
                    }
                    PointStage::Pruned => counts.pruned += 1,
                    PointStage::Evaluated { inside } => {
                        counts.evaluated += 1;
                        counts.inside += inside as u64;
                    }
                }
            }
        }
    }

    /// The points of a sub-block that its tests left (point index, point; at most `SUB`),
    /// against the links of `mask` (the sub-block's): per link, the points within the link's
    /// bound by its frontier nodes are descended, together ([`nearest_packet`]) when there are
    /// two or more, and their distances recorded. Returns each point's stage.
    #[inline]
    fn packet(
        &self,
        lanes: &[(u32, [f32; 3])],
        mask: u128,
        frontier: &[u32],
        spans: &[(u32, u32)],
    ) -> [PointStage; SUB] {
        let mut measured = [false; SUB];
        let mut inside = [false; SUB];
        for l in bits(mask) {
            let link = &self.links[l];
            let bound = self.threshold(l);
            let st = starts(frontier, spans, l);
            let mut q = [[0.0f32; 3]; SUB];
            let mut active = 0u32;
            for (j, &(_, p)) in lanes.iter().enumerate() {
                q[j] = self.posed[l].in_link(p);
                if reaches(link, q[j], st, bound) {
                    active |= 1 << j;
                }
            }
            if active == 0 {
                continue;
            }
            for j in bits(u128::from(active)) {
                measured[j] = true;
            }
            let mut record = |j: usize, d: f32| {
                inside[j] |= d == 0.0;
                self.record(l, lanes[j].0, d);
            };
            if active.count_ones() == 1 {
                let j = active.trailing_zeros() as usize;
                if let Some((d, _)) = nearest_from(link, q[j], st, bound) {
                    record(j, d);
                }
                continue;
            }
            // Lanes not in the packet repeat its first point (they change nothing).
            let first = q[active.trailing_zeros() as usize];
            let lane = |k: usize| {
                f32x8::from(std::array::from_fn::<f32, 8, _>(|j| {
                    if active & (1 << j) != 0 {
                        q[j][k]
                    } else {
                        first[k]
                    }
                }))
            };
            let d = nearest_packet(link, &[lane(0), lane(1), lane(2)], st, bound);
            for j in bits(u128::from(active)) {
                if d[j] < f32::INFINITY {
                    record(j, d[j]);
                }
            }
        }
        std::array::from_fn(|j| {
            if measured[j] {
                PointStage::Evaluated { inside: inside[j] }
            } else {
                PointStage::Pruned
            }
        })
    }

    /// The counts of `valid` more copies of a point that ended at `stage` (the rest of a run of
    /// blocks that repeat one point).
    fn repeat(&self, stage: PointStage, valid: u64) -> StageCounts {
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

    /// Seeds link `l`'s bound from the valid points of block `b` (the self-filter applies, so
    /// that the robot's own points never become a bound; nothing is counted).
    fn seed(&self, l: usize, b: usize, block: &Sphere) {
        with_scratch(self.links.len(), |frontier, spans| {
            let near = self.near_links(block.center, block.radius);
            // The robot's points (bit k: the k-th point of the block's sub-blocks), which
            // never become a bound.
            let mut robot = 0u32;
            let mut hint = usize::MAX;
            let points = self
                .tiling
                .subs(b)
                .into_iter()
                .flat_map(|(start, len)| &self.points[start..start + len]);
            for (k, &p) in points.enumerate() {
                if valid(p) && near != 0 && self.self_link(p, near, &mut hint).is_some() {
                    robot |= 1 << k;
                }
            }
            let mask = self.frontiers(block.center, block.radius, 1 << l, frontier, spans);
            let mut k = 0;
            for (start, len) in self.tiling.subs(b) {
                for (i, &p) in self.points[start..start + len].iter().enumerate() {
                    if valid(p)
                        && robot & (1 << k) == 0
                        && self.robot_box.within(p, self.robot_box.max_distance)
                    {
                        self.evaluate((start + i) as u32, p, mask, frontier, spans);
                    }
                    k += 1;
                }
            }
        });
    }
}

/// Per link, the seed samples found so far ([`offer`]), and the links' root-sphere centres eight
/// at a time with the farthest distance each list still takes (SIMD over links).
#[derive(Clone)]
struct SeedLists {
    lists: Vec<[Seed; SEEDS]>,
    centres: Vec<[f32x8; 3]>,
    worst: Vec<f32x8>,
}

impl SeedLists {
    fn new(posed: &[PosedLink]) -> Self {
        let octets = posed.len().div_ceil(8);
        let lane = |l: usize, k: usize| posed.get(l).map_or(0.0, |p| p.center[k]);
        Self {
            lists: vec![[NO_SEED; SEEDS]; posed.len()],
            centres: (0..octets)
                .map(|o| {
                    std::array::from_fn(|k| {
                        f32x8::from(std::array::from_fn(|j| lane(8 * o + j, k)))
                    })
                })
                .collect(),
            // Lanes past the last link take nothing.
            worst: (0..octets)
                .map(|o| {
                    f32x8::from(std::array::from_fn(|j| {
                        if 8 * o + j < posed.len() {
                            f32::INFINITY
                        } else {
                            f32::NEG_INFINITY
                        }
                    }))
                })
                .collect(),
        }
    }

    /// Offers point `i` to every link whose list it enters (a valid point, not the robot).
    #[inline]
    fn offer_point(&mut self, i: usize, p: [f32; 3], pass: &Pass, tiling: &Tiling) {
        if !valid(p) {
            return;
        }
        let (mut robot, mut block) = (None, None);
        for o in 0..self.centres.len() {
            let c = &self.centres[o];
            let d = [0, 1, 2].map(|k| c[k] - f32x8::splat(p[k]));
            let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let mut takes = d2.cmp_lt(self.worst[o]).move_mask() as u32;
            if takes == 0 || *robot.get_or_insert_with(|| pass.is_robot(p)) {
                continue;
            }
            let d2 = d2.to_array();
            let block = *block.get_or_insert_with(|| tiling.block_of(i) as u32);
            while takes != 0 {
                let j = takes.trailing_zeros() as usize;
                takes &= takes - 1;
                self.offer(8 * o + j, (d2[j], i as u32, block));
            }
        }
    }

    /// Offers the sample points `k · step` for `k` in `run`, read `GATHER` at a time: the
    /// loads of a batch all in flight at once (each sample is a cache line of its own, seldom
    /// cached: read one at a time, the scan waited on each), then their offers.
    fn offer_run(
        &mut self,
        points: &[[f32; 3]],
        step: usize,
        run: std::ops::Range<usize>,
        pass: &Pass,
        tiling: &Tiling,
    ) {
        for first in run.clone().step_by(GATHER) {
            let ks = first..(first + GATHER).min(run.end);
            let mut batch = [[0.0f32; 3]; GATHER];
            for (p, k) in batch.iter_mut().zip(ks.clone()) {
                *p = points[k * step];
            }
            for (&p, k) in batch.iter().zip(ks) {
                self.offer_point(k * step, p, pass, tiling);
            }
        }
    }

    fn offer(&mut self, l: usize, n: Seed) {
        offer(&mut self.lists[l], n);
        let mut w = self.worst[l / 8].to_array();
        w[l % 8] = self.lists[l][SEEDS - 1].0;
        self.worst[l / 8] = f32x8::from(w);
    }

    fn merge(&mut self, other: &Self) {
        for (l, list) in other.lists.iter().enumerate() {
            for &n in list.iter().filter(|n| n.1 != u32::MAX) {
                self.offer(l, n);
            }
        }
    }
}

/// A seed sample: squared distance to the link's root centre, point, block.
type Seed = (f32, u32, u32);

const NO_SEED: Seed = (f32::INFINITY, u32::MAX, u32::MAX);

/// Offers seed `n` to a link's seed list, sorted nearest first: it takes the place of a farther
/// sample of its own block, or of the farthest one. The list ends as the `SEEDS` nearest
/// blocks' nearest samples whatever the order of the offers.
fn offer(list: &mut [Seed; SEEDS], n: Seed) {
    let key = |m: &Seed| (m.0.to_bits(), m.1);
    let slot = match list.iter().position(|m| m.1 != u32::MAX && m.2 == n.2) {
        Some(k) if key(&n) < key(&list[k]) => k,
        Some(_) => return,
        None if key(&n) < key(&list[SEEDS - 1]) => SEEDS - 1,
        None => return,
    };
    list[slot] = n;
    list.sort_unstable_by_key(key);
}

/// Whether a node of `starts` lies within `bound` of `q` (link frame): `|q − c| − r ≤ bound`,
/// tested as `|q − c|² ≤ (bound + r)²` (no square root).
#[inline(always)]
fn reaches(link: &QueryLink, q: [f32; 3], starts: &[u32], bound: f32) -> bool {
    starts.iter().any(|&n| {
        let n = &link.nodes[n as usize];
        let reach = bound + n.radius;
        reach >= 0.0 && dist2(q, n.center) <= reach * reach
    })
}

/// The links of a mask, lowest first.
#[inline(always)]
fn bits(mut mask: u128) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let l = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            l
        })
    })
}

#[inline(always)]
fn starts<'a>(frontier: &'a [u32], spans: &[(u32, u32)], l: usize) -> &'a [u32] {
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

fn with_scratch<R>(links: usize, f: impl FnOnce(&mut Vec<u32>, &mut [(u32, u32)]) -> R) -> R {
    SCRATCH.with(|s| {
        let mut s = s.borrow_mut();
        let (frontier, spans) = &mut *s;
        if spans.len() < links {
            spans.resize(links, (0, 0));
        }
        f(frontier, spans)
    })
}

/// A query on the CPU, once `bounds` holds the posed links (`Bounds::prepare`, which gave
/// `robot_box`): seeds, the blocks' bounds, the main pass, then the shared refinement and
/// assembly.
pub(super) fn run(
    links: &[QueryLink],
    grids: &[SelfGrid],
    bounds: &mut Bounds,
    input: Input,
    robot_box: RobotBox,
) -> QueryResult {
    let Input {
        points, options, ..
    } = input;
    let tiling = Tiling::new(points.len(), input.width);
    let pass = Pass {
        links,
        tiling,
        posed: &bounds.posed,
        best: &bounds.best,
        global: &bounds.global,
        global_lower: &bounds.global_lower,
        candidates: &bounds.candidates,
        self_filtered: &bounds.self_filtered,
        points,
        mode: options.mode,
        per_link: options.per_link,
        per_link_range: options.per_link_range_m,
        max_gap: bounds.posed.iter().map(|p| p.gap).fold(0.0, f32::max),
        padding: options.self_filter_padding_m.unwrap_or(f32::NEG_INFINITY),
        grids,
        robot_box,
        roots: LinkRoots::new(&bounds.posed),
    };

    // 2. Seeds: each link from the blocks around the SEEDS sample points nearest to its root
    // sphere's centre (valid, not the robot, in distinct blocks), found in one pass over the
    // sample.
    // A coarse pass first (every 16th sample), so that the full pass starts from short lists
    // and offers few samples.
    let stride = SEED_STRIDE as usize;
    let mut coarse = SeedLists::new(pass.posed);
    let coarse_samples = points.len().div_ceil(16 * stride);
    coarse.offer_run(points, 16 * stride, 0..coarse_samples, &pass, &tiling);
    let empty = || coarse.clone();
    let samples = points.len().div_ceil(stride);
    let nearest = (0..samples.div_ceil(GATHER))
        .into_par_iter()
        .with_min_len(1024 / GATHER)
        .fold(empty, |mut lists, c| {
            let run = c * GATHER..((c + 1) * GATHER).min(samples);
            lists.offer_run(points, stride, run, &pass, &tiling);
            lists
        })
        .reduce(empty, |mut a, b| {
            a.merge(&b);
            a
        })
        .lists;
    let seeds: Vec<(usize, Seed)> = nearest
        .iter()
        .enumerate()
        .flat_map(|(l, list)| {
            list.iter()
                .filter(|n| n.1 != u32::MAX)
                .map(move |&n| (l, n))
        })
        .collect();
    // The sample points first (one descent each, the first bounds; for a global query on this
    // thread when they are few, since a parallel step costs about as much as a few dozen
    // descents: `SERIAL_SEEDS`), then, for per-link minima, their blocks.
    let seed_point = |&(l, (_, i, _)): &(usize, Seed)| {
        let p = points[i as usize];
        if pass.robot_box.within(p, pass.robot_box.max_distance) {
            let q = pass.posed[l].in_link(p);
            if let Some((d, _)) = nearest_sphere(&links[l], q, pass.threshold(l)) {
                pass.record(l, i, d);
            }
        }
    };
    if seeds.len() <= SERIAL_SEEDS && !options.per_link {
        seeds.iter().for_each(seed_point);
    } else {
        seeds.par_iter().for_each(seed_point);
    }
    // One bound serves every link of a global query, and the sample points give it close to
    // its final value: their blocks, which tighten each link's own bound, are descended only
    // for per-link minima (on the Kinect scene, global: 20 µs more for the blocks, 2–5 µs less
    // in the main pass).
    if options.per_link {
        seeds.into_par_iter().for_each(|(l, (_, _, b))| {
            let b = b as usize;
            pass.seed(l, b, &bound_block(points, tiling.subs(b)).sphere());
        });
    }

    // 3. Main pass, one sweep over the cloud in groups of `GROUP` blocks (parallel over the
    // groups): each block is bounded, then culled or descended; within a group the last point
    // measured is carried from block to block, so that a point repeated over many blocks is
    // measured once per group.
    let groups = tiling.blocks().div_ceil(GROUP);
    let counts = (0..groups)
        .into_par_iter()
        .map(|g| with_scratch(links.len(), |f, s| pass.group(g, f, s)))
        .reduce(StageCounts::default, |a, b| a + b);

    result::finish(links, bounds, input, counts, Backend::Cpu)
}

#[cfg(test)]
mod tests {
    use super::blocks::tests::xorshift;
    use super::*;

    /// A seed list ends as the `SEEDS` nearest blocks' nearest samples, whatever the order of
    /// the offers (the parallel scan merges lists in any order).
    #[test]
    fn seed_lists_do_not_depend_on_the_order_of_offers() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        for _ in 0..200 {
            // 40 samples in 12 blocks, distances with ties.
            let samples: Vec<Seed> = (0..40)
                .map(|i| ((next() % 16) as f32, i, (next() % 12) as u32))
                .collect();
            let mut expected: Vec<Seed> = Vec::new();
            for b in 0..12 {
                let best = samples
                    .iter()
                    .filter(|s| s.2 == b)
                    .min_by_key(|s| (s.0.to_bits(), s.1));
                expected.extend(best);
            }
            expected.sort_by_key(|s| (s.0.to_bits(), s.1));
            expected.truncate(SEEDS);
            for _ in 0..5 {
                let mut order = samples.clone();
                for k in (1..order.len()).rev() {
                    order.swap(k, (next() % (k as u64 + 1)) as usize);
                }
                let mut list = [NO_SEED; SEEDS];
                for &s in &order {
                    offer(&mut list, s);
                }
                assert_eq!(&list[..expected.len()], &expected[..]);
            }
        }
    }
}
