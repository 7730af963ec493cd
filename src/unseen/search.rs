//! Step 3, the search: the lattice centres nearest the robot whose ball no view rules out, and
//! the certified lower bound of their distance, found the way the query prunes: only what can
//! be nearer than the current bound is examined.
//!
//! Inputs: the [`Lattice`] (root frame), the views ([`PreparedView`]), the robot at the frame's
//! poses ([`RobotBody`]: its links' bounding spheres and trees), the exclusion volumes' test,
//! and the caller's certified distance over a batch of root-frame points (the monitor passes the
//! inner sphere trees' query, each link's h subtracted). Output: [`Found`].
//!
//! **Blocks, best first.** The lattice is cut into blocks of `4 × 4 × 4` centres, grouped in
//! super-blocks of `4 × 4 × 4` blocks. Each has a lower bound: the least, over the links, of
//! `|b − c_L| − r_L − h_L − ρ` (`b` its middle, `ρ` half its centres' diagonal, `(c_L, r_L)`
//! the link's bounding sphere): no centre in it is nearer that link. A heap yields them in the
//! order of that bound (a super-block yields its blocks when it comes up), in waves (32 blocks,
//! then twice as many each wave, each wave in parallel); after a wave its hidden centres go to
//! the caller's distance. A block, and within it a centre, is examined only while its bound is
//! below a best still open: the best distance found (or, per link, that link's best, within
//! `per_link_range`), unless that is at most the ball's margin, below which every distance is
//! 0 and nothing can lower it. The rest is never examined; its least bound per link is what a
//! link's distance is known to exceed there.
//!
//! **Per block and view** (each a shortcut the per-centre test agrees with: `footprint`):
//! - *outside*: every centre projects outside the image, lies nearer than the minimum range or
//!   beyond the maximum, or is too far for a whole pixel to fit in its ball;
//! - *free*: the smallest free distance over the pixels nearest the centres' projections
//!   exceeds the block's farthest centre, so each centre's nearest pixel rules its ball out;
//! - *hidden*: the largest free distance over every centre's window is below the block's
//!   nearest entry `l_min − r` (and, where the robot's shadow is told apart, the robot's image
//!   decides that for the whole block);
//! - otherwise each centre is judged on its own (`footprint::judge`).
//!
//! A centre is **dropped** when its ball leaves the monitored volume (within `r` of a face: the
//! guarantee is for a body inside it), meets one of the robot's inner spheres, or has its centre
//! in an exclusion volume that applies to every source. A centre no view rules out is
//! **hidden**; with the robot's shadow apart, it is in the **shadow** when every view that could
//! see it says the robot hides it, and then counts for the shadow's own distance only.
//!
//! Cost: per block examined a projection of its corners and a few pyramid reads per view; per
//! centre judged one read for free space, a footprint's pixels at a surface or a shadow's rim;
//! per wave one distance query over the hidden centres that can lower a best still open, each
//! link measured only below its own best still open (a link whose best is final, not at all;
//! the monitor's: `measure`). A centre's test against the bests is squared (no square root), on
//! the covers that may reach its block (`needs`), its bound for the markers' order taken only
//! where it is hidden.

use std::collections::BinaryHeap;

use nalgebra::Isometry3;
use rayon::prelude::*;

use super::ball::BallSize;
use super::camera::{half_window, Rect};
use super::cell::{judge_cell, CellSeen, PlacedView};
use super::footprint::{judge, Cause, Need, Seen, Why, PAIR, ROUNDING_M};
use super::lattice::{centre_at, Lattice};
use super::least::Least;
use super::measure::Batch;
use super::needs::Needs;
use super::prepared::PreparedView;
use super::robot::{LinkBound, RobotBody};

/// Centres per block edge, and blocks per super-block edge.
pub const BLOCK: usize = 4;
/// Blocks in the first wave.
const FIRST_WAVE: usize = 32;

/// What the search needs besides the views.
pub struct Search<'a> {
    pub lattice: &'a Lattice,
    pub views: &'a [&'a PreparedView],
    /// The GPU's verdicts on this lattice, per view where it made them (`cell`); may be
    /// shorter than `views`.
    pub verdicts: &'a [Option<&'a [u32]>],
    /// The robot at the frame's poses.
    pub robot: &'a RobotBody,
    /// Whether a root-frame centre lies in an exclusion volume.
    pub excluded: &'a (dyn Fn([f32; 3]) -> bool + Sync),
    /// The balls each cell stands for (`cell`).
    pub size: BallSize,
    /// The robot's shadow counts apart (`unobserved_self_shadow: apart`).
    pub apart: bool,
    /// Per-link minima up to this distance (`None`: the nearest only).
    pub per_link_range_m: Option<f64>,
    /// Most centres kept for the markers.
    pub markers: usize,
}

