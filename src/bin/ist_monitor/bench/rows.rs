//! One line of `bench query`'s table: a method's time on one scene (median, p10, p90, p99 over
//! its runs, ms) and its error against the exact distance (mm); printed as the table, written
//! as JSON and drawn by `plot.rs`.

use serde::Serialize;

use ist_monitor::stats::Spread;

use super::scenes::ScenarioName;

/// One line of the table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub scenario: ScenarioName,
    /// "fast", "certified", "exact", or a peer.
    pub method: String,
    pub per_link: bool,
    pub budget: Option<u32>,
    pub median_ms: f64,
    pub p10_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    /// Against the exact reference, over poses (None without peers).
    pub max_error_mm: Option<f64>,
    pub mean_error_mm: Option<f64>,
    pub runs: usize,
}

/// A row from a method's time samples (ms) and its errors (mm; none without a reference).
pub fn row(
    scenario: ScenarioName,
    method: &str,
    per_link: bool,
    budget: Option<u32>,
    samples: Vec<f64>,
    errors: &[f64],
) -> Row {
    let runs = samples.len();
    let Spread {
        median: m,
        p10: lo,
        p90: hi,
        p99,
    } = Spread::of(samples);
    Row {
        scenario,
        method: method.into(),
        per_link,
        budget,
        median_ms: m,
        p10_ms: lo,
        p90_ms: hi,
        p99_ms: p99,
        max_error_mm: (!errors.is_empty()).then(|| errors.iter().fold(0.0, |a: f64, &b| a.max(b))),
        mean_error_mm: (!errors.is_empty())
            .then(|| errors.iter().sum::<f64>() / errors.len() as f64),
        runs,
    }
}

/// The rows of one scene as a table, each time also as a multiple of the floor's.
pub fn print_table(rows: &[Row]) {
    let floor = rows
        .iter()
        .find(|r| r.method.starts_with("floor"))
        .map(|r| r.median_ms);
    println!(
        "{:<52} {:>8} {:>6} {:>10} {:>17} {:>8} {:>8} {:>13} {:>13}",
        "method",
        "per-link",
        "budget",
        "median ms",
        "[p10, p90] ms",
        "p99 ms",
        "× floor",
        "max err mm",
        "mean err mm"
    );
    for r in rows {
        let f = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
        println!(
            "{:<52} {:>8} {:>6} {:>10.3} {:>17} {:>8.3} {:>8.1} {:>13} {:>13}",
            r.method,
            if r.per_link { "yes" } else { "no" },
            r.budget
                .map(|b| b.to_string())
                .unwrap_or_else(|| "-".into()),
            r.median_ms,
            format!("[{:.3}, {:.3}]", r.p10_ms, r.p90_ms),
            r.p99_ms,
            floor.map_or(f64::NAN, |f| r.median_ms / f),
            f(r.max_error_mm),
            f(r.mean_error_mm)
        );
    }
}
