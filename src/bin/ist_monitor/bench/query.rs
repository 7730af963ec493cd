//! `ist_monitor bench query`: error against run time of the query modes over sphere budgets,
//! on the scenes of `scenes.rs`, with the peers measured in the same run; then the settings
//! the node runs (self-filter on, per-link minima within `per_link_range`) on every scene.
//!
//! For every budget the trees are built (or loaded from the cache) and every mode is timed
//! (median of `runs` queries per pose, pooled over poses) with per-link minima on and off. The
//! peers take every point as an obstacle, so the engine runs here without its self-filter (and
//! with the default region of interest, 2 m, which holds every point of these scenes). The
//! error is taken against the exact distance of peer (a) (parry3d, every point and link, no
//! pruning; peer (b) on the stress scenes, where (a) would take minutes, and the generator's
//! truth on the generated scenes): `upper − exact` for fast, `exact − lower` for certified (how
//! conservative the certified bound is), `|exact mode − exact|` for exact. Scenes that hold
//! the robot's own points (`robot_in_view`, `wrist`) have no peers and no sweep (every point
//! would be an obstacle at distance 0): only the node's settings, against the truth. The table goes to stdout, the rows to
//! JSON (`--json`) and the plot to a PNG (`--plot`; nothing is written unless asked).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use ist_monitor::ist::BuildOptions;
use ist_monitor::query::{peers, Backend, Engine, LinkSelection, Mode, QueryOptions, QueryResult};

use super::rows::{print_table, row, Row};
use super::scenes::{load_scenario, Case, Scenario, ScenarioName};
use crate::choice::choice;
use crate::setup::cached_trees;
use ist_monitor::choice::Choice;

#[derive(clap::Args)]
pub struct BenchQueryArgs {
    /// The shared data folder (default: ../shared beside the demo folder, or $IST_MONITOR_SHARED).
    #[arg(long)]
    shared: Option<PathBuf>,
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ScenarioName::Kinect, ScenarioName::Grabber, ScenarioName::RobotInView, ScenarioName::Wrist, ScenarioName::NearBlob, ScenarioName::Duplicates])]
    scenarios: Vec<ScenarioName>,
    /// Sphere budgets per link.
    #[arg(long, value_delimiter = ',', default_values_t = [64u32, 256, 1024, 4096, 8192, 16384])]
    budgets: Vec<u32>,
    #[arg(long, value_parser = choice::<Mode>(), value_delimiter = ',', default_values = Mode::ALL.iter().map(|m| m.name()))]
    modes: Vec<Mode>,
    /// Timed queries per pose and setting (the median is reported).
    #[arg(long, default_value_t = 20)]
    runs: usize,
    /// Timed runs of the slow peers (a) and (c) per pose.
    #[arg(long, default_value_t = 3)]
    peer_runs: usize,
    /// Peer (c), brute force over all spheres, only up to this budget (its cost grows with it).
    #[arg(long, default_value_t = 1024)]
    brute_force_max_budget: u32,
    /// Skip the peers (quick profiling of the engine alone; errors then need no reference).
    #[arg(long)]
    no_peers: bool,
    /// Tree cache folder (default as for `build`).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Write a PNG plot per scenario to PREFIX_<scenario>.png (the figures of docs/benchmarks.md:
    /// --plot docs/error_vs_time).
    #[arg(long, value_name = "PREFIX")]
    plot: Option<PathBuf>,
    /// A TrueType font for the plot's text (default: DejaVu Sans or another sans-serif font
    /// found in the system's font folders).
    #[arg(long)]
    font: Option<PathBuf>,
    /// Write every row as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Where the engine's queries run (the peers always run on the CPU).
    #[arg(long, value_parser = choice::<Backend>(), default_value = Backend::Cpu.name())]
    backend: Backend,
    /// The trees of the node-settings rows: most spheres per link (parameter max_spheres;
    /// equal to --node-start-spheres for a fixed budget).
    #[arg(long, default_value = crate::args::param("max_spheres"))]
    node_max_spheres: u32,
    /// The trees of the node-settings rows: the budget a link starts with (start_spheres).
    #[arg(long, default_value = crate::args::param("start_spheres"))]
    node_start_spheres: u32,
}

fn time<T>(runs: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, T) {
    let mut out = f();
    let mut samples = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t = Instant::now();
        out = std::hint::black_box(f());
        samples.push(t.elapsed().as_secs_f64() * 1e3);
    }
    (samples, out)
}

/// Every case timed `runs` times with `options` (one untimed query first): the samples of all
/// cases, and each case's result.
fn time_cases(
    engine: &mut Engine,
    cases: &[Case],
    runs: usize,
    options: &QueryOptions,
) -> Result<(Vec<f64>, Vec<QueryResult>)> {
    let mut samples = Vec::new();
    let mut results = Vec::new();
    for case in cases {
        let (s, r) = time(runs, || {
            engine.query_image(
                &case.points,
                case.width,
                &case.root_from_sensor,
                &case.link_poses,
                options,
            )
        });
        samples.extend(s);
        results.push(r?);
    }
    Ok((samples, results))
}