/// One hidden centre and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spot {
    pub centre: [f32; 3],
    pub cause: Cause,
}

/// What the search counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    pub blocks: usize,
    /// Blocks a view saw free as a whole.
    pub blocks_free: usize,
    /// Blocks never examined: no centre in them could be nearer than what was found.
    pub blocks_pruned: usize,
    pub centres_judged: usize,
    /// Centres dropped: outside the volume's margin, the robot's, in exclusion volumes.
    pub centres_dropped: usize,
    /// Hidden centres found, counted and (apart) in the robot's shadow.
    pub hidden: usize,
    pub shadow: usize,
    /// Distance queries made.
    pub batches: usize,
    /// Views whose cells the GPU judged (`cell`: their verdicts read, not scanned).
    pub views_on_gpu: usize,
}

/// What the search found. Distances are the caller's certified lower bounds at the centres,
/// before the ball's margin is subtracted.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Found {
    /// Over the counted hidden centres (`None`: none; `Some(∞)`: none within the query's reach).
    pub lower_m: Option<f64>,
    /// The nearest counted hidden centre and its cause.
    pub nearest: Option<Spot>,
    /// Over the hidden centres in the robot's shadow (apart only).
    pub shadow_lower_m: Option<f64>,
    /// Per link, over the counted hidden centres: a lower bound (∞: none).
    pub per_link: Vec<f64>,
    /// The counted hidden centres nearest the robot (by the links' bounds), at most `markers`.
    pub near: Vec<Spot>,
    pub counts: Counts,
}

/// A box of cells (a block or a super-block) and its bound.
#[derive(Debug, Clone, Copy)]
struct Cells {
    lo: [usize; 3],
    hi: [usize; 3],
    middle: [f32; 3],
    rho: f32,
    bound: f32,
    block: bool,
}

/// The boxes not yet examined, the least bound first: the boxes in `all`, their bounds with
/// their index there in `heap` (a pop moves 8 bytes; the boxes themselves stay put).
#[derive(Default)]
struct Queue {
    all: Vec<Cells>,
    heap: BinaryHeap<Least<u32>>,
}

impl Queue {
    fn push(&mut self, c: Cells) {
        let item = self.all.len() as u32;
        self.heap.push(Least {
            bound: c.bound,
            item,
        });
        self.all.push(c);
    }

    /// The least bound of the boxes left.
    fn least(&self) -> Option<f32> {
        self.heap.peek().map(|l| l.bound)
    }

    fn pop(&mut self) -> Option<Cells> {
        (self.heap.pop()).map(|l| self.all[l.item as usize])
    }

    /// The boxes left, in no order.
    fn rest(&self) -> impl Iterator<Item = &Cells> + '_ {
        self.heap.iter().map(|l| &self.all[l.item as usize])
    }
}

/// A view's verdict on a whole block: every cell's base ball free, or every ball of every
/// cell (base and sub-balls) hidden for one reason, or neither.
#[derive(Debug, Clone, Copy, PartialEq)]
enum BlockSeen {
    Free,
    Hidden(Why),
    Mixed,
}

/// A hidden centre: its centre, whether it counts (not the shadow apart), its cheap distance
/// for the markers.
#[derive(Debug, Clone, Copy)]
struct Hidden {
    centre: [f32; 3],
    counted: bool,
    near: f32,
}

#[derive(Default)]
struct BlockOut {
    hidden: Vec<Hidden>,
    judged: usize,
    dropped: usize,
    free: bool,
}

