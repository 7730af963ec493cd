//! A time series of samples, sorted by stamp, sampled at a stamp with a tolerance: the one
//! piece of code behind the TF edges and the joint states.

use std::collections::VecDeque;

/// Why a stamp could not be sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Miss {
    /// The newest sample is older than the stamp by more than the tolerance.
    Stale { newest_ns: i64 },
    /// The stamp precedes the oldest sample kept by more than the tolerance.
    TooOld { oldest_ns: i64 },
}

#[derive(Debug, Clone)]
pub struct History<T> {
    samples: VecDeque<(i64, T)>,
}

impl<T> Default for History<T> {
    fn default() -> Self {
        Self {
            samples: VecDeque::new(),
        }
    }
}

impl<T: Clone> History<T> {
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.samples.len()
    }
    /// The newest sample's stamp.
    pub fn newest_stamp(&self) -> Option<i64> {
        self.samples.back().map(|s| s.0)
    }

    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// Adds a sample in stamp order; a sample at an existing stamp replaces it. Then drops the
    /// oldest samples beyond `max_len`, and those older than the newest by more than `keep_ns`
    /// (keeping two, so that an old pair still interpolates).
    pub fn insert(&mut self, stamp_ns: i64, value: T, keep_ns: i64, max_len: usize) {
        let at = self.samples.partition_point(|(s, _)| *s <= stamp_ns);
        if at > 0 && self.samples[at - 1].0 == stamp_ns {
            self.samples[at - 1].1 = value;
        } else {
            self.samples.insert(at, (stamp_ns, value));
        }
        let newest = self.samples.back().map_or(stamp_ns, |s| s.0);
        while self.samples.len() > max_len
            || (self.samples.len() > 2
                && self
                    .samples
                    .front()
                    .is_some_and(|s| s.0 < newest.saturating_sub(keep_ns)))
        {
            self.samples.pop_front();
        }
    }

    /// Where `stamp_ns` (`None`: the newest) lies among the samples: past the newest or before
    /// the oldest by at most `tolerance_ns`, or between two. `None` when there is no sample.
    fn locate(&self, stamp_ns: Option<i64>, tolerance_ns: i64) -> Option<Result<Place, Miss>> {
        let (first, last) = (self.samples.front()?.0, self.samples.back()?.0);
        let Some(t) = stamp_ns else {
            return Some(Ok(Place::Newest));
        };
        Some(if t >= last {
            if t - last <= tolerance_ns {
                Ok(Place::Newest)
            } else {
                Err(Miss::Stale { newest_ns: last })
            }
        } else if t <= first {
            if first - t <= tolerance_ns {
                Ok(Place::Oldest)
            } else {
                Err(Miss::TooOld { oldest_ns: first })
            }
        } else {
            Ok(Place::Before(self.samples.partition_point(|(s, _)| *s < t)))
        })
    }

    /// The value at `stamp_ns` (`None`: the newest): `lerp(a, b, w)` between the two samples
    /// around it, or the nearest sample when the stamp lies past either end by at most
    /// `tolerance_ns`. `None` when there is no sample.
    pub fn sample(
        &self,
        stamp_ns: Option<i64>,
        tolerance_ns: i64,
        lerp: impl Fn(&T, &T, f64) -> T,
    ) -> Option<Result<T, Miss>> {
        Some(
            self.locate(stamp_ns, tolerance_ns)?
                .map(|place| match place {
                    Place::Newest => self.samples[self.samples.len() - 1].1.clone(),
                    Place::Oldest => self.samples[0].1.clone(),
                    Place::Before(k) => {
                        let (a, b) = (&self.samples[k - 1], &self.samples[k]);
                        let t = stamp_ns.unwrap_or(b.0);
                        lerp(&a.1, &b.1, (t - a.0) as f64 / (b.0 - a.0) as f64)
                    }
                }),
        )
    }
}

