//! The warning level and its hysteresis: OK above `warn_distance`, WARN below it, ERROR below
//! `stop_distance` or on a fault. A level is left upward only once the distance exceeds its
//! threshold by `hysteresis`, and lowered only after `release_frames` results in a row allow
//! it, so a distance hovering at a threshold does not flicker. Each source keeps one
//! (`source`), the cell one more for its fused level (`fusion`).

use crate::config::Config;
use crate::msg::DiagnosticStatus;

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Level {
    Ok,
    Warn,
    Error,
}

impl Level {
    pub fn diagnostic(self) -> u8 {
        match self {
            Level::Ok => DiagnosticStatus::OK,
            Level::Warn => DiagnosticStatus::WARN,
            Level::Error => DiagnosticStatus::ERROR,
        }
    }
}

/// The distance level with hysteresis.
#[derive(Debug, Clone)]
pub struct LevelTracker {
    warn_m: f64,
    stop_m: f64,
    hysteresis_m: f64,
    level: Level,
    /// A lower level is taken after this many consecutive updates allow it.
    release_frames: u32,
    /// Consecutive updates so far that allowed a lower level.
    lower_streak: u32,
}

impl LevelTracker {
    pub fn new(config: &Config) -> Self {
        Self {
            warn_m: config.warn_distance_m,
            stop_m: config.stop_distance_m,
            hysteresis_m: config.hysteresis_m,
            level: Level::Ok,
            release_frames: config.release_frames.max(1),
            lower_streak: 0,
        }
    }

    /// Takes `config`'s thresholds, keeping the level held and the count towards lowering it.
    pub fn set_thresholds(&mut self, config: &Config) {
        self.warn_m = config.warn_distance_m;
        self.stop_m = config.stop_distance_m;
        self.hysteresis_m = config.hysteresis_m;
        self.release_frames = config.release_frames.max(1);
    }

    /// The level when nothing about the distance can be said but no input failed either: at
    /// least `floor`, and never below the level held (the stop stays as it was).
    pub fn hold_at_least(&mut self, floor: Level) -> Level {
        if floor > self.level {
            self.level = floor;
            self.lower_streak = 0;
        }
        self.level
    }

    /// The level held now.
    pub fn level(&self) -> Level {
        self.level
    }

    /// The level for `d` by outputs that go before the frame's last word (its seen outputs,
    /// before the unseen pass under `protect`): raised at once where `d` asks for more, never
    /// lowered, and nothing counted towards lowering it (the frame's [`LevelTracker::update`]
    /// does that, once).
    pub fn raise_for(&mut self, d: f64) -> Level {
        let target = self.target(d);
        if target > self.level {
            self.level = target;
            self.lower_streak = 0;
        }
        self.level
    }

    /// The level for a conservative distance `d` (`None`: no distance is known, a fault).
    pub fn update(&mut self, d: Option<f64>) -> Level {
        let Some(d) = d else {
            self.level = Level::Error;
            self.lower_streak = 0;
            return self.level;
        };
        let current = self.level;
        let target = self.target(d);
        // Raising is immediate; lowering waits for `release_frames` results in a row.
        if target >= current {
            self.lower_streak = 0;
            self.level = target;
        } else {
            self.lower_streak += 1;
            if self.lower_streak >= self.release_frames {
                self.lower_streak = 0;
                self.level = target;
            }
        }
        self.level
    }

    /// The level `d` asks for, with the hysteresis of the level held.
    fn target(&self, d: f64) -> Level {
        // Thresholds are raised by the hysteresis for the levels we are above.
        let up = |level: Level, threshold: f64, current: Level| {
            if current >= level {
                threshold + self.hysteresis_m
            } else {
                threshold
            }
        };
        let current = self.level;
        if d < up(Level::Error, self.stop_m, current) {
            Level::Error
        } else if d < up(Level::Warn, self.warn_m, current) {
            Level::Warn
        } else {
            Level::Ok
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_have_hysteresis() {
        let config = Config::default();
        assert_eq!(
            (
                config.warn_distance_m,
                config.stop_distance_m,
                config.hysteresis_m
            ),
            (0.3, 0.1, 0.02)
        );
        let mut t = LevelTracker::new(&config);
        let seq = [
            (0.5, Level::Ok),
            (0.29, Level::Warn),
            (0.31, Level::Warn),
            (0.33, Level::Ok),
            (0.09, Level::Error),
            (0.11, Level::Error),
            (0.125, Level::Warn),
            (0.2, Level::Warn),
            (0.5, Level::Ok),
        ];
        for (d, expected) in seq {
            assert_eq!(t.update(Some(d)), expected, "{d}");
        }
        assert_eq!(t.update(None), Level::Error);
        assert_eq!(t.update(Some(0.11)), Level::Error);
    }

    #[test]
    fn a_level_is_lowered_only_after_release_frames_in_a_row() {
        let config = Config::from_overrides(&[("release_frames".into(), "3".into())]).unwrap();
        let mut t = LevelTracker::new(&config);
        // Raising is immediate.
        assert_eq!(t.update(Some(0.05)), Level::Error);
        // Two clear results are not enough; one near result starts the count again.
        assert_eq!(t.update(Some(1.0)), Level::Error);
        assert_eq!(t.update(Some(1.0)), Level::Error);
        assert_eq!(t.update(Some(0.05)), Level::Error);
        assert_eq!(t.update(Some(1.0)), Level::Error);
        assert_eq!(t.update(Some(1.0)), Level::Error);
        assert_eq!(t.update(Some(1.0)), Level::Ok);
        assert_eq!(t.update(Some(0.2)), Level::Warn);
    }
}
