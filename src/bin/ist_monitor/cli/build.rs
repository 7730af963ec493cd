//! `build` (pack, build, cache and report the trees of a robot) and `poses` (forward
//! kinematics).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;

use ist_monitor::ist::cache::TreeCache;
use ist_monitor::ist::{self, BuildOptions, LinkTree, Origin};
use ist_monitor::robot::{LinkGeometry, LinkSelection, RobotModel};

use crate::args::{parse_joint, RobotArgs, TreeArgs};
use crate::setup::build_trees;

#[derive(Args)]
pub struct BuildArgs {
    #[command(flatten)]
    trees: TreeArgs,
    /// Build everything anew and store nothing.
    #[arg(long)]
    no_cache: bool,
    /// Print the table as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Write {"<link>": [[x, y, z, r], ...]} (link frames, metres) to this file.
    #[arg(long, value_name = "FILE")]
    export_spheres: Option<PathBuf>,
    /// Print per link what its meshes needed (pieces read, welding, holes closed, shells) and
    /// what its validation checked. Every tree is validated whether or not this is given:
    /// before it is used, and before it is cached.
    #[arg(long)]
    validate: bool,
    /// Only these links (comma separated); the others' meshes are not read.
    #[arg(long, value_delimiter = ',')]
    links: Vec<String>,
    /// Leave these links out (comma separated); their meshes are not read.
    #[arg(long, value_delimiter = ',')]
    exclude_links: Vec<String>,
    /// Pack these links' convex hulls instead of their meshes (comma separated; '*': all).
    #[arg(long, value_delimiter = ',')]
    convex_hull_links: Vec<String>,
}

#[derive(Args)]
pub struct PosesArgs {
    #[command(flatten)]
    robot: RobotArgs,
    /// Joint values, NAME=VALUE,... (radians or metres); joints not named are 0.
    #[arg(long, value_delimiter = ',', value_parser = parse_joint)]
    joints: Vec<(String, f64)>,
}

#[derive(Serialize)]
struct LinkRow<'a> {
    name: &'a str,
    spheres: usize,
    /// The budget the link was packed with (grown from start_spheres while h was above the
    /// link's target).
    budget: usize,
    coverage: f64,
    /// The certified h the validation measured: the larger of the two below.
    gap_m: f64,
    /// h on the packed surface (the intake's closed meshes).
    elements_gap_m: f64,
    /// h on the mesh files' own triangles outside the solid (0: no file needed that pass).
    file_gap_m: f64,
    gap_sampled_m: f64,
    /// Largest distance sampled from the mesh files' own triangles to the spheres.
    file_gap_sampled_m: f64,
    /// The farthest point of the files' own triangles outside the solid where it is farther
    /// than the packed surface: element, triangle (index in the file as read), point, gap.
    uncovered: Option<ist::Uncovered>,
    /// What the intake did with that triangle (null: not in its record, or no such point).
    uncovered_fate: Option<ist_monitor::robot::TriangleFate>,
    /// This run's build, s; null for a tree from the cache.
    build_s: Option<f64>,
    /// Every tree passed validation: this run's, or the one before it was cached.
    validated: bool,
    /// This run's validation, s; null for a tree from the cache.
    validate_s: Option<f64>,
    /// Where this run's build went (packing, gap estimate, tree, rounds); null for a tree from
    /// the cache or shared.
    stages: Option<ist::StageTimes>,
    tree_volume_m3: f64,
    origin: Origin,
    from_cache: bool,
    warnings: Vec<String>,
    /// What the intake did to each mesh file, per collision element.
    intake: Vec<IntakeRow<'a>>,
}

#[derive(Serialize)]
struct IntakeRow<'a> {
    element: usize,
    file: String,
    summary: String,
    report: &'a ist_monitor::robot::MeshReport,
}

