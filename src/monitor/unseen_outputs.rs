//! The unobserved space's messages (`unobserved: report | protect`): `~/unseen_distance`
//! (`sensor_msgs/Range`, as `~/distance`: NaN where no unseen region can hold a body of the
//! detection capability, or where the pass failed), `~/unseen_link_distances`
//! (`sensor_msgs/JointState`, per link), the opened cells nearest the robot as one cube-list
//! marker (namespace `unseen`, on `~/closest_points`: where a second camera would help), and a
//! status `<node>: unobserved space` in `/diagnostics` with the fractions observed per source
//! and fused. Its level: OK, WARN where the pass failed under `report`, ERROR under `protect`
//! (then a fault of the cell too), and under `protect` the level the unseen distance implies.

use crate::config::Config;
use crate::msg::{
    ColorRgba, DiagnosticStatus, Header, JointState, KeyValue, Marker, Point, Range, Vector3,
};

use super::fusion::Fused;
use super::level::Level;
use super::stamped::stamped_distance;
use super::unseen_state::Unseen;

/// `~/unseen_distance`, `~/unseen_link_distances`, the marker and the status of `unseen`.
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

/// The messages of the pass `unseen` in the picture `fused`, under `header` (root frame).
pub fn unseen_messages(
    config: &Config,
    robot: &str,
    header: &Header,
    unseen: &Unseen,
    fused: &Fused,
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
    let (status, distance, links, marker) =
        match &unseen.outcome {
            Err(reason) => {
                let level = if u.protects() {
                    Level::Error
                } else {
                    Level::Warn
                };
                values.push(kv("fault", "unobserved_unknown".into()));
                let status = DiagnosticStatus {
                    level: level.diagnostic(),
                    name,
                    message: format!("unobserved space not known: {reason}"),
                    hardware_id: robot.to_owned(),
                    values,
                };
                (status, None, JointState::default(), delete_marker(&header))
            }
            Ok(f) => {
                let show = |d: Option<f64>| d.map_or("nan".to_string(), |d| format!("{d:.6}"));
                values.push(kv("distance_m", show(f.distance_m)));
                values.push(kv("self_shadow_distance_m", show(f.self_shadow_m)));
                values.push(kv(
                    "observed_fraction",
                    format!("{:.4}", f.observed_fraction),
                ));
                for (source, fraction) in &f.per_source {
                    let v = match fraction {
                        Ok(x) => format!("{x:.4}"),
                        Err(e) => format!("0 (observes nothing free: {e})"),
                    };
                    values.push(kv(&format!("observed_fraction.{source}"), v));
                }
                for (stage, t) in &f.stages_s {
                    values.push(kv(&format!("{stage}_ms"), format!("{:.3}", t * 1e3)));
                }
                for (key, n) in [
                    ("cells", f.cells),
                    ("unseen_cells", f.unseen_cells),
                    ("self_shadow_cells", f.shadow_cells),
                    ("opened_cells", f.opened_cells),
                ] {
                    values.push(kv(key, n.to_string()));
                }
                let level = if fused.unseen_limits {
                    fused.level
                } else {
                    Level::Ok
                };
                let message =
                    match f.distance_m {
                        None => format!(
                            "no unseen region can hold a body of {} m ({:.1} % of the volume seen)",
                            u.detection_capability_m,
                            100.0 * f.observed_fraction
                        ),
                        Some(d) => format!(
                    "unseen space within {d:.3} m of the robot{} ({:.1} % of the volume seen)",
                    if fused.unseen_limits { ", which sets the level (protect)" } else { "" },
                    100.0 * f.observed_fraction
                ),
                    };
                let status = DiagnosticStatus {
                    level: level.diagnostic(),
                    name,
                    message,
                    hardware_id: robot.to_owned(),
                    values,
                };
                let links = JointState {
                    header: header.clone(),
                    name: f.per_link.iter().map(|(l, _)| l.clone()).collect(),
                    position: f.per_link.iter().map(|(_, d)| *d).collect(),
                    ..JointState::default()
                };
                (
                    status,
                    f.distance_m,
                    links,
                    cells_marker(&header, f.resolution_m, &f.near_cells),
                )
            }
        };
    UnseenMessages {
        distance: stamped_distance(config, &header, distance),
        link_distances: JointState { header, ..links },
        marker,
        status,
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

/// The opened cells nearest the robot, one translucent cube each.
fn cells_marker(header: &Header, size: f64, centres: &[[f32; 3]]) -> Marker<'static> {
    if centres.is_empty() {
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
        color: ColorRgba {
            r: 0.6,
            g: 0.2,
            b: 0.8,
            a: 0.35,
        },
        points: (centres.iter())
            .map(|c| Point {
                x: f64::from(c[0]),
                y: f64::from(c[1]),
                z: f64::from(c[2]),
            })
            .collect(),
        ..Marker::default()
    }
}
