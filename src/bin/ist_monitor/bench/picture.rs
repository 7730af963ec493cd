//! `bench unseen`: a picture of one frame's unseen space, drawn offline from a replay (as the
//! error-against-time plots are): the bag replayed up to the frame, then two panels from the
//! monitor's state. Left, the first source's view as the pass judged it: each pixel's free
//! distance in grey (black: no return), the robot's padded body as the view rendered it in
//! blue, and the hidden places nearest the robot projected into the image, coloured by why no
//! source saw them (the colours of `~/closest_points`). Right, the same places from above (the
//! root frame's x–y plane), with the camera and the monitored volume's outline.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use nalgebra::Point3;
use plotters::prelude::*;

use ist_monitor::monitor::replay::{self, Clock};
use ist_monitor::monitor::unseen::cause_colour;
use ist_monitor::unseen::{Cause, Spot};

use crate::args::ConfigArgs;
use crate::choice::choice;
use crate::setup::monitor_from_config;
use ist_monitor::choice::Choice;

#[derive(Args)]
pub struct BenchUnseenArgs {
    /// The bag replayed (default: the bundled demo bag).
    bag: Option<PathBuf>,
    #[command(flatten)]
    config: ConfigArgs,
    /// The frame drawn (0-based, over every source's clouds).
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// Clock the stamps are checked against (as `replay --clock`).
    #[arg(long, value_parser = choice::<Clock>(), default_value = Clock::Log.name())]
    clock: Clock,
    /// Most hidden places drawn, the nearest the robot first.
    #[arg(long, default_value_t = 4000)]
    places: usize,
    /// The PNG written.
    #[arg(long)]
    out: PathBuf,
    /// TrueType font of the captions (default: DejaVu Sans or another sans-serif found).
    #[arg(long)]
    font: Option<PathBuf>,
}

pub fn bench_unseen(args: BenchUnseenArgs) -> Result<()> {
    let bag = crate::demo::or_demo(&args.bag, crate::demo::BAG)?;
    let markers = [("unobserved_markers".to_string(), args.places.to_string())];
    let config = args.config.load(crate::demo::CONFIG, &markers)?;
    if !config.unobserved.enabled() {
        bail!("unobserved: ignore: no unseen space to draw (set -p unobserved:=report)");
    }
    let mut monitor = monitor_from_config(config)?;
    let mut last = None;
    replay::replay_frames(
        &mut monitor,
        &bag,
        None,
        args.clock,
        args.frame + 1,
        &mut |f| last = Some(f.clone()),
    )?;
    let row = last.with_context(|| format!("{}: no frame {}", bag.display(), args.frame))?;
    let unseen = monitor.unseen().context("no unseen-space pass")?;
    let facts = match &unseen.outcome {
        Ok(f) => f.clone(),
        Err(e) => bail!("frame {}: the unseen-space pass failed: {e}", args.frame),
    };
    let source = (monitor.config.sources.iter())
        .position(|s| s.enabled)
        .context("no enabled source")?;
    let view = (monitor.unseen_view_whole(source))
        .with_context(|| format!("source {source} has no view (it observes nothing free)"))?;
    super::plot::register_font(args.font.as_deref())?;
    let o = view.optics();
    let px = view.pixels();
    let (w, h) = (o.width, o.height);
    let scale = (640 / w).max(1) as u32;
    let (iw, ih) = (w as u32 * scale, h as u32 * scale);
    let root = BitMapBackend::new(&args.out, (iw + 620, ih.max(560) + 60)).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!(
        "{} frame {}: unseen {} (seen {}); {} hidden places drawn",
        bag.file_name().unwrap_or_default().to_string_lossy(),
        args.frame,
        facts
            .distance_m
            .map_or("nothing hidden".into(), |d| format!("{d:.3} m")),
        row.min_distance_m
            .map_or("-".into(), |d| format!("{d:.3} m")),
        facts.near.len()
    );
    root.draw(&Text::new(title, (10, 10), ("sans-serif", 20)))?;
    let (left, right) = root.split_horizontally(iw + 20);
    let image = left.margin(40, 10, 10, 10);
    // The view: free distance in grey, no return black, the robot blue.
    let far = px.free.iter().copied().fold(0.0f32, f32::max).max(0.1);
    for v in 0..h {
        for u in 0..w {
            let q = v * w + u;
            let g = px.free[q];
            let colour = if px.robot[q].is_finite() && (g < 0.0 || px.robot[q] <= g + 0.05) {
                RGBColor(70, 110, 200)
            } else if g < 0.0 {
                BLACK
            } else {
                let c = (235.0 - 180.0 * g / far) as u8;
                RGBColor(c, c, c)
            };
            let (x, y) = ((u as u32 * scale) as i32, (v as u32 * scale) as i32);
            image.draw(&Rectangle::new(
                [(x, y), (x + scale as i32, y + scale as i32)],
                colour.filled(),
            ))?;
        }
    }
    // The hidden places, farthest first so that the nearest are on top.
    let cell = facts.resolution_m;
    let camera_from_root = view.camera_from_root();
    for s in facts.near.iter().rev() {
        let p = camera_from_root * Point3::from(s.centre.map(f64::from));
        if p.z <= 0.0 {
            continue;
        }
        let (u, v) = o.project([p.x as f32, p.y as f32, p.z as f32]);
        let half = (f64::from(o.fx) * 0.5 * cell / p.z).max(1.0) * f64::from(scale);
        let (x, y) = (
            f64::from(u) * f64::from(scale),
            f64::from(v) * f64::from(scale),
        );
        image.draw(&Rectangle::new(
            [
                ((x - half) as i32, (y - half) as i32),
                ((x + half) as i32, (y + half) as i32),
            ],
            colour(s.cause).filled(),
        ))?;
    }
    top_view(
        &right,
        &facts.near,
        facts.nearest.as_ref(),
        camera_from_root,
        cell,
    )?;
    root.present()?;
    println!("picture written to {}", args.out.display());
    Ok(())
}

