//! Sphere packing stage: fills a closed collision mesh (link frame) with non-overlapping inner
//! spheres by the Protosphere method (Weller & Zachmann, "ProtoSphere: A GPU-Assisted
//! Prototype Guided Sphere Packing Algorithm for Arbitrary Objects", 2010).
//!
//! Every prototype is a point inside the object. Its clearance is the distance to the nearest
//! obstacle: the mesh surface or an inner sphere already placed. A prototype *settles* by moving
//! away from its nearest obstacle point q, `p ← p + ε(t)·(p − q)/|p − q|·clearance`, with a
//! cooling ε(t), which climbs the clearance field to a local maximum, the centre of a locally
//! largest empty sphere. The settled prototypes with the largest clearance become spheres (all
//! those within `ACCEPT_RATIO` of the best that do not overlap each other), and only the
//! prototypes whose clearance the new spheres reduced settle again. Prototypes start one per
//! cell of a grid over the link; when the spheres become small against the cells, the cells that
//! still hold free space are split in eight and get prototypes of their own. Packing stops at the
//! sphere budget, the minimal radius or the target coverage.
//!
//! Largest-first packing fills volume, but the surface gap h (see `gap`) is set by the pockets
//! left between large spheres and the surface. So the volume pass spends half the budget, then a
//! gap pass seeds prototypes just under the surface samples farthest from the spheres (worst
//! first, found lazily in a max-heap) until every sample is within `target_gap_m − spacing/√3`
//! (each surface point lies within spacing/√3 of its sample, so that puts the whole surface
//! within `target_gap_m`), and the volume pass spends the rest. A seed starts half its sample's
//! gap deep; where that lands beyond a wall thinner than the gap (a vendor's 1 mm housing), the
//! sample's next seed starts at half the wall's thickness along the normal, and a sample whose
//! two seeds both found no room at an unchanged gap is dropped (a rim thinner than two minimal
//! radii), so the pass never stalls on its worst samples. On the Panda at 8192 spheres
//! per link the gap pass brought the worst h from 3.47 mm (volume pass alone, `--target-gap 1`)
//! to 1.99 mm, at the same coverage (85.3 % on the worst link either way) for 15 % more build
//! time. A [`Packer`] can grow: `ist::build_link` doubles a link's budget while its certified h
//! is above `target_gap_m`.
//!
//! Prototypes settle in parallel (rayon). Each settling step is one point-to-mesh query (parry3d,
//! BVH, f32) and one nearest-sphere query ([`grid::SphereGrid`]). A sphere's radius is its
//! prototype's clearance shrunk by a few f32 roundings. Before a sphere is kept, its centre is
//! tested inside the solid and its radius capped by the distance to the surface, both exactly
//! in f64 (`robot::exact`), so that a wrong f32 answer (a pseudo-normal turned by a sliver, which
//! let a prototype climb away from a vendor link and become a 1.69 m sphere) places no sphere
//! outside; `ist::validate` checks every tree again before it is used.

pub mod gap;
pub mod grid;

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{cross, norm, sub, widen};
use crate::robot::exact::ExactSolid;
use crate::robot::ClosedMesh;
use grid::{distance, midpoint, SphereGrid};

/// One inner sphere in its link's frame (metres). WGSL mirror: `Sphere { center: vec3<f32>,
/// radius: f32 }` in `shaders/traverse.wgsl`, checked member by member against
/// `query::layout::MIRRORS`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, Serialize, Deserialize)]
pub struct InnerSphere {
    pub center: [f32; 3],
    pub radius: f32,
}
const _: () = assert!(std::mem::size_of::<InnerSphere>() == 16);

