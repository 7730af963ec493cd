//! Intake step 4 (`super`'s module doc): the open edges of an oriented shell chained into loops,
//! a loop of no area (a T-junction crack) sewn by splitting the triangle across it, any other
//! closed by a fan around its centroid. Vertices in the link frame, metres; the holes closed,
//! the cracks sewn and the largest hole's diameter go to the [`MeshReport`].

use std::collections::HashMap;

use super::report::MeshReport;
use super::shells::EdgeUse;
use crate::geometry::{dist, dot, sub, triangle_area, widen};
use crate::robot::mesh::MeshError;

/// Closes the holes of an oriented shell: its open edges chained into loops, each loop closed
/// by a fan around its centroid (a new vertex).
pub(super) fn close_holes(
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

#[cfg(test)]
mod tests {
    use super::*;

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
