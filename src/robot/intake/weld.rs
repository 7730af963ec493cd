//! Intake steps 1 and 2 (`super`'s module doc): vertices closer than a tolerance welded (CAD
//! noise), then each repeated triangle kept once and a face present in both orientations (an
//! internal wall between two glued solids) dropped. Vertices in the link frame, metres; every
//! change counted in the [`MeshReport`].

use std::collections::HashMap;

use super::report::{MeshReport, TriangleFate};

/// Welding tolerance relative to the mesh's largest extent.
pub const WELD_RELATIVE: f64 = 1e-6;

/// Merges vertices within `tolerance` (the first of a cluster stands for it), through a hash
/// of cells of the tolerance's size (a vertex is compared with the 27 cells around it).
pub(super) fn weld(
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

/// Keeps one triangle of each orientation per vertex set, none where both orientations occur:
/// per triangle, None where kept, else why it is dropped.
pub(super) fn drop_repeated(
    triangles: &[[u32; 3]],
    report: &mut MeshReport,
) -> Vec<Option<TriangleFate>> {
    // Key: the sorted vertices; value: (a representative per orientation, count).
    let mut seen: HashMap<[u32; 3], [(usize, usize); 2]> = HashMap::with_capacity(triangles.len());
    let mut keys = Vec::with_capacity(triangles.len());
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
        keys.push(key);
    }
    keys.iter()
        .enumerate()
        .map(|(i, key)| {
            let v = seen.get(key).copied().unwrap_or_default();
            match (v[0].1, v[1].1) {
                (a, b) if a > 0 && b > 0 => {
                    report.repeated_triangles += 1;
                    Some(TriangleFate::InternalWall)
                }
                (a, _) => {
                    let first = if a > 0 { v[0].0 } else { v[1].0 };
                    report.repeated_triangles += usize::from(first != i);
                    (first != i).then_some(TriangleFate::Repeated)
                }
            }
        })
        .collect()
}
