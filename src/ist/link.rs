//! One link's tree, built: its elements packed (a sphere primitive gets its inscribed sphere),
//! the hierarchy built over the spheres, and the whole validated before it is returned; the h
//! the link reports is the one the validation measured.
//!
//! The budget starts at `start_spheres` and grows while h is above the link's target
//! (`target_gap_m`, or `target_gap_per_m` of a large link's diagonal). A link of one element
//! packs its volume to half of `start_spheres`, then runs its gap pass on towards the cap: first
//! until the surface samples are within 0.85 × target of the spheres, which usually gives h
//! within the target (h exceeds the samples' largest gap by a part of their spacing); the
//! packing's f32 estimate (`packing::gap`) checks it. If h is still above, the pass goes on to a
//! stop lowered by that excess, and at last to the samples' proof of the target. A link of
//! several elements grows its budget by rounds (an element's samples also lie on its surface
//! buried in the others, which needs no spheres): h ~ N^(−α), α fitted on the last two rounds
//! (about 1/2: spheres of h's size lining the surface), aiming a little under the target,
//! between 1.25× and 2× the last budget. Every decision depends on the rounds' values alone,
//! so the tree is the same on any number of threads.

use std::time::Instant;

use super::build;
use super::error::IstError;
use super::link_tree::{LinkQuality, LinkTree, StageTimes, Uncovered};
use super::options::BuildOptions;
use super::validate;
use crate::packing::gap::surface_gap;
use crate::packing::grid::SphereGrid;
use crate::packing::{pack_sphere, Packer, Packing, PackingParams};
use crate::robot::{LinkGeometry, TriangleFate};

/// Tolerance of the validation every tree passes, m.
pub const VALIDATION_TOLERANCE_M: f64 = 1e-6;

