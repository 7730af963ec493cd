//! Inner sphere tree (IST) stage: per link, the inner spheres from `packing`, a hierarchy of
//! bounding spheres over them (`build`), the measured quality (coverage and surface gap h), a
//! cache (`cache`) and checks (`validate`).
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
use crate::packing::{gap::surface_gap, pack, pack_sphere, PackingParams};
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
    /// Sphere volume / mesh volume.
    pub coverage: f64,
    /// Certified upper bound of the surface gap h, m (tessellation error of primitives included).
    pub gap_m: f64,
    /// Largest sampled surface-to-spheres distance, m (h lies in [gap_sampled_m, gap_m]).
    pub gap_sampled_m: f64,
    pub mesh_volume_m3: f64,
    /// Sum of the node sphere volumes, m³.
    pub tree_volume_m3: f64,
    /// Wall time of the build (packing, gap and tree), s.
    pub build_s: f64,
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
}

/// Packs every element of a link (a sphere primitive gets its inscribed sphere, which no packing
/// beats), measures the gap and builds the tree.
pub fn build_link(link: &LinkGeometry, options: &BuildOptions) -> Result<LinkTree, IstError> {
    let start = Instant::now();
    let params = &options.packing;
    let mesh_volume_m3: f64 = link.elements.iter().map(|e| e.mesh.volume_m3).sum();
    let mut spheres = Vec::new();
    let mut gap_m = 0.0f64;
    let mut gap_sampled_m = 0.0f64;
    let mut packings = Vec::with_capacity(link.elements.len());
    for element in &link.elements {
        let share = element.mesh.volume_m3 / mesh_volume_m3;
        let budget = ((params.max_spheres as f64 * share).round() as usize).max(1);
        let t = Instant::now();
        let packing = match element.sphere_center {
            // A sphere primitive: its inscribed sphere is the whole packing (no search needed).
            Some(center) => pack_sphere(&element.mesh, center, params),
            None => pack(&element.mesh, budget, params),
        };
        log::debug!(
            "link {} element {}: {} spheres, {} settles, packed in {:.2} s",
            link.name,
            element.index,
            packing.grid.spheres().len(),
            packing.settles,
            t.elapsed().as_secs_f64(),
        );
        packings.push(packing);
    }
    // The gap of each element's surface against all the link's spheres: the link's solid is
    // the union of its elements, so a sphere of one element covers the surface of another
    // that lies against it (a mesh file's shells, overlapping primitives). With one element
    // that is its own packing's grid.
    let union = (packings.len() > 1).then(|| {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for e in &link.elements {
            let (a, b) = e.mesh.bounds();
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        let mut grid = SphereGrid::new(lo, hi, 2.0 * params.min_radius_m);
        for p in &packings {
            for s in p.grid.spheres() {
                grid.insert(*s);
            }
        }
        grid
    });
    for (element, packing) in link.elements.iter().zip(&packings) {
        let t = Instant::now();
        let gap = surface_gap(
            &element.mesh,
            union.as_ref().unwrap_or(&packing.grid),
            options.gap_tolerance_m,
        );
        log::debug!(
            "link {} element {}: gap in {:.2} s, h {:.2} mm at {:?}",
            link.name,
            element.index,
            t.elapsed().as_secs_f64(),
            gap.upper_m * 1e3,
            gap.worst_point
        );
        gap_m = gap_m.max(gap.upper_m as f64 + element.tessellation_error_m);
        gap_sampled_m = gap_sampled_m.max(gap.lower_m as f64);
    }
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
    Ok(LinkTree {
        link: link.name.clone(),
        quality: LinkQuality {
            spheres: spheres.len(),
            coverage: sphere_volume / mesh_volume_m3,
            gap_m,
            gap_sampled_m,
            mesh_volume_m3,
            tree_volume_m3: build::tree_volume(&nodes),
            build_s: start.elapsed().as_secs_f64(),
        },
        nodes,
        spheres,
    })
}

/// Where a link's tree came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    Built,
    Cache,
}

/// Trees of every link with collision geometry, from the cache where it holds a valid entry,
/// built (and stored) otherwise; `done` is called as each link finishes. Links are built in
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
