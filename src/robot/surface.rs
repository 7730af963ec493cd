//! Exact point queries on a triangle surface in f64, independent of parry3d's f32 queries that
//! the packing climbs with: the distance to the nearest triangle (branch and bound over an
//! axis-aligned box tree) and the winding number of a closed, outward-oriented mesh counted
//! along a ray (each triangle the ray crosses adds the sign of its normal along the ray).
//!
//! The ray count is exact unless the ray grazes an edge or a vertex, or runs in a triangle's
//! plane, or the point lies on the surface: then another of three fixed directions is tried,
//! and when all three are ambiguous the winding number is summed in full from every triangle's
//! solid angle (`geometry::winding_number`). Used where a wrong answer would put a sphere
//! outside its link: the packing checks each sphere before it keeps it (`packing`), and
//! `ist::validate` checks every tree before it is used or cached.
//!
//! Cost: build O(n log n) for n triangles; a distance about O(log n); a ray O(√n) boxes in
//! the worst case, far fewer in practice.

use crate::geometry::{closest_point_triangle, cross, dist, dot, sub, winding_contribution, P3};

/// Triangles per leaf.
const LEAF: usize = 8;

/// Ray directions: none along an axis or a diagonal, where CAD meshes line up their edges.
const DIRECTIONS: [P3; 3] = [
    [0.267_261_24, 0.534_522_5, 0.801_783_7],
    [-0.623_479_6, 0.331_662_5, 0.708_09],
    [0.455_842_3, -0.797_724, 0.394_968_8],
];

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: P3,
    hi: P3,
    /// Leaf: first triangle and count (count > 0); inner: first child at `start`, the second
    /// at `start + 1`, count 0.
    start: u32,
    count: u32,
}

/// A triangle surface in f64 with a box tree over its triangles.
pub struct ExactSurface {
    vertices: Vec<P3>,
    /// Reordered by the tree.
    triangles: Vec<[u32; 3]>,
    nodes: Vec<Node>,
}

