//! Step 2 of the CPU traversal, the **seeds** (the GPU's `seed` pass does the same job on a
//! whole sample): before the main pass culls any block, each link's bound is made tight from a
//! few points near it. One scan of the sample (every `SEED_STRIDE`-th point, a coarse pass over
//! every 16th sample first so that the lists start short) keeps, per link, the `SEEDS` valid
//! points nearest to its root sphere's centre that are not the robot, in distinct blocks
//! ([`SeedLists`], eight links' centres at a time); those points are descended for their link,
//! and with per-link minima their blocks too (in parallel).

use rayon::prelude::*;
use wide::{f32x8, CmpLt};

use super::blocks::{bound_block, Sphere};
use super::pass::{with_scratch, Pass};
use crate::query::descent::{nearest_sphere, valid};
use crate::query::layout::{PosedLink, Tiling, SEED_COARSE, SEED_STRIDE};
use crate::query::work::{self, Tally};

/// Sample points read at once by the seeds' scan.
const GATHER: usize = 16;

/// Sample points (and their blocks) that seed each link.
const SEEDS: usize = 3;

/// Seed points of a global query descended on the query's own thread: up to this many cost less
/// than a parallel step (eleven links' 33: 11–12 µs against 15–22 µs in parallel, Kinect scene,
/// 2 cores). With per-link minima they stay parallel: on this thread the Kinect node defaults
/// measured 1.27 against 1.22 ms (the parallel step there is followed by the seeds' blocks).
const SERIAL_SEEDS: usize = 48;

/// Queries of at most this many points seed on their own thread, per-link minima included: a
/// parallel step costs more than their few seeds and blocks (the unseen-space pass's small
/// batches of hidden places: one point with per-link minima took 37 µs with parallel seeds, 8 µs
/// without, against 6 µs for the nearest alone; Kinect scene, 2 cores). At 1024 the pass's
/// 466-point batch lost more than the small ones gained (search 3.52–3.65 against 3.40–3.43 ms
/// at 0; 3.27–3.30 ms at 64, the three alternated).
const SERIAL_POINTS: usize = 64;

impl Pass<'_> {
    /// Whether `p` is the robot (within the padding of a link; false when the self-filter is
    /// off).
    fn is_robot(&self, p: [f32; 3]) -> bool {
        self.robot_box.within(p, self.padding)
            && self
                .self_link(p, self.near_links(p, 0.0), &mut { usize::MAX })
                .is_some()
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

/// Step 2 of the CPU traversal, the seeds: each link's bound from the `SEEDS` sample points
/// nearest to its root sphere's centre (every `SEED_STRIDE`-th point; valid, not the robot, in
/// distinct blocks), found in one pass over the sample, and with per-link minima from their
/// blocks too. Returns the work it counted.
pub(super) fn seeds(pass: &Pass, per_link: bool) -> Tally {
    let (points, links, tiling) = (pass.points, pass.links, pass.tiling);
    // A coarse pass first (every `SEED_COARSE`-th sample), so that the full pass starts from
    // short lists and offers few samples.
    let stride = SEED_STRIDE as usize;
    let step = SEED_COARSE as usize * stride;
    let mut coarse = SeedLists::new(pass.posed);
    coarse.offer_run(points, step, 0..points.len().div_ceil(step), pass, &tiling);
    let empty = || coarse.clone();
    let samples = points.len().div_ceil(stride);
    let nearest = (0..samples.div_ceil(GATHER))
        .into_par_iter()
        .with_min_len(1024 / GATHER)
        .fold(empty, |mut lists, c| {
            let run = c * GATHER..((c + 1) * GATHER).min(samples);
            lists.offer_run(points, stride, run, pass, &tiling);
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
    let small = points.len() <= SERIAL_POINTS;
    let mut tally = if small || (seeds.len() <= SERIAL_SEEDS && !per_link) {
        work::counted(|| seeds.iter().for_each(seed_point)).1
    } else {
        seeds
            .par_iter()
            .map(|s| work::counted(|| seed_point(s)).1)
            .reduce(Tally::default, work::sum)
    };
    // One bound serves every link of a global query, and the sample points give it close to
    // its final value: their blocks, which tighten each link's own bound, are descended only
    // for per-link minima (on the Kinect scene, global: 20 µs more for the blocks, 2–5 µs less
    // in the main pass).
    if per_link {
        let seed_block = |&(l, (_, _, b)): &(usize, Seed)| {
            let b = b as usize;
            work::counted(|| pass.seed(l, b, &bound_block(points, tiling.subs(b)).sphere())).1
        };
        let blocks = if small {
            seeds
                .iter()
                .map(seed_block)
                .fold(Tally::default(), work::sum)
        } else {
            (seeds.par_iter().map(seed_block)).reduce(Tally::default, work::sum)
        };
        tally = work::sum(tally, blocks);
    }
    tally
}

#[cfg(test)]
mod tests {
    use super::super::blocks::tests::xorshift;
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