pub fn build(args: BuildArgs) -> Result<()> {
    let options = args.trees.packing.options()?;
    let selection = LinkSelection {
        include: args.links.clone(),
        exclude: args.exclude_links.clone(),
        convex_hull: args.convex_hull_links.clone(),
    };
    let model = args.trees.robot.load(&selection)?;
    // Names the selection gives that the robot does not have, before anything is built.
    selection.check(&model)?;
    if !model.skipped_links.is_empty() && !args.json {
        eprintln!(
            "links without collision geometry (skipped): {}",
            model.skipped_links.join(", ")
        );
    }
    let cache = (!args.no_cache).then(|| TreeCache::at(args.trees.cache_dir.as_deref()));
    let start = Instant::now();
    let trees = build_trees(&model, &options, cache.as_ref())?;
    let total_s = start.elapsed().as_secs_f64();
    if args.validate && !args.json {
        print_validation(&model, &trees);
    }
    let rows: Vec<LinkRow> = trees
        .iter()
        .zip(&model.links)
        .map(|((t, origin), geometry)| link_row(t, *origin, geometry, &options))
        .collect();
    if let Some(path) = &args.export_spheres {
        export_spheres(path, &trees)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "links": rows }))?
        );
        return Ok(());
    }
    print_table(&model, &rows, total_s);
    Ok(())
}

/// With `--validate`: per link, what its meshes needed and what its validation checked.
fn print_validation(model: &RobotModel, trees: &[(LinkTree, Origin)]) {
    for ((tree, origin), geometry) in trees.iter().zip(&model.links) {
        println!("link {}:", geometry.name);
        for e in &geometry.elements {
            println!(
                "  element {} ({}): {}, {} triangles, {:.3e} m³",
                e.index,
                e.source,
                match &e.mesh.fill {
                    Some(f) => format!(
                        "filled (inside by exterior flood fill, {:.2} mm voxels; the \
                             triangles facing the outside)",
                        f.voxel_m * 1e3
                    ),
                    None => "closed (inside by its orientation)".into(),
                },
                e.mesh.triangles.len(),
                e.mesh.volume_m3
            );
        }
        for i in &geometry.intake {
            println!("  mesh {}: {}", i.file.display(), i.report.summary());
        }
        if let Some(v) = geometry.hull_of_volume_m3 {
            println!(
                "  convex hull of {v:.3e} m³ of mesh: distances to it are lower bounds of the \
                     link's, its distance is the certified lower bound"
            );
        }
        println!(
            "  checked ({}): {} spheres inside the solid (centre inside by ray winding number or \
             flood fill, radius within the f64 distance to the surface), no overlap beyond \
             {tol:.0e} m, every node bounds its children; h measured (certified, f64): {:.3} mm \
             on the packed surface, {:.3} mm on the files' own triangles outside the solid \
             (largest sampled there {:.3} mm); the link reports {:.3} mm",
            match origin {
                Origin::Cache => "before it was cached".to_string(),
                Origin::Shared => "as the link whose solid it shares".to_string(),
                Origin::Built => format!("{:.2} s", tree.quality.validate_s),
            },
            tree.spheres.len(),
            tree.quality.elements_gap_m * 1e3,
            tree.quality.file_gap_m * 1e3,
            tree.quality.file_gap_sampled_m * 1e3,
            tree.quality.gap_m * 1e3,
            tol = ist::VALIDATION_TOLERANCE_M,
        );
        if let Some(u) = &tree.quality.uncovered {
            println!("  {}", ist::describe_uncovered(u, &tree.quality, geometry));
        }
    }
}

