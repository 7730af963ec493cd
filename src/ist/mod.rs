//! Inner sphere tree (IST) stage: per link, the inner spheres from `packing` (the budget grown
//! from `start_spheres`, doubling while the link's certified h is above `target_gap_m`, up to
//! `max_spheres`), a hierarchy of bounding spheres over them (`build`), the measured quality
//! (coverage and surface gap h), the checks every tree passes before it is used or cached
//! (`validate`: the h they certify is the h reported) and the cache (`cache`).
//!
//! Output, per link and in the link frame: two flat `#[repr(C)]` Pod arrays, `nodes` (root at 0)
//! and `spheres`, which the CPU traversal walks and the GPU uploads as they are. Building a link
//! costs its packing (seconds); loading it from the cache costs a file read.

pub mod build;
pub mod cache;
pub mod validate;

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::packing::grid::SphereGrid;
pub use crate::packing::InnerSphere;
use crate::packing::{gap::surface_gap, pack_sphere, Packer, Packing, PackingParams};
use crate::robot::{LinkGeometry, RobotModel};
pub use build::TreeBuilder;
use cache::TreeCache;

/// A node of an inner sphere tree: a sphere bounding its children, which are
/// `child_count` consecutive entries from `first_child` of the node array, or of the sphere
/// array when `children_are_spheres` is 1. WGSL mirror (32 bytes): `Node` in
/// `shaders/traverse.wgsl`, checked member by member against `query::layout::MIRRORS`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct IstNode {
    pub center: [f32; 3],
    pub radius: f32,
    pub first_child: u32,
    pub child_count: u32,
    pub children_are_spheres: u32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<IstNode>() == 32);

/// Measured quality of a link's packing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinkQuality {
    pub spheres: usize,
    /// The sphere budget the link was packed with: `start_spheres`, doubled while its h was
    /// above `target_gap_m`, up to `max_spheres`.
    pub budget: usize,
    /// Sphere volume / mesh volume.
    pub coverage: f64,
    /// Certified upper bound of the surface gap h, m (tessellation error of primitives
    /// included): the bound `validate` confirmed, in f64, on the packed surface and on the
    /// mesh files' own triangles.
    pub gap_m: f64,
    /// Largest sampled surface-to-spheres distance, m (h lies in [gap_sampled_m, gap_m]).
    pub gap_sampled_m: f64,
    pub mesh_volume_m3: f64,
    /// Sum of the node sphere volumes, m³.
    pub tree_volume_m3: f64,
    /// Wall time of the build (packing, gap and tree), s; 0 for a tree from the cache (the
    /// cache stores no times).
    pub build_s: f64,
    /// Wall time of its validation (`validate`), s; 0 for a tree from the cache, which was
    /// validated before it was stored.
    pub validate_s: f64,
    /// Largest distance sampled from the mesh files' own triangles, outside the solid, to the
    /// spheres, m (validation certified it at most `gap_m` + 1e-6 m).
    pub file_gap_sampled_m: f64,
}

/// The inner sphere tree of one link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkTree {
    pub link: String,
    pub nodes: Vec<IstNode>,
    pub spheres: Vec<InnerSphere>,
    pub quality: LinkQuality,
}

