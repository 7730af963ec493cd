//! The robot in the unseen-space pass: its inner spheres placed in the root frame, each with the
//! padding its image takes ([`PaddedSphere`]), and the bounding sphere of each monitored link
//! ([`LinkBound`]).
//!
//! - **Its body is no hidden body.** A ball of the detection capability cannot overlap the robot,
//!   so a lattice centre is dropped when its ball (radius `r`, `footprint`) meets an inner
//!   sphere: `|x − c| < radius + r` ([`RobotBody::takes`], a bit per cell over the robot's
//!   box, less 10 µm so that the f32 placement never drops a centre whose ball only touches a
//!   sphere). Inner spheres lie inside the link's meshes, so every centre dropped is one where
//!   no hidden ball can be; nothing farther is dropped (the padding and h widen only what the
//!   views render as the robot).
//! - **Its image** (`prepared`): each sphere grown by the self-filter padding and its link's h,
//!   so that a return on the link's surface, which lies within h of the spheres, falls inside.
//! - **The search's bound** (`search`): a centre `x` is at least `|x − c_L| − r_L − h_L` from link
//!   `L`'s meshes, `(c_L, r_L)` the bounding sphere of its inner spheres: a lower bound of the
//!   query's certified lower bound there.
//!
//! Cost: per sphere the cells of its reach's bounding cube, once a frame; a bit read a centre.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::query::QueryLink;

use super::lattice::Lattice;

/// One inner sphere in the root frame with the padding its image takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaddedSphere {
    pub centre: [f32; 3],
    pub radius: f32,
    pub padding: f32,
}

/// A monitored link's inner spheres' bounding sphere in the root frame, the spheres of a cut of
/// its tree that cover them ([`COVERS`] or so), and its surface gap h.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkBound {
    pub centre: [f32; 3],
    pub radius: f32,
    pub gap_m: f32,
    /// Root-frame spheres (centre, radius) whose union holds every inner sphere of the link.
    pub covers: Vec<([f32; 3], f32)>,
}

/// Spheres of a link's tree taken as its cover: a cut about this large, the largest nodes
/// opened first. 32 rather than 16: on the Kinect frame the search judges 3,063 cells instead
/// of 3,368 and takes 1.25–1.29 ms instead of 1.31–1.34 (three runs alternated; squared tests
/// make a cover cheap).
pub const COVERS: usize = 32;

impl LinkBound {
    /// A lower bound of the certified distance from `p` (root frame) to the link (m, may be
    /// negative): from its covers.
    #[inline]
    pub fn lower_bound(&self, p: [f32; 3]) -> f32 {
        self.lower_bound_below(p, f32::INFINITY)
    }

    /// The same, from the bounding sphere alone where that bound is already at least `limit`.
    #[inline]
    pub fn lower_bound_below(&self, p: [f32; 3], limit: f32) -> f32 {
        let coarse = self.sphere_bound(p);
        if coarse >= limit || limit == f32::INFINITY || self.covers.is_empty() {
            return coarse;
        }
        self.covers_bound(p)
    }

    /// The lower bound from the bounding sphere alone.
    #[inline]
    pub fn sphere_bound(&self, p: [f32; 3]) -> f32 {
        distance(p, self.centre) - self.radius - self.gap_m
    }

    /// The lower bound from the covers (+∞ without covers).
    #[inline]
    pub fn covers_bound(&self, p: [f32; 3]) -> f32 {
        (self.covers.iter())
            .map(|(c, r)| distance(p, *c) - r)
            .fold(f32::INFINITY, f32::min)
            - self.gap_m
    }

    /// Whether [`LinkBound::lower_bound_below`]`(p, limit)` is below `limit`: some cover (or,
    /// without covers, the bounding sphere) comes within `limit` of `p`, tested on squared
    /// distances (no square root), the bounding sphere first.
    #[inline]
    pub fn may_be_within(&self, p: [f32; 3], limit: f32) -> bool {
        self.sphere_within(p, limit)
            && (self.covers.is_empty()
                || (self.covers.iter()).any(|&(c, r)| self.reaches(p, c, r, limit)))
    }

    /// Whether [`LinkBound::sphere_bound`]`(p)` is below `limit` (squared: no square root).
    #[inline]
    pub fn sphere_within(&self, p: [f32; 3], limit: f32) -> bool {
        self.reaches(p, self.centre, self.radius, limit)
    }

    /// Whether the sphere `(c, r)` of the link, grown by its h, comes within `limit` of `p`.
    #[inline]
    fn reaches(&self, p: [f32; 3], c: [f32; 3], r: f32, limit: f32) -> bool {
        let reach = self.reach(r, limit);
        reach > 0.0 && distance2(p, c) < reach * reach
    }

    /// How far from its centre a sphere of radius `r` of the link, grown by its h, comes within
    /// `limit` of a point: `limit + r + h`.
    #[inline]
    pub(super) fn reach(&self, r: f32, limit: f32) -> f32 {
        limit + r + self.gap_m
    }
}

/// The squared distance between two points.
#[inline]
pub(super) fn distance2(a: [f32; 3], b: [f32; 3]) -> f32 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
}