/// A link's row, with a warning where its packing fell short of the options.
fn link_row<'a>(
    t: &'a LinkTree,
    origin: Origin,
    geometry: &'a LinkGeometry,
    options: &BuildOptions,
) -> LinkRow<'a> {
    // A cached or shared tree took no time in this build.
    let cached = origin != Origin::Built;
    let mut warnings = Vec::new();
    if t.quality.coverage > 1.0 {
        warnings.push(format!(
            "coverage {:.1} % above 100 %: the link's elements overlap, and so do their \
                     spheres",
            100.0 * t.quality.coverage
        ));
    }
    let set_by_file =
        t.quality.uncovered.is_some() && t.quality.file_gap_m > t.quality.elements_gap_m;
    if let Some(u) = &t.quality.uncovered {
        warnings.push(ist::describe_uncovered(u, &t.quality, geometry));
    }
    let target = ist::target_gap(geometry, &options.packing);
    if t.quality.gap_m > target as f64 {
        warnings.push(format!(
            "h {:.3} mm above the target {:.3} mm at a budget of {} spheres ({})",
            1e3 * t.quality.gap_m,
            1e3 * target,
            t.quality.budget,
            if set_by_file {
                "set by the file's own surface outside the solid: more spheres cannot lower it"
            } else if t.quality.budget >= options.packing.max_spheres as usize {
                "the cap max_spheres"
            } else {
                "the packing found no room for more spheres of min_radius"
            }
        ));
    }
    if let Some(w) = ist::absurd_gap(&t.quality, geometry) {
        warnings.push(w);
    }
    LinkRow {
        name: &t.link,
        spheres: t.quality.spheres,
        budget: t.quality.budget,
        coverage: t.quality.coverage,
        gap_m: t.quality.gap_m,
        elements_gap_m: t.quality.elements_gap_m,
        file_gap_m: t.quality.file_gap_m,
        gap_sampled_m: t.quality.gap_sampled_m,
        file_gap_sampled_m: t.quality.file_gap_sampled_m,
        uncovered: t.quality.uncovered,
        uncovered_fate: t
            .quality
            .uncovered
            .and_then(|u| ist::uncovered_fate(&u, geometry)),
        build_s: (!cached).then_some(t.quality.build_s),
        validated: true,
        validate_s: (!cached).then_some(t.quality.validate_s),
        stages: (!cached).then_some(t.quality.stages),
        tree_volume_m3: t.quality.tree_volume_m3,
        origin,
        from_cache: origin == Origin::Cache,
        warnings,
        intake: geometry
            .intake
            .iter()
            .map(|i| IntakeRow {
                element: i.element,
                file: i.file.display().to_string(),
                summary: i.report.summary(),
                report: &i.report,
            })
            .collect(),
    }
}

/// The table of the links (the default output).
fn print_table(model: &RobotModel, rows: &[LinkRow], total_s: f64) {
    println!(
        "robot {} ({}), {} links",
        model.name,
        model.urdf_path.display(),
        rows.len()
    );
    println!(
        "{:<24} {:>8} {:>9} {:>8} {:>9} {:>10} {:>7}",
        "link", "spheres", "coverage", "h [mm]", "build [s]", "valid. [s]", "from"
    );
    for r in rows {
        println!(
            "{:<24} {:>8} {:>8.1}% {:>8.3} {:>9} {:>10} {:>7}{}",
            r.name,
            r.spheres,
            100.0 * r.coverage,
            1e3 * r.gap_m,
            r.build_s.map_or("-".into(), |s| format!("{s:.2}")),
            r.validate_s.map_or("-".into(), |s| format!("{s:.2}")),
            match r.origin {
                Origin::Built => "built",
                Origin::Cache => "cache",
                Origin::Shared => "shared",
            },
            if r.warnings.is_empty() { "" } else { "  (!)" }
        );
        for w in &r.warnings {
            println!("  {}: {w}", r.name);
        }
    }
    println!(
        "total {total_s:.2} s; every tree validated (f64: spheres inside; h the bound measured \
         on the packed surface and the files' own triangles){}",
        if rows.iter().any(|r| r.from_cache) {
            "; cached trees were validated before they were stored"
        } else {
            ""
        }
    );
}

fn export_spheres(path: &Path, trees: &[(LinkTree, Origin)]) -> Result<()> {
    let map: serde_json::Map<String, serde_json::Value> = trees
        .iter()
        .map(|(t, _)| {
            let spheres: Vec<[f32; 4]> = t
                .spheres
                .iter()
                .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
                .collect();
            (t.link.clone(), serde_json::json!(spheres))
        })
        .collect();
    std::fs::write(path, serde_json::to_string(&map)?)
        .with_context(|| format!("writing {}", path.display()))
}

pub fn poses(args: PosesArgs) -> Result<()> {
    let model = args.robot.load(&Default::default())?;
    let k = &model.kinematics;
    let q = k.values_from_names(&args.joints, Some(0.0))?;
    let poses = k.link_poses(&q);
    println!(
        "{:<24} {:>9} {:>9} {:>9}   (root frame {}, m)",
        "link",
        "x",
        "y",
        "z",
        k.root_link()
    );
    for (name, pose) in k.link_names().iter().zip(&poses) {
        let t = pose.translation.vector;
        println!("{name:<24} {:>9.4} {:>9.4} {:>9.4}", t.x, t.y, t.z);
    }
    Ok(())
}
