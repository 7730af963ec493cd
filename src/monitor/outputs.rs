//! The node's outputs for one frame, as ROS 2 messages: the output table, and the one step
//! that renders the cell's fused picture (`fusion::Fused`) into its messages. Each source's
//! status comes from its report (`report`), the levels from `level`, the markers from
//! `markers`. With the unseen space on, a frame publishes twice: its seen outputs the moment its
//! query is done (without the `~/unseen_*` topics), then after the pass its last word, of which
//! the seen distances (`~/min_distance`, `~/distance`, `~/link_distances`) are not repeated
//! ([`Outputs::visit_part`]; `monitor::measure`).
//!
//! | topic | type | content |
//! |---|---|---|
//! | `~/min_distance` | `std_msgs/Float64` | the conservative distance: the certified lower bound (certified), the exact distance (exact), the inner-sphere distance (fast, not conservative); `max_distance` when nothing is nearer; not published on a fault, a cloud without valid points, or one whose valid points the self-filter all removed |
//! | `~/distance` | `sensor_msgs/Range` | the same conservative distance, stamped: `header.stamp` is the stamp of the oldest cloud the fused result rests on (a consumer can age it), `header.frame_id` the robot's root; `range` NaN (REP 117: no valid reading) on a fault; `max_range` = `max_distance`; published on every frame and heartbeat |
//! | `~/link_distances` | `sensor_msgs/JointState` | `name` = links, `position` = each link's conservative distance (`max_distance` when nothing is nearer); `header` = cloud stamp, root frame |
//! | `~/closest_points` | `visualization_msgs/MarkerArray` | a line from the robot to the nearest obstacle point and a text with the distance, coloured by level; DELETEALL on a fault |
//! | `/diagnostics` | `diagnostic_msgs/DiagnosticArray` | one status per source (level, reason, figures), then the cell's fused one (`monitor::fusion`) |
//! | `~/safety_stop` | `std_msgs/Bool` | true at level ERROR (below `stop_distance`, or any fault) |
//! | `~/unseen_distance` | `sensor_msgs/Range` | `unobserved: report` or `protect`: the certified lower bound of the distance from the robot to a body of `detection_capability` that no source has seen (`monitor::unseen`); +∞ where none can lie in the monitored volume, NaN where the pass failed (REP 117); stamped with the frame it was computed at |
//! | `~/unseen_link_distances` | `sensor_msgs/JointState` | the same per link |
//! | `~/speed_scaling` | `control_msgs/SpeedScalingFactor` | the speed and separation monitor's factor (`crate::separation`): 0 on every fault; reliable and transient local, as `joint_trajectory_controller`'s `~/speed_scaling_input` subscribes; not published with `speed_scaling.enabled: false` |
//!
//! Levels: OK above `warn_distance`, WARN below it, ERROR below `stop_distance` or on a fault. A
//! level is left upward only once the distance exceeds its threshold by `hysteresis`, so a
//! distance hovering at a threshold does not flicker. A fault, a cloud without valid points
//! among them (a blinded or covered camera), is ERROR and never lowers the level; a frame over
//! the latency budget is at least WARN. The diagnostics carry the separation monitor's figures:
//! the factor, the separation margin, the protective distance, the approach speed v_r and the
//! time to collision of the link that limits the factor, and where the joint velocities came
//! from.

use crate::config::Config;
use crate::msg::{
    Bool, DiagnosticArray, DiagnosticStatus, Float64, Header, JointState, KeyValue, Marker,
    MarkerArray, OwnedMessage, Range, SpeedScalingFactor, Time,
};

use super::fusion::{Fused, NearestSource};
use super::level::Level;
use super::markers::{closest_markers, shape_markers};
use super::source::Part;
pub use super::stamped::stamped_distance;
use super::unseen::unseen_messages;

