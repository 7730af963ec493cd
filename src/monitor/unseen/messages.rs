//! The unseen space's messages (`unobserved: report | protect`): `~/unseen_distance`
//! (`sensor_msgs/Range`, as `~/distance`; REP 117: +∞ where no hidden body of the detection
//! capability can lie in the monitored volume, NaN where the pass failed), `~/unseen_link_distances`
//! (`sensor_msgs/JointState`, per link), the hidden places nearest the robot as one cube-list
//! marker coloured by cause (namespace `unseen`, on `~/closest_points`: where a second camera
//! would help), and a status `<node>: unobserved space` in `/diagnostics` with the nearest
//! hidden place, its cause, what each source observes, the search's counts and each stage's
//! time. Its level: OK, WARN where the pass failed under `report`, ERROR under `protect` (then a
//! fault of the cell too), and under `protect` the level the unseen distance implies.

use crate::config::Config;
use crate::msg::{
    ColorRgba, DiagnosticStatus, Header, JointState, KeyValue, Marker, Point, Range, Vector3,
};
use crate::unseen::{Cause, Spot};

use super::super::level::Level;
use super::super::stamped::stamped_distance;
use super::facts::{Unseen, UnseenFacts};

/// `~/unseen_distance`, `~/unseen_link_distances`, the marker and the status of one pass.
pub struct UnseenMessages {
    pub distance: Range,
    pub link_distances: JointState,
    pub marker: Marker<'static>,
    pub status: DiagnosticStatus,
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.into(),
        value,
    }
}

/// The colour of a hidden place of `cause` on `~/closest_points`.
pub fn cause_colour(cause: Cause) -> ColorRgba {
    let (r, g, b) = match cause {
        Cause::NoReturn => (0.6, 0.2, 0.8),
        Cause::Occluded => (1.0, 0.55, 0.0),
        Cause::RobotShadow => (0.35, 0.5, 0.75),
        Cause::OutsideView => (0.5, 0.5, 0.5),
    };
    ColorRgba { r, g, b, a: 0.4 }
}

/// The messages of the pass `unseen` under `header` (root frame), in a picture of the cell's
/// level `level`, which the unseen distance sets where `limits` (`protect`, and nearer than the
/// seen one).
pub fn unseen_messages(
    config: &Config,
    robot: &str,
    header: &Header,
    unseen: &Unseen,
    level: Level,
    limits: bool,
) -> UnseenMessages {
    let u = &config.unobserved;
    let header = Header {
        stamp: crate::msg::Time::from_nanos(unseen.stamp_ns),
        ..header.clone()
    };
    let mut values = vec![
        kv("policy", crate::choice::Choice::name(u.policy).into()),
        kv(
            "self_shadow",
            crate::choice::Choice::name(u.self_shadow).into(),
        ),
        kv(
            "detection_capability_m",
            format!("{}", u.detection_capability_m),
        ),
        kv("compute_ms", format!("{:.3}", unseen.compute_s * 1e3)),
    ];
    let name = format!("{}: unobserved space", config.node_name);
    let status = |level: Level, message: String, values: Vec<KeyValue>| DiagnosticStatus {
        level: level.diagnostic(),
        name: name.clone(),
        message,
        hardware_id: robot.to_owned(),
        values,
    };
    match &unseen.outcome {
        Err(fault) => {
            let level = if u.protects() {
                Level::Error
            } else {
                Level::Warn
            };
            values.push(kv("fault", "unobserved_unknown".into()));
            UnseenMessages {
                // NaN: not known (REP 117's erroneous reading).
                distance: stamped_distance(config, &header, None),
                link_distances: JointState {
                    header: header.clone(),
                    ..JointState::default()
                },
                marker: delete_marker(&header),
                status: status(
                    level,
                    format!("unobserved space not known: {fault}"),
                    values,
                ),
            }
        }
        Ok(f) => {
            fact_values(f, &mut values);
            let level = if limits { level } else { Level::Ok };
            let seen = |f: &UnseenFacts| match f.counts.blocks {
                0 => String::new(),
                _ => format!(
                    " ({} of {} blocks seen free whole, {} not needed)",
                    f.counts.blocks_free, f.counts.blocks, f.counts.blocks_pruned
                ),
            };
            let message = match (f.distance_m, &f.nearest) {
                _ if f.blind => {
                    "no source observes anything free: the whole volume is hidden".into()
                }
                (None, _) => format!(
                    "no hidden body of {} m can lie in the monitored volume{}",
                    u.detection_capability_m,
                    seen(f)
                ),
                (Some(d), nearest) => format!(
                    "unseen space within {d:.3} m of the robot{}{}{}",
                    nearest.map_or(String::new(), |n| format!(" ({})", n.cause.name())),
                    if limits {
                        ", which sets the level (protect)"
                    } else {
                        ""
                    },
                    seen(f)
                ),
            };
            // +∞: nothing hidden can be there (REP 117's "no detection within range").
            let distance = Range {
                range: f.distance_m.map_or(f32::INFINITY, |d| d as f32),
                ..stamped_distance(config, &header, None)
            };
            UnseenMessages {
                distance,
                link_distances: JointState {
                    header: header.clone(),
                    name: f.per_link.iter().map(|(l, _)| l.clone()).collect(),
                    position: f.per_link.iter().map(|(_, d)| *d).collect(),
                    ..JointState::default()
                },
                marker: spots_marker(&header, f.resolution_m, &f.near),
                status: status(level, message, values),
            }
        }
    }
}