/// Error of a result against the exact distance, mm: `upper − exact` (fast), `exact − lower`
/// (certified), `|exact mode − exact|` (exact).
fn error_mm(mode: Mode, n: &ist_monitor::query::Nearest, exact: f64) -> f64 {
    1e3 * match mode {
        Mode::Fast => n.distance_m - exact,
        Mode::Certified => exact - n.lower_m.unwrap_or(0.0),
        Mode::Exact => (n.distance_m - exact).abs(),
    }
}

/// The node's settings, timed on every scene at the default budget: (label, options).
fn node_settings(backend: Backend) -> Vec<(&'static str, QueryOptions)> {
    let node = QueryOptions {
        backend,
        ..QueryOptions::default()
    };
    vec![
        ("node defaults: certified, per-link ≤ 0.32 m", node.clone()),
        (
            "certified, every link measured",
            QueryOptions {
                per_link_range_m: f32::INFINITY,
                ..node.clone()
            },
        ),
        (
            "fast, global",
            QueryOptions {
                mode: Mode::Fast,
                per_link: false,
                ..node.clone()
            },
        ),
        (
            "exact, global",
            QueryOptions {
                mode: Mode::Exact,
                per_link: false,
                ..node.clone()
            },
        ),
        (
            "exact, per-link ≤ 0.32 m",
            QueryOptions {
                mode: Mode::Exact,
                ..node
            },
        ),
    ]
}

