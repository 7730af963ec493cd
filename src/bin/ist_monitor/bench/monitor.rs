//! `bench monitor`: what the monitor adds to the query on one real cloud (by default the Kinect
//! cloud of ../shared's MoveIt perception tutorial bag, with the Panda and
//! `config/panda_perception_tutorial.yaml`): the fusion across sources with the output messages
//! (one source, and two), the stray-point filter and ten exclusion volumes (placed where the
//! cloud has points, and where it has none: the filter's own cost), each as a ratio to the
//! decode + poses + query of the same frames; and the unseen space (`unseen_rows`). The variants
//! are alternated frame by frame in one run, so the machine's drift hits them alike. Each
//! monitor first replays the bag up to its first cloud (`primed`): a generated bag's joint
//! states place the robot as they do in `replay`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::bag::read_messages;
use ist_monitor::choice::Choice;
use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::SelfShadow;
use ist_monitor::monitor::replay::{replay_frames, Clock};
use ist_monitor::monitor::{Frame, Monitor};
use ist_monitor::stats::Spread;

use crate::args::ConfigArgs;
use crate::setup::monitor_from_config;

#[derive(Args)]
pub struct BenchMonitorArgs {
    /// Bag whose first cloud of the first source is measured (default: the Kinect bag of
    /// ../shared/bags/moveit_perception_tutorial).
    bag: Option<PathBuf>,
    #[command(flatten)]
    config: ConfigArgs,
    /// The shared data folder (default: ../shared beside the demo folder, or $IST_MONITOR_SHARED).
    #[arg(long)]
    shared: Option<PathBuf>,
    /// Timed frames per variant.
    #[arg(long, default_value_t = 200, value_parser = crate::args::parse_count)]
    runs: usize,
    /// Only the unseen-space rows.
    #[arg(long)]
    unseen_only: bool,
}

/// The bench's default config.
const CONFIG: &str = "config/panda_perception_tutorial.yaml";

/// A monitor of the config with `extra` parameters, [`primed`] with `bag`.
fn monitor(
    args: &BenchMonitorArgs,
    bag: &Path,
    extra: &[(impl AsRef<str>, impl AsRef<str>)],
) -> Result<Monitor> {
    let mut extra: Vec<(String, String)> = (extra.iter())
        .map(|(k, v)| (k.as_ref().to_owned(), v.as_ref().to_owned()))
        .collect();
    // The unobserved space only where a variant asks for it (its own row).
    if !extra.iter().any(|(k, _)| k == "unobserved") {
        extra.push(("unobserved".into(), "ignore".into()));
    }
    primed(monitor_from_config(args.config.load(CONFIG, &extra)?)?, bag)
}

