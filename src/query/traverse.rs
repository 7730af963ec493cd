//! The parallel traversal behind [`super::Engine::query`].
//!
//! 1. **Pose** (per link, f64): `sensor_from_link`, the root sphere of the link's tree in the
//!    sensor frame and `link_from_sensor`, rounded to f32 only then; the robot's bounding box in
//!    its root frame for the region of interest.
//! 2. **Seeds** (parallel over links): a sample of the cloud (every `SEED_STRIDE`-th point)
//!    gives each link the point nearest to its root sphere; the block around it is descended for
//!    that link, so that the shared bounds are tight before the main pass.
//! 3. **Main pass** (parallel over blocks of `BLOCK` consecutive points, rayon; the one sweep
//!    over the whole cloud). Each block gets its valid count and the bounding sphere of its valid
//!    points (eight lanes at a time, SIMD). Consecutive points of a scan or depth image lie close
//!    together, so these spheres are small. A block is dropped whole when its sphere lies outside
//!    the region of interest or farther from the robot's box than every link's bound; otherwise
//!    each link's tree is cut at the block: the **frontier**, the nodes no larger than the block
//!    whose lower bound over the block does not exceed the link's bound (a block × tree descent;
//!    most links end with an empty frontier and cost the block nothing more). Each point of the
//!    block is then tested against the frontier nodes (self-filter first), and descends from
//!    them, depth first, nearest child first, four children tested at once, pruning nodes whose
//!    lower bound `|p − c| − r` exceeds the bound. Minima go into the shared atomics with
//!    `fetch_min`, so every thread prunes with the best bound found by any.
//! 4. **Exact** (exact mode): see [`super::exact`].
//!
//! Nothing is allocated per query once the scratch memory has grown (thread-local frontier
//! buffers, the exact candidates' vector).

use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::sync::Mutex;

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;
use wide::{f32x4, f32x8, CmpEq, CmpLt};

use super::SphereSoa;
use super::{
    exact, load_distance, load_f32, pack, unpack, LinkDistance, Mode, Nearest, Outcome, QueryLink,
    QueryOptions, QueryResult, StageCounts, EMPTY,
};
use crate::ist::IstNode;

/// Points per block of the block pass.
pub const BLOCK: usize = 32;
/// Stride of the sample that seeds the links' bounds (prime, so that it does not alias with
/// the rows of an organized cloud).
const SEED_STRIDE: usize = 61;
/// Sample points (and their blocks) that seed each link.
const SEEDS: usize = 3;
/// Most frontier nodes per block and link.
pub const FRONTIER: usize = 32;
/// Depth-first stack size; trees deeper than `(STACK - FRONTIER) / (BRANCHING - 1)` are
/// refused.
pub const STACK: usize = 192;

#[derive(Clone, Copy, Default)]
struct Block {
    center: [f32; 3],
    radius: f32,
    valid: u32,
    invalid: u32,
}

/// A link posed for one query, in the sensor frame (f32, rounded from f64 poses).
#[derive(Clone, Copy, Default)]
pub(crate) struct PosedLink {
    /// Root sphere of the tree.
    pub center: [f32; 3],
    pub radius: f32,
    /// `link_from_sensor`: rows of the rotation, then the translation.
    pub rot: [[f32; 3]; 3],
    pub trans: [f32; 3],
    pub gap: f32,
}

impl PosedLink {
    /// Link `link` posed by `link_poses` (`root_from_link`), seen from the sensor.
    pub fn new(
        link: &QueryLink,
        sensor_from_root: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
    ) -> Self {
        let sensor_from_link = sensor_from_root * link_poses[link.pose_index];
        let root = link.nodes[0];
        let c = sensor_from_link
            * Point3::new(
                root.center[0] as f64,
                root.center[1] as f64,
                root.center[2] as f64,
            );
        let link_from_sensor = sensor_from_link.inverse().to_homogeneous();
        let mut rot = [[0.0f32; 3]; 3];
        let mut trans = [0.0f32; 3];
        for r in 0..3 {
            for k in 0..3 {
                rot[r][k] = link_from_sensor[(r, k)] as f32;
            }
            trans[r] = link_from_sensor[(r, 3)] as f32;
        }
        Self {
            center: [c.x as f32, c.y as f32, c.z as f32],
            radius: root.radius,
            rot,
            trans,
            gap: link.gap_m,
        }
    }