pub fn bench_query(args: BenchQueryArgs) -> Result<()> {
    if args.runs == 0 || args.peer_runs == 0 {
        bail!("--runs and --peer-runs must be at least 1");
    }
    println!(
        "bench query: {} threads, {} runs per pose and setting, {} per slow peer",
        rayon::current_num_threads(),
        args.runs,
        args.peer_runs
    );
    let demo = crate::demo::dir()?;
    let mut rows = Vec::new();
    for &name in &args.scenarios {
        let shared = if name.needs_shared() {
            crate::demo::shared(&args.shared)?
        } else {
            PathBuf::new()
        };
        let scenario = load_scenario(&shared, &demo, name)?;
        rows.extend(bench_scenario(&args, name, &scenario)?);
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One scene's rows: the floor, the exact peers, the node's settings and (without the robot
/// in view) the sweep over budgets; printed, and plotted when asked.
fn bench_scenario(
    args: &BenchQueryArgs,
    name: ScenarioName,
    scenario: &Scenario,
) -> Result<Vec<Row>> {
    let cases = &scenario.cases;
    let first = &cases[0].points;
    let valid = first
        .iter()
        .filter(|p| ist_monitor::query::is_valid_point(**p))
        .count();
    println!(
        "\n== {name:?}: {} ({} links), {} case(s) of {} points ({valid} valid in the first)",
        scenario.model.name,
        scenario.model.links.len(),
        cases.len(),
        first.len(),
    );
    let mut scenario_rows = Vec::new();
    // The floor and the exact peers do not depend on the budget: measured with the
    // node's trees (default: the node's default budget; peer (b) uses only the meshes).
    let mut node_build = BuildOptions::default();
    node_build.packing.max_spheres = args.node_max_spheres.max(1);
    node_build.packing.start_spheres = args.node_start_spheres.max(1);
    let default_trees = cached_trees(&scenario.model, &node_build, args.cache_dir.as_deref())?;
    let mut engine = Engine::new(&scenario.model, &default_trees, &LinkSelection::default())?;
    let mut floor = Vec::new();
    for case in cases {
        floor.extend(time(args.runs, || peers::touch_every_point(&case.points)).0);
    }
    scenario_rows.push(row(
        name,
        "floor (touch every point)",
        false,
        None,
        floor,
        &[],
    ));
    // The exact distance per case: the generator's truth, or peer (a) (peer (b) on the
    // stress scenes).
    // (all cases or none, so that reference[c] is case c's).
    let mut reference: Vec<f64> = cases
        .iter()
        .map(|c| c.truth_m)
        .collect::<Option<_>>()
        .unwrap_or_default();
    let peers = !args.no_peers && !scenario.robot_in_view;
    if peers {
        scenario_rows.extend(exact_peers(args, name, cases, &engine, &mut reference)?);
    }
    // The node's settings (self-filter on), at the default (grown) budget.
    for (label, options) in node_settings(args.backend) {
        let (samples, results) = time_cases(&mut engine, cases, args.runs, &options)?;
        let mut errors = Vec::new();
        for (r, &exact) in results.iter().zip(&reference) {
            if let Some(n) = &r.nearest {
                errors.push(error_mm(options.mode, n, exact));
            }
        }
        scenario_rows.push(row(
            name,
            &format!("{label}, self-filter"),
            options.per_link,
            // The default budget grows per link: the largest link's.
            default_trees.iter().map(|t| t.quality.budget as u32).max(),
            samples,
            &errors,
        ));
    }
    if scenario.robot_in_view {
        print_table(&scenario_rows);
        return Ok(scenario_rows);
    }
    for &budget in &args.budgets {
        scenario_rows.extend(budget_rows(
            args, name, scenario, budget, &reference, peers,
        )?);
    }
    print_table(&scenario_rows);
    if let Some(prefix) = &args.plot {
        let path = PathBuf::from(format!(
            "{}_{}.png",
            prefix.display(),
            format!("{name:?}").to_lowercase()
        ));
        super::plot::error_against_time(&path, args.font.as_deref(), name, &scenario_rows)
            .with_context(|| format!("plot {}", path.display()))?;
        println!("plot: {}", path.display());
    }
    Ok(scenario_rows)
}

/// The exact peers on every case, each case's exact distance appended to `reference`:
/// peer (a) (every point and link; only on the stress scenes) and peer (b) (shared bound),
/// which must agree.
fn exact_peers(
    args: &BenchQueryArgs,
    name: ScenarioName,
    cases: &[Case],
    engine: &Engine,
    reference: &mut Vec<f64>,
) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let slow = name.needs_shared();
    let (mut ta, mut tb) = (Vec::new(), Vec::new());
    for case in cases {
        let (points, sensor, lp) = (&case.points, &case.root_from_sensor, &case.link_poses);
        let a = if slow {
            let (s, a) = time(args.peer_runs, || {
                peers::exact_every_point(engine, points, sensor, lp)
            });
            ta.extend(s);
            Some(a.context("no valid point")?)
        } else {
            None
        };
        let (s, b) = time(args.runs, || {
            peers::exact_shared_bound(engine, points, sensor, lp)
        });
        tb.extend(s);
        let b = b.context("no valid point")?;
        let exact = a.as_ref().unwrap_or(&b);
        println!(
            "  {}: exact {:.4} m on {} (point {}); peer (b) {:.4} m",
            case.name,
            exact.distance,
            engine.links()[exact.link].name,
            exact.point,
            b.distance
        );
        if (exact.distance - b.distance).abs() > 1e-5 {
            bail!(
                "peer (b) {} differs from peer (a) {}",
                b.distance,
                exact.distance
            );
        }
        reference.push(exact.distance as f64);
    }
    if slow {
        rows.push(row(
            name,
            "(a) parry exact, every point",
            false,
            None,
            ta,
            &[],
        ));
    }
    rows.push(row(
        name,
        "(b) parry exact, shared bound",
        false,
        None,
        tb,
        &[],
    ));
    Ok(rows)
}

/// Every mode with per-link minima off and on at one fixed `budget`, and peer (c) (brute force
/// over the spheres) where it is asked for and affordable.
fn budget_rows(
    args: &BenchQueryArgs,
    name: ScenarioName,
    scenario: &Scenario,
    budget: u32,
    reference: &[f64],
    peers: bool,
) -> Result<Vec<Row>> {
    let cases = &scenario.cases;
    let mut rows = Vec::new();
    let mut options = BuildOptions::default();
    options.packing.max_spheres = budget;
    options.packing.start_spheres = budget;
    let trees = cached_trees(&scenario.model, &options, args.cache_dir.as_deref())?;
    let mut engine = Engine::new(&scenario.model, &trees, &LinkSelection::default())?;
    for &mode in &args.modes {
        for per_link in [false, true] {
            let options = QueryOptions {
                mode,
                per_link,
                per_link_range_m: f32::INFINITY,
                self_filter_padding_m: None,
                backend: args.backend,
                ..QueryOptions::default()
            };
            let (samples, results) = time_cases(&mut engine, cases, args.runs, &options)?;
            let mut errors = Vec::new();
            for (c, r) in results.iter().enumerate() {
                let n = r.nearest.as_ref().context("no nearest point")?;
                if let Some(&exact) = reference.get(c) {
                    errors.push(error_mm(mode, n, exact));
                }
            }
            rows.push(row(
                name,
                &format!("{mode:?}").to_lowercase(),
                per_link,
                Some(budget),
                samples,
                &errors,
            ));
        }
    }
    if peers && budget <= args.brute_force_max_budget && name.needs_shared() {
        let mut samples = Vec::new();
        let mut errors = Vec::new();
        for (c, case) in cases.iter().enumerate() {
            let (s, r) = time(args.peer_runs, || {
                peers::brute_force_spheres(
                    &engine,
                    &case.points,
                    &case.root_from_sensor,
                    &case.link_poses,
                )
            });
            samples.extend(s);
            let r = r.context("no valid point")?;
            errors.push(1e3 * (r.distance as f64 - reference[c]));
        }
        rows.push(row(
            name,
            "(c) brute force, all spheres",
            false,
            Some(budget),
            samples,
            &errors,
        ));
    }
    Ok(rows)
}