pub fn bench_monitor(args: BenchMonitorArgs) -> Result<()> {
    let bag = match &args.bag {
        Some(b) => b.clone(),
        None => crate::demo::shared(&args.shared)?
            .join("bags/moveit_perception_tutorial/perception_tutorial_mcap"),
    };
    let mut plain = monitor(&args, &bag, &[] as &[(&str, &str)])?;
    let source = plain
        .config
        .sources
        .iter()
        .find(|s| s.enabled)
        .context("no enabled source")?;
    let (name, topic) = (source.name.clone(), source.topic.clone());
    let messages = read_messages(&bag, &|t, _| t == topic)
        .with_context(|| format!("reading {}", bag.display()))?;
    let Some(cloud) = messages.first() else {
        bail!("{}: no message on {topic}", bag.display());
    };
    let payload = &cloud.data;
    if args.unseen_only {
        return unseen_rows(&args, &bag, payload);
    }
    let sources = format!("[{name}, {name}_2]");
    let second_topic = format!("{name}_2.topic");
    let second = [
        ("sources", sources.as_str()),
        (&second_topic, "/bench/second"),
    ];
    let mut two = monitor(&args, &bag, &second)?;
    let mut stray = monitor(&args, &bag, &[("stray_filter.min_points", "4")])?;
    let root = plain.model.kinematics.root_link().to_owned();
    let mut excluding = monitor(&args, &bag, &ten_volumes(&root, 0.0, None))?;
    let mut excluding_nothing = monitor(&args, &bag, &ten_volumes(&root, 10.0, None))?;
    // The nine boxes as meshes (an STL of a 0.3 m box, 5 mm of padding).
    let stl = std::env::temp_dir().join(format!("ist_monitor_bench_{}.stl", std::process::id()));
    write_box_stl(&stl, 0.3).with_context(|| format!("writing {}", stl.display()))?;
    let meshes = monitor(&args, &bag, &ten_volumes(&root, 0.0, Some(&stl)));
    let _ = std::fs::remove_file(&stl);
    let mut excluding_meshes = meshes?;

    // Warm-up: the GPU probe (backend auto), the caches and the self-filter's grids.
    for m in [
        &mut plain,
        &mut two,
        &mut stray,
        &mut excluding,
        &mut excluding_nothing,
        &mut excluding_meshes,
    ] {
        for _ in 0..3 {
            cloud_frame(m, 0, payload);
        }
    }
    cloud_frame(&mut two, 1, payload);
    let (mut query, mut outputs, mut query_two, mut outputs_two, mut query_stray) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut query_excluding, mut query_excluding_nothing) = (Vec::new(), Vec::new());
    let mut query_meshes = Vec::new();

    let (mut rejected, mut excluded, mut excluded_far, mut excluded_meshes) = (0, 0, 0, 0);
    for run in 0..args.runs {
        let f = cloud_frame(&mut plain, 0, payload);
        if let Err(e) = &f.result {
            bail!("{}: the cloud is a fault: {e}", bag.display());
        }
        query.push(f.processing_s * 1e3);
        outputs.push(f.outputs_s * 1e3);
        let f = cloud_frame(&mut two, run % 2, payload);
        query_two.push(f.processing_s * 1e3);
        outputs_two.push(f.outputs_s * 1e3);
        let f = cloud_frame(&mut stray, 0, payload);
        query_stray.push(f.processing_s * 1e3);
        rejected += f.result.as_ref().map_or(0, |r| r.stray_rejected);
        let count = |f: &Frame| -> u64 {
            (f.result.as_ref()).map_or(0, |r| r.excluded.iter().map(|(_, n)| n).sum())
        };
        let f = cloud_frame(&mut excluding, 0, payload);
        query_excluding.push(f.processing_s * 1e3);
        excluded += count(&f);
        let f = cloud_frame(&mut excluding_nothing, 0, payload);
        query_excluding_nothing.push(f.processing_s * 1e3);
        excluded_far += count(&f);
        let f = cloud_frame(&mut excluding_meshes, 0, payload);
        query_meshes.push(f.processing_s * 1e3);
        excluded_meshes += count(&f);
    }
    let ratio = |a: &[f64], b: &[f64]| Spread::of(a.iter().zip(b).map(|(x, y)| x / y).collect());
    let ms = |s: Spread| format!("{:.3} ms [{:.3}, {:.3}]", s.median, s.p10, s.p90);
    let pct = |s: Spread| {
        format!(
            "{:.2} % [{:.2}, {:.2}]",
            s.median * 100.0,
            s.p10 * 100.0,
            s.p90 * 100.0
        )
    };
    println!(
        "{}: one cloud of {topic} ({} bytes), {} frames per variant, alternated, {} threads",
        bag.display(),
        payload.len(),
        args.runs,
        rayon::current_num_threads()
    );
    println!(
        "decode + poses + query, one source:          {}",
        ms(Spread::of(query.clone()))
    );
    println!(
        "fusion + outputs, one source:                {}  = {} of the query",
        ms(Spread::of(outputs.clone())),
        pct(ratio(&outputs, &query))
    );
    println!(
        "fusion + outputs, two sources:               {}  = {} of the query",
        ms(Spread::of(outputs_two.clone())),
        pct(ratio(&outputs_two, &query_two))
    );
    println!(
        "decode + poses + query + stray filter (4):   {}  = {} of the query alone",
        ms(Spread::of(query_stray.clone())),
        pct(ratio(&query_stray, &query))
    );
    println!(
        "points the stray filter rejected:            {rejected} in {} frames",
        args.runs
    );
    println!(
        "decode + poses + exclusion (10) + query:     {}  = {} of the query alone ({} points excluded per frame)",
        ms(Spread::of(query_excluding.clone())),
        pct(ratio(&query_excluding, &query)),
        excluded / args.runs as u64
    );
    println!(
        "the same, the 10 volumes 10 m away:          {}  = {} of the query alone ({} points excluded)",
        ms(Spread::of(query_excluding_nothing.clone())),
        pct(ratio(&query_excluding_nothing, &query)),
        excluded_far
    );
    println!(
        "the same, the 9 boxes as meshes (5 mm pad):  {}  = {} of the query alone ({} points excluded per frame)",
        ms(Spread::of(query_meshes.clone())),
        pct(ratio(&query_meshes, &query)),
        excluded_meshes / args.runs as u64
    );
    unseen_rows(&args, &bag, payload)
}