    #[inline(always)]
    pub fn in_link(&self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rot;
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + self.trans[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + self.trans[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + self.trans[2],
        ]
    }
}

/// An exact-mode candidate: a (point, link) pair whose lower bound may beat the best upper bound.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub lower: f32,
    pub link: u32,
    pub point: u32,
}

/// Memory reused from query to query.
pub(super) struct Scratch {
    pub posed: Vec<PosedLink>,
    /// Per link: the minimum and its point, packed (`super::pack`).
    pub best: Vec<AtomicU64>,
    pub global: AtomicU32,
    pub global_lower: AtomicU32,
    pub candidates: Mutex<Vec<Candidate>>,
}

impl Scratch {
    pub fn new(links: usize) -> Self {
        Self {
            posed: vec![PosedLink::default(); links],
            best: (0..links).map(|_| AtomicU64::new(EMPTY)).collect(),
            global: AtomicU32::new(f32::INFINITY.to_bits()),
            global_lower: AtomicU32::new(f32::INFINITY.to_bits()),
            candidates: Mutex::new(Vec::new()),
        }
    }
}

#[inline(always)]
fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[inline(always)]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// A cloud point that carries a measurement: finite and not the (0, 0, 0) "no return".
#[inline(always)]
pub fn valid(p: [f32; 3]) -> bool {
    p[0].is_finite() && p[1].is_finite() && p[2].is_finite() && p != [0.0; 3]
}

#[inline(always)]
fn box_distance(p: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let mut s = 0.0;
    for k in 0..3 {
        let e = (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0);
        s += e * e;
    }
    s.sqrt()
}

/// The nearest inner sphere to `p` (link frame) whose signed distance `|p − c| − r` is at most
/// `bound`: the distance clamped at 0 (inside a sphere) and the sphere's index.
#[inline]
pub fn nearest_sphere(link: &QueryLink, p: [f32; 3], bound: f32) -> Option<(f32, u32)> {
    nearest_from(link, p, &[0], bound)
}

/// Lower bounds `|p − c| − r` of the (at most four) spheres `first..first + count` of `soa`;
/// lanes past `count` read +∞.
#[inline(always)]
fn lower_bounds(soa: &SphereSoa, p: [f32; 3], first: usize, count: usize) -> [f32; 4] {
    let load = |v: &[f32]| f32x4::from(<[f32; 4]>::try_from(&v[first..first + 4]).unwrap());
    let dx = load(&soa.x) - f32x4::splat(p[0]);
    let dy = load(&soa.y) - f32x4::splat(p[1]);
    let dz = load(&soa.z) - f32x4::splat(p[2]);
    let lb = (dx * dx + dy * dy + dz * dz).sqrt() - load(&soa.r);
    let mut out = lb.to_array();
    for v in out.iter_mut().skip(count) {
        *v = f32::INFINITY;
    }
    out
}