/// The messages of one frame. `min_distance` is `None` when nothing may be published.
#[derive(Debug, Clone)]
pub struct Outputs {
    pub level: Level,
    /// The conservative distance published on `~/min_distance`.
    pub min_distance: Option<Float64>,
    /// The same, stamped (NaN when none is known).
    pub distance: Range,
    pub link_distances: JointState,
    pub closest_points: MarkerArray<'static>,
    pub diagnostics: DiagnosticArray,
    pub safety_stop: Bool,
    /// `None` with the separation monitor off.
    pub speed_scaling: Option<SpeedScalingFactor>,
    /// `None` with `unobserved: ignore` (and before the first pass).
    pub unseen_distance: Option<Range>,
    pub unseen_link_distances: Option<JointState>,
}

/// The node's output topics: the one table that the node publishes, `replay --out` writes and
/// `record` records (the doc table at the top of this module).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OutputTopic {
    MinDistance,
    Distance,
    LinkDistances,
    ClosestPoints,
    Diagnostics,
    SafetyStop,
    SpeedScaling,
    UnseenDistance,
    UnseenLinkDistances,
}

impl OutputTopic {
    /// The topic's name: `~/…` is private to the node, anything else is absolute.
    pub fn name(self) -> &'static str {
        match self {
            OutputTopic::MinDistance => "~/min_distance",
            OutputTopic::Distance => "~/distance",
            OutputTopic::LinkDistances => "~/link_distances",
            OutputTopic::ClosestPoints => "~/closest_points",
            OutputTopic::Diagnostics => "/diagnostics",
            OutputTopic::SafetyStop => "~/safety_stop",
            OutputTopic::SpeedScaling => "~/speed_scaling",
            OutputTopic::UnseenDistance => "~/unseen_distance",
            OutputTopic::UnseenLinkDistances => "~/unseen_link_distances",
        }
    }

    /// Whether the topic keeps its last message for late subscribers (transient local): the
    /// speed-scaling factor, which `joint_trajectory_controller` subscribes to that way (a
    /// volatile publisher would not match it).
    pub fn transient_local(self) -> bool {
        self == OutputTopic::SpeedScaling
    }

    /// The topics of the node at `node_path` that keep their last message (transient local).
    pub fn latched(node_path: &str) -> Vec<String> {
        [OutputTopic::SpeedScaling]
            .into_iter()
            .filter(|t| t.transient_local())
            .map(|t| t.topic(node_path))
            .collect()
    }

    /// Whether the node publishes the topic on every heartbeat under `config`: all but
    /// `~/min_distance`, which carries only a known distance, `~/speed_scaling` with the
    /// separation monitor off and the unseen outputs with `unobserved: ignore`. These are the
    /// topics that can offer a QoS deadline.
    pub fn every_beat(self, config: &Config) -> bool {
        match self {
            OutputTopic::MinDistance => false,
            OutputTopic::SpeedScaling => config.ssm.enabled,
            OutputTopic::UnseenDistance | OutputTopic::UnseenLinkDistances => {
                config.unobserved.enabled()
            }
            _ => true,
        }
    }

    /// The fully qualified topic of the node at `node_path` (`/ns/name`).
    pub fn topic(self, node_path: &str) -> String {
        match self.name().strip_prefix("~/") {
            Some(name) => format!("{}/{name}", node_path.trim_end_matches('/')),
            None => self.name().to_owned(),
        }
    }
}

/// What the output table is walked with: each topic with its message type and, for a frame,
/// its message, handed over (`None` when nothing is published on it, as `~/min_distance` on a
/// fault, or when only the types are walked).
pub trait OutputVisitor {
    type Error;
    fn visit<T: OwnedMessage>(
        &mut self,
        topic: OutputTopic,
        message: Option<T>,
    ) -> Result<(), Self::Error>;
}

