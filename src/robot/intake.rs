//! Mesh intake: collision meshes as vendors ship them (STL with CAD noise, COLLADA with a few
//! open edges, visual meshes used as collision meshes: hollow shells with thin walls) made into
//! the closed, outward-oriented meshes the packing needs, each change counted in a
//! [`MeshReport`]. Input and output in the link frame, metres.
//!
//! The steps, in order:
//! 1. **Weld** vertices closer than `WELD_RELATIVE` × the mesh's extent (reported as
//!    `weld_tolerance_m`): CAD exports write one vertex as −1.5e-17 and −5.1e-18, which bit-exact
//!    welding takes for two, leaving false open edges. The tolerance is far below any feature
//!    a collision mesh has (0.2 µm on a 20 cm link).
//! 2. **Degenerate triangles** (a repeated vertex after welding, or area ≤ 1e-14 × extent²)
//!    enclose nothing and are dropped. **Repeated triangles**: one of each orientation is kept;
//!    a face present in both orientations is an internal wall between two glued solids and is
//!    dropped.
//! 3. **Shells**: triangles connected through edges shared by exactly two triangles (an edge of
//!    three or more, non-manifold, connects nothing, so two solids touching along an edge come
//!    apart); each shell is oriented consistently by a walk over its edges.
//! 4. **Holes**: the open edges of a shell are chained into loops. A loop of no area (a
//!    T-junction: one long edge against a chain of collinear short ones) is a crack, sewn by
//!    splitting the triangle of the long edge at the chain's vertices; any other loop is closed
//!    by a fan of triangles around its centroid (any surface spanning a hole closes it; the
//!    report gives the largest loop's diameter). A rim that passes a vertex twice (holes
//!    touching at a corner) is split there into simple loops first. The edges are taken in
//!    sorted order, never a hash map's, so the same file gives the same mesh on every run.
//! 5. **The solid is everything the outside cannot reach.** Each closed shell is made
//!    outward-oriented (positive volume). A shell that lies wholly inside another (a hollow
//!    part's inner wall) adds nothing and is dropped: its vertices lie inside the outer shell
//!    and none of its triangles meets the outer surface (parry3d's intersection test), so it
//!    cannot cross it anywhere. One closed shell left is the element as it is: its inside test
//!    is the exact one of a closed oriented mesh (pseudo-normals in the packing, the f64
//!    winding number in `ist::validate`). Several shells, or shells the repairs could not make
//!    closed, manifold and oriented, are one solid decided by an exterior flood fill
//!    (`robot::fill`): overlapping parts are their union, and the space they enclose together
//!    (a thin wall closed at its ends by other parts) is filled, with the triangles inside the
//!    solid dropped so that spheres grow across them. A wall thinner than the fill's voxel is
//!    still solid: the closed shells go with the fill, and a point inside one of them is inside
//!    (its own winding number), so a vendor's 1 mm housing open at its tube ends gets spheres.
//!
//! The guarantee stays: no inner sphere outside the solid, and h certified against the surface
//! that faces the outside. Refused, with the reason: a mesh whose surface, after all this,
//! separates no inside from the outside (a lone sheet, a Möbius strip).

use std::collections::HashMap;

use super::fill::Fill;
use super::mesh::{check_soup, extent, ClosedMesh, MeshError};
use super::solid::Solid;
use super::surface::ExactSurface;
use crate::geometry::{dist, dot, mesh_volume, sub, triangle_area, widen};

/// Welding tolerance relative to the mesh's largest extent.
pub const WELD_RELATIVE: f64 = 1e-6;