/// [`nearest_sphere`] over the subtrees rooted at `starts` (a block's frontier, which holds every
/// sphere that can lie within `bound` of the block's points). Depth first, nearest child on top
/// of the stack; a node is pruned when its lower bound exceeds the best; the four children of a
/// node are tested at once (SIMD over the structure-of-arrays copy of the tree).
#[inline]
pub fn nearest_from(
    link: &QueryLink,
    p: [f32; 3],
    starts: &[u32],
    bound: f32,
) -> Option<(f32, u32)> {
    debug_assert!(starts.len() <= FRONTIER);
    let nodes = &link.nodes;
    let mut best = bound;
    let mut arg = u32::MAX;
    // Uninitialized: entries below `sp` are always written before they are read (a zeroed
    // 1.5 KB array cost more than the descent itself on pruned points).
    let mut stack = [MaybeUninit::<(f32, u32)>::uninit(); STACK];
    let mut sp = 0;
    let mut nearest = (f32::INFINITY, 0);
    for &s in starts {
        let n = &nodes[s as usize];
        // The square root only for the starts that pass the squared test.
        let reach = best + n.radius;
        if reach < 0.0 || dist2(p, n.center) > reach * reach {
            continue;
        }
        let lb = dist(p, n.center) - n.radius;
        if lb <= best {
            stack[sp].write((lb, s));
            if lb < nearest.0 {
                nearest = (lb, sp);
            }
            sp += 1;
        }
    }
    if sp == 0 {
        return None;
    }
    // The nearest start on top.
    stack.swap(nearest.1, sp - 1);
    while sp > 0 {
        sp -= 1;
        // SAFETY: stack[..sp + 1] was written (sp only grows by the entries just written).
        let (lb, index) = unsafe { stack[sp].assume_init() };
        if lb > best {
            continue;
        }
        let node = &nodes[index as usize];
        let first = node.first_child as usize;
        let count = node.child_count as usize;
        if node.children_are_spheres != 0 {
            let d = lower_bounds(&link.sphere_soa, p, first, count);
            for (k, &d) in d.iter().enumerate() {
                if d <= best {
                    best = d;
                    arg = (first + k) as u32;
                }
            }
        } else {
            let lbs = lower_bounds(&link.node_soa, p, first, count);
            // Children within the bound, the nearest pushed last so that it is popped next.
            let mut top = (f32::INFINITY, usize::MAX);
            for (k, &lb) in lbs.iter().enumerate() {
                if lb <= best {
                    stack[sp].write((lb, (first + k) as u32));
                    if lb < top.0 {
                        top = (lb, sp);
                    }
                    sp += 1;
                }
            }
            if top.1 != usize::MAX {
                stack.swap(top.1, sp - 1);
            }
        }
    }
    (arg != u32::MAX).then_some((best.max(0.0), arg))
}

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
            let lbs = lower_bounds(&link.node_soa, c, first, count);
            for (k, &lb) in lbs.iter().enumerate().take(count) {
                if lb - r <= limit {
                    if n == FRONTIER {
                        return true;
                    }
                    next[n] = (first + k) as u32;
                    n += 1;
                }
            }
        }
        out.truncate(start);
        out.extend_from_slice(&next[..n]);
        if !refined || n == 0 {
            return n > 0;
        }
    }
}

/// Depth of a tree (root = 1); the traversal's stack holds `1 + depth·(BRANCHING − 1)` entries.
pub fn tree_depth(nodes: &[IstNode]) -> usize {
    fn depth(nodes: &[IstNode], i: usize) -> usize {
        let n = &nodes[i];
        if n.children_are_spheres != 0 {
            return 1;
        }
        let first = n.first_child as usize;
        1 + (first..first + n.child_count as usize)
            .map(|c| depth(nodes, c))
            .max()
            .unwrap_or(0)
    }
    depth(nodes, 0)
}

struct Pass<'a> {
    links: &'a [QueryLink],
    posed: &'a [PosedLink],
    best: &'a [AtomicU64],
    global: &'a AtomicU32,
    global_lower: &'a AtomicU32,
    candidates: &'a Mutex<Vec<Candidate>>,
    points: &'a [[f32; 3]],
    mode: Mode,
    per_link: bool,
    /// Self-filter padding; −∞ when off.
    padding: f32,
    robot_box: RobotBox,
    max_distance: f32,
}

