//! The gap pass's surface samples: triangles bisected at their longest edge down to half
//! `target_gap_m` (sparser on links of metres, so that at most about 2²⁰ fit), each sample the
//! centroid with its triangle's inward normal. Each point of a triangle lies within spacing/√3 of
//! its sample, and h is 1-Lipschitz, so samples within `target_gap_m − spacing/√3` of the
//! spheres (the proof target) put the whole surface within `target_gap_m`. The samples above it
//! wait in a max-heap by a gap that may be stale: gaps only shrink as spheres are added, so a
//! stale gap is an upper bound, and the worst sample is found by re-evaluating the top only.

use super::grid::{distance, midpoint, SphereGrid};
use crate::geometry::{cross, norm, sub, widen};
use crate::robot::ClosedMesh;
use rayon::prelude::*;

/// 1/√3.
const INV_SQRT3: f32 = 0.577_350_26;
/// Most surface samples of the gap pass (about 24 MiB); reached only by links of metres.
const MAX_GAP_SAMPLES: usize = 1 << 20;

/// Where the gap pass starts a prototype under a surface sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Seed {
    /// Half the sample's gap deep.
    HalfGap,
    /// Half the solid's thickness along the normal, where that is less: the second try.
    HalfThickness,
}

/// The gap pass's state, kept across a link's budget rounds: its surface samples (each with the
/// inward normal of its triangle), those still above the proof target in a max-heap by a gap
/// that may be stale (an upper bound: gaps only shrink as spheres are added), and per sample
/// the gap at which its seed last found no room.
pub(super) struct GapState {
    pub(super) samples: Vec<([f32; 3], [f32; 3])>,
    pub(super) heap: std::collections::BinaryHeap<(u32, u32)>,
    pub(super) failed: Vec<Option<(u32, Seed)>>,
    /// Samples within this gap put the whole surface within `target_gap_m`, m.
    pub(super) proof: f32,
}

impl GapState {
    /// Samples the surface (triangles bisected down to half `target_gap_m`) and evaluates each
    /// sample's gap once.
    pub(super) fn new(mesh: &ClosedMesh, grid: &SphereGrid, target_gap_m: f32) -> Self {
        // Half the target apart, so that the gap between samples stays near the target; on
        // very large links (metres), sparser, so that the samples stay within memory. Each
        // point of a triangle lies within spacing/√3 of its sample (the centroid), so samples
        // within `target − spacing/√3` put the whole surface within the target (h is
        // 1-Lipschitz).
        let sparse = (2.0 * mesh.area_m2() / MAX_GAP_SAMPLES as f64).sqrt() as f32;
        let spacing = (0.5 * target_gap_m).max(sparse);
        let samples = surface_samples(mesh, spacing);
        let proof = (target_gap_m - spacing * INV_SQRT3).max(0.25 * target_gap_m);
        // Non-negative f32 gaps order like their bits.
        let heap = samples
            .par_iter()
            .enumerate()
            .map(|(i, (p, _))| (grid.distance_to_union(*p).to_bits(), i as u32))
            .filter(|(g, _)| f32::from_bits(*g) > proof)
            .collect();
        let failed = vec![None; samples.len()];
        Self {
            samples,
            heap,
            failed,
            proof,
        }
    }

    /// The largest gap of a sample to `grid`'s spheres now, re-evaluated lazily from the top (a
    /// re-evaluated gap that beats the next stale one beats them all): a point of the surface
    /// that far from every sphere, so a lower bound of the element's h. None when no sample is
    /// left above the proof target.
    pub(super) fn worst(&mut self, grid: &SphereGrid) -> Option<f32> {
        while let Some((_, i)) = self.heap.pop() {
            let g = grid.distance_to_union(self.samples[i as usize].0);
            if g <= self.proof {
                continue;
            }
            let fresh = g.to_bits();
            let top = self.heap.peek().is_none_or(|&(next, _)| next <= fresh);
            self.heap.push((fresh, i));
            if top {
                return Some(g);
            }
        }
        None
    }
}

/// The centroids of the mesh triangles bisected at their longest edge until no edge is longer
/// than `spacing` (so slivers give few samples), each with its triangle's inward unit normal.
fn surface_samples(mesh: &ClosedMesh, spacing: f32) -> Vec<([f32; 3], [f32; 3])> {
    mesh.triangles
        .par_iter()
        .flat_map_iter(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
            let [wa, wb, wc] = [a, b, c].map(widen);
            let n = cross(sub(wb, wa), sub(wc, wa));
            let len = norm(n).max(f64::MIN_POSITIVE);
            let inward = n.map(|x| (-x / len) as f32);
            let mut out = Vec::new();
            let mut stack = vec![[a, b, c]];
            while let Some([a, b, c]) = stack.pop() {
                let edges = [distance(a, b), distance(b, c), distance(c, a)];
                let longest = edges.iter().copied().fold(0.0, f32::max);
                if longest <= spacing {
                    out.push((std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0), inward));
                    continue;
                }
                // Split the longest edge; the corner opposite it goes to both halves.
                let [p, q, r] = if edges[0] == longest {
                    [a, b, c]
                } else if edges[1] == longest {
                    [b, c, a]
                } else {
                    [c, a, b]
                };
                let m = midpoint(p, q);
                stack.push([p, m, r]);
                stack.push([m, q, r]);
            }
            out
        })
        .collect()
}