/// The unseen space on the same cloud, alternated frame by frame with the same monitor's
/// config at `unobserved: ignore` (the peer): at the default volume with the config's shadow
/// rule, with the shadow apart, and over a 2 × 2 × 2 m volume at 2 cm (10⁶ cells). Each row: the
/// pass, all of it (the frame's view made and prepared, the volume, the robot, the search), as a
/// ratio to the same run's frame with `ignore`; its stages; what the search examined.
fn unseen_rows(args: &BenchMonitorArgs, bag: &Path, payload: &[u8]) -> Result<()> {
    let mut peer = monitor(args, bag, &[] as &[(&str, &str)])?;
    let cube = [
        ("unobserved", "report"),
        ("monitored_volume.size", "[2.0, 2.0, 2.0]"),
        ("monitored_volume.translation", "[0.0, 0.0, 0.5]"),
    ];
    // The config's own volume and shadow, its volume with the other shadow, and a fixed cube.
    let volume = match peer.config.unobserved.volume {
        Some(_) => "the config's volume",
        None => "default volume",
    };
    let own = peer.config.unobserved.self_shadow;
    let other = match own {
        SelfShadow::Count => SelfShadow::Apart,
        SelfShadow::Apart => SelfShadow::Count,
    };
    let mut variants = [
        (
            format!("{volume}, shadow {}", own.name()),
            monitor(args, bag, &[("unobserved", "report")])?,
        ),
        (
            format!("{volume}, shadow {}", other.name()),
            monitor(
                args,
                bag,
                &[
                    ("unobserved", "report"),
                    ("unobserved_self_shadow", other.name()),
                ],
            )?,
        ),
        (
            format!("2 × 2 × 2 m at 2 cm, shadow {}", own.name()),
            monitor(args, bag, &cube)?,
        ),
    ];
    for _ in 0..3 {
        cloud_frame(&mut peer, 0, payload);
        for (_, m) in &mut variants {
            cloud_frame(m, 0, payload);
        }
    }
    let mut ignore = Vec::new();
    let mut rows: Vec<Row> = variants.iter().map(|_| Row::default()).collect();
    for _ in 0..args.runs {
        ignore.push(cloud_frame(&mut peer, 0, payload).processing_s * 1e3);
        for ((_, m), row) in variants.iter_mut().zip(&mut rows) {
            let f = cloud_frame(m, 0, payload);
            row.frame.push(f.processing_s * 1e3);
            row.pass
                .push(f.unseen_s.context("the unseen-space pass did not run")? * 1e3);
            for (k, (name, s)) in f.unseen_stages_s.iter().enumerate() {
                if row.stages.len() <= k {
                    row.stages.push((name, Vec::new()));
                }
                row.stages[k].1.push(s * 1e3);
            }
            let unseen = m.unseen().context("no unseen-space pass")?;
            match &unseen.outcome {
                Ok(f) => {
                    row.cells = f.cells;
                    row.counts = Some(f.counts);
                    row.distance = f.distance_m;
                    row.cause = f.nearest.map(|n| n.cause.name());
                }
                Err(e) => bail!("the unseen-space pass failed: {e}"),
            }
        }
    }
    let ms = |s: Spread| format!("{:.3} ms [{:.3}, {:.3}]", s.median, s.p10, s.p90);
    println!(
        "the frame (decode + poses + query) with unobserved: ignore:  {}",
        ms(Spread::of(ignore.clone()))
    );
    for ((name, _), row) in variants.iter().zip(rows) {
        let ratios = Spread::of(row.pass.iter().zip(&ignore).map(|(p, q)| p / q).collect());
        println!(
            "unseen space, {name} ({} cells): {}  = {:.2} × [{:.2}, {:.2}] the frame with ignore; \
             the frame with it {}",
            row.cells,
            ms(Spread::of(row.pass)),
            ratios.median,
            ratios.p10,
            ratios.p90,
            ms(Spread::of(row.frame))
        );
        for (stage, times) in row.stages {
            println!("  {stage:<10} {}", ms(Spread::of(times)));
        }
        if let Some(c) = row.counts {
            println!(
                "  found {} (nearest: {}); blocks examined {} of {} ({} seen free whole), cells \
                 judged {}, hidden {} (+{} in the robot's shadow), distance queries {}",
                row.distance
                    .map_or("nothing hidden".into(), |d| format!("{d:.4} m")),
                row.cause.unwrap_or("-"),
                c.blocks - c.blocks_pruned,
                c.blocks,
                c.blocks_free,
                c.centres_judged,
                c.hidden,
                c.shadow,
                c.batches
            );
        }
    }
    Ok(())
}