/// The robot's bounding box in its root frame (over the links' root spheres), where it is
/// tight for an arm standing on its base, with the sensor-to-root transform in f32 (rounded from
/// f64; the box is widened by `BOX_MARGIN` so that the rounding never drops a point).
#[derive(Clone, Copy)]
pub(super) struct RobotBox {
    /// `root_from_sensor`: rows of the rotation, then the translation.
    pub rot: [[f32; 3]; 3],
    pub trans: [f32; 3],
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

/// Widening of the robot box, m: far above the f32 rounding of a transformed point (~1e-6 m).
const BOX_MARGIN: f32 = 1e-4;

impl RobotBox {
    fn new(
        links: &[QueryLink],
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
    ) -> Self {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for link in links {
            let root = link.nodes[0];
            let c = link_poses[link.pose_index]
                * Point3::new(
                    root.center[0] as f64,
                    root.center[1] as f64,
                    root.center[2] as f64,
                );
            for k in 0..3 {
                lo[k] = lo[k].min((c[k] - root.radius as f64) as f32 - BOX_MARGIN);
                hi[k] = hi[k].max((c[k] + root.radius as f64) as f32 + BOX_MARGIN);
            }
        }
        let m = root_from_sensor.to_homogeneous();
        Self {
            rot: std::array::from_fn(|r| std::array::from_fn(|k| m[(r, k)] as f32)),
            trans: std::array::from_fn(|r| m[(r, 3)] as f32),
            lo,
            hi,
        }
    }

    /// Distance from a sensor-frame point to the box.
    #[inline(always)]
    fn distance(&self, p: [f32; 3]) -> f32 {
        let r = &self.rot;
        let q = std::array::from_fn(|k| {
            r[k][0] * p[0] + r[k][1] * p[1] + r[k][2] * p[2] + self.trans[k]
        });
        box_distance(q, self.lo, self.hi)
    }
}

impl Pass<'_> {
    /// The largest inner-sphere distance of link `l` that can still change the result.
    #[inline(always)]
    fn threshold(&self, l: usize) -> f32 {
        let g = load_f32(self.global);
        let mut t = if self.per_link {
            load_distance(&self.best[l])
        } else {
            g
        };
        match self.mode {
            Mode::Certified if !self.per_link => {
                t = t.max(load_f32(self.global_lower) + self.posed[l].gap)
            }
            Mode::Exact => t = t.max(g + self.posed[l].gap),
            _ => {}
        }
        t
    }

    #[inline]
    fn record(&self, l: usize, point: u32, d: f32) {
        self.best[l].fetch_min(pack(d, point), Relaxed);
        self.global.fetch_min(d.to_bits(), Relaxed);
        let lower = (d - self.posed[l].gap).max(0.0);
        match self.mode {
            Mode::Certified => {
                self.global_lower.fetch_min(lower.to_bits(), Relaxed);
            }
            Mode::Exact => {
                if lower <= load_f32(self.global) {
                    self.candidates.lock().unwrap().push(Candidate {
                        lower,
                        link: l as u32,
                        point,
                    });
                }
            }
            Mode::Fast => {}
        }
    }

    /// One valid point inside the region of interest; `mask` holds the links whose frontier
    /// (`frontier[spans[l]]`) is not empty.
    #[inline]
    fn point(
        &self,
        i: u32,
        p: [f32; 3],
        mask: u128,
        frontier: &[u32],
        spans: &[(u32, u32)],
        counts: &mut StageCounts,
    ) {
        // One look at the frontier nodes per link: which links may hold the point within the
        // padding (self-filter) and which within their bound (evaluation).
        let mut near = 0u128;
        let mut eval = 0u128;
        for l in bits(mask) {
            let link = &self.links[l];
            let q = self.posed[l].in_link(p);
            let t = self.threshold(l);
            // |q − c| − r ≤ b  ⇔  |q − c|² ≤ (b + r)²  for b + r ≥ 0: no square root.
            for &n in starts(frontier, spans, l) {
                let n = &link.nodes[n as usize];
                let d2 = dist2(q, n.center);
                let (pad, reach) = (self.padding + n.radius, t + n.radius);
                if pad >= 0.0 && d2 <= pad * pad {
                    near |= 1 << l;
                }
                if d2 <= reach * reach {
                    eval |= 1 << l;
                }
            }
        }
        if near != 0 && self.is_self(p, near, frontier, spans) {
            counts.self_filtered += 1;
            return;
        }
        if eval == 0 {
            counts.pruned += 1;
            return;
        }
        let inside = self.evaluate(i, p, eval, frontier, spans);
        counts.evaluated += 1;
        counts.inside += inside as u64;
    }