impl ExactSurface {
    pub fn new(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let vertices: Vec<P3> = vertices.iter().map(|v| v.map(f64::from)).collect();
        let mut triangles: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&i| (i as usize) < vertices.len()))
            .collect();
        let mut nodes = vec![Node {
            lo: [0.0; 3],
            hi: [0.0; 3],
            start: 0,
            count: 0,
        }];
        let mut stack = vec![(0usize, 0usize, triangles.len())];
        while let Some((node, start, end)) = stack.pop() {
            let (lo, hi) = bounds(&vertices, &triangles[start..end]);
            nodes[node].lo = lo;
            nodes[node].hi = hi;
            if end - start <= LEAF {
                nodes[node].start = start as u32;
                nodes[node].count = (end - start) as u32;
                continue;
            }
            let axis = (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0);
            let centre = |t: &[u32; 3]| t.iter().map(|&i| vertices[i as usize][axis]).sum::<f64>();
            let mid = (start + end) / 2;
            triangles[start..end]
                .select_nth_unstable_by(mid - start, |a, b| centre(a).total_cmp(&centre(b)));
            let first = nodes.len();
            nodes[node].start = first as u32;
            for _ in 0..2 {
                nodes.push(nodes[node]);
            }
            stack.push((first, start, mid));
            stack.push((first + 1, mid, end));
        }
        Self {
            vertices,
            triangles,
            nodes,
        }
    }

    fn corners(&self, t: [u32; 3]) -> [P3; 3] {
        t.map(|i| self.vertices[i as usize])
    }

    /// Distance from `p` to the nearest triangle, and that triangle's nearest point.
    pub fn distance(&self, p: P3) -> (f64, P3) {
        self.nearest_below(p, f64::INFINITY, f64::NEG_INFINITY)
    }

    /// Whether every triangle lies at least `d` from `p`: [`Self::distance`] `>= d`, stopping at
    /// the first triangle nearer (a point on the surface answers at its own triangle).
    pub fn at_least(&self, p: P3, d: f64) -> bool {
        self.nearest_below(p, d, d).0 >= d
    }

    /// The nearest triangle's distance and point where it is below `bound` (else `(bound, p)`),
    /// by branch and bound over the box tree, nearer child first; the walk stops at the first
    /// triangle found below `stop`.
    fn nearest_below(&self, p: P3, bound: f64, stop: f64) -> (f64, P3) {
        let mut best = (bound, p);
        if self.triangles.is_empty() {
            return best;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = self.nodes[i];
            if box_distance(p, n.lo, n.hi) >= best.0 {
                continue;
            }
            if n.count > 0 {
                for &t in &self.triangles[n.start as usize..(n.start + n.count) as usize] {
                    let [a, b, c] = self.corners(t);
                    let q = closest_point_triangle(p, a, b, c);
                    let d = dist(p, q);
                    if d < best.0 {
                        best = (d, q);
                        if d < stop {
                            return best;
                        }
                    }
                }
            } else {
                let (l, r) = (n.start as usize, n.start as usize + 1);
                let (dl, dr) = (
                    box_distance(p, self.nodes[l].lo, self.nodes[l].hi),
                    box_distance(p, self.nodes[r].lo, self.nodes[r].hi),
                );
                // Nearer child last, so it is searched first.
                if dl < dr {
                    stack.extend([r, l]);
                } else {
                    stack.extend([l, r]);
                }
            }
        }
        best
    }

    /// The winding number of a closed, outward-oriented surface about `p` (1 inside, 0
    /// outside), counted along a ray; see the module doc for the ambiguous cases.
    pub fn winding(&self, p: P3) -> f64 {
        for d in DIRECTIONS {
            if let Some(w) = self.ray_winding(p, d) {
                return w as f64;
            }
        }
        self.full_winding(p)
    }

    /// Whether `p` lies inside a closed, outward-oriented surface (never outside its box).
    pub fn contains(&self, p: P3) -> bool {
        self.contains_by_rays(p)
            .unwrap_or_else(|| self.full_winding(p) >= 0.5)
    }

    /// [`Self::contains`] by the ray count alone: `None` where every ray is ambiguous (a
    /// point on the surface, or within rounding of it), which the full sum would decide at
    /// the cost of every triangle's solid angle.
    pub fn contains_by_rays(&self, p: P3) -> Option<bool> {
        let root = &self.nodes[0];
        if !(0..3).all(|k| root.lo[k] <= p[k] && p[k] <= root.hi[k]) {
            return Some(false);
        }
        DIRECTIONS
            .iter()
            .find_map(|&d| self.ray_winding(p, d))
            .map(|w| w as f64 >= 0.5)
    }

    /// Every triangle's solid angle (the generalized winding number).
    fn full_winding(&self, p: P3) -> f64 {
        self.triangles
            .iter()
            .map(|&t| {
                let [a, b, c] = self.corners(t);
                winding_contribution(p, a, b, c)
            })
            .sum()
    }

    /// Signed crossings of the ray from `p` along `d`; None when a crossing is ambiguous.
    fn ray_winding(&self, p: P3, d: P3) -> Option<i64> {
        if self.triangles.is_empty() {
            return Some(0);
        }
        let inv = d.map(|x| 1.0 / x);
        let mut w = 0i64;
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = self.nodes[i];
            if !ray_meets_box(p, inv, n.lo, n.hi) {
                continue;
            }
            if n.count == 0 {
                stack.extend([n.start as usize, n.start as usize + 1]);
                continue;
            }
            for &t in &self.triangles[n.start as usize..(n.start + n.count) as usize] {
                let [a, b, c] = self.corners(t);
                match crossing(p, d, a, b, c) {
                    Crossing::None => {}
                    Crossing::Ambiguous => return None,
                    Crossing::Signed(s) => w += s,
                }
            }
        }
        Some(w)
    }
}

enum Crossing {
    None,
    Ambiguous,
    /// +1 where the ray leaves through the triangle's front (outward normal along the ray).
    Signed(i64),
}

