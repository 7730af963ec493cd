//! The depth-first descent of one point in one link's inner sphere tree, on the CPU: the
//! nearest inner sphere within a bound, from the root or from a block's frontier. The CPU
//! traversal (`cpu.rs`) runs it for every point that survives its block tests; the result
//! assembly (`result.rs`) runs it once to find the closest robot point of either backend's
//! answer. The GPU shader's `descend` follows the same rule, one child at a time.
//!
//! Order: depth first, nearest child on top of the stack; a node is pruned when its lower bound
//! `|p − c| − r` exceeds the best distance so far; the four children of a node are tested at
//! once (SIMD over the structure-of-arrays copy of the tree, `SphereSoa`).

use std::mem::MaybeUninit;

use wide::f32x4;

use super::layout::{FRONTIER, STACK};
use super::{QueryLink, SphereSoa};
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

/// Any inner sphere of the subtrees rooted at `starts` whose signed distance to `p` (link frame)
/// is at most `bound`: the first found, depth first, nearest child first (the self-filter's
/// test, which needs one such sphere, not the nearest).
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
    while sp > 0 {
        sp -= 1;
        // SAFETY: stack[..sp + 1] was written (sp only grows by the entries just written).
        let index = unsafe { stack[sp].assume_init() };
        let node = &nodes[index as usize];
        let first = node.first_child as usize;
        let count = node.child_count as usize;
        if node.children_are_spheres != 0 {
            let d = lower_bounds(&link.sphere_soa, p, first, count);
            if let Some(k) = d.iter().position(|&d| d <= bound) {
                return Some((first + k) as u32);
            }
        } else {
            let lbs = lower_bounds(&link.node_soa, p, first, count);
            // Within the bound, the nearest pushed last so that it is popped next.
            let mut top = (f32::INFINITY, usize::MAX);
            for (k, &lb) in lbs.iter().enumerate() {
                if lb <= bound {
                    stack[sp].write((first + k) as u32);
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
    None
}

/// Depth of a tree (root = 1), for `layout::max_tree_depth`.
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
