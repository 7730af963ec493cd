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
//! time. A [`Packer`] can grow, and its gap pass goes on where it stopped (its samples and heap
//! are kept): `ist::build_link` runs a one-element link's gap pass first until its samples are
//! within 0.85 × `target_gap_m` (h, which exceeds the samples' largest gap by a fraction of
//! their spacing, then usually meets the target), and only if the estimate says otherwise on to
//! the proof.
//!
//! Prototypes settle in parallel (rayon). Each settling step is one point-to-mesh query (parry3d,
//! BVH, f32) and one nearest-sphere query ([`grid::SphereGrid`]). A sphere's radius is its
//! prototype's clearance shrunk by a few f32 roundings. Before a sphere is kept, its centre is
//! tested inside the solid and its radius capped by the distance to the surface, both exactly
//! in f64 (`robot::exact`), so that a wrong f32 answer (a pseudo-normal turned by a sliver, which
//! let a prototype climb away from a vendor link and become a 1.69 m sphere) places no sphere
//! outside; `ist::validate` checks every tree again before it is used.

//!
//! Files, in the order of the data flow: `params` (what a link is packed for), `sphere` (the
//! output unit and its radius), `prototype` (the climb), `cells` (where prototypes start),
//! `packer` (one element's packing and its acceptance step), `volume` and `gap_pass` (the two
//! passes; `gap_samples`, the gap pass's samples and heap), `pack` (their order and the entry
//! points); `grid` (the spheres' grid) and `gap` (the measured h).

mod cells;
pub mod gap;
mod gap_pass;
mod gap_samples;
pub mod grid;
mod pack;
mod packer;
mod params;
mod prototype;
mod sphere;
mod volume;

pub use crate::robot::solid::Solid;
pub use pack::{pack, pack_sphere};
pub use packer::{Packer, Packing};
pub use params::PackingParams;
pub use sphere::InnerSphere;
