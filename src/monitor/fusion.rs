//! Fusion across sources: the cell has one level, one stop and one distance, over every enabled
//! source.
//!
//! The monitor keeps each source's latest result (its stamp, its distance or its fault, its
//! diagnostic status). Every frame of any source publishes the fused picture:
//!
//! - A source counts only if it is enabled. A disabled source never counts. With none enabled
//!   nothing watches the cell: that is a fault (ERROR, no distance), not a clean state.
//! - An enabled source **in fault** holds the fused level at ERROR with no distance until it
//!   recovers (its next good frame) or is disabled. In fault means: its latest frame was a fault
//!   (any kind: decode, stamp, transform, joints, no valid points, its `source_timeout` in the
//!   node), nothing received from it yet, or its latest result is older than its
//!   `source_timeout` by the clock of the frame being fused (stale). A blinded camera is never
//!   cleared by a healthy one.
//! - Otherwise the fused distance is the minimum of the sources' conservative distances, and the
//!   fused level follows it with the hysteresis of `LevelTracker`: one camera's far wall cannot
//!   release the stop another camera's near obstacle raised. A source whose valid points were
//!   all self-filtered contributes no distance and holds the fused level at WARN at least (it
//!   never lowers it).
//! - Per-link distances are each link's minimum over the sources; the closest-point markers are
//!   each source's nearest; the header stamp is the oldest stamp among the fused results (the
//!   age of the picture is that of its oldest part).
//! - `/diagnostics` carries one status per enabled source (its own level with its own
//!   hysteresis, as before) and one for the fused result, last, named `<node>: all sources`.
//!
//! The speed-scaling factor is fused by `separation::SpeedScaler` (the minimum over sources),
//! and is 0 while any source is in fault.

use crate::config::Config;
use crate::msg::{
    Bool, DiagnosticArray, DiagnosticStatus, Float64, Header, JointState, KeyValue, Marker,
    MarkerArray, SpeedScalingFactor, Time,
};
use crate::query::{Outcome, QueryResult};

use super::outputs::{
    closest_markers, link_positions, shape_markers, Level, LevelTracker, Outputs, SourceReport,
};

/// What the fused outputs are made for: a frame of `source` stamped `stamp_ns`, or a
/// heartbeat (`beat`: no new result; `stamp_ns` is the clock).
struct Moment {
    source: usize,
    stamp_ns: i64,
    /// The clock the sources' results are aged by.
    now_ns: i64,
    /// The frame took longer than `latency_budget`.
    over_budget: bool,
    /// The speed scaler's factor (`None` with the separation monitor off).
    factor: Option<f64>,
    beat: bool,
}

