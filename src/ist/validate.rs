//! Checks of a link's inner sphere tree against its collision geometry, in f64 and
//! independent of the f32 parry3d queries the packing climbed with (`robot::exact`), and the
//! measure of its surface gap h. Every build runs them before its tree is used or cached
//! (`ist::build_link`). Input: the tree and the link's geometry (link frame, m); output: a
//! [`Validation`] (the certified h and where it is set) or the [`ValidationError`] that refuses
//! the tree. Refused, naming the link, the element's file and the sphere, are only trees that
//! are wrong:
//! - the tree: every node bounds each of its children, every sphere is reached exactly once;
//! - every sphere lies inside the link: its centre inside one of the link's elements (the ray
//!   winding number of a closed mesh; for a solid the intake filled, its flood fill) and its
//!   radius at most the distance from the centre to that element's surface, plus `tolerance`;
//! - no two spheres overlap by more than `tolerance`, on links of one element (the elements of
//!   a link may overlap each other, and so may spheres packed into different elements).
//!
//! **h is measured, not checked against the packing's claim**: a certified upper bound of the
//! distance to the spheres over the surface the packing measured (each element's triangles,
//! plus its tessellation error) and over every triangle of the **mesh files as read, before
//! any repair**, outside the link's solid (where the intake changed nothing, the two are the
//! same triangles, measured once). That value is the h the tree reports, so a sound tree is
//! never refused because the packing's f32 estimate was optimistic; a piece of the file that
//! the intake lost raises h (more spheres cannot reach it) and is reported ([`Uncovered`]).
//!
//! The branch and bound is that of `packing::gap` in f64: g, the distance to the spheres, is
//! 1-Lipschitz, so a triangle with longest edge L is bounded by its largest corner gap + L/√3,
//! and by the convex bound of one sphere (largest corner distance to it less its radius). A
//! sub-triangle is done when its bound is at most a floor (on the packed surface the claim, the
//! packing's estimate, plus `eps_m`: where the claim is sound the splits are those of the old
//! yes/no check; on a file's own triangles the packed surface's measured h, so the two slacks
//! do not add up), or within `eps_m` of the largest gap at any corner of the input outside the
//! solid or of what this triangle sampled itself. Never what other triangles found meanwhile,
//! so the value has the same bits on any thread count. A file's sub-triangle deeper inside the solid than L/√3 everywhere is excused. A
//! leaf (L/√3 ≤ `tolerance`) is bounded by its corners, adding L/√3: those outside the solid
//! by their gap, those inside by the packed surface's h (a point outside the solid within L/√3
//! of one inside it is that near the solid's boundary). That is exact for a closed mesh; for a
//! filled solid the boundary is the fill's, to its voxel: the ~1 µm approximation of leaves
//! whose corners are partly inside.
//!
//! Cost: a box-tree query per sphere and per triangle corner visited; about a second per link
//! of 8192 spheres and a few thousand triangles on 2 cores; more where the claim is exceeded
//! (those triangles refine to `eps_m`).

use rayon::prelude::*;

use super::link_tree::{IstNode, LinkTree, Uncovered};
use super::measure::{measure, Accuracy, SphereIndex};
use crate::geometry::{dist, widen, P3};
use crate::packing::InnerSphere;
use crate::robot::exact::ExactSolid;
use crate::robot::{LinkGeometry, TriangleFate};

/// A failed check, naming the link, the element's source (its mesh file or primitive) and the
/// sphere or node.
#[derive(Debug, thiserror::Error)]
pub enum ValidationError {
    #[error(
        "link {link}: sphere {sphere} ({center:?}, r={radius}) is outside every collision \
         element (nearest: {nearest})"
    )]
    Outside {
        link: String,
        sphere: usize,
        center: [f32; 3],
        radius: f32,
        nearest: String,
    },
    #[error(
        "link {link}, {source_}: sphere {sphere} has radius {radius} but only {clearance} m to \
         the surface"
    )]
    Protrudes {
        link: String,
        source_: String,
        sphere: usize,
        radius: f32,
        clearance: f64,
    },
    #[error("link {link}, {source_}: spheres {a} and {b} overlap by {overlap_m} m")]
    Overlap {
        link: String,
        source_: String,
        a: usize,
        b: usize,
        overlap_m: f64,
    },
    #[error("link {link}: tree: {message}")]
    Tree { link: String, message: String },
    #[error("link {link}, {surface}: the surface gap has no finite bound")]
    Unbounded { link: String, surface: String },
}

