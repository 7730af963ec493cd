//! Intake step 3 (`super`'s module doc): the triangles using each edge, the shells they form
//! (triangles joined through edges of exactly two triangles; a non-manifold edge joins nothing)
//! and each shell's triangles turned to agree with their neighbours. Triangles are vertex
//! indices; nothing here measures.

use std::collections::HashMap;

use crate::robot::mesh::MeshError;

/// The triangles using each undirected edge.
pub(super) struct EdgeUse {
    pub(super) uses: HashMap<(u32, u32), Vec<u32>>,
}

impl EdgeUse {
    pub(super) fn count(triangles: &[[u32; 3]]) -> Self {
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
    pub(super) fn shells(&self, n: usize) -> Vec<Vec<usize>> {
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
pub(super) fn orient(triangles: &mut [[u32; 3]]) -> Result<bool, MeshError> {
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