/// Everything that decides the trees besides the meshes (part of the cache key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuildOptions {
    pub packing: PackingParams,
    pub tree: TreeBuilder,
    /// Accuracy of the surface gap's branch and bound, m.
    pub gap_tolerance_m: f32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            packing: PackingParams::default(),
            tree: TreeBuilder::NeuralGas,
            gap_tolerance_m: 2e-5,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum IstError {
    #[error("link {link}: no inner sphere fits (every element is thinner than 2 × min_radius_m = {min_radius_m} m)")]
    NoSpheres { link: String, min_radius_m: f32 },
    #[error("the tree fails its validation and is refused (not cached, not used): {0}")]
    Invalid(#[from] validate::ValidationError),
}

/// Tolerance of the validation every tree passes, m.
pub const VALIDATION_TOLERANCE_M: f64 = 1e-6;

/// Packs every element of a link (a sphere primitive gets its inscribed sphere, which no packing
/// beats), measures the gap, builds the tree and validates it (`validate`): a tree that fails
/// is an error naming the link and the sphere or surface point.
pub fn build_link(link: &LinkGeometry, options: &BuildOptions) -> Result<LinkTree, IstError> {
    let start = Instant::now();
    let params = &options.packing;
    let mesh_volume_m3: f64 = link.elements.iter().map(|e| e.mesh.volume_m3).sum();
    let mut spheres = Vec::new();
    // A sphere primitive's inscribed sphere is its whole packing (no search needed); the other
    // elements grow with the link's budget.
    enum Element<'a> {
        Grows(Box<Packer<'a>>),
        Fixed(Packing),
    }
    let mut packers: Vec<Element> = link
        .elements
        .iter()
        .map(|e| match e.sphere_center {
            Some(center) => Element::Fixed(pack_sphere(&e.mesh, center, params)),
            None => Element::Grows(Box::new(Packer::new(&e.mesh, params))),
        })
        .collect();
    let cap = params.max_spheres.max(1) as usize;
    let mut budget = (params.start_spheres.max(1) as usize).min(cap);
    let (gap_m, gap_sampled_m) = loop {
        let t = Instant::now();
        // Whether some growing element used (nearly) all of its budget: one that stopped
        // short has no room left for spheres of the minimal radius, and more budget is idle.
        let mut room = false;
        for (element, packer) in link.elements.iter().zip(&mut packers) {
            if let Element::Grows(packer) = packer {
                let share = element.mesh.volume_m3 / mesh_volume_m3;
                let element_budget = ((budget as f64 * share).round() as usize).max(1);
                packer.grow(element_budget);
                room |= packer.grid().spheres().len() >= element_budget * 9 / 10;
            }
        }
        let grids: Vec<&SphereGrid> = packers
            .iter()
            .map(|p| match p {
                Element::Grows(packer) => packer.grid(),
                Element::Fixed(packing) => &packing.grid,
            })
            .collect();
        let (gap_m, gap_sampled_m) = link_gap(link, &grids, options);
        log::debug!(
            "link {}: budget {budget}, {} spheres, h {:.3} mm ({:.2} s)",
            link.name,
            grids.iter().map(|g| g.spheres().len()).sum::<usize>(),
            gap_m * 1e3,
            t.elapsed().as_secs_f64()
        );
        // Grown while h (as it will be reported: the validation certifies it with its slack
        // added) is above the target, the cap allows, and the budget is used.
        let reported = gap_m + options.gap_tolerance_m as f64 + VALIDATION_TOLERANCE_M;
        if reported <= params.target_gap_m as f64 || budget >= cap || !room {
            break (gap_m, gap_sampled_m);
        }
        budget = (2 * budget).min(cap);
    };
    let packings: Vec<Packing> = packers
        .into_iter()
        .map(|p| match p {
            Element::Grows(packer) => packer.finish(),
            Element::Fixed(packing) => packing,
        })
        .collect();
    for packing in packings {
        spheres.extend(packing.grid.into_spheres());
    }
    if spheres.is_empty() {
        return Err(IstError::NoSpheres {
            link: link.name.clone(),
            min_radius_m: params.min_radius_m,
        });
    }
    let sphere_volume: f64 = spheres
        .iter()
        .map(|s| crate::geometry::ball_volume(s.radius as f64))
        .sum();
    let (nodes, spheres) = build::build_tree(spheres, options.tree);
    let mut tree = LinkTree {
        link: link.name.clone(),
        quality: LinkQuality {
            spheres: spheres.len(),
            budget,
            coverage: sphere_volume / mesh_volume_m3,
            gap_m,
            gap_sampled_m,
            mesh_volume_m3,
            tree_volume_m3: build::tree_volume(&nodes),
            build_s: start.elapsed().as_secs_f64(),
            validate_s: 0.0,
            file_gap_sampled_m: 0.0,
        },
        nodes,
        spheres,
    };
    let checked = validate::validate_link(
        &tree,
        link,
        VALIDATION_TOLERANCE_M,
        options.gap_tolerance_m as f64,
    )?;
    // The h the independent check certified is the one the link reports.
    tree.quality.gap_m = checked.gap_m;
    tree.quality.validate_s = checked.seconds;
    tree.quality.file_gap_sampled_m = checked.file_gap_sampled_m;
    Ok(tree)
}

/// The certified gap h of a link (its elements' surfaces against all its spheres, primitives'
/// tessellation error added) and the largest sampled gap, m.
fn link_gap(link: &LinkGeometry, grids: &[&SphereGrid], options: &BuildOptions) -> (f64, f64) {
    // The link's solid is the union of its elements, so a sphere of one element covers the
    // surface of another that lies against it (a mesh file's shells, overlapping
    // primitives). With one element that is its own packing's grid.
    let union = (grids.len() > 1).then(|| {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for e in &link.elements {
            let (a, b) = e.mesh.bounds();
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        let mut grid = SphereGrid::new(lo, hi, 2.0 * options.packing.min_radius_m);
        for g in grids {
            for s in g.spheres() {
                grid.insert(*s);
            }
        }
        grid
    });
    let mut gap_m = 0.0f64;
    let mut gap_sampled_m = 0.0f64;
    for (element, grid) in link.elements.iter().zip(grids) {
        let gap = surface_gap(
            &element.mesh,
            union.as_ref().unwrap_or(grid),
            options.gap_tolerance_m,
        );
        log::debug!(
            "link {} element {}: h {:.3} mm at {:?}",
            link.name,
            element.index,
            gap.upper_m * 1e3,
            gap.worst_point
        );
        gap_m = gap_m.max(gap.upper_m as f64 + element.tessellation_error_m);
        gap_sampled_m = gap_sampled_m.max(gap.lower_m as f64);
    }
    (gap_m, gap_sampled_m)
}

/// Where a link's tree came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    Built,
    Cache,
}

/// Trees of every link with collision geometry, from the cache where it holds a valid entry,
/// built, validated (and stored) otherwise: the cache holds validated trees only; `done` is called as each link finishes. Links are built in
/// parallel, and each packing is parallel inside.
pub fn build_robot(
    model: &RobotModel,
    options: &BuildOptions,
    cache: Option<&TreeCache>,
    done: &(dyn Fn(&str) + Sync),
) -> Result<Vec<(LinkTree, Origin)>, IstError> {
    build_links(model, &|_| true, options, cache, done)
}

/// As [`build_robot`], for the links whose name passes `selected` only.
pub fn build_links(
    model: &RobotModel,
    selected: &(dyn Fn(&str) -> bool + Sync),
    options: &BuildOptions,
    cache: Option<&TreeCache>,
    done: &(dyn Fn(&str) + Sync),
) -> Result<Vec<(LinkTree, Origin)>, IstError> {
    model
        .links
        .par_iter()
        .filter(|link| selected(&link.name))
        .map(|link| {
            let key = cache::key(link, options);
            if let Some(cache) = cache {
                match cache.load(&key, &link.name) {
                    Ok(Some(tree)) => {
                        done(&link.name);
                        return Ok((tree, Origin::Cache));
                    }
                    Ok(None) => {}
                    Err(e) => log::warn!("{e}; rebuilding link {}", link.name),
                }
            }
            let tree = build_link(link, options)?;
            if let Some(cache) = cache {
                if let Err(e) = cache.store(&key, &tree) {
                    log::warn!("{e}");
                }
            }
            done(&link.name);
            Ok((tree, Origin::Built))
        })
        .collect()
}