/// The facts as diagnostic values.
fn fact_values(f: &UnseenFacts, values: &mut Vec<KeyValue>) {
    let show = |d: Option<f64>| d.map_or("inf".to_string(), |d| format!("{d:.6}"));
    values.push(kv("distance_m", show(f.distance_m)));
    if let Some(s) = f.self_shadow_m {
        values.push(kv("self_shadow_distance_m", format!("{s:.6}")));
    }
    if let Some(n) = &f.nearest {
        values.push(kv("nearest_cause", n.cause.name().into()));
        let [x, y, z] = n.centre;
        values.push(kv("nearest_point", format!("{x:.3} {y:.3} {z:.3}")));
    }
    for (source, state) in &f.per_source {
        let v = match state {
            Ok(()) => "observes".to_string(),
            Err(e) => format!("observes nothing free: {e}"),
        };
        values.push(kv(&format!("source.{source}"), v));
    }
    for cause in Cause::ALL {
        let n = f.near.iter().filter(|s| s.cause == cause).count();
        if n > 0 {
            values.push(kv(&format!("drawn.{}", cause.name()), n.to_string()));
        }
    }
    for (stage, t) in &f.stages_s {
        values.push(kv(&format!("{stage}_ms"), format!("{:.3}", t * 1e3)));
    }
    let c = &f.counts;
    for (key, n) in [
        ("cells", f.cells),
        ("blocks", c.blocks),
        ("blocks_free", c.blocks_free),
        ("blocks_pruned", c.blocks_pruned),
        ("centres_judged", c.centres_judged),
        ("centres_dropped", c.centres_dropped),
        ("hidden_found", c.hidden),
        ("shadow_found", c.shadow),
        ("distance_queries", c.batches),
        ("views_on_gpu", c.views_on_gpu),
    ] {
        values.push(kv(key, n.to_string()));
    }
}

fn delete_marker(header: &Header) -> Marker<'static> {
    Marker {
        header: header.clone(),
        ns: "unseen".into(),
        action: Marker::DELETE,
        ..Marker::default()
    }
}

/// The hidden places nearest the robot, one translucent cube each, coloured by cause.
fn spots_marker(header: &Header, size: f64, spots: &[Spot]) -> Marker<'static> {
    if spots.is_empty() {
        return delete_marker(header);
    }
    Marker {
        header: header.clone(),
        ns: "unseen".into(),
        r#type: Marker::CUBE_LIST,
        action: Marker::ADD,
        pose: crate::msg::Pose::default(),
        scale: Vector3 {
            x: size,
            y: size,
            z: size,
        },
        color: cause_colour(spots[0].cause),
        points: (spots.iter())
            .map(|s| Point {
                x: f64::from(s.centre[0]),
                y: f64::from(s.centre[1]),
                z: f64::from(s.centre[2]),
            })
            .collect(),
        colors: spots.iter().map(|s| cause_colour(s.cause)).collect(),
        ..Marker::default()
    }
}