/// One source's latest frame.
#[derive(Debug, Clone)]
struct Latest {
    stamp_ns: i64,
    /// The result, or the fault's kind and reason.
    result: Result<QueryResult, (&'static str, String)>,
    report: SourceReport,
}

/// A source's part in the fused picture at one instant.
enum Part<'a> {
    Fault { kind: &'static str, reason: String },
    Measured(&'a Latest),
}

/// The latest result of every source and the fused level (see the module doc).
#[derive(Debug, Clone)]
pub struct Fusion {
    /// Each source's own level, for its own status.
    trackers: Vec<LevelTracker>,
    fused: LevelTracker,
    latest: Vec<Option<Latest>>,
}

impl Fusion {
    pub fn new(config: &Config) -> Self {
        Self {
            trackers: vec![LevelTracker::new(config); config.sources.len()],
            fused: LevelTracker::new(config),
            latest: vec![None; config.sources.len()],
        }
    }

    /// Takes the thresholds and enabled flags of `new` (a run-time change of `old`): each level
    /// is kept as held and left only by the new thresholds; a source enabled now starts as
    /// never heard from (a fault until its first frame), one disabled forgets its result.
    pub fn reconfigure(&mut self, old: &Config, new: &Config) {
        for t in self.trackers.iter_mut().chain([&mut self.fused]) {
            t.set_thresholds(new);
        }
        for (k, (o, n)) in old.sources.iter().zip(&new.sources).enumerate() {
            if o.enabled != n.enabled {
                self.latest[k] = None;
                self.trackers[k] = LevelTracker::new(new);
            }
        }
    }

    /// Forgets every source's result (each is then in fault until its next frame); the levels
    /// held are kept.
    pub fn forget_results(&mut self) {
        self.latest.iter_mut().for_each(|l| *l = None);
    }

    /// Whether the fused level is ERROR now (the safety stop is raised).
    pub fn stop_raised(&self) -> bool {
        self.fused.level() == Level::Error
    }

    /// Whether each source is in fault at `now_ns` (see the module doc); a disabled source is
    /// not.
    pub fn in_fault(&self, config: &Config, now_ns: i64) -> Vec<bool> {
        (0..config.sources.len())
            .map(|k| {
                config.sources[k].enabled
                    && matches!(
                        Self::part(&self.latest, config, k, now_ns),
                        Part::Fault { .. }
                    )
            })
            .collect()
    }

    /// Takes a frame of source `source` and returns the fused outputs. `now_ns` is the clock
    /// the other sources' results are aged by (the frame's own stamp where there is none).
    #[allow(clippy::too_many_arguments)]
    pub fn frame(
        &mut self,
        config: &Config,
        root_frame: &str,
        robot: &str,
        source: usize,
        stamp_ns: i64,
        now_ns: Option<i64>,
        result: &Result<QueryResult, super::Fault>,
        processing_s: f64,
        speed: Option<&crate::separation::SpeedScaling>,
    ) -> Outputs {
        let name = &config.sources[source].name;
        let report = SourceReport::new(
            config,
            robot,
            name,
            result,
            processing_s,
            speed,
            &mut self.trackers[source],
        );
        let over_budget = report.over_budget;
        self.latest[source] = Some(Latest {
            stamp_ns,
            result: match result {
                Ok(r) => Ok(r.clone()),
                Err(f) => Err((f.kind(), f.to_string())),
            },
            report,
        });
        let now_ns = now_ns.unwrap_or(stamp_ns);
        let moment = Moment {
            source,
            stamp_ns,
            now_ns,
            over_budget,
            factor: speed.map(|s| s.factor),
            beat: false,
        };
        self.outputs(config, root_frame, robot, moment)
    }

    /// The fused outputs at `now_ns` without a new frame (the node's heartbeat): every source's
    /// latest result aged by the clock, so a source gone stale shows at once. `factor` is the
    /// speed scaler's (`None` with the separation monitor off).
    pub fn heartbeat(
        &mut self,
        config: &Config,
        root_frame: &str,
        robot: &str,
        now_ns: i64,
        factor: Option<f64>,
    ) -> Outputs {
        let moment = Moment {
            source: config.sources.iter().position(|s| s.enabled).unwrap_or(0),
            stamp_ns: now_ns,
            now_ns,
            over_budget: false,
            factor,
            beat: true,
        };
        self.outputs(config, root_frame, robot, moment)
    }

    /// Source `k`'s part at `now_ns`.
    fn part<'a>(latest: &'a [Option<Latest>], config: &Config, k: usize, now_ns: i64) -> Part<'a> {
        let s = &config.sources[k];
        match &latest[k] {
            None => Part::Fault {
                kind: "no_message_yet",
                reason: "nothing received yet".into(),
            },
            Some(Latest {
                result: Err((kind, reason)),
                ..
            }) => Part::Fault {
                kind,
                reason: reason.clone(),
            },
            Some(l) => {
                let age_s = (now_ns as f64 - l.stamp_ns as f64) * 1e-9;
                if age_s > s.source_timeout_s {
                    Part::Fault {
                        kind: "stale_source",
                        reason: format!(
                            "its latest result is stamped {age_s:.3} s before now \
                             (source_timeout {} s)",
                            s.source_timeout_s
                        ),
                    }
                } else {
                    Part::Measured(l)
                }
            }
        }
    }