/// Where a stamp lies among a history's samples.
#[derive(Debug, Clone, Copy)]
enum Place {
    /// At or after the newest sample (within the tolerance).
    Newest,
    /// At or before the oldest (within the tolerance).
    Oldest,
    /// Between sample `k − 1` and sample `k`.
    Before(usize),
}

impl History<f64> {
    /// The rate of change at `stamp_ns` (`None`: the newest), per second: the slope between the
    /// two samples around it, or between the two newest (oldest) when the stamp lies past that
    /// end by at most `tolerance_ns`. `None` with fewer than two samples, or when those two lie
    /// more than `max_span_ns` apart (too far apart to tell the rate now).
    pub fn slope(
        &self,
        stamp_ns: Option<i64>,
        tolerance_ns: i64,
        max_span_ns: i64,
    ) -> Option<Result<f64, Miss>> {
        let n = self.samples.len();
        if n < 2 {
            return None;
        }
        let k = match self.locate(stamp_ns, tolerance_ns)? {
            Err(miss) => return Some(Err(miss)),
            Ok(Place::Newest) => n - 1,
            Ok(Place::Oldest) => 1,
            Ok(Place::Before(k)) => k,
        };
        let (a, b) = (&self.samples[k - 1], &self.samples[k]);
        let span = b.0 - a.0;
        (span <= max_span_ns).then(|| Ok((b.1 - a.1) / (span as f64 * 1e-9)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_interpolate_and_miss() {
        let mut h = History::default();
        for (t, v) in [(30, 3.0), (10, 1.0), (20, 2.0), (20, 2.5)] {
            h.insert(t, v, 1_000, 10);
        }
        assert_eq!(h.len(), 3);
        let lerp = |a: &f64, b: &f64, w: f64| a + w * (b - a);
        assert_eq!(h.sample(Some(15), 0, lerp), Some(Ok(1.75)));
        assert_eq!(h.sample(Some(34), 5, lerp), Some(Ok(3.0)));
        assert_eq!(
            h.sample(Some(40), 5, lerp),
            Some(Err(Miss::Stale { newest_ns: 30 }))
        );
        assert_eq!(
            h.sample(Some(0), 5, lerp),
            Some(Err(Miss::TooOld { oldest_ns: 10 }))
        );
        assert_eq!(h.sample(None, 0, lerp), Some(Ok(3.0)));
        h.insert(5_000, 9.0, 1_000, 10);
        assert_eq!(h.len(), 2, "samples older than keep_ns dropped, two kept");
        assert!(History::<f64>::default().sample(None, 0, lerp).is_none());
    }

    #[test]
    fn slopes_between_neighbours() {
        let mut h = History::default();
        assert_eq!(h.slope(None, 0, i64::MAX), None);
        h.insert(0, 1.0, i64::MAX, 10);
        assert_eq!(h.slope(None, 0, i64::MAX), None, "one sample has no rate");
        h.insert(100_000_000, 2.0, i64::MAX, 10);
        h.insert(200_000_000, 2.5, i64::MAX, 10);
        let close = |r: Option<Result<f64, Miss>>, v: f64| (r.unwrap().unwrap() - v).abs() < 1e-9;
        assert!(close(h.slope(Some(50_000_000), 0, i64::MAX), 10.0));
        assert!(close(h.slope(Some(150_000_000), 0, i64::MAX), 5.0));
        assert!(close(h.slope(Some(230_000_000), 50_000_000, i64::MAX), 5.0));
        assert!(close(
            h.slope(Some(-10_000_000), 50_000_000, i64::MAX),
            10.0
        ));
        assert_eq!(
            h.slope(Some(300_000_000), 50_000_000, i64::MAX),
            Some(Err(Miss::Stale {
                newest_ns: 200_000_000
            }))
        );
        assert_eq!(
            h.slope(Some(150_000_000), 0, 50_000_000),
            None,
            "samples too far apart"
        );
    }
}