/// The table: every output topic, in publication order, with its type and the frame's message
/// (only the topics that follow a frame's pass where `following`: see
/// [`Outputs::visit_part`]).
fn each_output<V: OutputVisitor>(
    o: Option<Outputs>,
    following: bool,
    v: &mut V,
) -> Result<(), V::Error> {
    let (mut min, mut distance, mut links, markers, diagnostics, stop, speed, unseen, unseen_links) =
        match o {
            Some(o) => (
                o.min_distance,
                Some(o.distance),
                Some(o.link_distances),
                Some(o.closest_points),
                Some(o.diagnostics),
                Some(o.safety_stop),
                o.speed_scaling,
                o.unseen_distance,
                o.unseen_link_distances,
            ),
            None => (None, None, None, None, None, None, None, None, None),
        };
    if following {
        (min, distance, links) = (None, None, None);
    }
    v.visit::<Float64>(OutputTopic::MinDistance, min)?;
    v.visit::<Range>(OutputTopic::Distance, distance)?;
    v.visit::<JointState>(OutputTopic::LinkDistances, links)?;
    v.visit::<MarkerArray<'static>>(OutputTopic::ClosestPoints, markers)?;
    v.visit::<DiagnosticArray>(OutputTopic::Diagnostics, diagnostics)?;
    v.visit::<Bool>(OutputTopic::SafetyStop, stop)?;
    v.visit::<SpeedScalingFactor>(OutputTopic::SpeedScaling, speed)?;
    v.visit::<Range>(OutputTopic::UnseenDistance, unseen)?;
    v.visit::<JointState>(OutputTopic::UnseenLinkDistances, unseen_links)
}

/// Walks every output topic with its type and no message (to create publishers or
/// subscriptions for all of them).
pub fn visit_output_topics<V: OutputVisitor>(v: &mut V) -> Result<(), V::Error> {
    each_output(None, false, v)
}

impl Outputs {
    /// The outputs of a node that is not monitoring yet (its robot or trees are still being
    /// loaded): ERROR with the reason, the safety stop, no distance and no links.
    pub fn not_monitoring(config: &Config, reason: &str, stamp_ns: i64) -> Self {
        let header = Header {
            stamp: Time::from_nanos(stamp_ns),
            frame_id: String::new(),
        };
        Self {
            level: Level::Error,
            min_distance: None,
            distance: stamped_distance(config, &header, None),
            link_distances: JointState {
                header: header.clone(),
                ..JointState::default()
            },
            closest_points: MarkerArray {
                markers: vec![Marker {
                    header: header.clone(),
                    action: Marker::DELETEALL,
                    ..Marker::default()
                }],
            },
            diagnostics: DiagnosticArray {
                header,
                status: vec![DiagnosticStatus {
                    level: Level::Error.diagnostic(),
                    name: format!("{}: monitor", config.node_name),
                    message: format!("not monitoring: {reason}"),
                    hardware_id: String::new(),
                    values: vec![KeyValue {
                        key: "fault".into(),
                        value: "not_monitoring".into(),
                    }],
                }],
            },
            safety_stop: Bool { data: true },
            speed_scaling: config
                .ssm
                .enabled
                .then_some(SpeedScalingFactor { factor: 0.0 }),
            unseen_distance: None,
            unseen_link_distances: None,
        }
    }

    /// The messages of the fused picture `fused` of the robot `robot` (its root frame
    /// `root_frame`).
    pub fn render(config: &Config, root_frame: &str, robot: &str, fused: Fused) -> Self {
        let header = Header {
            stamp: Time::from_nanos(fused.stamp_ns),
            frame_id: root_frame.to_owned(),
        };
        let mut markers = Vec::new();
        for (k, l) in fused.contributing() {
            let Ok(r) = &l.result else { continue };
            if let (Some(n), Some(d)) = (&r.nearest, l.report.distance) {
                let name = &config.sources[k].name;
                markers.extend(closest_markers(&header, name, n, d, fused.level));
            }
        }
        if markers.is_empty() {
            markers.push(Marker {
                header: header.clone(),
                ns: format!("{}/closest", config.sources[fused.source].name),
                action: Marker::DELETEALL,
                ..Marker::default()
            });
        }
        markers.extend(shape_markers(config, header.stamp));
        let mut statuses = source_statuses(config, robot, &fused);
        statuses.push(cell_status(config, robot, &fused));
        let unseen = (fused.unseen)
            .map(|u| unseen_messages(config, robot, &header, u, fused.level, fused.unseen_limits));
        let (unseen_distance, unseen_link_distances) = match unseen {
            Some(m) => {
                markers.push(m.marker);
                statuses.push(m.status);
                (Some(m.distance), Some(m.link_distances))
            }
            None => (None, None),
        };
        let level = fused.level;
        Outputs {
            level,
            min_distance: fused.distance.map(|data| Float64 { data }),
            distance: stamped_distance(config, &header, fused.distance),
            link_distances: JointState {
                header: header.clone(),
                name: fused.per_link.links,
                position: fused.per_link.distances_m,
                ..JointState::default()
            },
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
            speed_scaling: (fused.speed_factor).map(|factor| SpeedScalingFactor { factor }),
            unseen_distance,
            unseen_link_distances,
        }
    }

