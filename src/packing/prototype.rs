//! Prototypes, the packing's search points: each climbs the clearance field (distance to the
//! mesh surface or the nearest sphere already placed, m) to the centre of a locally largest
//! empty sphere, in parallel; a new sphere sends the prototypes whose clearance it reduced
//! climbing again. Inputs: the solid (f32 point-to-mesh query) and the sphere grid; output:
//! settled prototypes with their clearance, ranked largest first.

use rayon::prelude::*;

use super::grid::{distance, SphereGrid};
use super::params::PackingParams;
use super::sphere::InnerSphere;
use crate::robot::solid::Solid;

/// Prototypes allowed per sphere still to place, when a refinement spawns new ones.
pub(super) const PROTOTYPES_PER_SPHERE: usize = 4;

/// Where a prototype stands in its climb.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum State {
    Unsettled,
    Settled,
    Retired,
}

/// A point inside the object climbing its clearance field.
#[derive(Clone, Copy)]
pub(super) struct Prototype {
    pub(super) pos: [f32; 3],
    pub(super) clearance: f32,
    pub(super) state: State,
}

impl Prototype {
    pub(super) fn at(pos: [f32; 3]) -> Self {
        Self {
            pos,
            clearance: 0.0,
            state: State::Unsettled,
        }
    }
}

/// The nearest obstacle of a point inside the solid: clearance (negative inside a sphere), the
/// obstacle point, and the sphere when the obstacle is one.
#[inline]
fn clearance(
    solid: &Solid,
    grid: &SphereGrid,
    p: [f32; 3],
) -> Option<(f32, [f32; 3], Option<u32>)> {
    let (d_mesh, q) = solid.signed_distance(p);
    if d_mesh <= 0.0 {
        return None;
    }
    Some(match grid.nearest(p, d_mesh) {
        Some((d, i)) => {
            let s = grid.spheres()[i as usize];
            let len = distance(p, s.center).max(f32::MIN_POSITIVE);
            let q = std::array::from_fn(|k| s.center[k] + (p[k] - s.center[k]) * s.radius / len);
            (d, q, Some(i))
        }
        None => (d_mesh, q, None),
    })
}

/// Climbs the clearance field from `p`; returns the best position and its clearance, or None
/// when the prototype left the solid or found no room.
fn settle(
    solid: &Solid,
    grid: &SphereGrid,
    start: [f32; 3],
    iterations: u32,
) -> Option<(f32, [f32; 3])> {
    let mut p = start;
    let mut best: Option<(f32, [f32; 3])> = None;
    for t in 0..iterations {
        let (c, q, sphere) = clearance(solid, grid, p)?;
        if best.is_none_or(|(b, _)| c > b) {
            best = Some((c, p));
        }
        if c <= 0.0 {
            // Swallowed by a sphere: jump just outside it, away from its centre.
            let s = grid.spheres()[sphere? as usize];
            let away = std::array::from_fn::<f32, 3, _>(|k| p[k] - s.center[k]);
            let len = distance(away, [0.0; 3]);
            let dir = if len > s.radius * 1e-3 {
                away.map(|x| x / len)
            } else {
                // At the centre: any direction; this one is fixed so results repeat.
                [0.57735, 0.57735, 0.57735]
            };
            p = std::array::from_fn(|k| s.center[k] + dir[k] * s.radius * 1.05);
            continue;
        }
        // Cooling: large steps first, then small ones to settle on the ridge.
        let epsilon = 0.6 * (1.0 - t as f32 / iterations as f32) + 0.05;
        let len = distance(p, q).max(f32::MIN_POSITIVE);
        p = std::array::from_fn(|k| p[k] + (p[k] - q[k]) / len * epsilon * c);
    }
    best.filter(|(c, _)| *c > 0.0)
}

/// Settles every unsettled prototype in parallel, retiring those that find no room for a sphere
/// of the minimal radius (but the first sphere of an element); returns how many settled.
pub(super) fn settle_all(
    solid: &Solid,
    grid: &SphereGrid,
    prototypes: &mut [Prototype],
    params: &PackingParams,
) -> usize {
    let first = grid.spheres().is_empty();
    prototypes
        .par_iter_mut()
        .filter(|p| p.state == State::Unsettled)
        .map(|p| {
            match settle(solid, grid, p.pos, params.settle_iterations) {
                Some((c, pos)) if c >= params.min_radius_m || first => {
                    *p = Prototype {
                        pos,
                        clearance: c,
                        state: State::Settled,
                    }
                }
                _ => p.state = State::Retired,
            }
            1
        })
        .sum()
}

/// Indices of the settled prototypes, largest clearance first (ties by index, so repeatable).
pub(super) fn ranked(prototypes: &[Prototype]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..prototypes.len() as u32)
        .filter(|&i| prototypes[i as usize].state == State::Settled)
        .collect();
    order.sort_unstable_by(|&a, &b| {
        prototypes[b as usize]
            .clearance
            .total_cmp(&prototypes[a as usize].clearance)
            .then(a.cmp(&b))
    });
    order
}

/// Settled prototypes whose clearance one of the `new` spheres reduced must settle again.
pub(super) fn disturb(prototypes: &mut [Prototype], new: &[InnerSphere]) {
    prototypes
        .par_iter_mut()
        .filter(|p| p.state == State::Settled)
        .for_each(|p| {
            if new
                .iter()
                .any(|s| distance(p.pos, s.center) - s.radius < p.clearance)
            {
                p.state = State::Unsettled;
            }
        });
}
