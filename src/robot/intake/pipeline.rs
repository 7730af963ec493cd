//! The intake's steps in order (`super`'s module doc numbers them): a triangle soup in the link
//! frame, metres → the closed meshes the packing takes (one per outer shell, or one filled solid),
//! and its [`MeshReport`].

use super::enclosed::{apart, compact, drop_inner, filled};
use super::holes::close_holes;
use super::report::{MeshReport, TriangleFate};
use super::shells::{orient, EdgeUse};
use super::weld::{drop_repeated, weld, WELD_RELATIVE};
use crate::geometry::{mesh_volume, triangle_area, widen};
use crate::robot::mesh::{check_soup, extent, ClosedMesh, MeshError};
use crate::robot::solid::Solid;

/// The closed meshes (one per outer shell) of a triangle soup, what it took, and what became of
/// each of its triangles.
pub fn intake(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> Result<(Vec<ClosedMesh>, MeshReport, Vec<TriangleFate>), MeshError> {
    let mut report = MeshReport {
        triangles_in: triangles.len(),
        ..MeshReport::default()
    };
    check_soup(vertices, triangles)?;
    if let Some(bad) = triangles
        .iter()
        .flatten()
        .find(|&&i| i as usize >= vertices.len())
    {
        return Err(MeshError::Load(format!(
            "triangle index {bad} out of range"
        )));
    }
    let extent = extent(vertices);
    report.weld_tolerance_m = (extent * WELD_RELATIVE).max(f64::MIN_POSITIVE);
    // Welding keeps the triangles in the file's order; from here each carries its index there.
    let (welded, welded_tris) = weld(vertices, triangles, report.weld_tolerance_m, &mut report);
    let mut fates = vec![TriangleFate::Degenerate; triangles.len()];
    let min_area = (extent * extent * 1e-14).max(f64::MIN_POSITIVE);
    let (tris, origin): (Vec<[u32; 3]>, Vec<usize>) = welded_tris
        .into_iter()
        .enumerate()
        .filter(|(_, t)| {
            let keep = t[0] != t[1]
                && t[1] != t[2]
                && t[0] != t[2]
                && triangle_area(
                    widen(welded[t[0] as usize]),
                    widen(welded[t[1] as usize]),
                    widen(welded[t[2] as usize]),
                ) > min_area;
            report.degenerate_triangles += usize::from(!keep);
            keep
        })
        .map(|(i, t)| (t, i))
        .unzip();
    let repeated = drop_repeated(&tris, &mut report);
    let (tris, origin): (Vec<[u32; 3]>, Vec<usize>) = tris
        .into_iter()
        .zip(origin)
        .zip(repeated)
        .filter_map(|((t, o), fate)| match fate {
            Some(f) => {
                fates[o] = f;
                None
            }
            None => Some((t, o)),
        })
        .unzip();
    if tris.is_empty() {
        // Every face was degenerate or had its back face: a sheet, nothing inside.
        return Err(MeshError::ZeroVolume { volume_m3: 0.0 });
    }
    let meshes = take_shells(
        welded,
        &tris,
        &origin,
        extent,
        min_area,
        &mut report,
        &mut fates,
    )?;
    Ok((meshes, report, fates))
}

/// Steps 3 to 5 on the welded triangles (`origin`: each one's index in the file): the shells,
/// closed, oriented, nested or filled; `fates` is set for every triangle given.
fn take_shells(
    welded: Vec<[f32; 3]>,
    tris: &[[u32; 3]],
    origin: &[usize],
    extent: f64,
    min_area: f64,
    report: &mut MeshReport,
    fates: &mut [TriangleFate],
) -> Result<Vec<ClosedMesh>, MeshError> {
    let edges = EdgeUse::count(tris);
    report.open_edges = edges.uses.values().filter(|u| u.len() == 1).count();
    report.non_manifold_edges = edges.uses.values().filter(|u| u.len() > 2).count();
    let mut shells = Vec::new();
    // Triangles of shells the repairs could not close: the flood fill takes them as they are.
    let mut loose: Vec<[u32; 3]> = Vec::new();
    let mut loose_fates: Vec<(usize, u32)> = Vec::new();
    let mut all_vertices = welded;
    for (number, shell) in edges.shells(tris.len()).into_iter().enumerate() {
        let number = number as u32;
        let origins: Vec<usize> = shell.iter().map(|&t| origin[t]).collect();
        let mut shell_tris: Vec<[u32; 3]> = shell.iter().map(|&t| tris[t]).collect();
        let closed = orient(&mut shell_tris).and_then(|turned| {
            report.shells_reoriented += usize::from(turned);
            close_holes(&mut all_vertices, &mut shell_tris, report, min_area)
        });
        if closed.is_err() {
            report.open_shells += 1;
            loose.extend(shell.iter().map(|&t| tris[t]));
            loose_fates.extend(origins.iter().map(|&o| (o, number)));
            continue;
        }
        let (verts, mut shell_tris) = compact(&all_vertices, &shell_tris);
        let volume = mesh_volume(&verts, &shell_tris);
        if volume.abs() <= extent.powi(3) * 1e-9 {
            report.empty_shells += 1;
            for &o in &origins {
                fates[o] = TriangleFate::EmptyShell { shell: number };
            }
            continue;
        }
        if volume < 0.0 {
            report.shells_reoriented += 1;
            for t in &mut shell_tris {
                t.swap(1, 2);
            }
        }
        // The strict constructor and parry3d's oriented mesh (the packing's inside test) must
        // both take the shell; one they refuse goes to the fill instead.
        match ClosedMesh::new(verts, shell_tris.clone(), "")
            .and_then(|m| Solid::try_new(&m).map(|s| (m, s)))
        {
            Ok((mesh, solid)) => shells.push((mesh, solid, (number, origins))),
            Err(_) => {
                report.open_shells += 1;
                loose.extend(shell.iter().map(|&t| tris[t]));
                loose_fates.extend(origins.iter().map(|&o| (o, number)));
            }
        }
    }
    report.shells = shells.len() + report.empty_shells + report.open_shells;
    if shells.is_empty() && loose.is_empty() {
        return Err(MeshError::ZeroVolume { volume_m3: 0.0 });
    }
    let (shells, inner) = drop_inner(shells, report);
    for (shell, origins) in inner {
        for o in origins {
            fates[o] = TriangleFate::InnerShell { shell };
        }
    }
    let mut meshes = Vec::with_capacity(shells.len());
    let mut solids = Vec::with_capacity(shells.len());
    let mut tags: Vec<(u32, Vec<usize>)> = Vec::with_capacity(shells.len());
    for (mesh, solid, tag) in shells {
        meshes.push(mesh);
        solids.push(solid);
        tags.push(tag);
    }
    // One closed shell, or closed shells apart from each other: each a solid as it is (a slot
    // between two of them is outside, however narrow).
    if loose.is_empty() && (meshes.len() == 1 || apart(&meshes, &solids)) {
        for (shell, origins) in tags {
            for o in origins {
                fates[o] = TriangleFate::Kept { shell };
            }
        }
        return Ok(meshes);
    }
    let (mesh, facing) = filled(&meshes, loose, &all_vertices, report)?;
    // `facing` runs over the loose triangles, then each shell's, whose first triangles are
    // the shell's own in order (a crack's split keeps its place; fans and the split's other
    // pieces are appended).
    for (&(o, shell), &f) in loose_fates.iter().zip(&facing) {
        fates[o] = TriangleFate::Filled {
            shell,
            open: true,
            facing: f,
        };
    }
    let mut at = loose_fates.len();
    for (m, (shell, origins)) in meshes.iter().zip(&tags) {
        for (&o, &f) in origins.iter().zip(facing.get(at..).unwrap_or_default()) {
            fates[o] = TriangleFate::Filled {
                shell: *shell,
                open: false,
                facing: f,
            };
        }
        at += m.triangles.len();
    }
    Ok(vec![mesh])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box whose triangle [1, 2, 3] is split at a point `m` of its edge 1–2 while its
    /// neighbour [0, 2, 1] is not: exactly on the edge a T-junction, off it a small hole.
    fn split_box(off: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let b = crate::robot::mesh::tessellate_box([0.1, 0.1, 0.1]);
        let mut vertices = b.vertices;
        let (v1, v2, v0) = (vertices[1], vertices[2], vertices[0]);
        vertices.push(std::array::from_fn(|k| {
            0.5 * (v1[k] + v2[k]) + off * (v0[k] - 0.5 * (v1[k] + v2[k]))
        }));
        let mut triangles = b.triangles;
        let i = triangles.iter().position(|t| *t == [1, 2, 3]).unwrap();
        triangles[i] = [1, 8, 3];
        triangles.push([8, 2, 3]);
        (vertices, triangles)
    }

    #[test]
    fn a_t_junction_is_sewn_and_a_small_hole_fanned_both_closed() {
        let (v, t) = split_box(0.0);
        let (meshes, report, fates) = intake(&v, &t).unwrap();
        assert_eq!(fates, vec![TriangleFate::Kept { shell: 0 }; t.len()]);
        assert_eq!((report.open_edges, report.cracks_sewn), (3, 1));
        assert_eq!((report.holes_closed, report.open_shells), (0, 0));
        assert_eq!(meshes.len(), 1);
        assert!(meshes[0].fill.is_none(), "one closed shell, not the fill");
        assert!((meshes[0].volume_m3 - 1e-3).abs() < 1e-9);
        // Off the edge by 1 % of the way to vertex 0: a hole of area, not a crack.
        let (v, t) = split_box(0.01);
        let (meshes, report, _) = intake(&v, &t).unwrap();
        assert_eq!((report.cracks_sewn, report.holes_closed), (0, 1));
        assert_eq!((report.open_shells, meshes.len()), (0, 1));
        assert!(meshes[0].fill.is_none());
        assert!((meshes[0].volume_m3 - 1e-3).abs() < 1e-9);
    }

    /// Each triangle's fate, by its index in the file: a box kept, a degenerate triangle, a
    /// copy, a wall in both orientations, a box nested in the first; the same on every run.
    #[test]
    fn every_triangle_has_its_fate() {
        let b = crate::robot::mesh::tessellate_box([0.1, 0.1, 0.1]);
        let mut v = b.vertices.clone();
        let mut t = b.triangles.clone();
        let n = t.len() as u32;
        t.push([0, 0, 1]);
        t.push(b.triangles[0]);
        let inner = crate::robot::mesh::tessellate_box([0.02, 0.02, 0.02]);
        let base = v.len() as u32;
        v.extend_from_slice(&inner.vertices);
        t.extend(inner.triangles.iter().map(|x| x.map(|i| i + base)));
        let wall = v.len() as u32;
        v.extend_from_slice(&[[0.2, 0.0, 0.0], [0.3, 0.0, 0.0], [0.2, 0.1, 0.0]]);
        t.push([wall, wall + 1, wall + 2]);
        t.push([wall, wall + 2, wall + 1]);
        let (meshes, report, fates) = intake(&v, &t).unwrap();
        assert_eq!(meshes.len(), 1, "{report:?}");
        let mut expected = vec![TriangleFate::Kept { shell: 0 }; b.triangles.len()];
        expected.push(TriangleFate::Degenerate);
        expected.push(TriangleFate::Repeated);
        expected.extend(vec![
            TriangleFate::InnerShell { shell: 1 };
            inner.triangles.len()
        ]);
        expected.extend([TriangleFate::InternalWall; 2]);
        assert_eq!(fates, expected, "{report:?}");
        assert_eq!(
            fates[n as usize].describe(),
            "dropped by the intake as degenerate"
        );
        for _ in 0..6 {
            assert_eq!(intake(&v, &t).unwrap().2, fates);
        }
    }
}
