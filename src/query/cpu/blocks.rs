//! The cloud side of the CPU traversal (`cpu`): how the points are cut into blocks of `BLOCK`
//! (runs of consecutive points, or tiles of an organized cloud: `layout::Tiling`), sub-blocks of
//! `SUB` and groups of `GROUP` blocks, and each block's valid count and bounding box, read as
//! the points lie in memory with SIMD ([`accumulate`]); a block's box culls, the sphere around
//! it is what the links are tested against; the distances of eight blocks' boxes to the
//! robot's box at once ([`robot_distances2`]).

use wide::{f32x4, f32x8, CmpEq, CmpLt, CmpNe};

use crate::query::descent::{dist, valid};
use crate::query::layout::RobotBox;

/// Points per sub-block (`layout::SUB`, the GPU's tile rows too): a block that survives its own
/// tests is taken in runs of eight, each bounded by its own sphere (computed then, since most
/// blocks never need them).
pub(super) use crate::query::layout::SUB;
/// Rows of a tile.
pub(super) use crate::query::layout::TILE_ROWS;

/// A block of `BLOCK` points: the bounding box of its valid points (the
/// levels of the cloud-side hierarchy: run of blocks repeating one point, block, sub-block,
/// point). The box culls (no square root); a block that is not culled is taken with the
/// sphere around it ([`Block::sphere`]).
#[derive(Clone, Copy)]
pub(super) struct Block {
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
    pub(super) valid: u32,
    pub(super) invalid: u32,
}

impl Block {
    /// No points (the slots past a group's last block).
    pub(super) const EMPTY: Self = Self {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
        valid: 0,
        invalid: 0,
    };

    /// All valid points are the same point (a degenerate box).
    pub(super) fn uniform(&self) -> bool {
        self.lo == self.hi
    }

    /// The sphere around the box: centre, radius.
    pub(super) fn sphere(&self) -> Sphere {
        let (center, radius) = sphere_of(self.lo, self.hi);
        Sphere { center, radius }
    }
}

/// The sphere around a block, for the tests against the links.
#[derive(Clone, Copy)]
pub(super) struct Sphere {
    pub(super) center: [f32; 3],
    pub(super) radius: f32,
}

/// Blocks per group of the main pass (a rayon task's unit of work).
pub(super) const GROUP: usize = 16;

/// The sphere around a box `lo..hi` (radius < 0 for an empty box), rounded up so that every
/// point lies inside despite f32 rounding.
#[inline]
pub(super) fn sphere_of(l: [f32; 3], h: [f32; 3]) -> ([f32; 3], f32) {
    if l[0] > h[0] {
        return ([0.0; 3], -1.0);
    }
    let center = [
        0.5 * (l[0] + h[0]),
        0.5 * (l[1] + h[1]),
        0.5 * (l[2] + h[2]),
    ];
    (center, 0.5 * dist(l, h) * (1.0 + 1e-6) + 1e-6)
}