/// Packing parameters (per link).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackingParams {
    /// Most spheres of one link (split among its collision elements by volume): its budget
    /// starts at `start_spheres` (or this, if smaller) and doubles while the link's certified
    /// h stays above `target_gap_m` (`ist::build_link`).
    pub max_spheres: u32,
    /// The budget a link starts with.
    pub start_spheres: u32,
    /// Spheres smaller than this are not placed (the first sphere of an element always is), m.
    pub min_radius_m: f32,
    /// Stop once the spheres fill this fraction of the mesh volume.
    pub target_coverage: f64,
    /// Prototypes of the first grid, spread over the element's bounding box.
    pub prototypes: u32,
    /// Settling steps of a prototype.
    pub settle_iterations: u32,
    /// The surface gap h a link is packed for, m: the gap pass fills pockets under the surface
    /// until the samples put the whole surface this close to the spheres (or the budget is
    /// spent), and the budget grows until the certified h is at most this (or `max_spheres`).
    pub target_gap_m: f32,
}

impl Default for PackingParams {
    fn default() -> Self {
        Self {
            max_spheres: 65536,
            start_spheres: 8192,
            min_radius_m: 0.00015,
            target_coverage: 0.99,
            prototypes: 4096,
            settle_iterations: 24,
            target_gap_m: 0.0015,
        }
    }
}

/// Share of the budget the first volume pass may spend before the gap pass.
const VOLUME_SHARE: f64 = 0.5;
/// 1/√3.
const INV_SQRT3: f32 = 0.577_350_26;
/// Half the diagonal of a unit cube.
const HALF_DIAGONAL: f32 = 0.866_025_4;
/// Prototypes within this fraction of the round's largest clearance become spheres together.
const ACCEPT_RATIO: f32 = 0.95;
/// Smallest number of spheres a gap-pass round may place.
const GAP_ROUND_MIN: usize = 64;
/// The cells are split once the largest clearance falls below this fraction of a cell.
const REFINE_RATIO: f32 = 0.35;
/// Prototypes allowed per sphere still to place, when a refinement spawns new ones.
const PROTOTYPES_PER_SPHERE: usize = 4;
/// Live cells kept per prototype allowed, when the cells are split.
const CELLS_PER_PROTOTYPE: usize = 2;
/// Most surface samples of the gap pass (about 24 MiB); reached only by links of metres.
const MAX_GAP_SAMPLES: usize = 1 << 20;

pub use crate::robot::solid::Solid;

#[derive(Clone, Copy, PartialEq)]
enum State {
    Unsettled,
    Settled,
    Retired,
}

/// Where the gap pass starts a prototype under a surface sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seed {
    /// Half the sample's gap deep.
    HalfGap,
    /// Half the solid's thickness along the normal, where that is less: the second try.
    HalfThickness,
}

#[derive(Clone, Copy)]
struct Prototype {
    pos: [f32; 3],
    clearance: f32,
    state: State,
}