/// What a passed validation measured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Validation {
    /// The certified surface gap h, m: the larger of the two below, rounded up.
    pub gap_m: f64,
    /// Certified bound on the packed surface (elements' triangles + tessellation error), m.
    pub elements_gap_m: f64,
    /// Certified bound on the files' own triangles outside the solid, m (0 when no file needed
    /// its own pass).
    pub file_gap_m: f64,
    pub spheres: usize,
    /// Triangles over which h was measured: the elements' and the files' own.
    pub triangles: usize,
    /// Largest distance sampled from the files' own triangles to the spheres, m, outside the
    /// solid where above `elements_gap_m`: at most `gap_m`.
    pub file_gap_sampled_m: f64,
    /// Per mesh file, its farthest point outside the solid where that is farther than
    /// `elements_gap_m`; the farthest first.
    pub uncovered: Vec<Uncovered>,
    pub seconds: f64,
}

/// Runs every check on one link and measures its h (see the module doc): `eps_m` is the
/// accuracy of the value (at least 8 × `tolerance`).
pub fn validate_link(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    tolerance: f64,
    eps_m: f64,
) -> Result<Validation, ValidationError> {
    let start = std::time::Instant::now();
    let solids = check_spheres(tree, geometry, tolerance)?;
    let index = SphereIndex {
        nodes: &tree.nodes,
        spheres: &tree.spheres,
        slack: tolerance,
    };
    let accuracy = Accuracy {
        eps_m: eps_m.max(8.0 * tolerance),
        tolerance,
    };
    let (elements_gap_m, element_triangles) = measure_elements(tree, geometry, &index, accuracy)?;
    let files = measure_files(tree, geometry, &solids, &index, elements_gap_m, accuracy)?;
    Ok(Validation {
        // One ulp for the rounding of the sums above.
        gap_m: elements_gap_m.max(files.upper_m).next_up(),
        elements_gap_m,
        file_gap_m: files.upper_m,
        spheres: tree.spheres.len(),
        triangles: element_triangles + files.triangles,
        file_gap_sampled_m: files.sampled_m,
        uncovered: files.uncovered,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The checks that refuse a tree: its hierarchy, every sphere inside, no overlap. Returns the
/// elements' exact solids.
fn check_spheres(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    tolerance: f64,
) -> Result<Vec<ExactSolid>, ValidationError> {
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
    let source = |e: usize| geometry.elements.get(e).map_or("", |e| e.source.as_str());
    // The largest clearance of a sphere in any element whose solid holds its centre, and that
    // element.
    let clearance = |s: &InnerSphere| {
        solids
            .iter()
            .enumerate()
            .filter_map(|(e, solid)| {
                solid
                    .ball_clearance(widen(s.center), s.radius as f64)
                    .map(|c| (c, e))
            })
            .fold(None, |best: Option<(f64, usize)>, c| {
                Some(best.map_or(c, |b| if c.0 > b.0 { c } else { b }))
            })
    };
    let failure = tree
        .spheres
        .par_iter()
        .enumerate()
        .find_first(|(_, s)| clearance(s).is_none_or(|(c, _)| c < -tolerance));
    if let Some((i, s)) = failure {
        return Err(match clearance(s) {
            None => {
                let nearest = (0..solids.len())
                    .map(|e| (solids[e].surface.distance(widen(s.center)).0, e))
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map_or(String::new(), |(_, e)| source(e).to_owned());
                ValidationError::Outside {
                    link: link.clone(),
                    sphere: i,
                    center: s.center,
                    radius: s.radius,
                    nearest,
                }
            }
            Some((c, e)) => ValidationError::Protrudes {
                link: link.clone(),
                source_: source(e).to_owned(),
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
                source_: source(0).to_owned(),
                a,
                b,
                overlap_m,
            }
        })?;
    }
    Ok(solids)
}

/// h on the surface the packing measured: each element's triangles against the claim (less
/// the element's tessellation error, added back to its bound). Returns h and the triangles.
fn measure_elements(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    index: &SphereIndex,
    accuracy: Accuracy,
) -> Result<(f64, usize), ValidationError> {
    let mut gap_m = 0.0f64;
    let mut triangles = 0;
    for e in &geometry.elements {
        let corners: Vec<(usize, [P3; 3])> = e
            .mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| widen(e.mesh.vertices[i as usize])))
            .enumerate()
            .collect();
        triangles += corners.len();
        // The claim with its accuracy, as the old yes/no check had it: the same splits.
        let floor = tree.quality.gap_m - e.tessellation_error_m + accuracy.eps_m;
        let bound = measure(&corners, floor, accuracy, index, None);
        let upper = bound.upper_m + e.tessellation_error_m;
        if !upper.is_finite() {
            return Err(ValidationError::Unbounded {
                link: tree.link.clone(),
                surface: format!("collision element {} ({})", e.index, e.source),
            });
        }
        gap_m = gap_m.max(upper);
    }
    Ok((gap_m, triangles))
}

/// h on the mesh files' own triangles, outside the solid.
#[derive(Debug, Default)]
struct FileGaps {
    upper_m: f64,
    sampled_m: f64,
    triangles: usize,
    uncovered: Vec<Uncovered>,
}

/// h on every mesh file's own triangles (as read) outside the link's solid, for each file the
/// intake changed or that has several pieces (one taken as it was is its packed surface,
/// measured already), with the packed surface's h `elements_gap_m` as the floor.
fn measure_files(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    solids: &[ExactSolid],
    index: &SphereIndex,
    elements_gap_m: f64,
    accuracy: Accuracy,
) -> Result<FileGaps, ValidationError> {
    let mut out = FileGaps::default();
    for intake in geometry
        .intake
        .iter()
        .filter(|i| !i.report.clean() || i.report.pieces > 1)
    {
        // A triangle the intake kept as it was (its corners welded, each by at most the weld
        // tolerance; no crack sewn in the file) lies within that tolerance of its own
        // elements' surface (not a convex hull's): none of its points is deeper in them than
        // twice that.
        let as_kept = intake.report.cracks_sewn == 0 && geometry.hull_of_volume_m3.is_none();
        let kept_within = 2.0 * intake.report.weld_tolerance_m;
        let kept =
            |n: usize| as_kept && matches!(intake.fates.get(n), Some(TriangleFate::Kept { .. }));
        let own = |e: usize| {
            geometry
                .elements
                .get(e)
                .is_some_and(|e| e.index == intake.element)
        };
        // Whether a point of file triangle `n` lies inside the solid at least `d` deep: a
        // sub-triangle deeper than its reach is inside, where the solid's own surface is what
        // bounds the distance. The depth first, and not asked of a kept triangle's own
        // elements: the file's own points lie on the solid's surface or within rounding of it,
        // where the inside test's rays are ambiguous and it sums every triangle's solid angle
        // (issue 56: a 0.3 m cylinder of 6,000 slivers, CAD noise welded, validated in 537 s).
        let inside = |n: usize, p: P3, d: f64| -> bool {
            let shallow = d > kept_within && kept(n);
            solids.iter().enumerate().any(|(e, s)| {
                !(shallow && own(e)) && (d <= 0.0 || s.surface.at_least(p, d)) && s.contains(p)
            })
        };
        let (vertices, tris) = &*intake.original;
        // The index in the file is kept: the intake refused a file with an index out of range.
        let corners: Vec<(usize, [P3; 3])> = tris
            .iter()
            .enumerate()
            .filter(|(_, t)| t.iter().all(|&i| (i as usize) < vertices.len()))
            .map(|(n, t)| (n, t.map(|i| widen(vertices[i as usize]))))
            .collect();
        out.triangles += corners.len();
        let bound = measure(&corners, elements_gap_m, accuracy, index, Some(&inside));
        if !bound.upper_m.is_finite() {
            return Err(ValidationError::Unbounded {
                link: tree.link.clone(),
                surface: format!(
                    "collision element {}, mesh {} as read",
                    intake.element,
                    intake.file.display()
                ),
            });
        }
        out.upper_m = out.upper_m.max(bound.upper_m);
        out.sampled_m = out.sampled_m.max(bound.lower_m);
        if let Some((triangle, point)) = bound.worst.filter(|_| bound.lower_m > elements_gap_m) {
            let packed_surface_m = solids
                .iter()
                .map(|s| s.surface.distance(point).0)
                .fold(f64::INFINITY, f64::min);
            out.uncovered.push(Uncovered {
                element: intake.element,
                triangle,
                point,
                gap_m: bound.lower_m,
                packed_surface_m,
            });
        }
    }
    out.uncovered
        .sort_by(|a, b| b.gap_m.total_cmp(&a.gap_m).then(a.element.cmp(&b.element)));
    Ok(out)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ist::build::{build_tree, TreeBuilder};
    use crate::ist::link_tree::{LinkQuality, StageTimes};
    use crate::robot::mesh::{tessellate_box, ClosedMesh};
    use crate::robot::CollisionElement;

    /// A cube of side 2 around the origin, packed with `spheres`, claiming h = `claim_m`.
    fn cube(spheres: Vec<InnerSphere>, claim_m: f64) -> (LinkTree, LinkGeometry) {
        let t = tessellate_box([2.0, 2.0, 2.0]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "cube").expect("closed");
        let geometry = LinkGeometry {
            name: "cube".into(),
            elements: vec![CollisionElement {
                index: 0,
                source: "box 2 × 2 × 2".into(),
                mesh,
                tessellation_error_m: 0.0,
                sphere_center: None,
            }],
            intake: Vec::new(),
            hull_of_volume_m3: None,
        };
        let (nodes, spheres) = build_tree(spheres, TreeBuilder::MedianSplit);
        let tree = LinkTree {
            link: "cube".into(),
            quality: LinkQuality {
                spheres: spheres.len(),
                budget: spheres.len(),
                coverage: 0.0,
                gap_m: claim_m,
                gap_sampled_m: 0.0,
                mesh_volume_m3: 8.0,
                tree_volume_m3: 0.0,
                build_s: 0.0,
                validate_s: 0.0,
                stages: StageTimes::default(),
                elements_gap_m: claim_m,
                file_gap_m: 0.0,
                file_gap_sampled_m: 0.0,
                uncovered: None,
            },
            nodes,
            spheres,
        };
        (tree, geometry)
    }

    /// A claim below the true gap is not a refusal: the validation returns the certified value,
    /// √3 − 1 for the cube's inscribed ball; a claim above it does not raise the value either.
    #[test]
    fn the_gap_is_measured_not_checked() {
        let ball = InnerSphere {
            center: [0.0; 3],
            radius: 1.0,
        };
        let truth = 3f64.sqrt() - 1.0;
        let eps = 2e-5;
        for claim in [0.5, 0.9] {
            let (tree, geometry) = cube(vec![ball], claim);
            let v = validate_link(&tree, &geometry, 1e-6, eps)
                .unwrap_or_else(|e| panic!("claim {claim}: {e}"));
            assert!(
                v.gap_m >= truth && v.gap_m <= truth + eps + 1e-6,
                "claim {claim}: h {} for a true {truth}",
                v.gap_m
            );
            assert_eq!((v.file_gap_m, v.uncovered.len()), (0.0, 0));
        }
    }

    /// Two balls in the cube, claim 0: the gap (not at a corner, as with one ball) is refined
    /// to its value: at least every point sampled on the surface, and within the sampling's
    /// own error of the largest.
    #[test]
    fn a_refined_gap_bounds_every_sample() {
        let balls = [-0.5f32, 0.5].map(|x| InnerSphere {
            center: [x, 0.0, 0.0],
            radius: 0.45,
        });
        let (tree, geometry) = cube(balls.to_vec(), 0.0);
        let v = validate_link(&tree, &geometry, 1e-6, 2e-5).expect("a sound tree");
        let n = 200;
        let step = 2.0 / n as f64;
        let mut sampled = 0.0f64;
        for face in 0..6 {
            let (axis, side) = (face / 2, if face % 2 == 0 { -1.0 } else { 1.0 });
            for i in 0..=n {
                for j in 0..=n {
                    let mut p = [0.0f64; 3];
                    p[axis] = side;
                    p[(axis + 1) % 3] = -1.0 + i as f64 * step;
                    p[(axis + 2) % 3] = -1.0 + j as f64 * step;
                    let g = balls
                        .iter()
                        .map(|b| dist(p, widen(b.center)) - b.radius as f64)
                        .fold(f64::INFINITY, f64::min);
                    sampled = sampled.max(g);
                }
            }
        }
        // Every surface point lies within step/√2 of a sample (g is 1-Lipschitz).
        assert!(
            v.gap_m >= sampled && v.gap_m <= sampled + step / 2f64.sqrt() + 2e-5 + 1e-6,
            "h {} against a sampled {sampled}",
            v.gap_m
        );
    }
}