/// What the intake did to one mesh file.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MeshReport {
    /// Pieces the file holds (COLLADA geometry instances, STL solids, OBJ groups), all read.
    pub pieces: usize,
    /// What the reader noted (geometries the scene leaves out, a unit applied, ...).
    pub notes: Vec<String>,
    pub triangles_in: usize,
    /// Vertices closer than this were merged, m.
    pub weld_tolerance_m: f64,
    /// Vertices merged with another that was not bit-identical (CAD noise).
    pub welded_vertices: usize,
    pub degenerate_triangles: usize,
    pub repeated_triangles: usize,
    /// Edges used by one triangle, before the holes were closed.
    pub open_edges: usize,
    /// Edges used by three or more triangles.
    pub non_manifold_edges: usize,
    pub holes_closed: usize,
    /// Holes of no area (T-junctions) sewn by splitting the triangle across them.
    pub cracks_sewn: usize,
    /// Diameter of the largest hole closed, m.
    pub largest_hole_m: f64,
    pub shells: usize,
    /// Shells whose triangles were turned to agree with their neighbours, or turned outward.
    pub shells_reoriented: usize,
    /// Shells wholly inside another (a hollow part's inner walls): the solid fills them.
    pub inner_shells: usize,
    /// Shells enclosing no volume, dropped.
    pub empty_shells: usize,
    /// Shells still not closed and manifold after the repairs: their triangles go to the fill.
    pub open_shells: usize,
    /// The voxel of the exterior flood fill, m, when the shells were filled as one solid
    /// (gaps narrower than it are taken as closed).
    pub fill_voxel_m: Option<f64>,
    /// Triangles inside the filled solid (not facing the outside), dropped.
    pub inner_triangles: usize,
}

impl MeshReport {
    /// Whether the mesh was taken as it is (one closed shell, nothing welded but identical
    /// vertices, nothing dropped, closed or turned).
    pub fn clean(&self) -> bool {
        self.welded_vertices == 0
            && self.degenerate_triangles == 0
            && self.repeated_triangles == 0
            && self.open_edges == 0
            && self.non_manifold_edges == 0
            && self.shells <= 1
            && self.shells_reoriented == 0
            && self.empty_shells == 0
            && self.cracks_sewn == 0
            && self.open_shells == 0
    }

    /// One line: what the mesh needed.
    pub fn summary(&self) -> String {
        let mut line = self.repairs();
        if self.pieces > 1 {
            line = format!("{} pieces, {line}", self.pieces);
        }
        for n in &self.notes {
            line.push_str("; ");
            line.push_str(n);
        }
        line
    }

    fn repairs(&self) -> String {
        if self.clean() {
            return format!(
                "closed, {} triangles (weld tolerance {:.1e} m)",
                self.triangles_in, self.weld_tolerance_m
            );
        }
        let mut parts = vec![format!(
            "{} triangles, weld tolerance {:.1e} m",
            self.triangles_in, self.weld_tolerance_m
        )];
        let mut say = |n: usize, what: &str| {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        };
        say(self.welded_vertices, "near-identical vertices welded");
        say(self.degenerate_triangles, "degenerate triangles dropped");
        say(self.repeated_triangles, "repeated triangles dropped");
        say(self.open_edges, "open edges");
        say(self.non_manifold_edges, "non-manifold edges");
        say(self.shells_reoriented, "shells reoriented");
        say(self.inner_shells, "inner shells filled (hollow part)");
        say(self.empty_shells, "empty shells dropped");
        say(self.cracks_sewn, "T-junction cracks sewn");
        say(
            self.open_shells,
            "shells not closed by the repairs (taken by the flood fill)",
        );
        if let Some(v) = self.fill_voxel_m {
            parts.push(format!(
                "filled by an exterior flood fill ({:.2} mm voxels; {} inner triangles dropped)",
                v * 1e3,
                self.inner_triangles
            ));
        }
        if self.holes_closed > 0 {
            parts.push(format!(
                "{} holes closed (largest {:.2} mm)",
                self.holes_closed,
                self.largest_hole_m * 1e3
            ));
        }
        parts.push(format!("{} shells", self.shells));
        parts.join(", ")
    }
}

