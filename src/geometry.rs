//! Exact geometric predicates in f64, shared by validation, quality measurement and tests.
//!
//! These are the slow, trusted references: closest point on a triangle (Ericson, *Real-Time
//! Collision Detection*, 5.1.5) and the generalized winding number of a closed triangle mesh
//! (Jacobson et al. 2013), which is ±1 inside and 0 outside. The packing itself uses parry3d in
//! f32 for speed; everything it produces is checked against these.

/// A point or vector in f64, metres.
pub type P3 = [f64; 3];

#[inline]
pub fn sub(a: P3, b: P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub fn add(a: P3, b: P3) -> P3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub fn scale(a: P3, s: f64) -> P3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
pub fn dot(a: P3, b: P3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub fn cross(a: P3, b: P3) -> P3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub fn norm(a: P3) -> f64 {
    dot(a, a).sqrt()
}
#[inline]
pub fn dist(a: P3, b: P3) -> f64 {
    norm(sub(a, b))
}

/// Widens an f32 point to f64.
#[inline]
pub fn widen(p: [f32; 3]) -> P3 {
    [p[0] as f64, p[1] as f64, p[2] as f64]
}

/// The smallest f32 at least `x`: a bound (a radius, a gap) narrowed to f32 must not shrink,
/// and `as f32` rounds to the nearest, down as often as up.
pub fn f32_at_least(x: f64) -> f32 {
    let mut y = x as f32;
    while (y as f64) < x {
        y = y.next_up();
    }
    y
}

/// The largest f32 at most `x`: a radius that must not grow when narrowed to f32.
pub fn f32_at_most(x: f64) -> f32 {
    let mut y = x as f32;
    while (y as f64) > x {
        y = y.next_down();
    }
    y
}

/// Closest point to `p` on the triangle `abc` (Ericson's Voronoi-region method).
pub fn closest_point_triangle(p: P3, a: P3, b: P3, c: P3) -> P3 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return add(a, scale(ab, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return add(a, scale(ac, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return add(b, scale(sub(c, b), w));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    add(a, add(scale(ab, v), scale(ac, w)))
}

/// Distance from `p` to the triangle `abc`.
#[inline]
pub fn distance_point_triangle(p: P3, a: P3, b: P3, c: P3) -> f64 {
    dist(p, closest_point_triangle(p, a, b, c))
}

/// Solid angle of triangle `abc` seen from `p`, divided by 4π (Van Oosterom & Strackee).
pub fn winding_contribution(p: P3, a: P3, b: P3, c: P3) -> f64 {
    let (a, b, c) = (sub(a, p), sub(b, p), sub(c, p));
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let det = dot(a, cross(b, c));
    let div = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    2.0 * det.atan2(div) / (4.0 * std::f64::consts::PI)
}

/// Generalized winding number of a closed, outward-oriented mesh at `p`: ≈1 inside, ≈0 outside.
pub fn winding_number(p: P3, vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            winding_contribution(
                p,
                widen(vertices[t[0] as usize]),
                widen(vertices[t[1] as usize]),
                widen(vertices[t[2] as usize]),
            )
        })
        .sum()
}

/// Exact unsigned distance from `p` to the surface of a triangle mesh, by brute force.
pub fn distance_point_mesh(p: P3, vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            distance_point_triangle(
                p,
                widen(vertices[t[0] as usize]),
                widen(vertices[t[1] as usize]),
                widen(vertices[t[2] as usize]),
            )
        })
        .fold(f64::INFINITY, f64::min)
}

/// Signed volume of a closed mesh (divergence theorem); positive for outward orientation.
/// Taken about the first vertex, so that a mesh far from its frame's origin loses no digits.
pub fn mesh_volume(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    let origin = vertices.first().map_or([0.0; 3], |v| widen(*v));
    triangles
        .iter()
        .map(|t| {
            let a = sub(widen(vertices[t[0] as usize]), origin);
            let b = sub(widen(vertices[t[1] as usize]), origin);
            let c = sub(widen(vertices[t[2] as usize]), origin);
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

/// Area of triangle `abc`.
#[inline]
pub fn triangle_area(a: P3, b: P3, c: P3) -> f64 {
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

/// Axis-aligned bounds (min, max) of f32 points, in f64.
pub fn bounds_f64(vertices: &[[f32; 3]]) -> (P3, P3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k] as f64);
            hi[k] = hi[k].max(v[k] as f64);
        }
    }
    (lo, hi)
}

/// The closed, outward-oriented triangle mesh of a box of `size` centred at the origin: its 8
/// corners (corner `i` on the + side of axis `k` where bit `k` of `i` is set) and 12 triangles.
/// The one box every caller tessellates (`robot::mesh::tessellate_box`, the tests' cubes).
pub fn box_mesh(size: P3) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let h = size.map(|s| (s / 2.0) as f32);
    let vertices = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { -h[0] } else { h[0] },
                if i & 2 == 0 { -h[1] } else { h[1] },
                if i & 4 == 0 { -h[2] } else { h[2] },
            ]
        })
        .collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (vertices, triangles)
}

/// Volume of a ball of radius `r`.
#[inline]
pub fn ball_volume(r: f64) -> f64 {
    4.0 / 3.0 * std::f64::consts::PI * r * r * r
}

