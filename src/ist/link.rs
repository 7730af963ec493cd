//! One link's tree, built: its elements packed (a sphere primitive gets its inscribed sphere),
//! the budget doubled from `start_spheres` while the packing's estimate of h is above
//! `target_gap_m`, the hierarchy built over the spheres, and the whole validated before it is
//! returned; the h the link reports is the one the validation measured. Input: the link's
//! collision geometry (link frame, m); output: a [`LinkTree`] or an [`IstError`]; a part of a
//! file the packing cannot reach, or an absurd h, is logged as a warning naming the file.

use std::time::Instant;

use super::build;
use super::error::IstError;
use super::link_tree::{LinkQuality, LinkTree, StageTimes, Uncovered};
use super::options::BuildOptions;
use super::validate;
use crate::packing::gap::surface_gap;
use crate::packing::grid::SphereGrid;
use crate::packing::{pack_sphere, Packer, Packing};
use crate::robot::{LinkGeometry, TriangleFate};

/// Tolerance of the validation every tree passes, m.
pub const VALIDATION_TOLERANCE_M: f64 = 1e-6;

/// Packs every element of a link (a sphere primitive gets its inscribed sphere, which no packing
/// beats), estimates the gap, builds the tree and validates it (`validate`): a tree that fails
/// is an error naming the link, the file and the sphere; one that passes reports the h the
/// validation measured (the packing's estimate only decides the budget).
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
    let mut stages = StageTimes::default();
    let (gap_m, gap_sampled_m) = loop {
        let t = Instant::now();
        stages.rounds += 1;
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
        stages.packing_s += t.elapsed().as_secs_f64();
        let t_gap = Instant::now();
        let grids: Vec<&SphereGrid> = packers
            .iter()
            .map(|p| match p {
                Element::Grows(packer) => packer.grid(),
                Element::Fixed(packing) => &packing.grid,
            })
            .collect();
        let (gap_m, gap_sampled_m) = link_gap(link, &grids, options);
        stages.gap_estimate_s += t_gap.elapsed().as_secs_f64();
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
    let t_tree = Instant::now();
    let (nodes, spheres) = build::build_tree(spheres, options.tree);
    stages.tree_s = t_tree.elapsed().as_secs_f64();
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
            stages,
            elements_gap_m: gap_m,
            file_gap_m: 0.0,
            file_gap_sampled_m: 0.0,
            uncovered: None,
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
    // The h the independent check measured is the one the link reports.
    tree.quality.gap_m = checked.gap_m;
    tree.quality.elements_gap_m = checked.elements_gap_m;
    tree.quality.file_gap_m = checked.file_gap_m;
    tree.quality.validate_s = checked.seconds;
    tree.quality.file_gap_sampled_m = checked.file_gap_sampled_m;
    tree.quality.uncovered = checked.uncovered.first().copied();
    for u in &checked.uncovered {
        log::warn!(
            "link {}: {}",
            link.name,
            describe_uncovered(u, &tree.quality, link)
        );
    }
    if let Some(w) = absurd_gap(&tree.quality, link) {
        log::warn!("link {}: {w}", link.name);
    }
    Ok(tree)
}

/// Above this h, m, (or above the link's own size) a link's h is absurd for monitoring: it is
/// still certified, and reported loudly rather than refused.
pub const ABSURD_GAP_M: f64 = 0.05;

/// The file an element's mesh came from, or the element's source.
fn element_source(link: &LinkGeometry, element: usize) -> String {
    match link.intake.iter().find(|i| i.element == element) {
        Some(i) => format!("mesh {}", i.file.display()),
        None => format!("collision element {element}"),
    }
}

/// What the intake did with the triangle of an [`Uncovered`] point; None for a triangle the
/// intake never saw.
pub fn uncovered_fate(u: &Uncovered, link: &LinkGeometry) -> Option<TriangleFate> {
    link.intake
        .iter()
        .find(|i| i.element == u.element)
        .and_then(|i| i.fates.get(u.triangle).copied())
}

/// Says where a file's own triangles are farther from the spheres than the packed surface, and
/// what the intake did with that triangle (from the intake of this load: it is deterministic,
/// so a cached tree's triangle is the same).
pub fn describe_uncovered(u: &Uncovered, quality: &LinkQuality, link: &LinkGeometry) -> String {
    let fate =
        uncovered_fate(u, link).map_or("not in the intake's record".into(), |f| f.describe());
    format!(
        "{} triangle {} (as read; {fate}): the point [{:.5}, {:.5}, {:.5}] (link frame, m) lies \
         {:.4} mm from every sphere and outside the link's solid, {:.4} mm from the packed \
         surface (more spheres cannot reach it); h is {:.4} mm (the packed surface alone: {:.4} \
         mm)",
        element_source(link, u.element),
        u.triangle,
        u.point[0],
        u.point[1],
        u.point[2],
        u.gap_m * 1e3,
        u.packed_surface_m * 1e3,
        quality.gap_m * 1e3,
        quality.elements_gap_m * 1e3
    )
}

/// A warning when the link's h is absurd: above [`ABSURD_GAP_M`] or the diagonal of the link's
/// bounding box, naming the file that sets it.
pub fn absurd_gap(quality: &LinkQuality, link: &LinkGeometry) -> Option<String> {
    let (lo, hi) = link_bounds(link);
    let size_m = crate::geometry::dist(crate::geometry::widen(lo), crate::geometry::widen(hi));
    (quality.gap_m > ABSURD_GAP_M.min(size_m)).then(|| {
        format!(
            "h {:.2} mm is absurd for a link of {:.1} mm (above the smaller of {:.0} mm and its \
             size), set by {}: check that file",
            quality.gap_m * 1e3,
            size_m * 1e3,
            ABSURD_GAP_M * 1e3,
            match &quality.uncovered {
                Some(u) => format!(
                    "{} triangle {}",
                    element_source(link, u.element),
                    u.triangle
                ),
                None => {
                    let mut sources: Vec<&str> =
                        link.elements.iter().map(|e| e.source.as_str()).collect();
                    sources.dedup();
                    format!("the packed surface of {}", sources.join(", "))
                }
            }
        )
    })
}

/// The packing's estimate of a link's h (its elements' surfaces against all its spheres in f32,
/// primitives' tessellation error added), which decides the budget, and the largest sampled
/// gap, m.
fn link_gap(link: &LinkGeometry, grids: &[&SphereGrid], options: &BuildOptions) -> (f64, f64) {
    // The link's solid is the union of its elements, so a sphere of one element covers the
    // surface of another that lies against it (a mesh file's shells, overlapping
    // primitives). With one element that is its own packing's grid.
    let union = (grids.len() > 1).then(|| {
        let (lo, hi) = link_bounds(link);
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

/// The bounding box of a link's elements, link frame, m.
fn link_bounds(link: &LinkGeometry) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for e in &link.elements {
        let (a, b) = e.mesh.bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    (lo, hi)
}
