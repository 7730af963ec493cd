//! The volume pass: largest spheres first. Each round settles the prototypes, turns those within
//! `ACCEPT_RATIO` of the best clearance into spheres and sends the prototypes they disturbed
//! climbing again; when the best clearance falls below a fraction of the cells, the cells are
//! split and seed new prototypes. It stops at its sphere limit, the target coverage or the
//! minimal radius.

use super::cells::refine;
use super::packer::Packer;
use super::prototype::{disturb, ranked, settle_all, Prototype, State, PROTOTYPES_PER_SPHERE};

/// Prototypes within this fraction of the round's largest clearance become spheres together.
const ACCEPT_RATIO: f32 = 0.95;
/// The cells are split once the largest clearance falls below this fraction of a cell.
const REFINE_RATIO: f32 = 0.35;

impl Packer<'_> {
    /// Places the largest spheres first until `limit` spheres or the target coverage: settles
    /// the prototypes, splits the cells when the spheres become small against them, and accepts
    /// the prototypes within `ACCEPT_RATIO` of the round's best.
    pub(super) fn volume_pass(&mut self, limit: usize) {
        let target_volume = self.params.target_coverage * self.mesh.volume_m3;
        let min_radius = self.params.min_radius_m;
        while self.grid.spheres().len() < limit && self.sphere_volume < target_volume {
            self.settles += settle_all(&self.solid, &self.grid, &mut self.prototypes, self.params);
            let order = ranked(&self.prototypes);
            let best = order
                .first()
                .map_or(0.0, |&i| self.prototypes[i as usize].clearance);
            let can_refine = self.cell * 0.5 >= min_radius && !self.cells.is_empty();
            if (order.is_empty() || best < REFINE_RATIO * self.cell) && can_refine {
                self.cell *= 0.5;
                let room = PROTOTYPES_PER_SPHERE * (limit - self.grid.spheres().len());
                let spawned = refine(
                    &self.solid,
                    &self.grid,
                    &mut self.cells,
                    self.cell,
                    min_radius,
                    room,
                );
                self.prototypes.retain(|p| p.state != State::Retired);
                self.prototypes.extend(
                    spawned
                        .into_iter()
                        .take(room)
                        .map(|(_, pos)| Prototype::at(pos)),
                );
                continue;
            }
            if order.is_empty() {
                break;
            }
            let room = limit - self.grid.spheres().len();
            let mut prototypes = std::mem::take(&mut self.prototypes);
            let new = self.accept(&mut prototypes, &order, ACCEPT_RATIO * best, room);
            disturb(&mut prototypes, &new);
            self.prototypes = prototypes;
            if best < min_radius && !can_refine {
                break;
            }
        }
    }
}