/// Packs every element of a link (a sphere primitive gets its inscribed sphere, which no packing
/// beats), estimates the gap, builds the tree and validates it (`validate`): a tree that fails
/// is an error naming the link, the file and the sphere; one that passes reports the h the
/// validation measured (the packing's estimate only decides the budget).
pub fn build_link(link: &LinkGeometry, options: &BuildOptions) -> Result<LinkTree, IstError> {
    let start = Instant::now();
    // The link's own target: `target_gap_m`, or a share of its size for a large link.
    let params = &PackingParams {
        target_gap_m: target_gap(link, &options.packing),
        ..options.packing.clone()
    };
    let mesh_volume_m3: f64 = link.elements.iter().map(|e| e.mesh.volume_m3).sum();
    let mut spheres = Vec::new();
    // A sphere primitive's inscribed sphere is its whole packing (no search needed); the other
    // elements grow with the link's budget.
    let mut packers: Vec<Element> = link
        .elements
        .iter()
        .map(|e| match e.sphere_center {
            Some(center) => Element::Fixed(pack_sphere(&e.mesh, center, params)),
            None => Element::Grows(Box::new(Packer::new(&e.mesh, params))),
        })
        .collect();
    let mut stages = StageTimes::default();
    let (budget, gap_m, gap_sampled_m) = grow(
        link,
        &mut packers,
        mesh_volume_m3,
        params,
        options,
        &mut stages,
    );
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

/// One element's packing in a link: growing, or a sphere primitive's inscribed sphere.
enum Element<'a> {
    Grows(Box<Packer<'a>>),
    Fixed(Packing),
}

/// Grows the link's packings until the packing's estimate of h (with the validation's slack) is
/// within `params.target_gap_m` or the budget is spent (the module's documentation says how);
/// the budget is split among the elements by their share of `mesh_volume_m3`, the link's.
/// Returns the budget, the estimate and the largest sampled gap, m.
fn grow(
    link: &LinkGeometry,
    packers: &mut [Element],
    mesh_volume_m3: f64,
    params: &PackingParams,
    options: &BuildOptions,
    stages: &mut StageTimes,
) -> (usize, f64, f64) {
    let cap = params.max_spheres.max(1) as usize;
    let mut budget = (params.start_spheres.max(1) as usize).min(cap);
    let target = params.target_gap_m as f64;
    // One element: the gap pass runs on to the cap, stopping first at `FIRST_STOP` × target
    // (the module's documentation says why). Several elements: rounds of a growing budget, each
    // gap pass proving the target on its element's own surface. A fixed budget (`start_spheres`
    // at the cap) has no second round: its gap pass proves the target at once, as far as the
    // budget goes.
    let single = link.elements.len() == 1;
    let mut stop = if single && budget < cap {
        FIRST_STOP * params.target_gap_m
    } else {
        0.0
    };
    // (budget, h estimate) of each round, for the next budget.
    let mut history: Vec<(usize, f64)> = Vec::new();
    let (gap_m, gap_sampled_m) = loop {
        let t = Instant::now();
        stages.rounds += 1;
        // Whether some growing element used (nearly) all of its budget: one that stopped
        // short has no room left for spheres of the minimal radius, and more budget is idle.
        let mut room = false;
        let mut sampled = None;
        let mut placed = 0;
        for (element, packer) in link.elements.iter().zip(packers.iter_mut()) {
            match packer {
                Element::Grows(packer) => {
                    let share = element.mesh.volume_m3 / mesh_volume_m3;
                    let element_budget = ((budget as f64 * share).round() as usize).max(1);
                    let gap_limit = if single { cap } else { element_budget };
                    sampled = packer.grow(element_budget, gap_limit, stop);
                    placed += packer.grid().spheres().len();
                    room |= packer.grid().spheres().len() >= element_budget * 9 / 10;
                }
                Element::Fixed(packing) => placed += packing.grid.spheres().len(),
            }
        }
        // The budget spent, where the gap pass went beyond the round's.
        budget = budget.max(placed.min(cap));
        stages.packing_s += t.elapsed().as_secs_f64();
        let ran_to = stop;
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
        if reported <= target || budget >= cap || !room {
            break (gap_m, gap_sampled_m);
        }
        if single {
            // h exceeded the samples' largest gap by `reported − worst`: the next stop aims h
            // at `AIM` × target by that excess (below the last stop, as h > target), down to the
            // proof; after the proof, more rounds would add only volume spheres.
            match sampled.filter(|_| ran_to > 0.0) {
                Some(worst) => {
                    let next = AIM * target - (reported - worst as f64);
                    stop = next.max(0.0) as f32;
                }
                None => break (gap_m, gap_sampled_m),
            }
        } else {
            history.push((budget, reported));
            budget = next_budget(&history, target, cap);
        }
    };
    (budget, gap_m, gap_sampled_m)
}

/// Where a one-element link's gap pass stops first, as a share of the target: the samples'
/// largest gap, which h exceeds by less than their spacing/√3 (0.29 × target) and in practice
/// by far less.
const FIRST_STOP: f32 = 0.85;
/// The h a grown budget aims at, as a share of the target (a little under it, so that one more
/// round is rarely needed).
const AIM: f64 = 0.9;

/// The next budget of a link whose h (estimated, the last of `history`'s (budget, h)) is still
/// above `target`: a packing that lines the surface with spheres of about h's size places
/// N ~ area/h² of them, so h ~ N^(−α) with α near 1/2; α is fitted on the last two rounds
/// (clamped to [1/4, 1]), and the budget that brings h to `AIM` × target is taken, at least
/// 1.25× and at most 2× the last, rounded up to an eighth of it (a power of two: 1024 from
/// 8192) and at most `cap`. Only the rounds' h decide it, so it is the same on any number of
/// threads.
fn next_budget(history: &[(usize, f64)], target: f64, cap: usize) -> usize {
    let &(n, h) = history.last().expect("a round");
    let alpha = match history {
        [.., (n0, h0), _] if h < *h0 && n > *n0 => {
            ((h0 / h).ln() / (n as f64 / *n0 as f64).ln()).clamp(0.25, 1.0)
        }
        _ => 0.5,
    };
    let wanted = n as f64 * (h / (AIM * target)).powf(1.0 / alpha);
    let next = wanted.clamp(1.25 * n as f64, 2.0 * n as f64).ceil() as usize;
    let step = (n / 8).max(1).next_power_of_two();
    (next.div_ceil(step) * step).min(2 * n).min(cap)
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

/// The surface gap a link is packed for, m: `target_gap_m`, or `target_gap_per_m` of its
/// bounding box's diagonal where that is larger.
pub fn target_gap(link: &LinkGeometry, params: &PackingParams) -> f32 {
    let (lo, hi) = link_bounds(link);
    let size_m = crate::geometry::dist(crate::geometry::widen(lo), crate::geometry::widen(hi));
    if size_m.is_finite() {
        params.link_target_gap(size_m)
    } else {
        params.target_gap_m
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_next_budget_aims_under_the_target_within_its_bounds() {
        let target = 0.0015;
        // One round: α = 1/2, so h 2.18 mm wants (2.18 / 1.35)² ≈ 2.6× the budget: at most 2×.
        assert_eq!(next_budget(&[(8192, 0.00218)], target, 65536), 16384);
        // Just above the target: at least 1.25×.
        assert_eq!(next_budget(&[(8192, 0.001501)], target, 65536), 10240);
        // Two rounds fit α: 2.04 → 1.529 mm from 8192 to 16384 is α ≈ 0.42, which wants
        // 16384 × (1.529 / 1.35)^(1/0.42) ≈ 22,000: rounded up to 2048s.
        assert_eq!(
            next_budget(&[(8192, 0.00204), (16384, 0.001529)], target, 65536),
            22528
        );
        // An h that did not fall (the gap pass stopped short) fits no α: 1/2, 2× at most.
        assert_eq!(
            next_budget(&[(8192, 0.003), (16384, 0.003)], target, 65536),
            32768
        );
        // A fall too steep for the fit is clamped at α = 1: 4 → 2 mm from 8192 to 10240 wants
        // 10240 × 2 / 1.35 ≈ 15,170, rounded up to 2048s.
        assert_eq!(
            next_budget(&[(8192, 0.004), (10240, 0.002)], target, 65536),
            16384
        );
        // Never beyond the cap.
        assert_eq!(next_budget(&[(49152, 0.002)], target, 65536), 65536);
    }

    #[test]
    fn a_large_link_is_packed_for_its_share_of_its_size() {
        let params = PackingParams::default();
        // Up to 0.6 m: target_gap.
        assert_eq!(params.link_target_gap(0.3), 0.0015);
        assert_eq!(params.link_target_gap(0.6), 0.0015);
        // 1.2 m: 3 mm.
        assert!((params.link_target_gap(1.2) - 0.003).abs() < 1e-7);
        // target_gap_per_m 0: target_gap on every link.
        let fine = PackingParams {
            target_gap_per_m: 0.0,
            ..params
        };
        assert_eq!(fine.link_target_gap(1.2), 0.0015);
    }
}