    /// Walks every output topic with this frame's message, handed over.
    pub fn visit<V: OutputVisitor>(self, v: &mut V) -> Result<(), V::Error> {
        each_output(Some(self), false, v)
    }

    /// The same; where `following`, only the topics that follow a frame's unseen pass where its
    /// seen outputs went first (`Frame::outputs_follow`): the pass's own (`~/unseen_*`), the
    /// markers and `/diagnostics` with its status, and the stop and the speed factor, which
    /// under `protect` this frame's pass may move. The seen distances (`~/min_distance`,
    /// `~/distance`, `~/link_distances`) went out with the first outputs and are not repeated.
    pub fn visit_part<V: OutputVisitor>(self, following: bool, v: &mut V) -> Result<(), V::Error> {
        each_output(Some(self), following, v)
    }
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.into(),
        value,
    }
}

/// Each enabled source's status: its own where its latest frame made one (a result, or the
/// fault it was), one made here where it has none or its result went stale.
fn source_statuses(config: &Config, robot: &str, fused: &Fused) -> Vec<DiagnosticStatus> {
    let mut statuses = Vec::with_capacity(fused.parts.len() + 1);
    for (k, part) in &fused.parts {
        let name = &config.sources[*k].name;
        statuses.push(match part {
            Part::Measured(l) => l.report.status.clone(),
            Part::Fault {
                status: Some(status),
                ..
            } => (*status).clone(),
            Part::Fault { kind, reason, .. } => DiagnosticStatus {
                level: Level::Error.diagnostic(),
                name: format!("{}: {name}", config.node_name),
                message: reason.clone(),
                hardware_id: robot.to_owned(),
                values: vec![kv("source", name.clone()), kv("fault", (*kind).into())],
            },
        });
    }
    statuses
}

/// The cell's status, `<node>: all sources`: the fused level, and what it rests on.
fn cell_status(config: &Config, robot: &str, fused: &Fused) -> DiagnosticStatus {
    let names: Vec<&str> = (fused.parts.iter())
        .map(|(k, _)| config.sources[*k].name.as_str())
        .collect();
    let mut values = vec![kv("sources", names.join(", "))];
    let message = if !fused.faults.is_empty() {
        values.push(kv("fault", "source_fault".into()));
        format!("not monitoring the whole cell: {}", fused.faults.join("; "))
    } else if let Some(NearestSource {
        source,
        distance_m: d,
        seen,
    }) = &fused.nearest
    {
        let name = &config.sources[*source].name;
        values.push(kv("distance_m", format!("{d:.6}")));
        values.push(kv("nearest_source", name.clone()));
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
    DiagnosticStatus {
        level: fused.level.diagnostic(),
        name: format!("{}: all sources", config.node_name),
        message,
        hardware_id: robot.to_owned(),
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_topics_are_private_or_absolute() {
        assert_eq!(
            OutputTopic::MinDistance.topic("/robots/watch/"),
            "/robots/watch/min_distance"
        );
        assert_eq!(
            OutputTopic::Diagnostics.topic("/robots/watch"),
            "/diagnostics"
        );
        // The table visits every topic once, in order, with no message when asked for types.
        struct Names(Vec<(OutputTopic, bool)>);
        impl OutputVisitor for Names {
            type Error = ();
            fn visit<T: OwnedMessage>(
                &mut self,
                topic: OutputTopic,
                m: Option<T>,
            ) -> Result<(), ()> {
                self.0.push((topic, m.is_some()));
                Ok(())
            }
        }
        let mut names = Names(Vec::new());
        visit_output_topics(&mut names).unwrap();
        assert_eq!(names.0.len(), 9);
        assert!(names.0.iter().all(|(_, m)| !m));
    }
}