/// Lane masks for a nibble: entry `b` has lane `j` all ones where bit `j` of `b` is set.
static LANE_MASKS: [[u32; 4]; 16] = {
    let mut t = [[0u32; 4]; 16];
    let mut b = 0;
    while b < 16 {
        let mut j = 0;
        while j < 4 {
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
pub(super) const POINT_BITS: u32 = 0x0024_9249;

/// A block's bounding box before its lanes are folded: per bound, three 4-lane accumulators
/// (lane `j` of accumulator `m` holds axis `(4m + j) mod 3`), the box of the points past the
/// last whole octet of each sub-block, and the counts. Groups of blocks are merged lane by
/// lane ([`Raw::merge`]) and folded into a box ([`Raw::fold`]) only when needed.
#[derive(Clone, Copy)]
pub(super) struct Raw {
    lo: [f32x4; 3],
    hi: [f32x4; 3],
    tail_lo: [f32; 3],
    tail_hi: [f32; 3],
    pub(super) valid: u32,
    pub(super) invalid: u32,
}

impl Raw {
    /// No points.
    #[inline(always)]
    pub(super) fn empty() -> Self {
        Self {
            lo: [f32x4::splat(f32::INFINITY); 3],
            hi: [f32x4::splat(f32::NEG_INFINITY); 3],
            tail_lo: [f32::INFINITY; 3],
            tail_hi: [f32::NEG_INFINITY; 3],
            valid: 0,
            invalid: 0,
        }
    }

    /// Takes in another block's points (box and counts).
    #[inline(always)]
    pub(super) fn merge(&mut self, o: &Raw) {
        for m in 0..3 {
            self.lo[m] = self.lo[m].fast_min(o.lo[m]);
            self.hi[m] = self.hi[m].fast_max(o.hi[m]);
            self.tail_lo[m] = self.tail_lo[m].min(o.tail_lo[m]);
            self.tail_hi[m] = self.tail_hi[m].max(o.tail_hi[m]);
        }
        self.valid += o.valid;
        self.invalid += o.invalid;
    }

    /// The box: the lanes folded into their axes (nine comparisons per bound; the values are
    /// finite or ±∞, so plain comparisons do).
    #[inline(always)]
    pub(super) fn fold(&self) -> Block {
        let (mut l, mut h) = (self.tail_lo, self.tail_hi);
        for m in 0..3 {
            let (a, b) = (self.lo[m].to_array(), self.hi[m].to_array());
            for j in 0..4 {
                let axis = (4 * m + j) % 3;
                l[axis] = if a[j] < l[axis] { a[j] } else { l[axis] };
                h[axis] = if b[j] > h[axis] { b[j] } else { h[axis] };
            }
        }
        Block {
            lo: l,
            hi: h,
            valid: self.valid,
            invalid: self.invalid,
        }
    }
}

/// The bounding box and valid count of a block ([`accumulate`], folded).
#[inline(always)]
pub(super) fn bound_block(points: &[[f32; 3]], subs: [(usize, usize); TILE_ROWS]) -> Block {
    accumulate(points, subs).fold()
}

/// The bounding box and valid count of a block, read as it lies in memory: eight points are
/// 24 floats, six 4-lane vectors (SIMD through `wide`: SSE on x86, NEON on ARM). Their lanes
/// hold the axes in three patterns that repeat every three vectors (x y z x, y z x y,
/// z x y z), so that three accumulators per bound take them all ([`Raw`]). Per lane: finite?
/// zero? As bit masks (bit 3k + axis for point k), a point is invalid when any of its three
/// bits is non-finite or all three are zero; its lanes then take ±∞ in the box.
///
/// Inlined where it is called: passed through memory, the sub-block array stalled every call
/// on its own loads (the bounding pass alone over the Kinect cloud, timed: 324 → 259 µs).
#[inline(always)]
pub(super) fn accumulate(points: &[[f32; 3]], subs: [(usize, usize); TILE_ROWS]) -> Raw {
    let inf = f32x4::splat(f32::INFINITY);
    let mut lo = [inf; 3];
    let mut hi = [-inf; 3];
    let mut invalid = 0u32;
    let mut n = 0u32;
    let mut l = [f32::INFINITY; 3];
    let mut h = [f32::NEG_INFINITY; 3];
    for (start, len) in subs {
        let chunk = &points[start..start + len];
        n += len as u32;
        let flat: &[f32] = bytemuck::cast_slice(chunk);
        let groups = chunk.len() / 8;
        for g in 0..groups {
            let v: [f32x4; 6] = std::array::from_fn(|k| {
                let at = 24 * g + 4 * k;
                f32x4::from(<[f32; 4]>::try_from(&flat[at..at + 4]).unwrap())
            });
            let zero = f32x4::ZERO;
            // One test for the common case, eight valid points with no zero coordinate: `0 · v`
            // is 0 for a finite lane and NaN otherwise, so their sum equals itself only when all
            // 24 lanes are finite; no lane compares equal to zero. The per-point masks only
            // otherwise.
            let t = (v[0] * zero + v[1] * zero)
                + (v[2] * zero + v[3] * zero)
                + (v[4] * zero + v[5] * zero);
            let odd = t.cmp_ne(t)
                | (v[0].cmp_eq(zero) | v[1].cmp_eq(zero))
                | (v[2].cmp_eq(zero) | v[3].cmp_eq(zero))
                | (v[4].cmp_eq(zero) | v[5].cmp_eq(zero));
            let bad = if odd.move_mask() == 0 {
                0
            } else {
                let mut nonfinite = 0u32;
                let mut zeros = 0u32;
                for (k, v) in v.iter().enumerate() {
                    nonfinite |= (!v.abs().cmp_lt(inf).move_mask() as u32 & 0xf) << (4 * k);
                    zeros |= (v.cmp_eq(zero).move_mask() as u32 & 0xf) << (4 * k);
                }
                ((nonfinite | nonfinite >> 1 | nonfinite >> 2) | (zeros & zeros >> 1 & zeros >> 2))
                    & POINT_BITS
            };
            invalid += bad.count_ones();
            if bad == 0 {
                // All eight valid (the common case): no masks.
                for (k, v) in v.iter().enumerate() {
                    lo[k % 3] = lo[k % 3].fast_min(*v);
                    hi[k % 3] = hi[k % 3].fast_max(*v);
                }
            } else if bad != POINT_BITS {
                let lanes = bad | bad << 1 | bad << 2;
                for (k, v) in v.iter().enumerate() {
                    let ok = LANE_MASKS[(!(lanes >> (4 * k)) & 0xf) as usize];
                    let ok = f32x4::from(bytemuck::cast::<[u32; 4], [f32; 4]>(ok));
                    lo[k % 3] = lo[k % 3].fast_min(ok.blend(*v, inf));
                    hi[k % 3] = hi[k % 3].fast_max(ok.blend(*v, -inf));
                }
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
    }
    Raw {
        lo,
        hi,
        tail_lo: l,
        tail_hi: h,
        valid: n - invalid,
        invalid,
    }
}

/// [`RobotBox::box_distances2`] for a group's blocks, eight at a time ([`box_distances2_x8`]):
/// (nearest, farthest) per block; the values of empty blocks mean nothing.
#[inline(always)]
pub(super) fn robot_distances2(
    robot: &RobotBox,
    blocks: &[Block; GROUP],
) -> ([f32; GROUP], [f32; GROUP]) {
    let mut near2 = [0.0f32; GROUP];
    let mut far2 = [0.0f32; GROUP];
    for o in 0..GROUP / 8 {
        let (mut lo, mut hi) = ([[0.0f32; 8]; 3], [[0.0f32; 8]; 3]);
        for (j, b) in blocks[8 * o..8 * o + 8].iter().enumerate() {
            for k in 0..3 {
                lo[k][j] = b.lo[k];
                hi[k][j] = b.hi[k];
            }
        }
        let (near, far) = box_distances2_x8(robot, lo.map(f32x8::from), hi.map(f32x8::from));
        near2[8 * o..8 * o + 8].copy_from_slice(&near.to_array());
        far2[8 * o..8 * o + 8].copy_from_slice(&far.to_array());
    }
    (near2, far2)
}

/// [`RobotBox::box_distances2`] for eight blocks' boxes at once (SIMD over the blocks; lane by
/// lane the same arithmetic, so the same values).
#[inline(always)]
pub(super) fn box_distances2_x8(rb: &RobotBox, lo: [f32x8; 3], hi: [f32x8; 3]) -> (f32x8, f32x8) {
    let half = f32x8::splat(0.5);
    let c = [0, 1, 2].map(|k| half * (lo[k] + hi[k]));
    let e = [0, 1, 2].map(|k| half * (hi[k] - lo[k]));
    let slack = f32x8::splat(1e-6) * (f32x8::ONE + c[0].abs() + c[1].abs() + c[2].abs());
    let zero = f32x8::ZERO;
    let (mut near, mut far) = (zero, zero);
    for (k, r) in rb.rows.iter().enumerate() {
        let [r0, r1, r2, r3] = r.map(f32x8::splat);
        let q = r0 * c[0] + r1 * c[1] + r2 * c[2] + r3;
        let w = (r0.abs() * e[0] + r1.abs() * e[1] + r2.abs() * e[2]) * f32x8::splat(1.0 + 1e-6)
            + slack;
        let (l, h) = (f32x8::splat(rb.lo[k]), f32x8::splat(rb.hi[k]));
        let n = (l - (q + w)).max((q - w) - h).max(zero);
        let f = (l - (q - w)).max((q + w) - h).max(zero);
        near += n * n;
        far += f * f;
    }
    (near, far)
}

/// The bounding sphere of the valid points of a sub-block (radius < 0: none).
#[inline]
pub(super) fn bound_sub(chunk: &[[f32; 3]]) -> ([f32; 3], f32) {
    let mut l = [f32::INFINITY; 3];
    let mut h = [f32::NEG_INFINITY; 3];
    for &p in chunk {
        if valid(p) {
            for k in 0..3 {
                l[k] = l[k].min(p[k]);
                h[k] = h[k].max(p[k]);
            }
        }
    }
    sphere_of(l, h)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::query::layout::{Tiling, BLOCK};

    /// A reproducible xorshift stream for the tests.
    pub(in crate::query::cpu) fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    /// `bound_block` (SIMD, with its one-test path for octets of eight valid points) against a
    /// point-by-point bound, on blocks whose octets are all valid, all invalid or mixed, with
    /// every kind of invalid point (NaN, ±∞, the zero point) and valid points with zero
    /// coordinates.
    #[test]
    fn block_bounds_as_point_by_point() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        for round in 0..3000 {
            // Per block a share of invalid points: none, few, half, all.
            let share = [0, 4, 50, 100][round % 4];
            let len = if round % 5 == 0 { 29 } else { BLOCK };
            let points: Vec<[f32; 3]> = (0..len)
                .map(|_| {
                    let mut coordinate = || (next() % 20_001) as f32 * 1e-4 - 1.0;
                    let p = [coordinate(), coordinate(), coordinate()];
                    if (next() % 100) as u32 >= share {
                        // Valid, sometimes on a coordinate plane.
                        match next() % 10 {
                            0 => [0.0, p[1], p[2]],
                            1 => [p[0], -0.0, 0.0],
                            _ => p,
                        }
                    } else {
                        match next() % 4 {
                            0 => [f32::NAN, p[1], p[2]],
                            1 => [p[0], f32::INFINITY, p[2]],
                            2 => [p[0], p[1], f32::NEG_INFINITY],
                            _ => [0.0; 3],
                        }
                    }
                })
                .collect();
            let tiling = Tiling::new(points.len(), None);
            let block = bound_block(&points, tiling.subs(0));
            let valid_points: Vec<_> = points.iter().copied().filter(|&p| valid(p)).collect();
            assert_eq!(block.valid as usize, valid_points.len(), "round {round}");
            assert_eq!(block.invalid as usize, len - valid_points.len());
            if valid_points.is_empty() {
                continue;
            }
            // The scalar bound of a sub-block, point by point, over the whole block.
            let sphere = block.sphere();
            assert_eq!(
                (sphere.center, sphere.radius),
                bound_sub(&points),
                "round {round}"
            );
            assert_eq!(
                block.uniform(),
                valid_points.iter().all(|&p| p == valid_points[0])
            );
        }
    }

    /// A group's merged accumulators fold into the box of all its blocks' valid points, and
    /// eight blocks' distances to the robot's box taken at once are, lane by lane, the ones
    /// taken one block at a time (same bits).
    #[test]
    fn groups_bound_as_their_blocks() {
        let mut next = xorshift(0x6a09_e667_f3bc_c908);
        for round in 0..300 {
            // Blocks of 29 or 32 points (a short tail too), some all invalid.
            let points: Vec<[f32; 3]> = (0..GROUP * BLOCK - (round % 3) * 3)
                .map(|i| {
                    let mut coordinate = || (next() % 40_001) as f32 * 1e-4 - 2.0;
                    let p = [coordinate(), coordinate(), coordinate()];
                    if (i / BLOCK) % 5 == 3 || next().is_multiple_of(9) {
                        [f32::NAN, p[1], p[2]]
                    } else {
                        p
                    }
                })
                .collect();
            let tiling = Tiling::new(points.len(), None);
            let mut all = Raw::empty();
            let mut blocks = [Block::EMPTY; GROUP];
            for (b, block) in blocks.iter_mut().enumerate().take(tiling.blocks()) {
                let raw = accumulate(&points, tiling.subs(b));
                all.merge(&raw);
                *block = raw.fold();
            }
            let group = all.fold();
            let valid: Vec<_> = points.iter().copied().filter(|&p| valid(p)).collect();
            assert_eq!(group.valid as usize, valid.len());
            assert_eq!(group.invalid as usize, points.len() - valid.len());
            for k in 0..3 {
                let lo = valid.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
                let hi = valid.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(
                    (group.lo[k], group.hi[k]),
                    (lo, hi),
                    "round {round} axis {k}"
                );
            }
            // A posed robot box: a rotation about a random axis, a shift.
            let (a, t) = (
                (next() % 628) as f64 * 0.01,
                (next() % 200) as f32 * 0.01 - 1.0,
            );
            let axis = nalgebra::Vector3::new(0.3, -0.5, 0.8).normalize();
            let m = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), a);
            let rows = std::array::from_fn(|r| {
                [
                    m[(r, 0)] as f32,
                    m[(r, 1)] as f32,
                    m[(r, 2)] as f32,
                    t * r as f32,
                ]
            });
            let robot = RobotBox {
                rows,
                lo: [-0.4, -0.3, 0.0],
                max_distance: 1.5,
                hi: [0.4, 0.3, 1.1],
                padding: -1.0,
            };
            let (near, far) = robot_distances2(&robot, &blocks);
            for (k, b) in blocks.iter().enumerate().filter(|(_, b)| b.valid > 0) {
                let (n, f) = robot.box_distances2(b.lo, b.hi);
                assert_eq!(near[k].to_bits(), n.to_bits(), "round {round} block {k}");
                assert_eq!(far[k].to_bits(), f.to_bits(), "round {round} block {k}");
            }
        }
    }
}
