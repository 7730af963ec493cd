//! One link's tree, built: its elements packed (a sphere primitive gets its inscribed sphere),
//! the budget doubled from `start_spheres` while the certified h is above `target_gap_m`, the
//! hierarchy built over the spheres, and the whole validated before it is returned. Input: the
//! link's collision geometry (link frame, m); output: a [`LinkTree`] or an [`IstError`].

use std::time::Instant;

use super::build;
use super::error::IstError;
use super::link_tree::{LinkQuality, LinkTree};
use super::options::BuildOptions;
use super::validate;
use crate::packing::gap::surface_gap;
use crate::packing::grid::SphereGrid;
use crate::packing::{pack_sphere, Packer, Packing};
use crate::robot::LinkGeometry;

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