#[inline]
fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d2: f32 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
    d2.sqrt()
}

/// The inner spheres of `links` of at least `smallest_m` radius, placed by `poses`
/// (`root_from_link`, the kinematics' order), each padded by `padding_m` and its link's h.
/// Leaving small spheres out only leaves a centre undropped or a pixel not the robot's: the
/// conservative side.
pub fn padded_spheres(
    links: &[QueryLink],
    poses: &[Isometry3<f64>],
    padding_m: f32,
    smallest_m: f32,
) -> Vec<PaddedSphere> {
    (links.iter())
        .flat_map(|l| {
            let pose = poses[l.pose_index];
            let spheres = l.spheres.iter().filter(move |s| s.radius >= smallest_m);
            spheres.map(move |s| PaddedSphere {
                centre: place(&pose, s.center),
                radius: s.radius,
                padding: padding_m + l.gap_m,
            })
        })
        .collect()
}

/// Each link's bounding sphere at `poses` (the engine's order): its tree's root node, which
/// encloses every inner sphere of the link.
pub fn link_bounds(links: &[QueryLink], poses: &[Isometry3<f64>]) -> Vec<LinkBound> {
    (links.iter())
        .map(|l| {
            let pose = &poses[l.pose_index];
            // f32 rounding of the placement, on the safe side.
            let safe = |r: f32| r * (1.0 + 1e-6) + 1e-6;
            match l.nodes.first() {
                Some(root) => LinkBound {
                    centre: place(pose, root.center),
                    radius: safe(root.radius),
                    gap_m: l.gap_m,
                    covers: (cover(l).into_iter())
                        .map(|(c, r)| (place(pose, c), safe(r)))
                        .collect(),
                },
                // No sphere: nothing of the link to be near.
                None => LinkBound {
                    centre: [0.0; 3],
                    radius: f32::NEG_INFINITY,
                    gap_m: 0.0,
                    covers: Vec::new(),
                },
            }
        })
        .collect()
}

/// A cut of `link`'s tree of about [`COVERS`] spheres (link frame): from the root, the largest
/// node whose children are nodes is replaced by them, and one whose children are inner spheres
/// by those, while the cut is smaller.
fn cover(link: &QueryLink) -> Vec<([f32; 3], f32)> {
    // (centre, radius, the node it is, if its children can replace it).
    let mut cut: Vec<([f32; 3], f32, Option<usize>)> = match link.nodes.first() {
        Some(root) => vec![(root.center, root.radius, Some(0))],
        None => return Vec::new(),
    };
    while cut.len() < COVERS {
        let Some(k) = (0..cut.len())
            .filter(|&k| cut[k].2.is_some())
            .max_by(|&a, &b| cut[a].1.total_cmp(&cut[b].1))
        else {
            break;
        };
        let Some(n) = cut.swap_remove(k).2 else { break };
        let node = &link.nodes[n];
        let (first, count) = (node.first_child as usize, node.child_count as usize);
        if node.children_are_spheres != 0 {
            cut.extend(
                (link.spheres[first..first + count].iter()).map(|s| (s.center, s.radius, None)),
            );
        } else {
            cut.extend((first..first + count).map(|c| {
                let child = &link.nodes[c];
                (child.center, child.radius, Some(c))
            }));
        }
    }
    cut.into_iter().map(|(c, r, _)| (c, r)).collect()
}

/// The robot at a frame's poses, as the search reads it: each link's bounding sphere, and the
/// lattice centres whose ball meets an inner sphere.
pub struct RobotBody {
    bounds: Vec<LinkBound>,
    /// The cells of the robot's box on the lattice (cell index ranges), one bit a cell.
    lo: [usize; 3],
    dims: [usize; 3],
    bits: Vec<u64>,
}

impl RobotBody {
    /// The robot of `links` at `poses` on `lattice`, for balls of radius `ball_m`; spheres under
    /// `smallest_m` are left out of the centres dropped (the conservative side: a centre not
    /// dropped is judged by the views).
    pub fn new(
        lattice: &Lattice,
        links: &[QueryLink],
        poses: &[Isometry3<f64>],
        ball_m: f32,
        smallest_m: f32,
    ) -> Self {
        let spheres = padded_spheres(links, poses, 0.0, smallest_m);
        Self::from_spheres(lattice, links, poses, &spheres, ball_m)
    }