impl Search<'_> {
    /// The search (see the module doc); `measure` is the caller's distance over a batch, given
    /// the distance below which the nearest (over every link) is still worth measuring and,
    /// per link (empty: none), the distance below which that link's minimum is (−∞: final).
    pub fn run<E>(
        &self,
        mut measure: impl FnMut(&[[f32; 3]], f64, &[f64]) -> Result<Batch, E>,
    ) -> Result<Found, E> {
        let placed: Vec<PlacedView> = (self.views.iter().enumerate())
            .map(|(i, v)| {
                let verdicts = self.verdicts.get(i).copied().flatten();
                PlacedView::new(v, self.lattice).with_verdicts(verdicts)
            })
            .collect();
        let (origin, steps) = self.lattice.in_frame(&Isometry3::identity());
        let keep = self.kept_indices();
        let links = self.robot.bounds();
        let dims = self.lattice.dims();
        let nb = dims.map(|n| n.div_ceil(BLOCK));
        let ns = nb.map(|n| n.div_ceil(BLOCK));
        let mut heap = Queue::default();
        for s in 0..ns[0] * ns[1] * ns[2] {
            let ijk = [s % ns[0], (s / ns[0]) % ns[1], s / (ns[0] * ns[1])];
            let lo = ijk.map(|x| x * BLOCK * BLOCK);
            let hi = std::array::from_fn(|a| (lo[a] + BLOCK * BLOCK).min(dims[a]));
            heap.push(self.cells(lo, hi, false, origin, &steps, links));
        }
        let per_link = self.per_link_range_m.is_some();
        let range = self.per_link_range_m.unwrap_or(0.0);
        let mut found = Found {
            per_link: vec![f64::INFINITY; if per_link { links.len() } else { 0 }],
            counts: Counts {
                blocks: nb[0] * nb[1] * nb[2],
                views_on_gpu: placed.iter().filter(|p| p.has_verdicts()).count(),
                ..Counts::default()
            },
            ..Found::default()
        };
        let (mut best, mut best_shadow) = (f64::INFINITY, f64::INFINITY);
        let mut near: Vec<Hidden> = Vec::new();
        let mut skipped: Vec<Cells> = Vec::new();
        let mut wave = FIRST_WAVE;
        let mut examined = 0;
        // A best at or below the margin is final: the margin takes it to 0, and nothing is
        // needed to lower it.
        let open = |best: f64| {
            if best > self.size.margin_m {
                best
            } else {
                f64::NEG_INFINITY
            }
        };
        loop {
            let needs = Needs {
                counted: open(best),
                shadow: if self.apart {
                    open(best_shadow)
                } else {
                    f64::NEG_INFINITY
                },
                links: (found.per_link.iter())
                    .map(|&b| open(b.min(range)))
                    .collect(),
            };
            let stop = needs.stop();
            let mut todo = Vec::with_capacity(wave);
            while todo.len() < wave {
                match heap.least() {
                    Some(bound) if f64::from(bound) < stop => {}
                    _ => break,
                }
                let Some(c) = heap.pop() else { break };
                let link_bound = |l: usize| links[l].lower_bound(c.middle) - c.rho;
                if !needs.wants(c.bound, link_bound) {
                    skipped.push(c);
                } else if c.block {
                    todo.push(c);
                } else {
                    self.split(&c, &mut heap, origin, &steps, links);
                }
            }
            if todo.is_empty() {
                break;
            }
            wave *= 2;
            examined += todo.len();
            let outs: Vec<BlockOut> = todo
                .par_iter()
                .map(|b| self.block(b, &placed, origin, &steps, &keep, links, &needs))
                .collect();
            let mut counted = Vec::new();
            let mut shadow = Vec::new();
            for out in outs {
                found.counts.blocks_free += usize::from(out.free);
                found.counts.centres_judged += out.judged;
                found.counts.centres_dropped += out.dropped;
                for h in out.hidden {
                    if h.counted {
                        found.counts.hidden += 1;
                        counted.push(h);
                    } else {
                        found.counts.shadow += 1;
                        shadow.push(h.centre);
                    }
                }
            }
            if !counted.is_empty() {
                let centres: Vec<[f32; 3]> = counted.iter().map(|h| h.centre).collect();
                let batch = measure(&centres, needs.counted, &needs.links)?;
                found.counts.batches += 1;
                if let Some(lower) = batch.lower_m.filter(|&l| l < best) {
                    best = lower;
                    found.nearest = batch.nearest.map(|i| Spot {
                        centre: centres[i],
                        cause: Cause::OutsideView,
                    });
                }
                for (b, &l) in found.per_link.iter_mut().zip(&batch.per_link) {
                    *b = b.min(l);
                }
                near.extend(counted);
                keep_nearest(&mut near, self.markers);
            }
            if !shadow.is_empty() {
                let batch = measure(&shadow, needs.shadow, &[])?;
                found.counts.batches += 1;
                best_shadow = best_shadow.min(batch.lower_m.unwrap_or(f64::INFINITY));
            }
        }
        // Every box not examined bounds what it could hold: per link, the least bound among
        // them is a certified lower bound of that link's distance there.
        skipped.extend(heap.rest());
        found.counts.blocks_pruned = found.counts.blocks - examined;
        for (l, link) in links.iter().enumerate().filter(|_| per_link) {
            let least = (skipped.iter())
                .map(|c| link.lower_bound(c.middle) - c.rho)
                .fold(f32::INFINITY, f32::min);
            found.per_link[l] = found.per_link[l].min(f64::from(least).max(0.0));
        }
        found.lower_m = (found.counts.hidden > 0).then_some(best);
        found.shadow_lower_m = (found.counts.shadow > 0).then_some(best_shadow);
        near.sort_by(|a, b| a.near.total_cmp(&b.near));
        // Causes are named afterwards (`name_causes`), once the views can tell them.
        found.near = (near.iter())
            .map(|h| Spot {
                centre: h.centre,
                cause: Cause::OutsideView,
            })
            .collect();
        Ok(found)
    }

    /// The root-frame centres whose causes [`Search::name_causes`] reads: the nearest hidden
    /// place and those kept for the markers (a view prepared with `RobotImage::Deferred`
    /// renders the rows their tests read first: `PreparedView::render_robot_for`).
    pub fn spots(found: &Found) -> Vec<[f32; 3]> {
        (found.nearest.iter().chain(&found.near))
            .map(|s| s.centre)
            .collect()
    }

    /// Names the cause of the nearest hidden place and of each kept for the markers (see
    /// [`Search::spots`]).
    pub fn name_causes(&self, found: &mut Found) {
        let placed: Vec<PlacedView> = (self.views.iter())
            .map(|v| PlacedView::new(v, self.lattice))
            .collect();
        if let Some(spot) = &mut found.nearest {
            spot.cause = self.cause(&placed, spot.centre);
        }
        (found.near.par_iter_mut()).for_each(|s| s.cause = self.cause(&placed, s.centre));
    }

    /// The box of cells `lo..hi` with its middle, half diagonal and bound.
    fn cells(
        &self,
        lo: [usize; 3],
        hi: [usize; 3],
        block: bool,
        origin: [f32; 3],
        steps: &[[f32; 3]; 3],
        links: &[LinkBound],
    ) -> Cells {
        let h = self.lattice.resolution_m() as f32;
        let a = centre_at(origin, steps, lo);
        let z = centre_at(origin, steps, hi.map(|x| x - 1));
        let middle = std::array::from_fn(|k| 0.5 * (a[k] + z[k]));
        let span: f32 = (0..3).map(|k| ((hi[k] - lo[k] - 1) as f32).powi(2)).sum();
        let rho = 0.5 * h * span.sqrt() * (1.0 + 1e-5) + 1e-6;
        let bound = (links.iter())
            .map(|l| l.lower_bound(middle) - rho)
            .fold(f32::INFINITY, f32::min);
        Cells {
            lo,
            hi,
            middle,
            rho,
            bound,
            block,
        }
    }

    /// A super-block's blocks, onto the heap.
    fn split(
        &self,
        s: &Cells,
        heap: &mut Queue,
        origin: [f32; 3],
        steps: &[[f32; 3]; 3],
        links: &[LinkBound],
    ) {
        for k in (s.lo[2]..s.hi[2]).step_by(BLOCK) {
            for j in (s.lo[1]..s.hi[1]).step_by(BLOCK) {
                for i in (s.lo[0]..s.hi[0]).step_by(BLOCK) {
                    let lo = [i, j, k];
                    let hi = std::array::from_fn(|a| (lo[a] + BLOCK).min(s.hi[a]));
                    heap.push(self.cells(lo, hi, true, origin, steps, links));
                }
            }
        }
    }

    /// Per axis, the cell indices whose centre's ball lies inside the monitored volume.
    fn kept_indices(&self) -> [std::ops::Range<usize>; 3] {
        let dims = self.lattice.dims();
        let half = self.lattice.half_extents_m();
        let h = self.lattice.resolution_m();
        let r = f64::from(self.size.radius_m);
        std::array::from_fn(|a| {
            let n = dims[a];
            // Centre i at (i + ½ − n/2)·h from the middle; kept when |that| + r ≤ half.
            let fits = |i: usize| ((i as f64 + 0.5 - 0.5 * n as f64) * h).abs() + r <= half[a];
            let start = (0..n).find(|&i| fits(i)).unwrap_or(n);
            let end = (0..n).rev().find(|&i| fits(i)).map_or(start, |i| i + 1);
            start..end.max(start)
        })
    }

    /// The hidden centres of one block that may lower a best still open.
    #[allow(clippy::too_many_arguments)]
    fn block(
        &self,
        b: &Cells,
        placed: &[PlacedView],
        origin: [f32; 3],
        steps: &[[f32; 3]; 3],
        keep: &[std::ops::Range<usize>; 3],
        links: &[LinkBound],
        needs: &Needs,
    ) -> BlockOut {
        let need = if self.apart {
            Need::Shadow
        } else {
            Need::Verdict
        };
        let mut known = Vec::with_capacity(placed.len());
        for p in placed {
            match self.block_seen(p, b, need) {
                BlockSeen::Free => {
                    return BlockOut {
                        free: true,
                        ..BlockOut::default()
                    }
                }
                BlockSeen::Hidden(why) => known.push(Some(why)),
                BlockSeen::Mixed => known.push(None),
            }
        }
        let wanted = needs.in_block(links, b.middle, b.rho);
        let mut out = BlockOut::default();
        for k in b.lo[2]..b.hi[2] {
            for j in b.lo[1]..b.hi[1] {
                for i in b.lo[0]..b.hi[0] {
                    let centre = centre_at(origin, steps, [i, j, k]);
                    let kept = keep[0].contains(&i) && keep[1].contains(&j) && keep[2].contains(&k);
                    if !kept || self.robot.takes([i, j, k]) || (self.excluded)(centre) {
                        out.dropped += 1;
                        continue;
                    }
                    if !wanted.point(centre) {
                        continue;
                    }
                    out.judged += 1;
                    if let CellSeen::Hidden { shadow } =
                        judge_cell(placed, [i, j, k], &self.size, need, &known, true)
                    {
                        out.hidden.push(Hidden {
                            centre,
                            counted: !shadow,
                            near: needs.near(links, centre),
                        });
                    }
                }
            }
        }
        out
    }

    /// A view's verdict on a whole block (see the module doc).
    fn block_seen(&self, p: &PlacedView, b: &Cells, need: Need) -> BlockSeen {
        let o = p.view.optics();
        let size = &self.size;
        let (r, r_sub) = (size.radius_m, size.sub_radius_m);
        let radius = size.capability_radius_m as f32;
        // Sub-ball centres lie within d/4 of their cell's.
        let offset = 0.5 * size.half_diagonal_m as f32;
        let mut corners = [[0.0f32; 3]; 8];
        for (c, corner) in corners.iter_mut().enumerate() {
            let ijk = std::array::from_fn(|a| {
                if c >> a & 1 == 0 {
                    b.lo[a]
                } else {
                    b.hi[a] - 1
                }
            });
            *corner = p.centre(ijk);
        }
        if corners.iter().any(|c| c[2] <= radius + offset + 1e-3) {
            return BlockSeen::Mixed;
        }
        let (mut u_lo, mut u_hi, mut v_lo, mut v_hi) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
        let (mut l_max, mut cos_min, mut z_min) = (0.0f32, 1.0f32, f32::MAX);
        for c in &corners {
            let (u, v) = o.project(*c);
            u_lo = u_lo.min(u);
            u_hi = u_hi.max(u);
            v_lo = v_lo.min(v);
            v_hi = v_hi.max(v);
            let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            l_max = l_max.max(l);
            cos_min = cos_min.min(c[2] / l);
            z_min = z_min.min(c[2]);
        }
        let first = p.centre(b.lo);
        let last = p.centre(b.hi.map(|x| x - 1));
        let m: [f32; 3] = std::array::from_fn(|a| 0.5 * (first[a] + last[a]));
        let l_min = ((m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt() - b.rho).max(0.0);
        // How far a sub-ball's centre may project from its cell's (pixels, with room).
        let shift = 2.0 * o.fx.max(o.fy) * offset / (z_min - offset) + 1.0;
        let (w, h) = (o.width as f32, o.height as f32);
        let outside_image = u_hi + shift < -0.5
            || v_hi + shift < -0.5
            || u_lo - shift > w - 0.5
            || v_lo - shift > h - 0.5;
        // Every ball (base or sub) nearer than the minimum range, beyond the maximum, or too
        // far for a whole pixel: `l − r` lies within [l_min − R, l_max − R + d/2] over them.
        let d_half = size.half_diagonal_m as f32;
        if outside_image
            || l_max - radius + d_half < o.min_range_m
            || l_min - radius > o.max_range_m
            || o.footprint(r_sub, (l_min - offset).max(r_sub)).is_none()
        {
            return BlockSeen::Hidden(Why::Known(Cause::OutsideView));
        }
        // The shortcuts need every centre inside the image and the ranges, and each base
        // ball's nearest pixel well inside its footprint.
        let inside = u_lo - shift >= 0.5
            && v_lo - shift >= 0.5
            && u_hi + shift <= w - 1.5
            && v_hi + shift <= h - 1.5;
        let ranged = l_min - radius >= o.min_range_m && l_max - r <= o.max_range_m;
        let far = o.footprint(r, l_max).map_or(0.0, |c| c.sin);
        if !(inside && ranged && far >= 1.1 * o.pixel_angle) {
            return BlockSeen::Mixed;
        }
        let pyr = p.view.pyramids();
        // Free: each cell's base ball ruled out by the pixel nearest its centre, or (where the
        // footprints hold them) by one of the 2 × 2 pixels about it.
        let nearest = Rect::covering(o, u_lo - 0.51, u_hi + 0.51, v_lo - 0.51, v_hi + 0.51);
        if let Some(rect) = nearest {
            if pyr.free.min(rect) >= l_max + ROUNDING_M {
                return BlockSeen::Free;
            }
        }
        let (a, b) = ((u_lo - 0.01).floor() - 0.01, (v_lo - 0.01).floor() - 0.01);
        let corners = Rect::covering(o, a, u_hi + 0.01, b, v_hi + 0.01);
        if let Some(rect) = corners.filter(|_| far >= PAIR * o.pixel_angle) {
            if pyr.pairs.min(rect) >= l_max + ROUNDING_M {
                return BlockSeen::Free;
            }
        }
        // Hidden: no pixel of any ball's window passes the least entry of them all, l_min − R.
        let near = (l_min - offset).max(r_sub);
        let Some(alpha) = o.footprint(r_sub, near) else {
            return BlockSeen::Mixed;
        };
        let Some(half) = half_window(cos_min, alpha) else {
            return BlockSeen::Mixed;
        };
        let (hu, hv) = (o.fx * half + 1.6 + shift, o.fy * half + 1.6 + shift);
        let Some(rect) = Rect::covering(o, u_lo - hu, u_hi + hu, v_lo - hv, v_hi + hv) else {
            return BlockSeen::Mixed;
        };
        let entry = l_min - radius - ROUNDING_M;
        if pyr.free.max(rect) <= entry {
            if need == Need::Verdict {
                return BlockSeen::Hidden(Why::Unknown);
            }
            if pyr.robot.max(rect) <= entry {
                return BlockSeen::Hidden(Why::Known(Cause::RobotShadow));
            }
            if need == Need::Shadow && pyr.robot.min(rect) > l_max + radius + offset {
                return BlockSeen::Hidden(Why::NotShadow);
            }
        }
        BlockSeen::Mixed
    }

    /// Why no view rules out the base ball at root-frame `centre` ([`fused_cause`] of the
    /// views').
    fn cause(&self, placed: &[PlacedView], centre: [f32; 3]) -> Cause {
        let causes: Vec<Cause> = (placed.iter())
            .filter_map(|p| {
                let v = p.view;
                let q = v.camera_from_root() * nalgebra::Point3::from(centre.map(f64::from));
                let q = [q.x as f32, q.y as f32, q.z as f32];
                let seen = judge(
                    v.optics(),
                    &v.pixels(),
                    Some(v.pyramids()),
                    q,
                    self.size.radius_m,
                    Need::Cause,
                );
                match seen {
                    Seen::Hidden(Why::Known(c)) => Some(c),
                    // Free in one view in f64 placement: a centre between two roundings.
                    _ => None,
                }
            })
            .collect();
        fused_cause(&causes)
    }
}

/// The cause reported for a centre hidden from every view: no return first, then another
/// body's shadow, then the robot's, then outside every view.
pub fn fused_cause(causes: &[Cause]) -> Cause {
    [
        Cause::NoReturn,
        Cause::Occluded,
        Cause::RobotShadow,
        Cause::OutsideView,
    ]
    .into_iter()
    .find(|c| causes.contains(c))
    .unwrap_or(Cause::OutsideView)
}

/// Keeps the `most` entries of `near` with the least cheap distance.
fn keep_nearest(near: &mut Vec<Hidden>, most: usize) {
    if near.len() > most {
        if most == 0 {
            near.clear();
            return;
        }
        near.select_nth_unstable_by(most - 1, |a, b| a.near.total_cmp(&b.near));
        near.truncate(most);
    }
}