/// One unseen-space row's measurements.
#[derive(Default)]
struct Row {
    frame: Vec<f64>,
    pass: Vec<f64>,
    stages: Vec<(&'static str, Vec<f64>)>,
    cells: usize,
    counts: Option<ist_monitor::unseen::Counts>,
    distance: Option<f64>,
    cause: Option<&'static str>,
}

/// An ASCII STL of a cube of edge `edge` m centred on the origin.
fn write_box_stl(path: &std::path::Path, edge: f64) -> std::io::Result<()> {
    std::fs::write(
        path,
        ist_monitor::robot::mesh::tessellate_box([edge; 3]).to_ascii_stl(),
    )
}

/// Ten exclusion volumes in frame `root`, `away` metres up: nine 0.3 m boxes on a grid in front
/// of the robot, from the floor up (or the mesh `mesh` of one, with 5 mm of padding), and one
/// cylinder around its base.
fn ten_volumes(root: &str, away: f64, mesh: Option<&std::path::Path>) -> Vec<(String, String)> {
    let mut names = Vec::new();
    let mut p = Vec::new();
    for (k, (x, y)) in [-0.4, 0.0, 0.4]
        .iter()
        .flat_map(|x| [-0.4, 0.0, 0.4].map(|y| (0.6 + x, y)))
        .enumerate()
    {
        let name = format!("box{k}");
        p.push((format!("{name}.frame"), root.to_owned()));
        match mesh {
            None => p.push((format!("{name}.size"), "[0.3, 0.3, 0.3]".to_owned())),
            Some(file) => {
                p.push((format!("{name}.shape"), "mesh".to_owned()));
                p.push((format!("{name}.mesh"), file.display().to_string()));
                p.push((format!("{name}.padding"), "0.005".to_owned()));
            }
        }
        p.push((
            format!("{name}.translation"),
            format!("[{x}, {y}, {}]", 0.15 * k as f64 / 8.0 + away),
        ));
        names.push(name);
    }
    p.push(("base.frame".into(), root.to_owned()));
    p.push(("base.shape".into(), "cylinder".into()));
    p.push(("base.radius".into(), "0.2".into()));
    p.push(("base.length".into(), "0.4".into()));
    p.push(("base.translation".into(), format!("[0, 0, {}]", away)));
    names.push("base".into());
    p.push((
        "exclusion_volumes".into(),
        format!("[{}]", names.join(", ")),
    ));
    p
}

/// Source `source`'s cloud from its CDR payload, decoded as `replay` decodes it (the decoding
/// timed with the frame).
/// `m` after the bag's inputs up to its first cloud (TF, joint states, camera info: a generated
/// bag's joints come from its joint states, the Kinect config's from the config), and that
/// cloud, replayed by its stamps.
fn primed(mut m: Monitor, bag: &Path) -> Result<Monitor> {
    replay_frames(&mut m, bag, None, Clock::Stamp, 1, &mut |_| {})
        .with_context(|| format!("replaying the first cloud of {}", bag.display()))?;
    Ok(m)
}

fn cloud_frame(m: &mut Monitor, source: usize, payload: &[u8]) -> Frame {
    let start = std::time::Instant::now();
    match pointcloud2::decode(payload) {
        Ok(c) => m.on_cloud(source, &c, start, None),
        Err(e) => m.on_undecodable(source, e, start, None),
    }
}