    /// As [`RobotBody::new`], from the spheres already placed at `poses` (their padding is not
    /// taken: a cell is dropped by the inner spheres themselves).
    pub fn from_spheres(
        lattice: &Lattice,
        links: &[QueryLink],
        poses: &[Isometry3<f64>],
        spheres: &[PaddedSphere],
        ball_m: f32,
    ) -> Self {
        let to = ToCells::new(lattice);
        let dims = lattice.dims();
        // The cells the spheres' reach covers, in cell coordinates (centre i at i + ½).
        let reach_of = |s: &PaddedSphere| (s.radius + ball_m - 1e-5).max(0.0) * to.inv_h;
        let (mut lo, mut hi) = ([usize::MAX; 3], [0usize; 3]);
        // Per sphere: its cells' index ranges, its centre in cell coordinates and its reach.
        type Reach = ([usize; 3], [usize; 3], [f32; 3], f32);
        let ranges: Vec<Reach> = (spheres.iter())
            .filter_map(|s| {
                let reach = reach_of(s);
                let c = to.at(s.centre);
                let a = c.map(|x| (x - reach - 0.5).ceil().max(0.0) as usize);
                let b: [usize; 3] = std::array::from_fn(|k| {
                    let top = (c[k] + reach - 0.5).floor();
                    if top < 0.0 {
                        0
                    } else {
                        (top as usize + 1).min(dims[k])
                    }
                });
                (0..3).all(|k| a[k] < b[k]).then_some((a, b, c, reach))
            })
            .collect();
        for (a, b, _, _) in &ranges {
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        if ranges.is_empty() {
            (lo, hi) = ([0; 3], [0; 3]);
        }
        let size: [usize; 3] = std::array::from_fn(|k| hi[k] - lo[k]);
        let bits: Vec<AtomicU64> = (0..(size[0] * size[1] * size[2]).div_ceil(64))
            .map(|_| AtomicU64::new(0))
            .collect();
        // Spheres in parallel, each setting its cells' bits (an atomic or: two spheres may
        // share a word).
        ranges.par_iter().for_each(|&(a, b, c, reach)| {
            let reach2 = reach * reach;
            for k in a[2]..b[2] {
                let dz = k as f32 + 0.5 - c[2];
                for j in a[1]..b[1] {
                    let dy = j as f32 + 0.5 - c[1];
                    let row = size[0] * ((j - lo[1]) + size[1] * (k - lo[2])) - lo[0];
                    // The row's cells within reach, gathered a word at a time.
                    let (mut word, mut mask) = (usize::MAX, 0u64);
                    for i in a[0]..b[0] {
                        let dx = i as f32 + 0.5 - c[0];
                        if dx * dx + dy * dy + dz * dz < reach2 {
                            let n = row + i;
                            if n / 64 != word {
                                if mask != 0 {
                                    bits[word].fetch_or(mask, Relaxed);
                                }
                                (word, mask) = (n / 64, 0);
                            }
                            mask |= 1 << (n % 64);
                        }
                    }
                    if mask != 0 {
                        bits[word].fetch_or(mask, Relaxed);
                    }
                }
            }
        });
        let bits = bits.into_iter().map(AtomicU64::into_inner).collect();
        Self {
            bounds: link_bounds(links, poses),
            lo,
            dims: size,
            bits,
        }
    }

    /// Each link's bounding sphere, the engine's order.
    pub fn bounds(&self) -> &[LinkBound] {
        &self.bounds
    }

    /// Whether the ball at cell `ijk`'s centre meets an inner sphere.
    #[inline]
    pub fn takes(&self, ijk: [usize; 3]) -> bool {
        let inside = (0..3).all(|k| ijk[k] >= self.lo[k] && ijk[k] - self.lo[k] < self.dims[k]);
        inside && {
            let [i, j, k] = std::array::from_fn(|a| ijk[a] - self.lo[a]);
            let n = i + self.dims[0] * (j + self.dims[1] * k);
            self.bits[n / 64] >> (n % 64) & 1 == 1
        }
    }
}

/// The lattice's frame in f32: a root-frame point to fractional cell coordinates.
struct ToCells {
    box_from_root: Rigid32,
    inv_h: f32,
    half: [f32; 3],
}

impl ToCells {
    fn new(lattice: &Lattice) -> Self {
        Self {
            box_from_root: Rigid32::of(&lattice.root_from_box().inverse()),
            inv_h: (1.0 / lattice.resolution_m()) as f32,
            half: lattice.dims().map(|n| 0.5 * n as f32),
        }
    }

    /// Cell coordinates of a root-frame point: cell `i` spans `[i, i + 1)`.
    #[inline]
    fn at(&self, p: [f32; 3]) -> [f32; 3] {
        let q = self.box_from_root.apply(p);
        std::array::from_fn(|r| q[r] * self.inv_h + self.half[r])
    }
}

/// A rigid transform rounded to f32 once, its rotation as a matrix, for the hot loops that
/// move many root-frame points into one frame (a lattice's box, a camera's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid32 {
    rotation: [[f32; 3]; 3],
    translation: [f32; 3],
}

impl Rigid32 {
    pub fn of(iso: &Isometry3<f64>) -> Self {
        let m = iso.rotation.to_rotation_matrix();
        let t = iso.translation.vector;
        Self {
            rotation: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32)),
            translation: [t.x as f32, t.y as f32, t.z as f32],
        }
    }

    #[inline]
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|r| {
            (0..3).map(|c| self.rotation[r][c] * p[c]).sum::<f32>() + self.translation[r]
        })
    }
}

/// The root-frame point of a point given in a link's frame, placed by `root_from_link`.
pub fn place(root_from_link: &Isometry3<f64>, centre: [f32; 3]) -> [f32; 3] {
    let p = root_from_link * Point3::from(centre.map(f64::from));
    [p.x as f32, p.y as f32, p.z as f32]
}
