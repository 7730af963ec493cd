//! Checks of a link's inner sphere tree against its collision meshes, in f64 with exact
//! point–triangle distances and winding numbers (`geometry`), independent of the f32 parry3d
//! queries the packing used:
//! - every sphere lies inside the link: inside one of its elements, i.e. its centre inside the
//!   element (winding number ≥ ½; for a solid the intake filled, its flood fill) and its radius
//!   at most the distance from the centre to that element's surface, plus `tolerance`;
//! - no two spheres overlap by more than `tolerance`, on links of one element (the elements of
//!   a link may overlap each other, and so may spheres packed into different elements);
//! - every node bounds each of its children, and every sphere is reached exactly once.
//!
//! Cost: O(spheres × triangles) for the first check; run by `build --validate` and the tests.

use rayon::prelude::*;

use super::{IstNode, LinkTree};
use crate::geometry::{dist, distance_point_mesh, widen, winding_number};
use crate::packing::InnerSphere;
use crate::robot::LinkGeometry;

/// A failed check, naming the sphere or node.
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
}

/// Runs every check on one link.
pub fn validate_link(
    tree: &LinkTree,
    geometry: &LinkGeometry,
    tolerance: f64,
) -> Result<(), ValidationError> {
    let link = &tree.link;
    check_tree(&tree.nodes, &tree.spheres, tolerance).map_err(|message| ValidationError::Tree {
        link: link.clone(),
        message,
    })?;
    let inside = |s: &InnerSphere| {
        let c = widen(s.center);
        let mut best_clearance = f64::NEG_INFINITY;
        for e in &geometry.elements {
            // A filled solid's inside is its flood fill's (its triangles face the outside
            // and need not be closed); a closed mesh's is the f64 winding number.
            let inside = match &e.mesh.fill {
                Some(fill) => fill.contains(s.center, false),
                None => winding_number(c, &e.mesh.vertices, &e.mesh.triangles) >= 0.5,
            };
            if inside {
                let clearance = distance_point_mesh(c, &e.mesh.vertices, &e.mesh.triangles);
                if s.radius as f64 <= clearance + tolerance {
                    return Ok(());
                }
                best_clearance = best_clearance.max(clearance);
            }
        }
        Err(best_clearance)
    };
    let failure = tree
        .spheres
        .par_iter()
        .enumerate()
        .find_first(|(_, s)| inside(s).is_err());
    if let Some((i, s)) = failure {
        let clearance = inside(s).err().unwrap_or(f64::NEG_INFINITY);
        return Err(if clearance == f64::NEG_INFINITY {
            ValidationError::Outside {
                link: link.clone(),
                sphere: i,
                center: s.center,
                radius: s.radius,
            }
        } else {
            ValidationError::Protrudes {
                link: link.clone(),
                sphere: i,
                radius: s.radius,
                clearance,
            }
        });
    }
    if geometry.elements.len() > 1 {
        return Ok(());
    }
    check_no_overlap(&tree.spheres, tolerance).map_err(|(a, b, overlap_m)| {
        ValidationError::Overlap {
            link: link.clone(),
            a,
            b,
            overlap_m,
        }
    })
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
