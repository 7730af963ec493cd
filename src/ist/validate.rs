//! Checks of a link's inner sphere tree against its collision geometry, in f64 and
//! independent of the f32 parry3d queries the packing climbed with (`robot::exact`). Every
//! build runs them before its tree is used or cached (`ist::build_link`):
//! - the tree: every node bounds each of its children, every sphere is reached exactly once;
//! - every sphere lies inside the link: its centre inside one of the link's elements (the ray
//!   winding number of a closed mesh; for a solid the intake filled, its flood fill) and its
//!   radius at most the distance from the centre to that element's surface, plus `tolerance`;
//! - no two spheres overlap by more than `tolerance`, on links of one element (the elements of
//!   a link may overlap each other, and so may spheres packed into different elements);
//! - **h is certified** on the surface the packing measured (each element's triangles, less
//!   its tessellation error) and on every triangle of the **mesh files as read, before any
//!   repair** (where the intake changed nothing, the two are the same triangles, checked once):
//!   every point of them lies within h + `gap_slack_m` + `tolerance` of the spheres, or (for
//!   the file's own triangles) inside the link's solid, where the solid's own surface is what
//!   bounds the distance. That sum is the h the validation certifies, and the one the tree
//!   reports (`gap_slack_m` is the accuracy of the packing's own measure, `packing::gap`). A
//!   piece of the file that the intake lost shows here as a point far from every sphere. The
//!   branch and bound is that of `packing::gap` in f64: a triangle is done when the Lipschitz
//!   bound (largest corner gap + longest edge / √3) or the convex bound of one sphere (largest
//!   corner distance to it less its radius) is at most h + `gap_slack_m`, or all of it is
//!   deeper inside the solid than its longest edge / √3; otherwise its longest edge is split,
//!   down to triangles of `tolerance`, whose corners decide.
//!
//! Cost: a box-tree query per sphere and per triangle corner visited; about a second per link
//! of 8192 spheres and a few thousand triangles on 2 cores.

use rayon::prelude::*;

use super::link_tree::{IstNode, LinkTree};
use crate::geometry::{dist, widen, P3};
use crate::packing::InnerSphere;
use crate::robot::exact::ExactSolid;
use crate::robot::LinkGeometry;

/// A failed check, naming the link and the sphere, node or surface point.
#[derive(Debug, thiserror::Error)]
pub enum ValidationError {
    #[error(
        "link {link}: sphere {sphere} ({center:?}, r={radius}) is outside every collision element"
    )]
    Outside {
        link: String,
        sphere: usize,
        center: [f32; 3],
        radius: f32,
    },
    #[error(
        "link {link}: sphere {sphere} has radius {radius} but only {clearance} m to the surface"
    )]
    Protrudes {
        link: String,
        sphere: usize,
        radius: f32,
        clearance: f64,
    },
    #[error("link {link}: spheres {a} and {b} overlap by {overlap_m} m")]
    Overlap {
        link: String,
        a: usize,
        b: usize,
        overlap_m: f64,
    },
    #[error("link {link}: tree: {message}")]
    Tree { link: String, message: String },
    #[error(
        "link {link}, {surface}: the point {point:?} (link frame, m) lies {gap_m} m from every \
         inner sphere (and is not inside the link's solid), more than the claimed h = {h_m} m \
         (part of the file lost by the intake, or a gap the packing did not see)"
    )]
    Gap {
        link: String,
        surface: String,
        point: [f64; 3],
        gap_m: f64,
        h_m: f64,
    },
}

/// What a passed validation checked.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Validation {
    /// The certified surface gap h, m: the tree's claim + `gap_slack_m` + `tolerance`.
    pub gap_m: f64,
    pub spheres: usize,
    /// Triangles over which h was certified: the elements' and the files' own.
    pub triangles: usize,
    /// Largest distance sampled from the files' own triangles (outside the solid) to the
    /// spheres, m: at most h + tolerance.
    pub file_gap_sampled_m: f64,
    pub seconds: f64,
}

