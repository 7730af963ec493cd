//! The gap pass: fills the pockets that the volume pass leaves between its large spheres and the
//! surface, which set the surface gap h. Surface samples (triangles bisected to half
//! `target_gap_m`, each with its inward normal) wait in a max-heap by their gap; the worst seed
//! prototypes just under the surface, which settle into their pockets and become spheres, until
//! every sample lies within `target_gap_m − spacing/√3` of the spheres or the limit is reached.

use super::grid::{distance, midpoint};
use super::packer::Packer;
use super::prototype::{disturb, settle_all, Prototype, State, PROTOTYPES_PER_SPHERE};
use crate::geometry::{cross, norm, sub, widen};
use crate::robot::ClosedMesh;
use rayon::prelude::*;

/// 1/√3.
const INV_SQRT3: f32 = 0.577_350_26;
/// Smallest number of spheres a gap-pass round may place.
const GAP_ROUND_MIN: usize = 64;
/// Most surface samples of the gap pass (about 24 MiB); reached only by links of metres.
const MAX_GAP_SAMPLES: usize = 1 << 20;

/// Where the gap pass starts a prototype under a surface sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seed {
    /// Half the sample's gap deep.
    HalfGap,
    /// Half the solid's thickness along the normal, where that is less: the second try.
    HalfThickness,
}

impl Packer<'_> {
    /// Samples the surface (triangles bisected down to half `target_gap_m`); while samples lie
    /// farther than that from the spheres, starts a prototype just inside the worst ones (half
    /// their gap deep, against the triangle's normal), lets them settle into their pockets and
    /// accepts those that do not overlap, the worst gap first.
    ///
    /// A sample's gap only shrinks as spheres are added, so a stale gap is an upper bound: the
    /// samples wait in a max-heap by stale gap, and a round re-evaluates only the top until the
    /// re-evaluated value still beats the next stale one (lazy greedy). Cost: one evaluation
    /// per sample, then about one per seed.
    pub(super) fn gap_pass(&mut self, limit: usize) {
        use std::collections::BinaryHeap;
        // Half the target apart, so that the gap between samples stays near the target; on
        // very large links (metres), sparser, so that the samples stay within memory. Each
        // point of a triangle lies within spacing/√3 of its sample (the centroid), so samples
        // within `target − spacing/√3` put the whole surface within the target (h is
        // 1-Lipschitz).
        let sparse = (2.0 * self.mesh.area_m2() / MAX_GAP_SAMPLES as f64).sqrt() as f32;
        let spacing = (0.5 * self.params.target_gap_m).max(sparse);
        let samples = surface_samples(self.mesh, spacing);
        let target =
            (self.params.target_gap_m - spacing * INV_SQRT3).max(0.25 * self.params.target_gap_m);
        let grid = &self.grid;
        // Non-negative f32 gaps order like their bits.
        let mut heap: BinaryHeap<(u32, u32)> = samples
            .par_iter()
            .enumerate()
            .map(|(i, (p, _))| (grid.distance_to_union(*p).to_bits(), i as u32))
            .filter(|(g, _)| f32::from_bits(*g) > target)
            .collect();
        let before = self.grid.spheres().len();
        let mut rounds = 0;
        let mut dropped = 0;
        // Per sample, the gap at which its seed last found no room, and whether that seed was
        // already the one held to the solid's thickness: a seed is a function of the sample
        // and its gap, so a sample whose gap did not change since is not tried the same way
        // again (which would stall the pass on its worst samples).
        let mut failed: Vec<Option<(u32, Seed)>> = vec![None; samples.len()];
        while self.grid.spheres().len() < limit {
            rounds += 1;
            let room = limit - self.grid.spheres().len();
            // A quarter of the room per round, so that the next round sees what these fixed;
            // four seeds per sphere, for the seeds that overlap or find no room.
            let round_room = (room / 4).max(GAP_ROUND_MIN).min(room);
            let mut picked: Vec<(u32, u32, Seed)> = Vec::new();
            while picked.len() < PROTOTYPES_PER_SPHERE * round_room {
                let Some((_, i)) = heap.pop() else { break };
                let g = self.grid.distance_to_union(samples[i as usize].0);
                if g <= target {
                    continue;
                }
                if heap
                    .peek()
                    .is_some_and(|&(next, _)| f32::from_bits(next) > g)
                {
                    heap.push((g.to_bits(), i));
                    continue;
                }
                let seed = match failed[i as usize] {
                    Some((at, Seed::HalfGap)) if at == g.to_bits() => Seed::HalfThickness,
                    Some((at, Seed::HalfThickness)) if at == g.to_bits() => {
                        dropped += 1;
                        continue;
                    }
                    _ => Seed::HalfGap,
                };
                picked.push((g.to_bits(), i, seed));
            }
            if picked.is_empty() {
                break;
            }
            let mut seeds: Vec<Prototype> = picked
                .iter()
                .map(|&(g, i, seed)| {
                    let (p, n) = samples[i as usize];
                    let gap = f32::from_bits(g);
                    // Half the gap deep; failing that, no deeper than half the solid's
                    // thickness there (under a wall thinner than the gap, half the gap lands
                    // beyond it).
                    let depth = match seed {
                        Seed::HalfGap => 0.5 * gap,
                        Seed::HalfThickness => 0.5 * self.solid.thickness(p, n, gap),
                    };
                    Prototype::at(std::array::from_fn(|k| p[k] + n[k] * depth))
                })
                .collect();
            self.settles += settle_all(&self.solid, &self.grid, &mut seeds, self.params);
            // The worst gaps first: seeds were picked in decreasing order of their gap.
            let order: Vec<u32> = (0..seeds.len() as u32)
                .filter(|&i| seeds[i as usize].state == State::Settled)
                .collect();
            let new = self.accept(&mut seeds, &order, self.params.min_radius_m, round_room);
            // A seed that retired found no room; when none of the round's seeds gave a sphere,
            // every one of them failed. Each round thus adds a sphere or moves its samples on
            // (half the gap, half the thickness, dropped), so the pass ends.
            for (&(g, i, seed), prototype) in picked.iter().zip(&seeds) {
                if new.is_empty() || prototype.state == State::Retired {
                    failed[i as usize] = Some((g, seed));
                }
                heap.push((g, i));
            }
            disturb(&mut self.prototypes, &new);
        }
        log::debug!(
            "gap pass: {} spheres in {rounds} rounds, {} of {} surface samples may lie above {target} m ({dropped} without room for a sphere)",
            self.grid.spheres().len() - before,
            heap.len(),
            samples.len()
        );
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

#[cfg(test)]
mod tests {
    use crate::packing::gap;
    use crate::packing::pack::pack;
    use crate::packing::params::PackingParams;
    use crate::robot::mesh::tessellate_box;
    use crate::robot::ClosedMesh;

    /// At the same budget, the gap pass leaves a smaller surface gap than the volume pass alone.
    #[test]
    fn the_gap_pass_shrinks_the_surface_gap() {
        let t = tessellate_box([0.05, 0.08, 0.12]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "box").expect("closed");
        let gap = |target_gap_m: f32| {
            let params = PackingParams {
                target_gap_m,
                ..PackingParams::default()
            };
            let packing = pack(&mesh, 1500, &params);
            gap::surface_gap(&mesh, &packing.grid, 2e-5).upper_m
        };
        let (with, without) = (gap(0.0015), gap(1.0));
        assert!(
            with < 0.5 * without,
            "gap pass {with} m, volume only {without} m"
        );
    }
}
