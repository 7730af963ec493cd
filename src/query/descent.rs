//! The depth-first descent of one point in one link's inner sphere tree, on the CPU: the
//! nearest inner sphere within a bound, from the root or from a block's frontier. The CPU
//! traversal (`cpu`) runs it for the seeds and for a point that survives its block tests
//! alone in its sub-block (the others go in packets, below); the result assembly (`result.rs`)
//! runs it once to find the closest robot point of either backend's answer. The GPU shader's
//! `descend` follows the same rule, one child at a time.
//!
//! Order: depth first, nearest child on top of the stack; a node is pruned when its lower bound
//! `|p − c| − r` exceeds the best distance so far; the four children of a node are tested at
//! once (SIMD over the structure-of-arrays copy of the tree, `SphereSoa`).
//!
//! A **packet** of eight points near one another (a sub-block's) descends at once,
//! [`nearest_packet`], SIMD over the points instead: a node is kept while it is within the best
//! of any of them. Near points visit nearly the same nodes, so that where many points of a
//! sub-block must be descended (a surface about as far from the link as the bound: a person a
//! metre from the arm, all of whose front lies within a few centimetres of the nearest distance)
//! eight descents cost little more than one. Each lane ends with the distance its own descent
//! would give, bit for bit (the same arithmetic, and a lane only ever visits more nodes).

use std::mem::MaybeUninit;

use wide::{f32x4, f32x8, CmpGe, CmpLe};

use super::layout::{FRONTIER, STACK};
use super::link::{QueryLink, SphereSoa};
use super::work;
use crate::ist::IstNode;

