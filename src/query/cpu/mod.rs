//! The CPU backend's traversal, steps 2 and 3 of [`super::Engine::query`] (step 1, posing, is
//! `pose.rs`; steps 4 and 5, exact refinement and the result, are `exact.rs` and `result.rs`,
//! shared with the GPU). Each stage sits under the name of the GPU pass that does its job
//! (`shaders/traverse.wgsl`):
//!
//! 2. **Seeds** (`seed.rs`; the GPU's `seed`): tight bounds before any block is culled, from
//!    the sample points nearest to each link.
//! 3. **Main pass** (here; the GPU's `blocks`, then `measure`), parallel over groups of blocks
//!    (rayon), the one sweep over the whole cloud. The cloud's hierarchy (`blocks.rs`: the
//!    tiling and the blocks' SIMD bounds), bottom up: points; **sub-blocks** of `SUB` = 8
//!    points; **blocks** of `BLOCK` = 32 points, runs of consecutive points or, for an
//!    organized cloud, tiles of 8 × 4 pixels ([`Tiling`]; a tile's sphere is about a third of a
//!    row run's); groups of 16 blocks, a rayon task. Each block gets its valid count and the
//!    bounding box of its valid points (eight lanes at a time, SIMD). A group, then a block, is
//!    dropped whole when its box lies outside the region of interest or farther from the
//!    robot's box than every link's bound (squared distances between the boxes, eight blocks at
//!    a time); a block, also when its box is beyond every link's root sphere by the link's
//!    bound (eight links at a time). No square root for the blocks dropped here, nearly all of
//!    them (on the Kinect scene, global: about 250 of 9600 blocks go further). Otherwise a block
//!    is taken (`measure.rs`), as the sphere around its box, in two phases: **the robot** (the
//!    self-filter, through each link's grid) and **the obstacles** (each link's tree cut at the
//!    block, the frontier; sub-blocks tested against it; points descending from it in packets
//!    of up to eight).
//!
//!    A point equal to the one before it (within a group, across blocks too) takes its result
//!    with no work. Minima go into the shared atomics with `fetch_min`, so every thread prunes
//!    with the best bound found by any.
//!
//! The pruning rule ([`Pass::threshold`]) and the recording rule ([`Pass::record`]) are the
//! ones the GPU shader implements; the frontiers, sub-blocks, packets and SIMD are the CPU's
//! own. Both count their work alike (`query::work`: blocks, culled, items, descents, nodes).
//! Nothing is allocated per query once the scratch memory has grown (thread-local frontier
//! buffers, the exact candidates' vector), but the seed lists (a few hundred bytes per rayon
//! split).

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use rayon::prelude::*;
use wide::{f32x8, CmpGe, CmpLe};

pub(super) mod blocks;
mod measure;
mod seed;

use super::bounds::{load_distance, load_f32, pack_minimum, threshold, threshold_x8, Bounds};
use super::layout::{Candidate, PosedLink, RobotBox, Work};
use super::self_grid::SelfGrid;
use super::work::{self, Tally};
use super::{result, Backend, Input, Mode, QueryLink, QueryResult, StageCounts, MAX_LINKS};
use blocks::{accumulate, robot_distances2, Block, Raw, Tiling, GROUP};

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

    /// Whether point `p` of a block that straddles the region of interest lies outside it.
    #[inline(always)]
    fn outside(&self, p: [f32; 3], partial_roi: bool) -> bool {
        partial_roi && !self.robot_box.within(p, self.robot_box.max_distance)
    }

    /// One group of `GROUP` blocks (a rayon task): each block bounded; the group's box tested
    /// against the robot's box (most groups away from the robot end here, as one); else all
    /// its blocks tested against the robot's box at once ([`robot_distances2`]), then block by
    /// block ([`Pass::block`]). Within the group the last point measured is carried from block
    /// to block, so that a point repeated over many blocks is measured once per group.
    fn group(&self, g: usize, frontier: &mut Vec<u32>, spans: &mut [(u32, u32)]) -> StageCounts {
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
    fn block(
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

    // 2. Seeds.
    let seeded = seed::seeds(&pass, options.per_link);

    // 3. Main pass, one sweep over the cloud in groups of `GROUP` blocks (parallel over the
    // groups): each block is bounded, then culled or descended; within a group the last point
    // measured is carried from block to block, so that a point repeated over many blocks is
    // measured once per group.
    let groups = tiling.blocks().div_ceil(GROUP);
    let (counts, swept) = (0..groups)
        .into_par_iter()
        .map(|g| work::counted(|| with_scratch(links.len(), |f, s| pass.group(g, f, s))))
        .reduce(
            || (StageCounts::default(), Tally::default()),
            |a, b| (a.0 + b.0, work::sum(a.1, b.1)),
        );
    for (a, n) in bounds.work.iter().zip(work::sum(seeded, swept)) {
        a.store(n, Relaxed);
    }

    result::finish(links, bounds, input, counts, Backend::Cpu)
}
