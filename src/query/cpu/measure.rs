//! A block the main pass kept (the GPU's `measure` pass does this job, per point and link):
//! **taken** as the sphere around its box, in two phases.
//!
//! - **The robot** (self-filter), only for a block within the padding of some link's root
//!   sphere: each point is looked up in that link's self-filter grid ([`SelfGrid`]: cells wholly
//!   within the padding of the inner spheres, wholly beyond it, or across it), the link that
//!   took the point before it first; only a point in a cell across the padding descends the
//!   tree (stopping at the first sphere within the padding). A block that is all robot ends
//!   here.
//! - **The obstacles**: each link's tree is cut at the block with the link's bound as the limit
//!   (the **frontier**: the nodes no larger than the block whose lower bound over the block is
//!   within the limit; most links end with an empty one and cost the block nothing more); each
//!   sub-block is tested against the frontier nodes, and a link it reaches only through them is
//!   confirmed by a descent of its centre that stops at the first inner sphere within the bound
//!   plus its radius: the links that remain are the only ones its points look at. Each point is
//!   tested against their frontier nodes; the points of a sub-block that pass descend from
//!   them together, a packet of up to eight (`descent::nearest_packet`, SIMD over the points;
//!   one point alone descends by itself, four children tested at once), depth first, nearest
//!   child first, pruning nodes whose lower bound `|p − c| − r` exceeds the bound of every
//!   point of the packet.
//!
//! [`SelfGrid`]: crate::query::self_grid::SelfGrid

use std::sync::atomic::Ordering::Relaxed;

use wide::f32x8;

use super::blocks::{bound_sub, Block, Sphere, SUB, TILE_ROWS};
use super::pass::{bits, starts, Pass, PointStage, Slot};
use crate::query::descent::{
    any_within, dist, dist2, nearest_from, nearest_packet, valid, within_reach,
};
use crate::query::layout::{Cell, Work, FRONTIER, MAX_LINKS};
use crate::query::link::QueryLink;
use crate::query::result::StageCounts;
use crate::query::work;

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

impl Pass<'_> {
    /// A link of `mask` with an inner sphere within the self-filter padding of `p`: `hint` (the
    /// link that took the point before it, kept up to date) first, then the others in engine
    /// order. Its grid settles most points ([`SelfGrid`]), a descent from its root the points in
    /// the grid's shell.
    #[inline]
    pub(super) fn self_link(&self, p: [f32; 3], mask: u128, hint: &mut usize) -> Option<usize> {
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
    pub(super) fn may_be_robot(&self, block: &Sphere, near: u128) -> bool {
        let limit = self.padding + block.radius;
        bits(near).any(|l| {
            let c = self.posed[l].in_link(block.center);
            any_within(&self.links[l], c, &[0], limit).is_some()
        })
    }

    /// The links whose root sphere comes within the padding of a block (centre `c`, radius
    /// `r`, sensor frame): the only ones that may take its points as the robot (none when the
    /// self-filter is off).
    #[inline]
    pub(super) fn near_links(&self, c: [f32; 3], r: f32) -> u128 {
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

    /// Descends the links of `mask` for an obstacle point and records its distances; returns
    /// whether the point is inside an inner sphere.
    #[inline]
    pub(super) fn evaluate(
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
    pub(super) fn frontiers(
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
    pub(super) fn sub_mask(
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

    /// A block that its box's tests did not drop (`near2`: its squared distance to the robot's
    /// box; `links`: the links within its reach): phase 1, the self-filter, then phase 2,
    /// sub-block by sub-block (each tested against the block's frontier, which also narrows the
    /// links its points descend), then its points, a packet per sub-block. A point equal to the
    /// one before it ends where that one ended.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn take(
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
            work::add(Work::Items, u64::from(mask.count_ones()));
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
    pub(super) fn obstacles(
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
    pub(super) fn packet(
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
            let d = nearest_packet(
                link,
                &[lane(0), lane(1), lane(2)],
                st,
                bound,
                active.count_ones(),
            );
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
}