/// The closed meshes (one per outer shell) of a triangle soup, and what it took.
pub fn intake(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> Result<(Vec<ClosedMesh>, MeshReport), MeshError> {
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
    let (welded, mut tris) = weld(vertices, triangles, report.weld_tolerance_m, &mut report);
    let min_area = (extent * extent * 1e-14).max(f64::MIN_POSITIVE);
    tris.retain(|t| {
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
    });
    let tris = drop_repeated(tris, &mut report);
    if tris.is_empty() {
        // Every face was degenerate or had its back face: a sheet, nothing inside.
        return Err(MeshError::ZeroVolume { volume_m3: 0.0 });
    }
    let edges = EdgeUse::count(&tris);
    report.open_edges = edges.uses.values().filter(|u| u.len() == 1).count();
    report.non_manifold_edges = edges.uses.values().filter(|u| u.len() > 2).count();
    let mut shells = Vec::new();
    // Triangles of shells the repairs could not close: the flood fill takes them as they are.
    let mut loose: Vec<[u32; 3]> = Vec::new();
    let mut all_vertices = welded;
    for shell in edges.shells(tris.len()) {
        let mut shell_tris: Vec<[u32; 3]> = shell.iter().map(|&t| tris[t]).collect();
        let closed = orient(&mut shell_tris).and_then(|turned| {
            report.shells_reoriented += usize::from(turned);
            close_holes(&mut all_vertices, &mut shell_tris, &mut report, min_area)
        });
        if closed.is_err() {
            report.open_shells += 1;
            loose.extend(shell.iter().map(|&t| tris[t]));
            continue;
        }
        let (verts, mut shell_tris) = compact(&all_vertices, &shell_tris);
        let volume = mesh_volume(&verts, &shell_tris);
        if volume.abs() <= extent.powi(3) * 1e-9 {
            report.empty_shells += 1;
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
            Ok(shell) => shells.push(shell),
            Err(_) => {
                report.open_shells += 1;
                loose.extend(shell.iter().map(|&t| tris[t]));
            }
        }
    }
    report.shells = shells.len() + report.empty_shells + report.open_shells;
    if shells.is_empty() && loose.is_empty() {
        return Err(MeshError::ZeroVolume { volume_m3: 0.0 });
    }
    let shells = drop_inner(shells, &mut report);
    if shells.len() == 1 && loose.is_empty() {
        return Ok((shells, report));
    }
    Ok((
        vec![filled(&shells, loose, &all_vertices, &mut report)?],
        report,
    ))
}

/// Merges vertices within `tolerance` (the first of a cluster stands for it), through a hash
/// of cells of the tolerance's size (a vertex is compared with the 27 cells around it).
fn weld(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
    tolerance: f64,
    report: &mut MeshReport,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let cell = |v: [f32; 3]| v.map(|x| (x as f64 / tolerance).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::with_capacity(vertices.len());
    let mut welded: Vec<[f32; 3]> = Vec::with_capacity(vertices.len());
    let mut map = vec![u32::MAX; vertices.len()];
    let mut used = vec![false; vertices.len()];
    for t in triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    for (i, v) in vertices.iter().enumerate() {
        if !used[i] {
            continue;
        }
        let c = cell(*v);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &w in list {
                            let u = welded[w as usize];
                            let d2: f64 = (0..3).map(|k| (u[k] as f64 - v[k] as f64).powi(2)).sum();
                            if d2 <= tolerance * tolerance {
                                if u.map(|x| (x + 0.0).to_bits()) != v.map(|x| (x + 0.0).to_bits())
                                {
                                    report.welded_vertices += 1;
                                }
                                found = Some(w);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        map[i] = found.unwrap_or_else(|| {
            welded.push(*v);
            let w = (welded.len() - 1) as u32;
            grid.entry(c).or_default().push(w);
            w
        });
    }
    let triangles = triangles
        .iter()
        .map(|t| t.map(|i| map[i as usize]))
        .collect();
    (welded, triangles)
}

/// Keeps one triangle of each orientation per vertex set, none where both orientations occur.
fn drop_repeated(triangles: Vec<[u32; 3]>, report: &mut MeshReport) -> Vec<[u32; 3]> {
    // Key: the sorted vertices; value: (a representative per orientation, count).
    let mut seen: HashMap<[u32; 3], [(usize, usize); 2]> = HashMap::with_capacity(triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        let mut key = *t;
        key.sort_unstable();
        // Even permutations of the sorted order keep the orientation.
        let rotated = [
            [key[0], key[1], key[2]],
            [key[1], key[2], key[0]],
            [key[2], key[0], key[1]],
        ];
        let orientation = usize::from(!rotated.contains(t));
        let e = seen.entry(key).or_insert([(usize::MAX, 0); 2]);
        if e[orientation].1 == 0 {
            e[orientation].0 = i;
        }
        e[orientation].1 += 1;
    }
    let mut keep = vec![false; triangles.len()];
    for v in seen.values() {
        match (v[0].1, v[1].1) {
            (a, b) if a > 0 && b > 0 => report.repeated_triangles += a + b,
            (a, b) => {
                let (i, n) = if a > 0 { (v[0].0, a) } else { (v[1].0, b) };
                keep[i] = true;
                report.repeated_triangles += n - 1;
            }
        }
    }
    triangles
        .into_iter()
        .zip(keep)
        .filter_map(|(t, k)| k.then_some(t))
        .collect()
}

/// The triangles using each undirected edge.
struct EdgeUse {
    uses: HashMap<(u32, u32), Vec<u32>>,
}

impl EdgeUse {
    fn count(triangles: &[[u32; 3]]) -> Self {
        let mut uses: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(triangles.len() * 2);
        for (i, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                uses.entry((a.min(b), a.max(b))).or_default().push(i as u32);
            }
        }
        Self { uses }
    }

    /// Triangles connected through edges of exactly two triangles (union-find).
    fn shells(&self, n: usize) -> Vec<Vec<usize>> {
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for u in self.uses.values().filter(|u| u.len() == 2) {
            let (a, b) = (
                root(&mut parent, u[0] as usize),
                root(&mut parent, u[1] as usize),
            );
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
        let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
        for i in 0..n {
            let r = root(&mut parent, i);
            groups.entry(r).or_default().push(i);
        }
        let mut shells: Vec<Vec<usize>> = groups.into_values().collect();
        shells.sort_unstable_by_key(|s| s[0]);
        shells
    }
}

/// Orients a shell's triangles consistently (a walk from its first triangle over edges of two
/// triangles); true when any triangle was turned. Refused when the shell cannot be oriented.
fn orient(triangles: &mut [[u32; 3]]) -> Result<bool, MeshError> {
    let edges = EdgeUse::count(triangles);
    let mut done = vec![false; triangles.len()];
    let mut turned = false;
    for start in 0..triangles.len() {
        if done[start] {
            continue;
        }
        done[start] = true;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            let t = triangles[i];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let Some(u) = edges.uses.get(&(a.min(b), a.max(b))) else {
                    continue;
                };
                if u.len() != 2 {
                    continue;
                }
                let j = if u[0] as usize == i { u[1] } else { u[0] } as usize;
                // Consistent: the neighbour runs the edge b → a.
                let runs_ab =
                    (0..3).any(|m| triangles[j][m] == a && triangles[j][(m + 1) % 3] == b);
                if done[j] {
                    if runs_ab {
                        return Err(MeshError::Unorientable);
                    }
                    continue;
                }
                if runs_ab {
                    triangles[j].swap(1, 2);
                    turned = true;
                }
                done[j] = true;
                stack.push(j);
            }
        }
    }
    Ok(turned)
}

/// Closes the holes of an oriented shell: its open edges chained into loops, each loop closed
/// by a fan around its centroid (a new vertex).
fn close_holes(
    vertices: &mut Vec<[f32; 3]>,
    triangles: &mut Vec<[u32; 3]>,
    report: &mut MeshReport,
    min_area: f64,
) -> Result<(), MeshError> {
    let edges = EdgeUse::count(triangles);
    // A hole runs its open edges backwards: b → a for a triangle's a → b.
    // In edge order, not the hash map's (which differs from run to run): where a rim passes a
    // vertex twice, the order decides which loops are closed.
    let mut open_edges: Vec<((u32, u32), u32)> = edges
        .uses
        .iter()
        .filter(|(_, u)| u.len() == 1)
        .map(|(&e, u)| (e, u[0]))
        .collect();
    open_edges.sort_unstable();
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut open = 0;
    for ((lo, hi), t) in open_edges {
        let t = triangles[t as usize];
        let a_to_b = (0..3).any(|m| t[m] == lo && t[(m + 1) % 3] == hi);
        let (from, to) = if a_to_b { (hi, lo) } else { (lo, hi) };
        next.entry(from).or_default().push(to);
        open += 1;
    }
    if open == 0 {
        return Ok(());
    }
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    for start in starts {
        while let Some(first) = next.get_mut(&start).and_then(Vec::pop) {
            let mut lp = vec![start, first];
            let mut at = first;
            while at != start {
                let Some(n) = next.get_mut(&at).and_then(Vec::pop) else {
                    return Err(MeshError::OpenChain { open_edges: open });
                };
                lp.push(n);
                at = n;
            }
            lp.pop(); // the start again
                      // A rim that passes a vertex twice (two holes touching at a corner) is split there
                      // into simple loops, each closed on its own: one fan over a figure eight would
                      // leave an edge of three triangles.
            for lp in simple_loops(&lp) {
                if lp.len() < 3 {
                    continue;
                }
                if crack(vertices, triangles, &edges, &lp, min_area) {
                    report.cracks_sewn += 1;
                    continue;
                }
                let mut c = [0.0f64; 3];
                for &v in &lp {
                    for k in 0..3 {
                        c[k] += vertices[v as usize][k] as f64 / lp.len() as f64;
                    }
                }
                let centre = c.map(|x| x as f32);
                let diameter = lp
                    .iter()
                    .map(|&v| {
                        let p = vertices[v as usize];
                        2.0 * (0..3)
                            .map(|k| (p[k] as f64 - c[k]).powi(2))
                            .sum::<f64>()
                            .sqrt()
                    })
                    .fold(0.0, f64::max);
                report.largest_hole_m = report.largest_hole_m.max(diameter);
                report.holes_closed += 1;
                let ci = vertices.len() as u32;
                vertices.push(centre);
                for k in 0..lp.len() {
                    triangles.push([lp[k], lp[(k + 1) % lp.len()], ci]);
                }
            }
        }
    }
    Ok(())
}

/// A closed walk split at its repeated vertices into simple loops (in walk order).
fn simple_loops(walk: &[u32]) -> Vec<Vec<u32>> {
    let mut loops = Vec::new();
    let mut path: Vec<u32> = Vec::with_capacity(walk.len());
    let mut at: HashMap<u32, usize> = HashMap::new();
    for &v in walk.iter().chain(walk.first()) {
        if let Some(&i) = at.get(&v) {
            for u in &path[i + 1..] {
                at.remove(u);
            }
            loops.push(path.split_off(i));
        }
        at.insert(v, path.len());
        path.push(v);
    }
    loops
}

/// A hole of no area (a T-junction: one long edge on one side, a chain of collinear shorter
/// edges on the other) is a crack, not an opening: the triangle of the long edge is split at
/// the chain's vertices, which sews it. True when `lp` was such a crack and is sewn.
fn crack(
    vertices: &[[f32; 3]],
    triangles: &mut Vec<[u32; 3]>,
    edges: &EdgeUse,
    lp: &[u32],
    min_area: f64,
) -> bool {
    let n = lp.len();
    let v = |i: u32| widen(vertices[i as usize]);
    let length = |k: usize| dist(v(lp[k]), v(lp[(k + 1) % n]));
    // The longest loop edge, u → w: the triangle on its other side runs w → u.
    let Some(long) = (0..n).max_by(|&a, &b| length(a).total_cmp(&length(b))) else {
        return false;
    };
    let (u, w) = (lp[long], lp[(long + 1) % n]);
    // The chain w → … → u, every vertex between on the segment from w to u (zero area).
    let chain: Vec<u32> = (1..=n).map(|k| lp[(long + k) % n]).collect();
    let along = sub(v(u), v(w));
    let on_segment = |c: u32| {
        let t = dot(sub(v(c), v(w)), along);
        triangle_area(v(w), v(u), v(c)) <= min_area && t > 0.0 && t < dot(along, along)
    };
    if !chain[1..n - 1].iter().all(|&c| on_segment(c)) || chain.windows(2).any(|e| e[0] == e[1]) {
        return false;
    }
    let Some(t) = edges
        .uses
        .get(&(u.min(w), u.max(w)))
        .and_then(|t| (t.len() == 1).then_some(t[0] as usize))
    else {
        return false;
    };
    let tri = triangles[t];
    let Some(m) = (0..3).find(|&m| tri[m] == w && tri[(m + 1) % 3] == u) else {
        return false;
    };
    let x = tri[(m + 2) % 3];
    // w → chain… → u replaces w → u: (w, c1, x), (c1, c2, x), …, (ck, u, x).
    let mut pieces = chain.windows(2).map(|e| [e[0], e[1], x]);
    if let Some(first) = pieces.next() {
        triangles[t] = first;
    }
    triangles.extend(pieces);
    true
}

/// The vertices a shell uses, renumbered.
fn compact(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
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
/// (`robot::fill`), with the triangles that face the outside as its surface.
fn filled(
    shells: &[ClosedMesh],
    loose: Vec<[u32; 3]>,
    loose_vertices: &[[f32; 3]],
    report: &mut MeshReport,
) -> Result<ClosedMesh, MeshError> {
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
    Ok(mesh)
}

/// Drops the shells that lie wholly inside another shell (see the module doc for the test).
fn drop_inner(mut shells: Vec<(ClosedMesh, Solid)>, report: &mut MeshReport) -> Vec<ClosedMesh> {
    // Largest first: an inner shell is enclosed by a larger one.
    shells.sort_by(|a, b| b.0.volume_m3.total_cmp(&a.0.volume_m3));
    let mut kept: Vec<(ClosedMesh, Solid)> = Vec::new();
    for (shell, solid) in shells {
        let (lo, hi) = shell.bounds();
        let inside = kept.iter().any(|(outer, outer_solid)| {
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
        } else {
            kept.push((shell, solid));
        }
    }
    kept.into_iter().map(|(m, _)| m).collect()
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
        let (meshes, report) = intake(&v, &t).unwrap();
        assert_eq!((report.open_edges, report.cracks_sewn), (3, 1));
        assert_eq!((report.holes_closed, report.open_shells), (0, 0));
        assert_eq!(meshes.len(), 1);
        assert!(meshes[0].fill.is_none(), "one closed shell, not the fill");
        assert!((meshes[0].volume_m3 - 1e-3).abs() < 1e-9);
        // Off the edge by 1 % of the way to vertex 0: a hole of area, not a crack.
        let (v, t) = split_box(0.01);
        let (meshes, report) = intake(&v, &t).unwrap();
        assert_eq!((report.cracks_sewn, report.holes_closed), (0, 1));
        assert_eq!((report.open_shells, meshes.len()), (0, 1));
        assert!(meshes[0].fill.is_none());
        assert!((meshes[0].volume_m3 - 1e-3).abs() < 1e-9);
    }

    #[test]
    fn a_figure_eight_splits_at_its_repeated_vertex() {
        // s a b v c d v e (back to s): the loop v c d, then s a b v e.
        assert_eq!(
            simple_loops(&[0, 1, 2, 9, 3, 4, 9, 5]),
            vec![vec![9, 3, 4], vec![0, 1, 2, 9, 5]]
        );
        assert_eq!(simple_loops(&[0, 1, 2]), vec![vec![0, 1, 2]]);
    }
}