/// A solid primitive as URDF describes one: centred on its frame's origin, a cylinder's axis
/// along z. Exclusion volumes (`cloud::exclusion`) and attached objects (`robot::attach`) are
/// these, or meshes ([`Shape`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// Edge lengths along x, y and z.
    Box {
        size: P3,
    },
    Sphere {
        radius: f64,
    },
    Cylinder {
        radius: f64,
        length: f64,
    },
}

impl Primitive {
    /// Whether `p` (in the primitive's frame) lies inside or on it.
    pub fn contains(&self, p: P3) -> bool {
        match *self {
            Primitive::Box { size } => (0..3).all(|a| p[a].abs() <= 0.5 * size[a]),
            Primitive::Sphere { radius } => dot(p, p) <= radius * radius,
            Primitive::Cylinder { radius, length } => {
                p[0] * p[0] + p[1] * p[1] <= radius * radius && p[2].abs() <= 0.5 * length
            }
        }
    }

    /// The half extents of its bounding box in its frame.
    pub fn half_extents(&self) -> P3 {
        match *self {
            Primitive::Box { size } => scale(size, 0.5),
            Primitive::Sphere { radius } => [radius; 3],
            Primitive::Cylinder { radius, length } => [radius, radius, 0.5 * length],
        }
    }

    /// As a URDF geometry, for the robot model.
    pub fn to_urdf(&self) -> urdf_rs::Geometry {
        match *self {
            Primitive::Box { size } => urdf_rs::Geometry::Box {
                size: urdf_rs::Vec3(size),
            },
            Primitive::Sphere { radius } => urdf_rs::Geometry::Sphere { radius },
            Primitive::Cylinder { radius, length } => {
                urdf_rs::Geometry::Cylinder { radius, length }
            }
        }
    }
}

impl std::fmt::Display for Primitive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Primitive::Box { size } => write!(f, "box {} × {} × {} m", size[0], size[1], size[2]),
            Primitive::Sphere { radius } => write!(f, "sphere r = {radius} m"),
            Primitive::Cylinder { radius, length } => {
                write!(f, "cylinder r = {radius} m, length {length} m")
            }
        }
    }
}

/// The shape of a known object of the cell (an exclusion volume, an attached object): a
/// primitive, or a mesh file (STL, OBJ, DAE, PLY) in its own frame, scaled per axis as URDF
/// scales one.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    Primitive(Primitive),
    Mesh { file: std::path::PathBuf, scale: P3 },
}

impl From<Primitive> for Shape {
    fn from(p: Primitive) -> Self {
        Shape::Primitive(p)
    }
}

impl Shape {
    /// The URDF geometry of the shape.
    pub fn to_urdf(&self) -> urdf_rs::Geometry {
        match self {
            Shape::Primitive(p) => p.to_urdf(),
            Shape::Mesh { file, scale } => urdf_rs::Geometry::Mesh {
                filename: file.display().to_string(),
                scale: Some(urdf_rs::Vec3(*scale)),
            },
        }
    }
}

impl std::fmt::Display for Shape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Shape::Primitive(p) => p.fmt(f),
            Shape::Mesh { file, scale } if *scale == [1.0; 3] => {
                write!(f, "mesh {}", file.display())
            }
            Shape::Mesh { file, scale } => write!(f, "mesh {} scaled {scale:?}", file.display()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The unit cube [0, 1]³: the shared box, moved by half its edge.
    fn unit_cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let (v, t) = box_mesh([1.0; 3]);
        (v.into_iter().map(|p| p.map(|x| x + 0.5)).collect(), t)
    }

    #[test]
    fn cube_volume_and_winding() {
        let (v, t) = unit_cube();
        assert!((mesh_volume(&v, &t) - 1.0).abs() < 1e-12);
        assert!((winding_number([0.5, 0.5, 0.5], &v, &t) - 1.0).abs() < 1e-9);
        assert!(winding_number([1.5, 0.5, 0.5], &v, &t).abs() < 1e-9);
    }

    proptest! {
        /// The f32 of a bound is the smallest at least the bound: never below it (as `as f32`
        /// is for about half of them), and the f32 before it is below.
        #[test]
        fn f32_at_least_rounds_up_by_less_than_one_step(x in 1e-9f64..1.0) {
            let y = f32_at_least(x);
            prop_assert!(y as f64 >= x);
            prop_assert!((y.next_down() as f64) < x);
        }

        /// The closest point is never farther than any sampled point of the triangle.
        #[test]
        fn closest_point_beats_samples(
            p in prop::array::uniform3(-2.0f64..2.0),
            a in prop::array::uniform3(-1.0f64..1.0),
            b in prop::array::uniform3(-1.0f64..1.0),
            c in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let d = distance_point_triangle(p, a, b, c);
            for i in 0..=10 {
                for j in 0..=(10 - i) {
                    let (u, v) = (i as f64 / 10.0, j as f64 / 10.0);
                    let q = add(a, add(scale(sub(b, a), u), scale(sub(c, a), v)));
                    prop_assert!(d <= dist(p, q) + 1e-12);
                }
            }
        }

        #[test]
        fn cube_distance_matches_box_formula(p in prop::array::uniform3(-1.0f64..2.0)) {
            let (v, t) = unit_cube();
            let outside = p.iter().any(|x| *x < 0.0 || *x > 1.0);
            let expected = if outside {
                let q = p.map(|x| x.clamp(0.0, 1.0));
                dist(p, q)
            } else {
                p.iter().map(|x| x.min(1.0 - x)).fold(f64::INFINITY, f64::min)
            };
            prop_assert!((distance_point_mesh(p, &v, &t) - expected).abs() < 1e-6);
        }
    }
}
