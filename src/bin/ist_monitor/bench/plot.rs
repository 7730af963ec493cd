//! The plots of `bench query` — error against query time per scenario, one series per mode and
//! per-link setting (labelled with the sphere budget), the peers and the floor as markers — and
//! of `bench ssm`: distance, protective separation distance and speed factor over time.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{bail, Context, Result};

use ist_monitor::monitor::replay::ReplayFrame;

use super::rows::Row;
use super::scenes::ScenarioName;

/// Where a sans-serif TrueType font is looked for when none is given, preferred names first.
const FONT_DIRS: &[&str] = &["/usr/share/fonts", "/usr/local/share/fonts"];
const FONT_NAMES: &[&str] = &[
    "DejaVuSans.ttf",
    "LiberationSans-Regular.ttf",
    "FreeSans.ttf",
];

/// The first font file named in `FONT_NAMES` under `dirs` (searched recursively).
fn find_font(dirs: &[std::path::PathBuf]) -> Option<std::path::PathBuf> {
    fn walk(dir: &Path, name: &str, depth: usize) -> Option<std::path::PathBuf> {
        let entries = std::fs::read_dir(dir).ok()?;
        let mut subdirs = Vec::new();
        for e in entries.flatten() {
            let path = e.path();
            if path.is_dir() {
                subdirs.push(path);
            } else if path.file_name().is_some_and(|f| f == name) {
                return Some(path);
            }
        }
        if depth == 0 {
            return None;
        }
        subdirs.sort();
        subdirs.iter().find_map(|d| walk(d, name, depth - 1))
    }
    FONT_NAMES
        .iter()
        .find_map(|name| dirs.iter().find_map(|d| walk(d, name, 4)))
}

/// Registers the plot's font once per process (plotters keeps a `'static` reference).
pub(super) fn register_font(font: Option<&Path>) -> Result<()> {
    static FONT: OnceLock<Vec<u8>> = OnceLock::new();
    if FONT.get().is_some() {
        return Ok(());
    }
    let mut dirs: Vec<std::path::PathBuf> = FONT_DIRS.iter().map(Into::into).collect();
    if let Some(home) = std::env::var_os("HOME") {
        dirs.push(Path::new(&home).join(".local/share/fonts"));
    }
    let path = match font {
        Some(f) => f.to_owned(),
        None => find_font(&dirs).with_context(|| {
            format!(
                "no sans-serif font ({}) under {}: install fonts-dejavu-core or give --font FILE",
                FONT_NAMES.join(", "),
                FONT_DIRS.join(", ")
            )
        })?,
    };
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let bytes: &'static [u8] = FONT.get_or_init(|| bytes);
    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes)
        .map_err(|_| anyhow::anyhow!("{}: not a TrueType font", path.display()))
}

/// Errors below this are drawn on the axis (log scale).
const ERROR_FLOOR_MM: f64 = 1e-4;

