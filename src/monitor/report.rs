//! One source's report of a frame: its own level (with its own hysteresis), its diagnostic
//! status (the reason of a fault, or the counts of the query and the separation monitor's
//! figures), and what it contributes to the fused picture (`fusion`): its conservative distance,
//! whether the self-filter took every valid point, whether it ran over the latency budget.
//! Distances in m, times in s (ms in the status).

use super::fault::Fault;
use super::level::{Level, LevelTracker};
use crate::config::Config;
use crate::msg::{DiagnosticStatus, KeyValue};
use crate::query::{Outcome, QueryResult};
use crate::separation::SpeedScaling;

/// The conservative distance of a result: `None` when there were no valid points.
pub fn conservative_distance(r: &QueryResult) -> Option<f64> {
    match (&r.outcome, &r.nearest) {
        (Outcome::Nearest, Some(n)) => Some(n.lower_m.unwrap_or(n.distance_m)),
        (Outcome::NothingWithinMaxDistance, _) => Some(f64::from(r.max_distance_m)),
        _ => None,
    }
}

/// Every valid point within the self-filter padding of the robot: the camera sees only the
/// robot, or an obstacle touching it, which the padding cannot tell apart.
fn all_self_filtered(r: &QueryResult) -> bool {
    let c = &r.counts;
    c.self_filtered > 0 && c.self_filtered == c.total - c.invalid
}

/// What `~/min_distance` carries for a result: its conservative distance, unless the
/// self-filter removed every valid point (then nothing is known).
pub fn published_distance(r: &QueryResult) -> Option<f64> {
    conservative_distance(r).filter(|_| !all_self_filtered(r))
}

/// One source's part of a frame: its own level (with its own hysteresis), its diagnostic
/// status, and what it contributes to the fused result (`monitor::fusion`).
#[derive(Debug, Clone)]
pub struct SourceReport {
    pub level: Level,
    pub status: DiagnosticStatus,
    /// The source's conservative distance (`None`: a fault, or every valid point
    /// self-filtered).
    pub distance: Option<f64>,
    /// Every valid point self-filtered: no distance, and the level held at WARN at least.
    pub all_self: bool,
    /// The frame took longer than `latency_budget`.
    pub over_budget: bool,
}

/// What a frame of a source gave, as its report reads it.
#[derive(Clone, Copy)]
pub struct FrameFacts<'a> {
    /// The source's name.
    pub source: &'a str,
    pub result: Result<&'a QueryResult, &'a Fault>,
    /// Decode, poses and query, s.
    pub processing_s: f64,
    /// The separation stage (`None` with the separation monitor off).
    pub speed: Option<&'a SpeedScaling>,
}

impl SourceReport {
    /// The report of `facts` by the robot `robot`; `tracker` is the source's own level.
    pub fn new(
        config: &Config,
        robot: &str,
        facts: FrameFacts,
        tracker: &mut LevelTracker,
    ) -> Self {
        let FrameFacts {
            source,
            result,
            processing_s,
            speed,
        } = facts;
        let kv = |key: &str, value: String| KeyValue {
            key: key.into(),
            value,
        };
        let mut values = vec![
            kv("source", source.into()),
            kv("latency_ms", format!("{:.3}", processing_s * 1e3)),
        ];
        let over_budget = processing_s > config.latency_budget_s;
        // Every valid point self-filtered: no distance, WARN at least, and the level held (a
        // stop is never released by this).
        let all_self = result.is_ok_and(all_self_filtered);
        let (distance, mut message) = match result {
            Err(fault) => {
                values.push(kv("fault", fault.kind().into()));
                (None, fault.to_string())
            }
            Ok(r) => {
                let c = &r.counts;
                let used = c.evaluated + c.pruned;
                values.extend([
                    kv("mode", format!("{:?}", r.mode).to_lowercase()),
                    kv("points_total", c.total.to_string()),
                    kv("points_used", used.to_string()),
                    kv("points_culled", c.outside_roi.to_string()),
                    kv("points_self_filtered", c.self_filtered.to_string()),
                    kv("points_invalid", c.invalid.to_string()),
                ]);
                if config.stray.enabled() {
                    values.push(kv("points_stray_rejected", r.stray_rejected.to_string()));
                }
                values.extend(
                    (r.excluded.iter())
                        .map(|(v, n)| kv(&format!("points_excluded.{v}"), n.to_string())),
                );
                values.extend(
                    r.self_filtered_by_link.iter().map(|(link, n)| {
                        kv(&format!("points_self_filtered.{link}"), n.to_string())
                    }),
                );
                if let Some(n) = &r.nearest {
                    values.extend([
                        kv("distance_m", format!("{:.6}", n.distance_m)),
                        kv("link", n.link.clone()),
                    ]);
                    if let Some(l) = n.lower_m {
                        values.push(kv("lower_m", format!("{l:.6}")));
                    }
                }
                let d = published_distance(r);
                let message = match d {
                    _ if all_self => format!(
                        "the self-filter removed every valid point ({} within \
                         self_filter_padding of the robot): only the robot is seen, or an \
                         obstacle touching it",
                        c.self_filtered
                    ),
                    Some(d) if r.outcome == Outcome::Nearest => format!("min distance {d:.3} m"),
                    Some(d) => format!("nothing within {d:.3} m"),
                    None => "no valid points in the cloud".into(),
                };
                (d, message)
            }
        };
        // No distance (a fault, or a result without one) is ERROR: never read as "clear".
        let mut level = if all_self {
            tracker.hold_at_least(Level::Warn)
        } else {
            tracker.update(distance)
        };
        if over_budget {
            level = level.max(Level::Warn);
            message.push_str(&format!(
                "; over the latency budget ({:.1} ms > {:.1} ms)",
                processing_s * 1e3,
                config.latency_budget_s * 1e3
            ));
        }
        if let Some(speed) = speed {
            values.push(kv("speed_scaling", format!("{:.3}", speed.factor)));
            match &speed.separation {
                Ok(s) => values.extend([
                    kv("ssm_link", s.link.clone()),
                    kv("separation_margin_m", format!("{:.4}", s.margin_m)),
                    kv("protective_distance_m", format!("{:.4}", s.protective_m)),
                    kv("approach_speed_mps", format!("{:.4}", s.approach_mps)),
                    kv(
                        "nearest_approach_speed_mps",
                        s.nearest_approach_mps
                            .map_or_else(|| "-".into(), |v| format!("{v:.4}")),
                    ),
                    kv(
                        "time_to_collision_s",
                        format!("{:.3}", s.time_to_collision_s),
                    ),
                    kv("ssm_allowed_factor", format!("{:.3}", s.allowed)),
                    kv("joint_velocities", s.velocity_source.name().into()),
                ]),
                Err(reason) => values.push(kv("ssm_fault", reason.clone())),
            }
        }
        Self {
            level,
            status: DiagnosticStatus {
                level: level.diagnostic(),
                name: format!("{}: {source}", config.node_name),
                message,
                hardware_id: robot.to_owned(),
                values,
            },
            distance,
            all_self,
            over_budget,
        }
    }
}
