//! Intake step 5 (`super`'s module doc): the solid is everything the outside cannot reach. Shells
//! wholly inside another are dropped; closed shells that lie apart (`apart`) are each a solid of
//! their own; shells that meet, or shells the repairs could not close, become one solid decided
//! by the exterior flood fill (`robot::fill`), its surface the triangles that face the outside.
//! Link frame, metres.

use std::collections::HashMap;

use super::report::MeshReport;
use crate::robot::fill::Fill;
use crate::robot::mesh::{ClosedMesh, MeshError};
use crate::robot::solid::Solid;
use crate::robot::surface::ExactSurface;

/// The vertices a shell uses, renumbered.
pub(super) fn compact(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut map = HashMap::new();
    let mut out = Vec::new();
    let triangles = triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                *map.entry(i).or_insert_with(|| {
                    out.push(vertices[i as usize]);
                    (out.len() - 1) as u32
                })
            })
        })
        .collect();
    (out, triangles)
}

/// The solid of several closed shells together: everything the outside cannot reach
/// (`robot::fill`), with the triangles that face the outside as its surface; and whether each
/// triangle given (`loose`, then each shell's) faces the outside.
pub(super) fn filled(
    shells: &[ClosedMesh],
    loose: Vec<[u32; 3]>,
    loose_vertices: &[[f32; 3]],
    report: &mut MeshReport,
) -> Result<(ClosedMesh, Vec<bool>), MeshError> {
    let mut vertices = loose_vertices.to_vec();
    let mut triangles = loose;
    for s in shells {
        let base = vertices.len() as u32;
        vertices.extend_from_slice(&s.vertices);
        triangles.extend(s.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let closed = shells
        .iter()
        .map(|s| ExactSurface::new(&s.vertices, &s.triangles))
        .collect();
    let (fill, facing) = Fill::new(&vertices, &triangles, closed)
        .ok_or_else(|| MeshError::Load("parry3d refuses the mesh's triangles".into()))?;
    if fill.encloses_nothing() {
        return Err(MeshError::EnclosesNothing {
            open_shells: report.open_shells,
        });
    }
    let kept: Vec<[u32; 3]> = triangles
        .iter()
        .zip(&facing)
        .filter_map(|(t, f)| f.then_some(*t))
        .collect();
    report.fill_voxel_m = Some(fill.voxel_m);
    report.inner_triangles = triangles.len() - kept.len();
    let (vertices, kept) = compact(&vertices, &kept);
    let mesh = ClosedMesh {
        vertices,
        triangles: kept,
        volume_m3: fill.volume_m3(),
        fill: Some(std::sync::Arc::new(fill)),
    };
    // The packing's solid takes it: checked here, never panicked on later.
    Solid::try_new(&mesh)?;
    Ok((mesh, facing))
}

/// Whether the closed, outward-oriented `shells` (none inside another: `drop_inner` ran) lie
/// apart: no triangle of one meets another's surface (parry3d's intersection test, for the
/// pairs whose boxes meet) and none holds a vertex of another. Closed surfaces that do not meet
/// bound insides that are nested or disjoint, and a held vertex would be the nesting: so their
/// insides are disjoint, and each shell is a solid of its own, with its exact inside test; the
/// space between two of them, however narrow, stays outside (issue 56: a body and a boss 1 mm
/// apart, a slot the fill's voxel cannot enter).
pub(super) fn apart(shells: &[ClosedMesh], solids: &[Solid]) -> bool {
    let boxes: Vec<([f32; 3], [f32; 3])> = shells.iter().map(ClosedMesh::bounds).collect();
    let meet = |i: usize, j: usize| {
        let ((alo, ahi), (blo, bhi)) = (boxes[i], boxes[j]);
        if (0..3).any(|k| ahi[k] < blo[k] || bhi[k] < alo[k]) {
            return false;
        }
        let (a, b) = (&shells[i], &shells[j]);
        let held =
            |s: &Solid, v: &[[f32; 3]]| v.first().is_some_and(|&p| s.signed_distance(p).0 >= 0.0);
        held(&solids[i], &b.vertices)
            || held(&solids[j], &a.vertices)
            || (b.triangles.iter())
                .any(|t| solids[i].meets_triangle(t.map(|v| b.vertices[v as usize])))
    };
    (0..shells.len()).all(|i| (i + 1..shells.len()).all(|j| !meet(i, j)))
}

/// Drops the shells that lie wholly inside another shell (see the module doc for the test):
/// the shells kept, each with its solid and `tag`, and the tags of those dropped.
pub(super) fn drop_inner<T>(
    mut shells: Vec<(ClosedMesh, Solid, T)>,
    report: &mut MeshReport,
) -> (Vec<(ClosedMesh, Solid, T)>, Vec<T>) {
    // Largest first: an inner shell is enclosed by a larger one.
    shells.sort_by(|a, b| b.0.volume_m3.total_cmp(&a.0.volume_m3));
    let mut kept: Vec<(ClosedMesh, Solid, T)> = Vec::new();
    let mut dropped = Vec::new();
    for (shell, solid, tag) in shells {
        let (lo, hi) = shell.bounds();
        let inside = kept.iter().any(|(outer, outer_solid, _)| {
            let (olo, ohi) = outer.bounds();
            (0..3).all(|k| olo[k] <= lo[k] && hi[k] <= ohi[k])
                && shell
                    .vertices
                    .iter()
                    .all(|&v| outer_solid.signed_distance(v).0 > 0.0)
                && shell
                    .triangles
                    .iter()
                    .all(|t| !outer_solid.meets_triangle(t.map(|i| shell.vertices[i as usize])))
        });
        if inside {
            report.inner_shells += 1;
            dropped.push(tag);
        } else {
            kept.push((shell, solid, tag));
        }
    }
    (kept, dropped)
}