#[inline(always)]
pub(super) fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[inline(always)]
pub(super) fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// A cloud point that carries a measurement: finite and not the (0, 0, 0) "no return".
#[inline(always)]
pub fn valid(p: [f32; 3]) -> bool {
    p[0].is_finite() && p[1].is_finite() && p[2].is_finite() && p != [0.0; 3]
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
pub(super) fn lower_bounds(soa: &SphereSoa, p: [f32; 3], first: usize, count: usize) -> [f32; 4] {
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

/// The spheres `first..first + count` of `soa` (at most four) within `reach` of `p`,
/// `|p − c| − r ≤ reach`, as a bit mask (bit k: sphere `first + k`), tested as
/// `|p − c|² ≤ (reach + r)²`: no square root.
#[inline(always)]
pub(super) fn within_reach(
    soa: &SphereSoa,
    p: [f32; 3],
    first: usize,
    count: usize,
    reach: f32,
) -> u32 {
    reach_keys(soa, p, first, count, reach).1
}

/// [`within_reach`] with a key per sphere that orders them as their lower bounds do on either
/// side of `reach`: `|p − c|² − (reach + r)²`, negative within.
#[inline(always)]
fn reach_keys(
    soa: &SphereSoa,
    p: [f32; 3],
    first: usize,
    count: usize,
    reach: f32,
) -> ([f32; 4], u32) {
    let load = |v: &[f32]| f32x4::from(<[f32; 4]>::try_from(&v[first..first + 4]).unwrap());
    let dx = load(&soa.x) - f32x4::splat(p[0]);
    let dy = load(&soa.y) - f32x4::splat(p[1]);
    let dz = load(&soa.z) - f32x4::splat(p[2]);
    let r = load(&soa.r) + f32x4::splat(reach);
    let d2 = dx * dx + dy * dy + dz * dz;
    let within = d2.cmp_le(r * r) & r.cmp_ge(f32x4::ZERO);
    (
        (d2 - r * r).to_array(),
        within.move_mask() as u32 & ((1 << count) - 1),
    )
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
        work::descended(1, 0);
        return None;
    }
    // The nearest start on top.
    stack.swap(nearest.1, sp - 1);
    let mut expanded = 0;
    while sp > 0 {
        sp -= 1;
        // SAFETY: stack[..sp + 1] was written (sp only grows by the entries just written).
        let (lb, index) = unsafe { stack[sp].assume_init() };
        if lb > best {
            continue;
        }
        expanded += 1;
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
    work::descended(1, expanded);
    (arg != u32::MAX).then_some((best.max(0.0), arg))
}

/// Lower bounds `|p − c| − r` of sphere `i` of `soa` for eight points (SIMD over the points;
/// the arithmetic of [`lower_bounds`], lane for lane).
#[inline(always)]
fn packet_lower_bounds(soa: &SphereSoa, p: &[f32x8; 3], i: usize) -> f32x8 {
    let dx = f32x8::splat(soa.x[i]) - p[0];
    let dy = f32x8::splat(soa.y[i]) - p[1];
    let dz = f32x8::splat(soa.z[i]) - p[2];
    (dx * dx + dy * dy + dz * dz).sqrt() - f32x8::splat(soa.r[i])
}

/// [`nearest_from`] for a packet of eight points (link frame, as three 8-lane vectors):
/// per point, the distance to its nearest inner sphere of the subtrees rooted at `starts`
/// whose signed distance is at most `bound`, clamped at 0; +∞ where none is. A node is pruned
/// when its lower bound exceeds the best distance of every lane; the nearest child (by the
/// lanes' sum) is popped next. `lanes`: the points of the packet (the others repeat one of
/// them), for the work count.
#[inline]
pub(super) fn nearest_packet(
    link: &QueryLink,
    p: &[f32x8; 3],
    starts: &[u32],
    bound: f32,
    lanes: u32,
) -> [f32; 8] {
    debug_assert!(starts.len() <= FRONTIER);
    let nodes = &link.nodes;
    let mut best = f32x8::splat(bound);
    let mut found = f32x8::ZERO;
    let mut stack = [MaybeUninit::<(f32x8, u32)>::uninit(); STACK];
    let mut sp = 0;
    let soa = &link.node_soa;
    push_within(
        &mut stack,
        &mut sp,
        best,
        starts
            .iter()
            .map(|&s| (packet_lower_bounds(soa, p, s as usize), s)),
    );
    let mut expanded = 0;
    while sp > 0 {
        sp -= 1;
        // SAFETY: stack[..sp + 1] was written (sp only grows by the entries just written).
        let (lb, index) = unsafe { stack[sp].assume_init() };
        if !lb.cmp_le(best).any() {
            continue;
        }
        expanded += 1;
        let node = &nodes[index as usize];
        let first = node.first_child as usize;
        let count = node.child_count as usize;
        if node.children_are_spheres != 0 {
            for i in first..first + count {
                let d = packet_lower_bounds(&link.sphere_soa, p, i);
                let within = d.cmp_le(best);
                found |= within;
                best = within.blend(d, best);
            }
        } else {
            push_within(
                &mut stack,
                &mut sp,
                best,
                (first..first + count).map(|i| (packet_lower_bounds(soa, p, i), i as u32)),
            );
        }
    }
    work::descended(u64::from(lanes), expanded * u64::from(lanes));
    let (best, found) = (best.to_array(), found.move_mask());
    std::array::from_fn(|j| {
        if found & (1 << j) != 0 {
            best[j].max(0.0)
        } else {
            f32::INFINITY
        }
    })
}

/// Pushes the nodes of `kids` (lower bounds per lane, index) that are within some lane's best,
/// the nearest (by the lanes' sum) last, so that it is popped next.
#[inline(always)]
fn push_within(
    stack: &mut [MaybeUninit<(f32x8, u32)>; STACK],
    sp: &mut usize,
    best: f32x8,
    kids: impl Iterator<Item = (f32x8, u32)>,
) {
    let mut top = (f32::INFINITY, usize::MAX);
    for (lb, n) in kids {
        if lb.cmp_le(best).any() {
            stack[*sp].write((lb, n));
            let key = lb.reduce_add();
            if key < top.0 {
                top = (key, *sp);
            }
            *sp += 1;
        }
    }
    if top.1 != usize::MAX {
        stack.swap(top.1, *sp - 1);
    }
}

/// Any inner sphere of the subtrees rooted at `starts` whose signed distance to `p` (link frame)
/// is at most `bound`: the first found, depth first, nearest child first (by
/// `|p − c|² − (bound + r)²`; no square root), the self-filter's test, which needs one such
/// sphere, not the nearest.
#[inline]
pub(super) fn any_within(link: &QueryLink, p: [f32; 3], starts: &[u32], bound: f32) -> Option<u32> {
    let nodes = &link.nodes;
    let mut stack = [MaybeUninit::<u32>::uninit(); STACK];
    let mut sp = 0;
    for &s in starts {
        let n = &nodes[s as usize];
        let reach = bound + n.radius;
        if reach >= 0.0 && dist2(p, n.center) <= reach * reach {
            stack[sp].write(s);
            sp += 1;
        }
    }
    let mut expanded = 0;
    while sp > 0 {
        sp -= 1;
        // SAFETY: stack[..sp + 1] was written (sp only grows by the entries just written).
        let index = unsafe { stack[sp].assume_init() };
        expanded += 1;
        let node = &nodes[index as usize];
        let first = node.first_child as usize;
        let count = node.child_count as usize;
        if node.children_are_spheres != 0 {
            let within = within_reach(&link.sphere_soa, p, first, count, bound);
            if within != 0 {
                work::descended(1, expanded);
                return Some((first + within.trailing_zeros() as usize) as u32);
            }
        } else {
            let (keys, mut within) = reach_keys(&link.node_soa, p, first, count, bound);
            // Within the bound, the nearest pushed last so that it is popped next.
            let mut top = (f32::INFINITY, usize::MAX);
            while within != 0 {
                let k = within.trailing_zeros() as usize;
                within &= within - 1;
                stack[sp].write((first + k) as u32);
                if keys[k] < top.0 {
                    top = (keys[k], sp);
                }
                sp += 1;
            }
            if top.1 != usize::MAX {
                stack.swap(top.1, sp - 1);
            }
        }
    }
    work::descended(1, expanded);
    None
}

/// The first node of a tree whose children lie outside `nodes` (or, for a node of spheres,
/// outside the `spheres` spheres), number more than the builder's `BRANCHING`, or come before it
/// in `nodes` (which is what makes every descent, and [`tree_depth`], end), and node 0 of an
/// empty tree; `None` for a tree both backends can walk without bounds checks.
pub fn bad_node(nodes: &[IstNode], spheres: usize) -> Option<usize> {
    if nodes.is_empty() {
        return Some(0);
    }
    nodes.iter().enumerate().position(|(i, n)| {
        let (first, count) = (n.first_child as usize, n.child_count as usize);
        let len = if n.children_are_spheres != 0 {
            spheres
        } else {
            nodes.len()
        };
        count > crate::ist::build::BRANCHING
            || first + count > len
            || (n.children_are_spheres == 0 && count > 0 && first <= i)
    })
}

/// Depth of a tree (root = 1), for `layout::max_tree_depth`; the tree must have no
/// [`bad_node`].
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ist::build::{build_tree, TreeBuilder};
    use crate::packing::InnerSphere;

    /// A packet's lanes give, bit for bit, the distances of the points' own descents: packets of
    /// points near one another (a sub-block's) and of points far apart, from the root and from
    /// a frontier (the root's grandchildren), under bounds that prune nothing, some lanes, or
    /// every lane.
    #[test]
    fn packets_descend_as_their_points() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        // A link of 400 spheres in a 20 × 10 × 10 cm box.
        let spheres: Vec<InnerSphere> = (0..400)
            .map(|_| InnerSphere {
                center: [0.2 * rand(), 0.1 * rand(), 0.1 * rand()],
                radius: 0.002 + 0.01 * rand(),
            })
            .collect();
        let (nodes, spheres) = build_tree(spheres, TreeBuilder::MedianSplit);
        let link = QueryLink::new("l".into(), 0, nodes, spheres, 0.0, Vec::new());
        let grandchildren: Vec<u32> = {
            let root = &link.nodes[0];
            (root.first_child..root.first_child + root.child_count)
                .flat_map(|c| {
                    let n = &link.nodes[c as usize];
                    n.first_child..n.first_child + n.child_count
                })
                .collect()
        };
        let (mut lanes_seen, mut pruned_seen) = (0, 0);
        for round in 0..2000 {
            // A cluster 2 cm across somewhere from inside the link to 1.5 m away, or points
            // scattered over that range.
            let spread = if round % 3 == 0 { 1.5 } else { 0.02 };
            let at = [
                -0.7 + 1.6 * rand(),
                -0.7 + 1.5 * rand(),
                -0.7 + 1.5 * rand(),
            ];
            let q: [[f32; 3]; 8] =
                std::array::from_fn(|_| [0, 1, 2].map(|k| at[k] + spread * (rand() - 0.5)));
            let starts: &[u32] = if round % 2 == 0 { &[0] } else { &grandchildren };
            let nearest = |p, bound| nearest_from(&link, p, starts, bound).map(|(d, _)| d);
            // The bound: none, or about the nearest distance of one lane (some lanes beyond
            // it, some within).
            let bound = match round % 4 {
                0 => f32::INFINITY,
                _ => nearest(q[round % 8], f32::INFINITY).unwrap() + 0.01 * (rand() - 0.5),
            };
            let packet = [0, 1, 2].map(|k| f32x8::from(q.map(|p| p[k])));
            let got = nearest_packet(&link, &packet, starts, bound, 8);
            for j in 0..8 {
                let want = nearest(q[j], bound).unwrap_or(f32::INFINITY);
                assert_eq!(
                    got[j].to_bits(),
                    want.to_bits(),
                    "round {round}, lane {j}: packet {} against {want}",
                    got[j]
                );
                lanes_seen += 1;
                pruned_seen += usize::from(want == f32::INFINITY);
            }
        }
        // Both kinds of lane were seen.
        assert!(pruned_seen > 1000 && lanes_seen - pruned_seen > 1000);
    }
}