/// The colour of a cause, opaque (the marker's colour without its transparency).
fn colour(cause: Cause) -> RGBColor {
    let c = cause_colour(cause);
    RGBColor(
        (c.r * 255.0) as u8,
        (c.g * 255.0) as u8,
        (c.b * 255.0) as u8,
    )
}

/// The hidden places from above (root x–y), the camera, and the legend.
fn top_view<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    near: &[Spot],
    nearest: Option<&Spot>,
    camera_from_root: &nalgebra::Isometry3<f64>,
    cell: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let camera = camera_from_root.inverse().translation.vector;
    let (mut lo, mut hi) = ([camera.x, camera.y], [camera.x, camera.y]);
    for s in near {
        for a in 0..2 {
            lo[a] = lo[a].min(f64::from(s.centre[a]));
            hi[a] = hi[a].max(f64::from(s.centre[a]));
        }
    }
    let (cx, cy) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
    let half = 0.55 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.5);
    let (_, height) = area.dim_in_pixel();
    let (chart_area, legend) = area.split_vertically(height.saturating_sub(120));
    let mut chart = ChartBuilder::on(&chart_area.margin(40, 10, 10, 10))
        .caption("from above (root frame, m)", ("sans-serif", 18))
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)?;
    chart.configure_mesh().x_desc("x").y_desc("y").draw()?;
    let side = cell / 2.0;
    for s in near.iter().rev() {
        let (x, y) = (f64::from(s.centre[0]), f64::from(s.centre[1]));
        chart.draw_series(std::iter::once(Rectangle::new(
            [(x - side, y - side), (x + side, y + side)],
            colour(s.cause).filled(),
        )))?;
    }
    chart.draw_series(std::iter::once(TriangleMarker::new(
        (camera.x, camera.y),
        9,
        BLACK.filled(),
    )))?;
    if let Some(n) = nearest {
        chart.draw_series(std::iter::once(Circle::new(
            (f64::from(n.centre[0]), f64::from(n.centre[1])),
            7,
            BLACK.stroke_width(2),
        )))?;
    }
    for (k, cause) in Cause::ALL.iter().enumerate() {
        let (x, y) = (60 + 230 * (k as i32 % 2), 10 + 24 * (k as i32 / 2));
        legend.draw(&Rectangle::new(
            [(x, y), (x + 14, y + 14)],
            colour(*cause).filled(),
        ))?;
        legend.draw(&Text::new(cause.name(), (x + 20, y), ("sans-serif", 15)))?;
    }
    legend.draw(&Text::new(
        "▲ the camera; ○ the nearest hidden place",
        (60, 10 + 24 * 2),
        ("sans-serif", 15),
    ))?;
    Ok(())
}