/// Möller–Trumbore in f64, with margins that call a hit near an edge, a vertex, the ray's
/// origin or the triangle's plane ambiguous rather than risk a wrong count.
fn crossing(p: P3, d: P3, a: P3, b: P3, c: P3) -> Crossing {
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let h = cross(d, e2);
    let det = dot(e1, h);
    let scale = dot(e1, e1).max(dot(e2, e2));
    if det.abs() <= 1e-12 * scale {
        // In the triangle's plane (or a degenerate triangle): it can only matter if the ray
        // passes through it, which the margins below cannot tell.
        let n = cross(e1, e2);
        let off = dot(sub(p, a), n);
        return if off.abs() <= 1e-12 * scale * scale.sqrt() && norm2(n) > 0.0 {
            Crossing::Ambiguous
        } else {
            Crossing::None
        };
    }
    let f = 1.0 / det;
    let s = sub(p, a);
    let u = f * dot(s, h);
    let q = cross(s, e1);
    let v = f * dot(d, q);
    let t = f * dot(e2, q);
    const EPS: f64 = 1e-9;
    if u < -EPS || v < -EPS || u + v > 1.0 + EPS || t < -EPS * scale.sqrt() {
        return Crossing::None;
    }
    if u <= EPS || v <= EPS || u + v >= 1.0 - EPS || t <= EPS * scale.sqrt() {
        return Crossing::Ambiguous;
    }
    // The outward normal e1 × e2 along d is det's sign (d · (e1 × e2) = −(d × e2) · e1).
    Crossing::Signed(if det < 0.0 { 1 } else { -1 })
}

fn norm2(a: P3) -> f64 {
    dot(a, a)
}

fn bounds(vertices: &[P3], triangles: &[[u32; 3]]) -> (P3, P3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for t in triangles {
        for &i in t {
            let v = vertices[i as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
    }
    (lo, hi)
}

fn box_distance(p: P3, lo: P3, hi: P3) -> f64 {
    let mut s = 0.0;
    for k in 0..3 {
        let d = (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0);
        s += d * d;
    }
    s.sqrt()
}

/// Slab test, the box widened a little so that rounding never drops a crossing.
fn ray_meets_box(p: P3, inv: P3, lo: P3, hi: P3) -> bool {
    let mut t0 = 0.0f64;
    let mut t1 = f64::INFINITY;
    for k in 0..3 {
        let pad = 1e-9 * (hi[k] - lo[k]).abs().max(1e-9);
        let (a, b) = ((lo[k] - pad - p[k]) * inv[k], (hi[k] + pad - p[k]) * inv[k]);
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        t0 = t0.max(a);
        t1 = t1.min(b);
    }
    t0 <= t1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::winding_number;
    use crate::robot::mesh::{tessellate_box, tessellate_sphere};
    use proptest::prelude::*;

    proptest! {
        /// Distance and inside against brute force (every triangle; the solid-angle sum).
        #[test]
        fn as_brute_force(p in prop::array::uniform3(-0.12f64..0.12), sphere in any::<bool>()) {
            let t = if sphere { tessellate_sphere(0.07) } else { tessellate_box([0.1, 0.06, 0.14]) };
            let s = ExactSurface::new(&t.vertices, &t.triangles);
            let brute = crate::geometry::distance_point_mesh(p, &t.vertices, &t.triangles);
            prop_assert!((s.distance(p).0 - brute).abs() <= 1e-12);
            let w = winding_number(p, &t.vertices, &t.triangles);
            prop_assert!((s.winding(p) - w).abs() < 1e-6, "{} vs {}", s.winding(p), w);
        }

        /// `at_least` is the distance compared, on both sides of it and at it.
        #[test]
        fn at_least_is_the_distance_compared(
            p in prop::array::uniform3(-0.12f64..0.12),
            d in 0.0f64..0.1,
            sphere in any::<bool>(),
        ) {
            let t = if sphere { tessellate_sphere(0.07) } else { tessellate_box([0.1, 0.06, 0.14]) };
            let s = ExactSurface::new(&t.vertices, &t.triangles);
            let exact = s.distance(p).0;
            for d in [d, exact, exact.next_up(), exact.next_down()] {
                prop_assert_eq!(s.at_least(p, d), exact >= d, "d {}, distance {}", d, exact);
            }
        }
    }

    #[test]
    fn on_faces_edges_and_vertices_falls_back_or_agrees() {
        let t = tessellate_box([2.0, 2.0, 2.0]);
        let s = ExactSurface::new(&t.vertices, &t.triangles);
        // Points on the axes through edges and vertices, where rays line up with the mesh.
        for p in [[0.0, 0.0, 0.0], [0.999, 0.999, 0.999], [0.0, 0.999, 0.0]] {
            assert!(s.contains(p), "{p:?}");
        }
        for p in [[1.001, 1.001, 1.001], [0.0, 1.5, 0.0], [3.0, 0.0, 0.0]] {
            assert!(!s.contains(p), "{p:?}");
        }
    }
}
