//! The packer: one link element's packing in progress (its solid, the exact f64 test, the
//! spheres placed so far in their grid, the volume pass's prototypes and cells), and the step
//! every pass ends with, turning settled prototypes into spheres that the exact test confirms
//! inside the solid. The passes that grow it are `volume` and `gap_pass`; `pack` runs them.

use super::cells::first_grid;
use super::gap_samples::GapState;
use super::grid::{distance, SphereGrid};
use super::params::PackingParams;
use super::prototype::{Prototype, State};
use super::sphere::{exact_radius, shrink, InnerSphere};
use crate::robot::exact::ExactSolid;
use crate::robot::solid::Solid;
use crate::robot::ClosedMesh;

/// What a packing produced, with the grid over its spheres for the gap measurement.
pub struct Packing {
    pub grid: SphereGrid,
    /// Prototypes settled, summed over rounds (a measure of the work done).
    pub settles: usize,
}

/// One packing, which can grow: [`Packer::grow`] to a budget, look at the spheres
/// ([`Packer::grid`]), grow further, then [`Packer::finish`].
pub struct Packer<'a> {
    pub(super) solid: Solid,
    /// The exact f64 test every sphere passes before it is kept.
    pub(super) exact: ExactSolid,
    /// Prototypes whose centre the exact test put outside the solid.
    pub(super) refused: usize,
    pub(super) mesh: &'a ClosedMesh,
    pub(super) params: &'a PackingParams,
    pub(super) grid: SphereGrid,
    pub(super) sphere_volume: f64,
    pub(super) settles: usize,
    /// The volume pass's prototypes, its live cells and their current size.
    pub(super) prototypes: Vec<Prototype>,
    pub(super) cells: Vec<[f32; 3]>,
    pub(super) cell: f32,
    /// The gap pass's samples and heap, once it has run.
    pub(super) gap: Option<GapState>,
}

impl<'a> Packer<'a> {
    /// Seeds the first grid: a prototype at every cell centre (jittered) inside the solid; the
    /// cells that reach the solid are kept for refinement.
    pub fn new(mesh: &'a ClosedMesh, params: &'a PackingParams) -> Self {
        let solid = Solid::new(mesh);
        let (lo, hi) = mesh.bounds();
        let grid = SphereGrid::new(lo, hi, 2.0 * params.min_radius_m);
        let (cells, prototypes, cell) = first_grid(&solid, lo, hi, params.prototypes);
        Self {
            solid,
            exact: ExactSolid::new(mesh),
            refused: 0,
            mesh,
            params,
            grid,
            sphere_volume: 0.0,
            settles: 0,
            prototypes,
            cells,
            cell,
            gap: None,
        }
    }

    pub fn grid(&self) -> &SphereGrid {
        &self.grid
    }

    pub fn finish(self) -> Packing {
        if self.refused > 0 {
            log::debug!(
                "{} prototypes refused: the exact test puts their centre outside the solid",
                self.refused
            );
        }
        Packing {
            grid: self.grid,
            settles: self.settles,
        }
    }

    /// Turns the settled `prototypes` in `order` into spheres, up to `room`, skipping those whose
    /// clearance is below `floor` and those that overlap a sphere accepted before them; the
    /// prototypes examined must settle again. Returns the new spheres.
    pub(super) fn accept(
        &mut self,
        prototypes: &mut [Prototype],
        order: &[u32],
        floor: f32,
        room: usize,
    ) -> Vec<InnerSphere> {
        let mut round: Vec<InnerSphere> = Vec::new();
        for &i in order {
            let p = &mut prototypes[i as usize];
            if round.len() >= room {
                break;
            }
            if p.clearance < floor {
                continue;
            }
            let radius = shrink(p.clearance);
            let apart = |r: f32| {
                round
                    .iter()
                    .all(|s| distance(s.center, p.pos) >= s.radius + r)
            };
            if radius > 0.0 && apart(radius) {
                // The f32 climb's clearance, capped by the exact f64 one; a centre the exact
                // test puts outside is never kept (a wrong pseudo-normal in the f32 query).
                match self
                    .exact
                    .ball_clearance(crate::geometry::widen(p.pos), 0.0)
                {
                    Some(clearance) => {
                        let radius = exact_radius(radius, clearance);
                        if radius > 0.0 {
                            round.push(InnerSphere {
                                center: p.pos,
                                radius,
                            });
                        }
                    }
                    None => {
                        p.state = State::Retired;
                        self.refused += 1;
                        continue;
                    }
                }
            }
            p.state = State::Unsettled;
        }
        for s in &round {
            self.grid.insert(*s);
            self.sphere_volume += crate::geometry::ball_volume(s.radius as f64);
        }
        round
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packing::prototype::{Prototype, State};
    use crate::robot::mesh::tessellate_box;

    /// A prototype the f32 climb believes inside (a wrong pseudo-normal) is refused by the exact
    /// test, and a clearance the climb overstated is cut to the exact one: no sphere outside.
    #[test]
    fn the_exact_test_refuses_a_centre_outside_and_caps_a_radius() {
        let t = tessellate_box([0.1, 0.1, 0.1]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "cube").expect("closed");
        let params = PackingParams::default();
        let mut packer = Packer::new(&mesh, &params);
        let settled = |pos: [f32; 3], clearance: f32| Prototype {
            pos,
            clearance,
            state: State::Settled,
        };
        // 1.75 m away with a clearance of 1.69 m, as a vendor link once gave; then a centre
        // 10 mm inside a face that claims 40 mm.
        let mut prototypes = vec![
            settled([1.75, 0.0, 0.0], 1.69),
            settled([0.0, 0.0, 0.04], 0.04),
        ];
        let new = packer.accept(&mut prototypes, &[0, 1], 0.0, 10);
        assert_eq!(packer.refused, 1);
        assert!(prototypes[0].state == State::Retired);
        assert_eq!(new.len(), 1);
        // The face at 0.05 (f32) is this far from the centre, in f64.
        let exact = 0.05f32 as f64 - 0.04f32 as f64;
        assert!(
            new[0].radius as f64 <= exact && new[0].radius as f64 > exact - 1e-8,
            "{:?}",
            new[0]
        );
    }
}