/// Runs every check on one link (see the module doc for `tolerance` and `gap_slack_m`).
pub fn validate_link(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    tolerance: f64,
    gap_slack_m: f64,
) -> Result<Validation, ValidationError> {
    let start = std::time::Instant::now();
    let link = &tree.link;
    check_tree(&tree.nodes, &tree.spheres, tolerance).map_err(|message| ValidationError::Tree {
        link: link.clone(),
        message,
    })?;
    let solids: Vec<ExactSolid> = geometry
        .elements
        .par_iter()
        .map(|e| ExactSolid::new(&e.mesh))
        .collect();
    // The largest clearance of a sphere in any element whose solid holds its centre.
    let clearance = |s: &InnerSphere| {
        solids
            .iter()
            .filter_map(|solid| solid.ball_clearance(widen(s.center), s.radius as f64))
            .fold(None, |best: Option<f64>, c| {
                Some(best.map_or(c, |b| b.max(c)))
            })
    };
    let failure = tree
        .spheres
        .par_iter()
        .enumerate()
        .find_first(|(_, s)| clearance(s).is_none_or(|c| c < -tolerance));
    if let Some((i, s)) = failure {
        return Err(match clearance(s) {
            None => ValidationError::Outside {
                link: link.clone(),
                sphere: i,
                center: s.center,
                radius: s.radius,
            },
            Some(c) => ValidationError::Protrudes {
                link: link.clone(),
                sphere: i,
                radius: s.radius,
                clearance: c + s.radius as f64,
            },
        });
    }
    if geometry.elements.len() == 1 {
        check_no_overlap(&tree.spheres, tolerance).map_err(|(a, b, overlap_m)| {
            ValidationError::Overlap {
                link: link.clone(),
                a,
                b,
                overlap_m,
            }
        })?;
    }
    let index = SphereIndex {
        nodes: &tree.nodes,
        spheres: &tree.spheres,
        slack: tolerance,
    };
    let h = tree.quality.gap_m + gap_slack_m;
    let gap_error = |surface: String, (point, gap_m): (P3, f64)| ValidationError::Gap {
        link: link.clone(),
        surface,
        point,
        gap_m,
        h_m: h,
    };
    let mut triangles = 0;
    // The surface the packing measured: inside is not an excuse there.
    for e in &geometry.elements {
        let corners: Vec<[P3; 3]> = e
            .mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| widen(e.mesh.vertices[i as usize])))
            .collect();
        triangles += corners.len();
        certify(
            &corners,
            h - e.tessellation_error_m,
            tolerance,
            &index,
            None,
        )
        .map_err(|f| gap_error(format!("collision element {} ({})", e.index, e.source), f))?;
    }
    // The files as read: a point may also lie inside the solid, deeper than the sub-triangle.
    let depth = |p: P3| -> f64 {
        solids
            .iter()
            .filter(|s| s.contains(p))
            .map(|s| s.surface.distance(p).0)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let mut file_gap: f64 = 0.0;
    // A file the intake took as it was is the packed surface itself, certified above.
    for intake in geometry
        .intake
        .iter()
        .filter(|i| !i.report.clean() || i.report.pieces > 1)
    {
        let (vertices, tris) = &*intake.original;
        let corners: Vec<[P3; 3]> = tris
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < vertices.len()))
            .map(|t| t.map(|i| widen(vertices[i as usize])))
            .collect();
        triangles += corners.len();
        let sampled = certify(&corners, h, tolerance, &index, Some(&depth)).map_err(|f| {
            gap_error(
                format!(
                    "collision element {}, mesh {} as read",
                    intake.element,
                    intake.file.display()
                ),
                f,
            )
        })?;
        file_gap = file_gap.max(sampled);
    }
    Ok(Validation {
        gap_m: h + tolerance,
        spheres: tree.spheres.len(),
        triangles,
        file_gap_sampled_m: file_gap,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Nearest-sphere queries through the tree's own nodes (checked by [`check_tree`] to bound
/// their children within `slack`).
struct SphereIndex<'a> {
    nodes: &'a [IstNode],
    spheres: &'a [InnerSphere],
    slack: f64,
}

impl SphereIndex<'_> {
    /// The smallest `|p − c| − r` over the spheres, and that sphere.
    fn nearest(&self, p: P3) -> (f64, usize) {
        let mut best = (f64::INFINITY, 0usize);
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let Some(n) = self.nodes.get(i) else { continue };
            if dist(p, widen(n.center)) - n.radius as f64 - self.slack >= best.0 {
                continue;
            }
            let range = n.first_child as usize..(n.first_child + n.child_count) as usize;
            if n.children_are_spheres == 1 {
                for (k, s) in self.spheres[range.clone()].iter().enumerate() {
                    let d = dist(p, widen(s.center)) - s.radius as f64;
                    if d < best.0 {
                        best = (d, range.start + k);
                    }
                }
            } else {
                stack.extend(range);
            }
        }
        best
    }

    /// Largest distance from the triangle's corners to sphere `k`'s ball.
    fn convex_bound(&self, corners: [P3; 3], k: usize) -> f64 {
        let s = self.spheres[k];
        corners
            .iter()
            .map(|&v| dist(v, widen(s.center)) - s.radius as f64)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

const INV_SQRT3: f64 = 0.577_350_269_189_625_8;

/// Certifies that every point of `triangles` lies within `h + tolerance` of the spheres, or,
/// with `depth` (the depth of a point inside the solid, −∞ outside), inside the solid. Returns
/// the largest gap sampled outside the solid, or the first point that fails and its gap.
fn certify(
    triangles: &[[P3; 3]],
    h: f64,
    tolerance: f64,
    index: &SphereIndex,
    depth: Option<&(dyn Fn(P3) -> f64 + Sync)>,
) -> Result<f64, (P3, f64)> {
    let limit = h + tolerance;
    let g = |p: P3| {
        let (d, k) = index.nearest(p);
        (d.max(0.0), k)
    };
    let excused = |p: P3, gap: f64| gap <= limit || depth.is_some_and(|f| f(p) >= 0.0);
    triangles
        .par_iter()
        .map(|&[a, b, c]| {
            let mut sampled = 0.0f64;
            let mut stack = vec![([a, b, c], [g(a), g(b), g(c)])];
            while let Some((t, gs)) = stack.pop() {
                let longest = dist(t[0], t[1]).max(dist(t[1], t[2])).max(dist(t[2], t[0]));
                let lipschitz = gs[0].0.max(gs[1].0).max(gs[2].0) + longest * INV_SQRT3;
                let convex = gs
                    .iter()
                    .map(|&(_, k)| index.convex_bound(t, k))
                    .fold(f64::INFINITY, f64::min)
                    .max(0.0);
                if lipschitz.min(convex) <= limit {
                    sampled = sampled.max(gs[0].0.max(gs[1].0).max(gs[2].0));
                    continue;
                }
                if let Some(depth) = depth {
                    if t.iter().all(|&v| depth(v) >= longest * INV_SQRT3) {
                        continue;
                    }
                }
                if longest * INV_SQRT3 <= tolerance {
                    for (v, (gap, _)) in t.iter().zip(gs) {
                        if !excused(*v, gap) {
                            return Err((*v, gap));
                        }
                        if gap <= limit {
                            sampled = sampled.max(gap);
                        }
                    }
                    continue;
                }
                // Split the longest edge: slivers (a tessellated cylinder's faces) become
                // rounder pieces at once instead of four slivers.
                let k = (0..3)
                    .max_by(|&i, &j| {
                        dist(t[i], t[(i + 1) % 3]).total_cmp(&dist(t[j], t[(j + 1) % 3]))
                    })
                    .unwrap_or(0);
                let (p, q, r) = (k, (k + 1) % 3, (k + 2) % 3);
                let m: P3 = std::array::from_fn(|x| 0.5 * (t[p][x] + t[q][x]));
                let gm = g(m);
                stack.push(([t[p], m, t[r]], [gs[p], gm, gs[r]]));
                stack.push(([m, t[q], t[r]], [gm, gs[q], gs[r]]));
            }
            Ok(sampled)
        })
        .try_reduce(|| 0.0, |x, y| Ok(x.max(y)))
}

/// Sweep along x: a pair of spheres that overlap by more than `tolerance`.
fn check_no_overlap(spheres: &[InnerSphere], tolerance: f64) -> Result<(), (usize, usize, f64)> {
    let mut order: Vec<usize> = (0..spheres.len()).collect();
    let left = |i: usize| spheres[i].center[0] as f64 - spheres[i].radius as f64;
    order.sort_by(|&a, &b| left(a).total_cmp(&left(b)));
    let max_radius = spheres.iter().map(|s| s.radius as f64).fold(0.0, f64::max);
    for (k, &a) in order.iter().enumerate() {
        let sa = spheres[a];
        let right = sa.center[0] as f64 + sa.radius as f64;
        for &b in &order[k + 1..] {
            if left(b) > right + max_radius {
                break;
            }
            let sb = spheres[b];
            let overlap =
                sa.radius as f64 + sb.radius as f64 - dist(widen(sa.center), widen(sb.center));
            if overlap > tolerance {
                return Err((a, b, overlap));
            }
        }
    }
    Ok(())
}

/// Every node encloses each child (node or sphere) within `tolerance`, and every sphere is a
/// child of exactly one node.
pub fn check_tree(
    nodes: &[IstNode],
    spheres: &[InnerSphere],
    tolerance: f64,
) -> Result<(), String> {
    let mut reached = vec![0u32; spheres.len()];
    let mut stack = vec![0usize];
    let mut visited = 0usize;
    while let Some(i) = stack.pop() {
        visited += 1;
        if visited > nodes.len() {
            return Err("the nodes do not form a tree".into());
        }
        let node = nodes.get(i).ok_or(format!("node {i} does not exist"))?;
        let range = node.first_child as usize..(node.first_child + node.child_count) as usize;
        let encloses = |c: [f32; 3], r: f32| {
            dist(widen(node.center), widen(c)) + r as f64 <= node.radius as f64 + tolerance
        };
        if node.children_are_spheres == 1 {
            let children = spheres
                .get(range.clone())
                .ok_or(format!("node {i}: sphere range {range:?} out of bounds"))?;
            for (j, s) in range.zip(children) {
                if !encloses(s.center, s.radius) {
                    return Err(format!("node {i} does not enclose sphere {j}"));
                }
                reached[j] += 1;
            }
        } else {
            let children = nodes
                .get(range.clone())
                .ok_or(format!("node {i}: child range {range:?} out of bounds"))?;
            for (j, n) in range.zip(children) {
                if j <= i {
                    return Err(format!("node {i} has child {j} before it"));
                }
                if !encloses(n.center, n.radius) {
                    return Err(format!("node {i} does not enclose node {j}"));
                }
                stack.push(j);
            }
        }
    }
    match reached.iter().position(|&n| n != 1) {
        Some(j) => Err(format!("sphere {j} is reached {} times", reached[j])),
        None => Ok(()),
    }
}
