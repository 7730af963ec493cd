//! Order statistics of timing samples, for the benchmarks, `replay` and `play`: one definition
//! of a percentile (nearest rank, the sample at `round((n − 1)·q)` of the sorted samples) so that
//! every figure the tools print is computed the same way.

/// The percentile `q` ∈ [0, 1] of samples sorted ascending; `None` when there are none.
pub fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let at = ((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(sorted[at])
}

/// Median and spread (10th, 90th and 99th percentiles) of timing samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Spread {
    pub median: f64,
    pub p10: f64,
    pub p90: f64,
    pub p99: f64,
}

impl Spread {
    /// The spread of `samples` (NaN for all three when there are none).
    pub fn of(mut samples: Vec<f64>) -> Self {
        samples.sort_by(f64::total_cmp);
        let at = |q| percentile(&samples, q).unwrap_or(f64::NAN);
        Self {
            median: at(0.5),
            p10: at(0.1),
            p90: at(0.9),
            p99: at(0.99),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let s: Vec<f64> = (0..=100).map(f64::from).collect();
        assert_eq!(percentile(&s, 0.5), Some(50.0));
        assert_eq!(percentile(&s, 0.99), Some(99.0));
        assert_eq!(percentile(&[], 0.5), None);
        let spread = Spread::of(vec![3.0, 1.0, 2.0]);
        assert_eq!((spread.median, spread.p10, spread.p90), (2.0, 1.0, 3.0));
        assert!(Spread::of(Vec::new()).median.is_nan());
    }
}
