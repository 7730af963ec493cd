//! The gap pass: fills the pockets that the volume pass leaves between its large spheres and the
//! surface, which set the surface gap h. Surface samples (triangles bisected to half
//! `target_gap_m`, each with its inward normal) wait in a max-heap by their gap; the worst seed
//! prototypes just under the surface, which settle into their pockets and become spheres, until
//! every sample lies within the pass's stop (at least `target_gap_m − spacing/√3`, which proves
//! the target) or the limit is reached. The samples and the heap are kept in the packer, so a
//! later call with a lower stop or a higher limit goes on from there.

use super::gap_samples::{GapState, Seed};
use super::packer::Packer;
use super::prototype::{disturb, settle_all, Prototype, State, PROTOTYPES_PER_SPHERE};

/// Smallest number of spheres a gap-pass round may place.
const GAP_ROUND_MIN: usize = 64;
/// Most spheres a gap-pass round may place (when its limit is far), so that the next round
/// sees what these fixed.
const GAP_ROUND_MAX: usize = 2048;

impl Packer<'_> {
    /// While samples of the surface lie farther than `stop` (at least the proof target) from
    /// the spheres and the packing has fewer than `limit` spheres, starts a prototype just
    /// inside the worst ones (half their gap deep, against the triangle's normal), lets them
    /// settle into their pockets and accepts those that do not overlap, the worst gap first.
    /// The samples and their heap are kept ([`GapState`]), so a later call with a lower `stop`
    /// or a higher `limit` goes on where this one stopped.
    ///
    /// A sample's gap only shrinks as spheres are added, so a stale gap is an upper bound: the
    /// samples wait in a max-heap by stale gap, and a round re-evaluates only the top until the
    /// re-evaluated value still beats the next stale one (lazy greedy). Cost: one evaluation
    /// per sample, then about one per seed.
    pub(super) fn gap_pass(&mut self, limit: usize, stop: f32) {
        let mut state = match self.gap.take() {
            Some(state) => state,
            None => GapState::new(self.mesh, &self.grid, self.params.target_gap_m),
        };
        let stop = stop.max(state.proof);
        let before = self.grid.spheres().len();
        let mut rounds = 0;
        let mut dropped = 0;
        while self.grid.spheres().len() < limit {
            rounds += 1;
            let room = limit - self.grid.spheres().len();
            // A quarter of the room per round (at most GAP_ROUND_MAX), so that the next round
            // sees what these fixed; four seeds per sphere, for the seeds that overlap or find
            // no room.
            let round_room = (room / 4).clamp(GAP_ROUND_MIN, GAP_ROUND_MAX).min(room);
            let mut picked: Vec<(u32, u32, Seed)> = Vec::new();
            while picked.len() < PROTOTYPES_PER_SPHERE * round_room {
                let Some((_, i)) = state.heap.pop() else {
                    break;
                };
                let g = self.grid.distance_to_union(state.samples[i as usize].0);
                if g <= state.proof {
                    continue;
                }
                if state
                    .heap
                    .peek()
                    .is_some_and(|&(next, _)| f32::from_bits(next) > g)
                {
                    state.heap.push((g.to_bits(), i));
                    continue;
                }
                if g <= stop {
                    // The worst sample is within `stop`: kept for a later, lower stop.
                    state.heap.push((g.to_bits(), i));
                    break;
                }
                // Per sample, the gap at which its seed last found no room, and whether that
                // seed was already the one held to the solid's thickness: a seed is a function
                // of the sample and its gap, so a sample whose gap did not change since is not
                // tried the same way again (which would stall the pass on its worst samples).
                let seed = match state.failed[i as usize] {
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
                    let (p, n) = state.samples[i as usize];
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
                    state.failed[i as usize] = Some((g, seed));
                }
                state.heap.push((g, i));
            }
            disturb(&mut self.prototypes, &new);
        }
        log::debug!(
            "gap pass: {} spheres in {rounds} rounds, {} of {} surface samples may lie above {} m ({dropped} without room for a sphere), stopped at {stop} m",
            self.grid.spheres().len() - before,
            state.heap.len(),
            state.samples.len(),
            state.proof
        );
        self.gap = Some(state);
    }
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