/// What a packing produced, with the grid over its spheres for the gap measurement.
pub struct Packing {
    pub grid: SphereGrid,
    /// Prototypes settled, summed over rounds (a measure of the work done).
    pub settles: usize,
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

/// A deterministic offset in [-0.25, 0.25) of a cell, from its coordinates.
fn jitter(cell: [i64; 3], axis: usize) -> f32 {
    let mut h = (cell[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (cell[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (cell[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ (axis as u64).wrapping_mul(0x27D4_EB2F_1656_67C5);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h >> 40) as f32 / (1u64 << 24) as f32 * 0.5 - 0.25
}

/// Packs one closed mesh with at most `budget` spheres: the volume pass fills the solid with the
/// largest spheres first, the gap pass then fills the pockets under the surface where the gap is
/// above `target_gap_m`, and the volume pass spends what budget is left.
pub fn pack(mesh: &ClosedMesh, budget: usize, params: &PackingParams) -> Packing {
    let mut packer = Packer::new(mesh, params);
    packer.grow(budget);
    packer.finish()
}

/// The packing of a sphere primitive: its inscribed sphere about `center` (the exact f64
/// distance to the tessellation's faces, shrunk like every sphere's radius), which no packing
/// beats, so no search is run.
pub fn pack_sphere(mesh: &ClosedMesh, center: [f64; 3], params: &PackingParams) -> Packing {
    let radius = crate::geometry::distance_point_mesh(center, &mesh.vertices, &mesh.triangles);
    let (lo, hi) = mesh.bounds();
    let mut grid = SphereGrid::new(lo, hi, 2.0 * params.min_radius_m);
    grid.insert(InnerSphere {
        center: center.map(|x| x as f32),
        radius: shrink(radius as f32),
    });
    Packing { grid, settles: 0 }
}

/// A sphere radius from a clearance, shrunk by a few f32 roundings so that the sphere stays
/// inside the mesh and apart from its neighbours.
fn shrink(clearance: f32) -> f32 {
    clearance * (1.0 - 4.0 * f32::EPSILON) - 2e-7
}

/// The largest f32 radius at most `radius` whose ball lies within `clearance` (f64) of its
/// centre.
fn exact_radius(radius: f32, clearance: f64) -> f32 {
    let mut r = radius.min(clearance as f32);
    while r > 0.0 && r as f64 > clearance {
        r = r.next_down();
    }
    r
}

/// One packing, which can grow: [`Packer::grow`] to a budget, look at the spheres
/// ([`Packer::grid`]), grow further, then [`Packer::finish`].
pub struct Packer<'a> {
    solid: Solid,
    /// The exact f64 test every sphere passes before it is kept.
    exact: ExactSolid,
    /// Prototypes whose centre the exact test put outside the solid.
    refused: usize,
    mesh: &'a ClosedMesh,
    params: &'a PackingParams,
    grid: SphereGrid,
    sphere_volume: f64,
    settles: usize,
    /// The volume pass's prototypes, its live cells and their current size.
    prototypes: Vec<Prototype>,
    cells: Vec<[f32; 3]>,
    cell: f32,
}

impl<'a> Packer<'a> {
    /// Packs up to `budget` spheres in all: the volume pass to half of it, the gap pass, the
    /// volume pass to the rest; a packing already past a step's limit skips it.
    pub fn grow(&mut self, budget: usize) {
        self.volume_pass((budget as f64 * VOLUME_SHARE).ceil() as usize);
        self.gap_pass(budget);
        self.volume_pass(budget);
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

    /// Seeds the first grid: a prototype at every cell centre (jittered) inside the solid; the
    /// cells that reach the solid are kept for refinement.
    pub fn new(mesh: &'a ClosedMesh, params: &'a PackingParams) -> Self {
        let solid = Solid::new(mesh);
        let (lo, hi) = mesh.bounds();
        let grid = SphereGrid::new(lo, hi, 2.0 * params.min_radius_m);
        let box_volume: f64 = (0..3).map(|k| (hi[k] - lo[k]) as f64).product();
        let cell = (box_volume / params.prototypes.max(1) as f64).cbrt() as f32;
        let counts = std::array::from_fn::<usize, 3, _>(|k| {
            ((hi[k] - lo[k]) / cell).ceil().max(1.0) as usize
        });
        let first: Vec<[i64; 3]> = (0..counts[2])
            .flat_map(|z| {
                (0..counts[1])
                    .flat_map(move |y| (0..counts[0]).map(move |x| [x as i64, y as i64, z as i64]))
            })
            .collect();
        let centre = |c: [i64; 3], jittered: bool| -> [f32; 3] {
            std::array::from_fn(|k| {
                let offset = if jittered { jitter(c, k) } else { 0.0 };
                lo[k] + (c[k] as f32 + 0.5 + offset) * cell
            })
        };
        let seeded: Vec<([i64; 3], f32, [f32; 3])> = first
            .par_iter()
            .map(|&c| {
                let p = centre(c, true);
                (c, solid.signed_distance(p).0, p)
            })
            .collect();
        let mut cells = Vec::new();
        let mut prototypes = Vec::new();
        for (c, d, p) in seeded {
            if d > -cell * HALF_DIAGONAL {
                cells.push(centre(c, false));
            }
            if d > 0.0 {
                prototypes.push(Prototype::at(p));
            }
        }
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
        }
    }

    fn volume_pass(&mut self, limit: usize) {
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

    /// Samples the surface (triangles bisected down to half `target_gap_m`); while samples lie
    /// farther than that from the spheres, starts a prototype just inside the worst ones (half
    /// their gap deep, against the triangle's normal), lets them settle into their pockets and
    /// accepts those that do not overlap, the worst gap first.
    ///
    /// A sample's gap only shrinks as spheres are added, so a stale gap is an upper bound: the
    /// samples wait in a max-heap by stale gap, and a round re-evaluates only the top until the
    /// re-evaluated value still beats the next stale one (lazy greedy). Cost: one evaluation
    /// per sample, then about one per seed.
    fn gap_pass(&mut self, limit: usize) {
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

    /// Turns the settled `prototypes` in `order` into spheres, up to `room`, skipping those whose
    /// clearance is below `floor` and those that overlap a sphere accepted before them; the
    /// prototypes examined must settle again. Returns the new spheres.
    fn accept(
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

impl Prototype {
    fn at(pos: [f32; 3]) -> Self {
        Self {
            pos,
            clearance: 0.0,
            state: State::Unsettled,
        }
    }
}

/// Settles every unsettled prototype in parallel, retiring those that find no room for a sphere
/// of the minimal radius (but the first sphere of an element); returns how many settled.
fn settle_all(
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
fn ranked(prototypes: &[Prototype]) -> Vec<u32> {
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
fn disturb(prototypes: &mut [Prototype], new: &[InnerSphere]) {
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

/// Splits every live cell in eight, keeps the children that may still hold free space, and
/// returns the children whose centre has room for a sphere, largest room first.
fn refine(
    solid: &Solid,
    grid: &SphereGrid,
    cells: &mut Vec<[f32; 3]>,
    size: f32,
    min_radius: f32,
    room: usize,
) -> Vec<(f32, [f32; 3])> {
    let half = size * 0.5;
    let half_diagonal = size * HALF_DIAGONAL;
    let children: Vec<(f32, [f32; 3])> = cells
        .par_iter()
        .flat_map_iter(|c| {
            (0..8).map(move |i| {
                std::array::from_fn::<f32, 3, _>(|k| {
                    c[k] + if i >> k & 1 == 1 { half } else { -half }
                })
            })
        })
        .map(|p| {
            let (d_mesh, _) = solid.signed_distance(p);
            let room = match grid.nearest(p, d_mesh) {
                Some((d, _)) => d,
                None => d_mesh,
            };
            (room, p)
        })
        .filter(|(room, _)| *room > -half_diagonal)
        .collect();
    // Keep the roomiest cells: no more than the remaining budget can use.
    let mut children = children;
    children.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    children.truncate(CELLS_PER_PROTOTYPE * room.max(1));
    *cells = children.iter().map(|(_, p)| *p).collect();
    children.retain(|(room, _)| *room > min_radius);
    children
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::mesh::tessellate_box;

    #[test]
    fn a_cube_gets_one_big_sphere_first_and_fills_up() {
        let t = tessellate_box([0.1, 0.1, 0.1]);
        let mesh = ClosedMesh::new(t.vertices, t.triangles, "cube").expect("closed");
        let params = PackingParams::default();
        let one = pack(&mesh, 1, &params);
        let s = one.grid.spheres()[0];
        assert!((s.radius - 0.05).abs() < 5e-4, "first sphere {s:?}");
        let many = pack(&mesh, 500, &params);
        let spheres = many.grid.spheres();
        assert_eq!(spheres.len(), 500);
        let volume: f64 = spheres
            .iter()
            .map(|s| crate::geometry::ball_volume(s.radius as f64))
            .sum();
        assert!(
            volume / mesh.volume_m3 > 0.6,
            "coverage {}",
            volume / mesh.volume_m3
        );
    }

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