    fn outputs(
        &mut self,
        config: &Config,
        root_frame: &str,
        robot: &str,
        moment: Moment,
    ) -> Outputs {
        let Moment {
            source,
            stamp_ns,
            now_ns,
            over_budget,
            factor,
            beat,
        } = moment;
        let kv = |key: &str, value: String| KeyValue {
            key: key.into(),
            value,
        };
        let enabled: Vec<usize> = (0..config.sources.len())
            .filter(|&k| config.sources[k].enabled)
            .collect();
        let Self { fused, latest, .. } = self;
        let latest = &*latest;
        let parts: Vec<(usize, Part)> = enabled
            .iter()
            .map(|&k| (k, Self::part(latest, config, k, now_ns)))
            .collect();
        let mut statuses = Vec::with_capacity(parts.len() + 1);
        let mut faults = Vec::new();
        let mut measured = Vec::new();
        for (k, part) in &parts {
            let name = &config.sources[*k].name;
            match part {
                Part::Measured(l) => {
                    statuses.push(l.report.status.clone());
                    measured.push((*k, *l));
                }
                Part::Fault { kind, reason } => {
                    faults.push(format!("source {name}: {reason}"));
                    // The source's own status where its latest frame was the fault; one made
                    // here where it has none or its result went stale.
                    match &latest[*k] {
                        Some(l) if l.result.is_err() => statuses.push(l.report.status.clone()),
                        _ => statuses.push(DiagnosticStatus {
                            level: Level::Error.diagnostic(),
                            name: format!("{}: {name}", config.node_name),
                            message: reason.clone(),
                            hardware_id: robot.to_owned(),
                            values: vec![kv("source", name.clone()), kv("fault", (*kind).into())],
                        }),
                    }
                }
            }
        }
        if enabled.is_empty() {
            // Nothing watches the cell (every source disabled, at start or at run time): as a
            // fault, never a clean state.
            faults.push("no source is enabled: nothing watches the cell".into());
        }
        let max_distance = f64::from(config.query.max_distance_m);
        // What the picture rests on: every measured source, or nothing while one is in fault.
        let contributing: &[(usize, &Latest)] = if faults.is_empty() { &measured } else { &[] };
        let holding = contributing.iter().any(|(_, l)| l.report.all_self);
        // The nearest source: the smallest conservative distance.
        let nearest = contributing
            .iter()
            .filter_map(|(k, l)| l.report.distance.map(|d| (*k, *l, d)))
            .min_by(|a, b| a.2.total_cmp(&b.2));
        let distance = nearest.map(|(_, _, d)| d);
        let mut level = if !faults.is_empty() {
            fused.update(None)
        } else if beat {
            // A heartbeat brings no new result: the level stays as the results left it.
            fused.level()
        } else if let Some(d) = distance {
            let before = fused.level();
            let level = fused.update(Some(d));
            if holding {
                fused.hold_at_least(before.max(Level::Warn))
            } else {
                level
            }
        } else {
            // Every measured source self-filtered all its points: nothing is known, nothing
            // failed: WARN at least, the level held.
            fused.hold_at_least(Level::Warn)
        };
        if over_budget {
            level = level.max(Level::Warn);
        }
        let header = Header {
            stamp: Time::from_nanos(
                contributing
                    .iter()
                    .map(|(_, l)| l.stamp_ns)
                    .min()
                    .unwrap_or(stamp_ns),
            ),
            frame_id: root_frame.to_owned(),
        };
        // Per link, the minimum over the sources (every source's links come in the engine's
        // order).
        let mut link_distances = JointState {
            header: header.clone(),
            ..JointState::default()
        };
        let mut markers = Vec::new();
        for (k, l) in contributing {
            let Ok(r) = &l.result else { continue };
            let positions = link_positions(r, max_distance);
            if link_distances.name.is_empty() {
                link_distances.name = r.links.iter().map(|l| l.link.clone()).collect();
                link_distances.position = positions;
            } else {
                for (p, q) in link_distances.position.iter_mut().zip(positions) {
                    *p = p.min(q);
                }
            }
            if let (Some(n), Some(d)) = (&r.nearest, l.report.distance) {
                let name = &config.sources[*k].name;
                markers.extend(closest_markers(&header, name, n, d, level));
            }
        }
        if markers.is_empty() {
            markers.push(Marker {
                header: header.clone(),
                ns: format!("{}/closest", config.sources[source].name),
                action: Marker::DELETEALL,
                ..Marker::default()
            });
        }
        markers.extend(shape_markers(config, header.stamp));
        let mut values = vec![kv(
            "sources",
            enabled
                .iter()
                .map(|&k| config.sources[k].name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        )];
        let message = if !faults.is_empty() {
            values.push(kv("fault", "source_fault".into()));
            format!("not monitoring the whole cell: {}", faults.join("; "))
        } else if let Some((k, l, d)) = nearest {
            let name = &config.sources[k].name;
            values.push(kv("distance_m", format!("{d:.6}")));
            values.push(kv("nearest_source", name.clone()));
            let seen = (l.result.as_ref().ok())
                .filter(|r| r.outcome == Outcome::Nearest)
                .and_then(|r| r.nearest.as_ref());
            match seen {
                Some(n) => {
                    values.push(kv("link", n.link.clone()));
                    format!("min distance {d:.3} m (source {name}, link {})", n.link)
                }
                None => format!("nothing within {d:.3} m"),
            }
        } else {
            "every source's valid points were all self-filtered: only the robot is seen, or an \
             obstacle touching it"
                .into()
        };
        statuses.push(DiagnosticStatus {
            level: level.diagnostic(),
            name: format!("{}: all sources", config.node_name),
            message,
            hardware_id: robot.to_owned(),
            values,
        });
        Outputs {
            level,
            min_distance: distance.map(|data| Float64 { data }),
            distance: super::outputs::stamped_distance(config, &header, distance),
            link_distances,
            closest_points: MarkerArray { markers },
            diagnostics: DiagnosticArray {
                header: Header {
                    frame_id: String::new(),
                    ..header
                },
                status: statuses,
            },
            safety_stop: Bool {
                data: level == Level::Error,
            },
            // A source in fault allows no motion, whatever the scaler last had from it.
            speed_scaling: factor.map(|f| SpeedScalingFactor {
                factor: if faults.is_empty() { f } else { 0.0 },
            }),
        }
    }
}