    /// Whether `p` is within the self-filter padding of an inner sphere of a link in `mask`.
    #[inline]
    fn is_self(&self, p: [f32; 3], mask: u128, frontier: &[u32], spans: &[(u32, u32)]) -> bool {
        if self.padding < 0.0 {
            return false;
        }
        for l in bits(mask) {
            let link = &self.links[l];
            let q = self.posed[l].in_link(p);
            if nearest_from(link, q, starts(frontier, spans, l), self.padding).is_some() {
                return true;
            }
        }
        false
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

    /// The frontiers of a block in every link (`limit`: the link's threshold, at least the
    /// padding); returns the mask of links with a frontier.
    fn frontiers(
        &self,
        center: [f32; 3],
        radius: f32,
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
    ) -> u128 {
        frontier.clear();
        let mut mask = 0u128;
        for (l, pl) in self.posed.iter().enumerate() {
            let limit = self.threshold(l).max(self.padding);
            // Root sphere first, in the sensor frame (no transform, no square root).
            let reach = limit + radius + pl.radius;
            if dist2(center, pl.center) > reach * reach {
                continue;
            }
            let start = frontier.len() as u32;
            let c = pl.in_link(center);
            if self::frontier(&self.links[l], c, radius, limit, frontier) {
                spans[l] = (start, frontier.len() as u32 - start);
                mask |= 1 << l;
            }
        }
        mask
    }

    fn block(
        &self,
        b: usize,
        block: &Block,
        frontier: &mut Vec<u32>,
        spans: &mut [(u32, u32)],
    ) -> StageCounts {
        let mut counts = StageCounts {
            total: (block.valid + block.invalid) as u64,
            invalid: block.invalid as u64,
            ..Default::default()
        };
        if block.valid == 0 {
            return counts;
        }
        let roi = self.robot_box.distance(block.center);
        if roi - block.radius > self.max_distance {
            counts.outside_roi = block.valid as u64;
            return counts;
        }
        let partial_roi = roi + block.radius > self.max_distance;
        // The robot's bounding box is also a cheap lower bound for every link at once.
        let mut reach = self.padding;
        for l in 0..self.links.len() {
            reach = reach.max(self.threshold(l));
        }
        if roi - block.radius > reach && !partial_roi {
            counts.pruned = block.valid as u64;
            return counts;
        }
        let mask = self.frontiers(block.center, block.radius, frontier, spans);
        if mask == 0 && !partial_roi {
            counts.pruned = block.valid as u64;
            return counts;
        }
        let start = b * BLOCK;
        let end = (start + BLOCK).min(self.points.len());
        for (i, &p) in self.points[start..end].iter().enumerate() {
            if !valid(p) {
                continue;
            }
            if partial_roi && self.robot_box.distance(p) > self.max_distance {
                counts.outside_roi += 1;
            } else if mask == 0 {
                counts.pruned += 1;
            } else {
                self.point((start + i) as u32, p, mask, frontier, spans, &mut counts);
            }
        }
        counts
    }

    /// Seeds link `l`'s bound from the valid points of block `b` (the self-filter applies, so
    /// that the robot's own points never become a bound; nothing is counted).
    fn seed(&self, l: usize, b: usize, block: &Block) {
        with_scratch(self.links.len(), |frontier, spans| {
            let mask = self.frontiers(block.center, block.radius, frontier, spans);
            let start = b * BLOCK;
            let end = (start + BLOCK).min(self.points.len());
            for (i, &p) in self.points[start..end].iter().enumerate() {
                if valid(p)
                    && self.robot_box.distance(p) <= self.max_distance
                    && !self.is_self(p, mask, frontier, spans)
                {
                    self.evaluate((start + i) as u32, p, mask & (1 << l), frontier, spans);
                }
            }
        });
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

/// Lane masks for a byte: entry `b` has lane `j` all ones where bit `j` of `b` is set.
static LANE_MASKS: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut b = 0;
    while b < 256 {
        let mut j = 0;
        while j < 8 {
            if (b >> j) & 1 == 1 {
                t[b][j] = u32::MAX;
            }
            j += 1;
        }
        b += 1;
    }
    t
};

/// Every third bit (bit 3k stands for point k of a group of eight).
const POINT_BITS: u32 = 0x0024_9249;

/// The bounding sphere and valid count of a block, read as it lies in memory: eight points are
/// 24 floats, three 8-lane vectors (SIMD through `wide`: SSE/AVX on x86, NEON on ARM). Per lane:
/// finite? zero? As bit masks (bit 3k + axis for point k), a point is invalid when any of its
/// three bits is non-finite or all three are zero; its lanes then take ±∞ in the box.
#[inline]
fn bound_block(chunk: &[[f32; 3]]) -> Block {
    let flat: &[f32] = bytemuck::cast_slice(chunk);
    let inf = f32x8::splat(f32::INFINITY);
    let mut lo = [inf; 3];
    let mut hi = [-inf; 3];
    let mut invalid = 0u32;
    let groups = chunk.len() / 8;
    for g in 0..groups {
        let v: [f32x8; 3] = std::array::from_fn(|k| {
            let at = 24 * g + 8 * k;
            f32x8::from(<[f32; 8]>::try_from(&flat[at..at + 8]).unwrap())
        });
        let mut nonfinite = 0u32;
        let mut zero = 0u32;
        for (k, v) in v.iter().enumerate() {
            nonfinite |= (!v.abs().cmp_lt(inf).move_mask() as u32 & 0xff) << (8 * k);
            zero |= (v.cmp_eq(f32x8::ZERO).move_mask() as u32 & 0xff) << (8 * k);
        }
        let bad = ((nonfinite | nonfinite >> 1 | nonfinite >> 2) | (zero & zero >> 1 & zero >> 2))
            & POINT_BITS;
        invalid += bad.count_ones();
        let lanes = bad | bad << 1 | bad << 2;
        for k in 0..3 {
            let ok = LANE_MASKS[(!(lanes >> (8 * k)) & 0xff) as usize];
            let ok = f32x8::from(bytemuck::cast::<[u32; 8], [f32; 8]>(ok));
            lo[k] = lo[k].fast_min(ok.blend(v[k], inf));
            hi[k] = hi[k].fast_max(ok.blend(v[k], -inf));
        }
    }
    // Lane j of vector k holds axis (8k + j) mod 3; the values are finite or ±∞, so plain
    // comparisons do.
    let mut l = [f32::INFINITY; 3];
    let mut h = [f32::NEG_INFINITY; 3];
    for k in 0..3 {
        let (a, b) = (lo[k].to_array(), hi[k].to_array());
        for j in 0..8 {
            let axis = (8 * k + j) % 3;
            l[axis] = if a[j] < l[axis] { a[j] } else { l[axis] };
            h[axis] = if b[j] > h[axis] { b[j] } else { h[axis] };
        }
    }
    for &p in &chunk[8 * groups..] {
        if valid(p) {
            for k in 0..3 {
                l[k] = l[k].min(p[k]);
                h[k] = h[k].max(p[k]);
            }
        } else {
            invalid += 1;
        }
    }
    let n = chunk.len() as u32;
    if invalid == n {
        return Block {
            invalid,
            ..Block::default()
        };
    }
    let center = [
        0.5 * (l[0] + h[0]),
        0.5 * (l[1] + h[1]),
        0.5 * (l[2] + h[2]),
    ];
    // Rounded up so that every point lies inside despite f32 rounding.
    let radius = 0.5 * dist(l, h) * (1.0 + 1e-6) + 1e-6;
    Block {
        center,
        radius,
        valid: n - invalid,
        invalid,
    }
}

/// Step 1 of a query: poses the links (f64, rounded once) into `scratch`, resets its minima, and
/// returns the robot's box. Shared by the CPU and GPU backends.
pub(super) fn prepare(
    links: &[QueryLink],
    scratch: &mut Scratch,
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
) -> RobotBox {
    let sensor_from_root = root_from_sensor.inverse();
    for (link, posed) in links.iter().zip(&mut scratch.posed) {
        *posed = PosedLink::new(link, &sensor_from_root, link_poses);
    }
    for b in &scratch.best {
        b.store(EMPTY, Relaxed);
    }
    scratch.global.store(f32::INFINITY.to_bits(), Relaxed);
    scratch.global_lower.store(f32::INFINITY.to_bits(), Relaxed);
    scratch.candidates.get_mut().unwrap().clear();
    RobotBox::new(links, root_from_sensor, link_poses)
}

/// What one query asks: the cloud, where its sensor is, how the robot is posed, the options.
#[derive(Clone, Copy)]
pub(super) struct Input<'a> {
    pub points: &'a [[f32; 3]],
    pub root_from_sensor: &'a Isometry3<f64>,
    pub link_poses: &'a [Isometry3<f64>],
    pub options: &'a QueryOptions,
}

pub(super) fn run(links: &[QueryLink], scratch: &mut Scratch, input: Input) -> QueryResult {
    let Input {
        points,
        root_from_sensor,
        link_poses,
        options,
    } = input;
    // 1. Pose, in f64, rounded once.
    let robot_box = prepare(links, scratch, root_from_sensor, link_poses);
    let pass = Pass {
        links,
        posed: &scratch.posed,
        best: &scratch.best,
        global: &scratch.global,
        global_lower: &scratch.global_lower,
        candidates: &scratch.candidates,
        points,
        mode: options.mode,
        per_link: options.per_link,
        padding: options.self_filter_padding_m.unwrap_or(f32::NEG_INFINITY),
        robot_box,
        max_distance: options.max_distance_m,
    };

    // 2. Seeds: each link from the blocks around the SEEDS sample points nearest to its root
    // sphere's centre.
    (0..links.len()).into_par_iter().for_each(|l| {
        let c = pass.posed[l].center;
        let mut nearest = [(f32::INFINITY, usize::MAX); SEEDS];
        for i in (0..points.len()).step_by(SEED_STRIDE) {
            let p = points[i];
            let d = dist2(p, c);
            if d < nearest[SEEDS - 1].0
                && valid(p)
                && !nearest.iter().any(|n| n.1 / BLOCK == i / BLOCK)
            {
                nearest[SEEDS - 1] = (d, i);
                nearest.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            }
        }
        for &(_, i) in nearest.iter().filter(|n| n.1 != usize::MAX) {
            let b = i / BLOCK;
            let chunk = &points[b * BLOCK..((b + 1) * BLOCK).min(points.len())];
            pass.seed(l, b, &bound_block(chunk));
        }
    });

    // 3. Main pass, one sweep over the cloud: each block is bounded, then culled or descended.
    let counts = points
        .par_chunks(BLOCK)
        .enumerate()
        .with_min_len(16)
        .map(|(b, chunk)| {
            let block = bound_block(chunk);
            with_scratch(links.len(), |f, s| pass.block(b, &block, f, s))
        })
        .reduce(StageCounts::default, |a, b| a + b);

    finish(links, scratch, input, counts)
}

/// Steps 4 and 5 of a query, once `scratch` holds the minima, the exact candidates and the
/// counts of the sweep (from either backend): exact refinement, then the result.
pub(super) fn finish(
    links: &[QueryLink],
    scratch: &mut Scratch,
    input: Input,
    mut counts: StageCounts,
) -> QueryResult {
    let Input {
        points,
        root_from_sensor,
        link_poses,
        options,
    } = input;
    // 4. Exact refinement.
    let refined = if options.mode == Mode::Exact {
        let candidates = scratch.candidates.get_mut().unwrap();
        let upper = load_f32(&scratch.global);
        exact::refine(
            links,
            &scratch.posed,
            candidates,
            points,
            upper,
            &mut counts,
        )
    } else {
        None
    };
    assemble(
        links,
        scratch,
        points,
        root_from_sensor,
        link_poses,
        options,
        counts,
        refined,
    )
}

#[allow(clippy::too_many_arguments)]
fn assemble(
    links: &[QueryLink],
    scratch: &Scratch,
    points: &[[f32; 3]],
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
    options: &QueryOptions,
    counts: StageCounts,
    refined: Option<exact::Refined>,
) -> QueryResult {
    let certified = options.mode != Mode::Fast;
    let within = |d: f32| d <= options.max_distance_m;
    let per_link: Vec<(f32, u32)> = scratch
        .best
        .iter()
        .map(|b| {
            let v = b.load(Relaxed);
            if v == EMPTY {
                (f32::INFINITY, u32::MAX)
            } else {
                unpack(v)
            }
        })
        .collect();
    let mut nearest_link = None;
    for (l, &(d, _)) in per_link.iter().enumerate() {
        if within(d) && nearest_link.is_none_or(|n: usize| d < per_link[n].0) {
            nearest_link = Some(l);
        }
    }
    let global_lower = if options.per_link {
        per_link
            .iter()
            .zip(links)
            .filter(|((d, _), _)| d.is_finite())
            .map(|((d, _), link)| (d - link.gap_m).max(0.0))
            .fold(f32::INFINITY, f32::min)
    } else {
        load_f32(&scratch.global_lower)
    };
    let link_results = if options.per_link {
        per_link
            .iter()
            .zip(links)
            .enumerate()
            .map(|(l, (&(d, p), link))| {
                let ok = within(d);
                LinkDistance {
                    link: link.name.clone(),
                    distance_m: ok.then_some(d as f64),
                    lower_m: (ok && certified).then_some((d - link.gap_m).max(0.0) as f64),
                    exact_m: refined
                        .as_ref()
                        .filter(|r| r.link == l)
                        .map(|r| r.distance as f64),
                    point_index: ok.then_some(p),
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    let to_root = |p: [f32; 3]| {
        let q = root_from_sensor * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        [q.x, q.y, q.z]
    };
    let nearest = match (&refined, nearest_link) {
        (Some(r), _) if within(r.distance) => {
            let link = &links[r.link];
            let p = points[r.point as usize];
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
            let p = points[i as usize];
            let q = scratch.posed[l].in_link(p);
            let (_, s) = nearest_sphere(link, q, f32::INFINITY)
                .expect("a tree with spheres has a nearest one");
            let s = link.spheres[s as usize];
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
            let r =
                link_poses[link.pose_index] * Point3::new(on[0] as f64, on[1] as f64, on[2] as f64);
            Some(Nearest {
                distance_m: d as f64,
                lower_m: certified.then_some(global_lower as f64),
                link: link.name.clone(),
                point_index: i,
                point_sensor: p,
                point_root: to_root(p),
                robot_point_root: [r.x, r.y, r.z],
            })
        }
        _ => None,
    };
    let outcome = if counts.total == counts.invalid {
        Outcome::NoPoints
    } else if nearest.is_some() {
        Outcome::Nearest
    } else {
        Outcome::NothingWithinMaxDistance
    };
    QueryResult {
        mode: options.mode,
        backend: super::Backend::Cpu,
        outcome,
        max_distance_m: options.max_distance_m,
        nearest,
        links: link_results,
        counts,
    }
}