/// Draws `rows` of one scenario to the PNG `path`.
pub fn error_against_time(
    path: &Path,
    font: Option<&Path>,
    name: ScenarioName,
    rows: &[Row],
) -> Result<()> {
    use plotters::prelude::*;
    register_font(font)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let pts: Vec<&Row> = rows.iter().filter(|r| r.max_error_mm.is_some()).collect();
    if pts.is_empty() {
        bail!("no errors measured (run with the peers)");
    }
    let xs = rows.iter().map(|r| r.median_ms);
    let (xmin, xmax) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    let ymax = pts
        .iter()
        .filter_map(|r| r.max_error_mm)
        .fold(ERROR_FLOOR_MM, f64::max);
    let root = BitMapBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{name:?}: error against query time (max over poses)"),
            ("sans-serif", 24),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (xmin * 0.7..xmax * 4.0).log_scale(),
            (ERROR_FLOOR_MM * 0.7..ymax * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("query time per cloud, ms (median)")
        .y_desc("error against exact distance, mm (below 1e-4 drawn at 1e-4)")
        .draw()?;
    let styles: [(&str, bool, RGBColor); 6] = [
        ("fast", false, RGBColor(31, 119, 180)),
        ("certified", false, RGBColor(255, 127, 14)),
        ("exact", false, RGBColor(44, 160, 44)),
        ("fast", true, RGBColor(120, 170, 220)),
        ("certified", true, RGBColor(255, 187, 120)),
        ("exact", true, RGBColor(152, 223, 138)),
    ];
    for (method, per_link, color) in styles {
        let series: Vec<(f64, f64, u32)> = pts
            .iter()
            .filter(|r| r.method == method && r.per_link == per_link)
            .map(|r| {
                (
                    r.median_ms,
                    r.max_error_mm.unwrap_or(ERROR_FLOOR_MM).max(ERROR_FLOOR_MM),
                    r.budget.unwrap_or(0),
                )
            })
            .collect();
        if series.is_empty() {
            continue;
        }
        let label = format!(
            "{method}{}",
            if per_link {
                ", per-link minima"
            } else {
                ", global minimum"
            }
        );
        chart
            .draw_series(LineSeries::new(
                series.iter().map(|&(x, y, _)| (x, y)),
                color.stroke_width(2),
            ))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(series.iter().map(|&(x, y, b)| {
            EmptyElement::at((x, y))
                + Circle::new((0, 0), 4, color.filled())
                + Text::new(b.to_string(), (6, -14), ("sans-serif", 12))
        }))?;
    }
    for r in rows
        .iter()
        .filter(|r| r.method.starts_with('(') || r.method.starts_with("floor"))
    {
        let y = r.max_error_mm.unwrap_or(ERROR_FLOOR_MM).max(ERROR_FLOOR_MM);
        let label = match r.budget {
            Some(b) => format!("{} {b}", &r.method[..3]),
            None => r.method.clone(),
        };
        chart.draw_series(std::iter::once(
            EmptyElement::at((r.median_ms, y))
                + TriangleMarker::new((0, 0), 6, BLACK.filled())
                + Text::new(label, (6, 4), ("sans-serif", 12)),
        ))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// A labelled series of (time, value) and its colour.
type Line<'a> = (&'a str, Vec<(f64, f64)>, plotters::style::RGBColor);

/// One panel of the separation plot: `lines` over time up to `t_end`, values in `y`.
fn panel<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    t_end: f64,
    y: (f64, &str),
    lines: Vec<Line>,
    legend: plotters::prelude::SeriesLabelPosition,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, 0.0..y.0)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc(y.1)
        .draw()?;
    for (label, points, color) in lines {
        chart
            .draw_series(LineSeries::new(points, color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .position(legend)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// Draws the separation monitor over a replay to the PNG `path`: above, the true distance, the
/// published (certified) distance, and the distance and protective separation distance S_p of
/// the link that limits the factor (the least margin when none does); below, the factor each
/// frame allows and the one published.
pub fn separation(path: &Path, font: Option<&Path>, frames: &[ReplayFrame]) -> Result<()> {
    use plotters::prelude::*;
    register_font(font)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let Some(t0) = frames.first().map(|f| f.stamp_ns) else {
        bail!("no frames to plot");
    };
    let t = |f: &ReplayFrame| (f.stamp_ns - t0) as f64 * 1e-9;
    let t_end = frames.last().map_or(1.0, t).max(1e-3);
    let series = |get: &dyn Fn(&ReplayFrame) -> Option<f64>| -> Vec<(f64, f64)> {
        frames
            .iter()
            .filter_map(|f| get(f).map(|v| (t(f), v)))
            .collect()
    };
    let distances: Vec<Line> = vec![
        (
            "true distance (generator)",
            series(&|f| f.truth_m),
            RGBColor(0, 0, 0),
        ),
        (
            "published distance (certified lower bound)",
            series(&|f| f.min_distance_m),
            RGBColor(31, 119, 180),
        ),
        (
            "distance of the link that limits the factor",
            series(&|f| f.ssm_distance_m),
            RGBColor(148, 103, 189),
        ),
        (
            "its S_p at the motion as measured",
            series(&|f| f.protective_m),
            RGBColor(214, 39, 40),
        ),
    ];
    let d_max = distances
        .iter()
        .flat_map(|l| l.1.iter().map(|p| p.1))
        .fold(0.5, f64::max);
    let factors: Vec<Line> = vec![
        (
            "allowed by this frame",
            series(&|f| f.speed_scaling.map(|_| f.allowed_factor.unwrap_or(0.0))),
            RGBColor(255, 127, 14),
        ),
        (
            "published (hysteresis, rate limit)",
            series(&|f| f.speed_scaling),
            RGBColor(44, 160, 44),
        ),
    ];
    let root = BitMapBackend::new(path, (1100, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(480);
    panel(
        &upper,
        "generated approach: distance and protective separation distance",
        t_end,
        (d_max * 1.1, "m"),
        distances,
        SeriesLabelPosition::UpperRight,
    )?;
    panel(
        &lower,
        "speed-scaling factor",
        t_end,
        (1.05, "factor"),
        factors,
        SeriesLabelPosition::LowerRight,
    )?;
    root.present()?;
    Ok(())
}
