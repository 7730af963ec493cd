//! The node's outputs for one frame, as ROS 2 messages, and the warning level with hysteresis.
//! Each source's part of a frame is a [`SourceReport`]; `monitor::fusion` makes the published
//! outputs from every source's latest.
//!
//! | topic | type | content |
//! |---|---|---|
//! | `~/min_distance` | `std_msgs/Float64` | the conservative distance: the certified lower bound (certified), the exact distance (exact), the inner-sphere distance (fast, not conservative); `max_distance` when nothing is nearer; not published on a fault, a cloud without valid points, or one whose valid points the self-filter all removed |
//! | `~/distance` | `sensor_msgs/Range` | the same conservative distance, stamped: `header.stamp` is the stamp of the oldest cloud the fused result rests on (a consumer can age it), `header.frame_id` the robot's root; `range` NaN (REP 117: no valid reading) on a fault; `max_range` = `max_distance`; published on every frame and heartbeat |
//! | `~/link_distances` | `sensor_msgs/JointState` | `name` = links, `position` = each link's conservative distance (`max_distance` when nothing is nearer); `header` = cloud stamp, root frame |
//! | `~/closest_points` | `visualization_msgs/MarkerArray` | a line from the robot to the nearest obstacle point and a text with the distance, coloured by level; DELETEALL on a fault |
//! | `/diagnostics` | `diagnostic_msgs/DiagnosticArray` | one status per source (level, reason, figures), then the cell's fused one (`monitor::fusion`) |
//! | `~/safety_stop` | `std_msgs/Bool` | true at level ERROR (below `stop_distance`, or any fault) |
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
    Bool, ColorRgba, DiagnosticArray, DiagnosticStatus, Duration, Float64, Header, JointState,
    KeyValue, Marker, MarkerArray, OwnedMessage, Point, Pose, Quaternion, Range,
    SpeedScalingFactor, Time, Vector3,
};
use crate::query::{Outcome, QueryResult};
use crate::separation::SpeedScaling;
use nalgebra::Isometry3;

use super::Fault;

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
    fn color(self) -> ColorRgba {
        let (r, g, b) = match self {
            Level::Ok => (0.1, 0.8, 0.2),
            Level::Warn => (1.0, 0.7, 0.0),
            Level::Error => (0.9, 0.1, 0.1),
        };
        ColorRgba { r, g, b, a: 1.0 }
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

    /// The level for a conservative distance `d` (`None`: no distance is known, a fault).
    pub fn update(&mut self, d: Option<f64>) -> Level {
        let Some(d) = d else {
            self.level = Level::Error;
            self.lower_streak = 0;
            return self.level;
        };
        // Thresholds are raised by the hysteresis for the levels we are above.
        let up = |level: Level, threshold: f64, current: Level| {
            if current >= level {
                threshold + self.hysteresis_m
            } else {
                threshold
            }
        };
        let current = self.level;
        let target = if d < up(Level::Error, self.stop_m, current) {
            Level::Error
        } else if d < up(Level::Warn, self.warn_m, current) {
            Level::Warn
        } else {
            Level::Ok
        };
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
}

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

    /// Whether the node publishes the topic on every heartbeat (with `ssm` the separation
    /// monitor on): all but `~/min_distance`, which carries only a known distance. These are
    /// the topics that can offer a QoS deadline.
    pub fn every_beat(self, ssm: bool) -> bool {
        match self {
            OutputTopic::MinDistance => false,
            OutputTopic::SpeedScaling => ssm,
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

/// The table: every output topic, in publication order, with its type and the frame's message.
fn each_output<V: OutputVisitor>(o: Option<Outputs>, v: &mut V) -> Result<(), V::Error> {
    let (min, distance, links, markers, diagnostics, stop, speed) = match o {
        Some(o) => (
            o.min_distance,
            Some(o.distance),
            Some(o.link_distances),
            Some(o.closest_points),
            Some(o.diagnostics),
            Some(o.safety_stop),
            o.speed_scaling,
        ),
        None => (None, None, None, None, None, None, None),
    };
    v.visit::<Float64>(OutputTopic::MinDistance, min)?;
    v.visit::<Range>(OutputTopic::Distance, distance)?;
    v.visit::<JointState>(OutputTopic::LinkDistances, links)?;
    v.visit::<MarkerArray<'static>>(OutputTopic::ClosestPoints, markers)?;
    v.visit::<DiagnosticArray>(OutputTopic::Diagnostics, diagnostics)?;
    v.visit::<Bool>(OutputTopic::SafetyStop, stop)?;
    v.visit::<SpeedScalingFactor>(OutputTopic::SpeedScaling, speed)
}

/// Walks every output topic with its type and no message (to create publishers or
/// subscriptions for all of them).
pub fn visit_output_topics<V: OutputVisitor>(v: &mut V) -> Result<(), V::Error> {
    each_output(None, v)
}

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

/// `~/distance`: the conservative distance `d` stamped with `header` (NaN: none known).
pub fn stamped_distance(config: &Config, header: &Header, d: Option<f64>) -> Range {
    Range {
        header: header.clone(),
        // Depth cameras and lidars are infrared sensors; the field has no better value.
        radiation_type: 1,
        field_of_view: 0.0,
        min_range: 0.0,
        max_range: config.query.max_distance_m,
        range: d.map_or(f32::NAN, |d| d as f32),
        variance: 0.0,
    }
}

fn point(p: [f64; 3]) -> Point {
    Point {
        x: p[0],
        y: p[1],
        z: p[2],
    }
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
        }
    }

    /// Walks every output topic with this frame's message, handed over.
    pub fn visit<V: OutputVisitor>(self, v: &mut V) -> Result<(), V::Error> {
        each_output(Some(self), v)
    }
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

impl SourceReport {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        config: &Config,
        robot: &str,
        source: &str,
        result: &Result<QueryResult, Fault>,
        processing_s: f64,
        speed: Option<&SpeedScaling>,
        tracker: &mut LevelTracker,
    ) -> Self {
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
        let all_self = result.as_ref().is_ok_and(all_self_filtered);
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

/// Each link's conservative distance in a result, in the engine's link order (a link beyond
/// `per_link_range`: the bound it is known to exceed; `max_distance` when nothing is nearer).
pub fn link_positions(r: &QueryResult, max_distance: f64) -> Vec<f64> {
    r.links
        .iter()
        .map(|l| {
            l.exact_m
                .or(l.lower_m)
                .or(l.distance_m)
                .or(l.farther_than_m)
                .unwrap_or(max_distance)
        })
        .collect()
}

/// The markers of a source's nearest point: a line from the robot to it and the distance as
/// text, coloured by `level`, under the namespace `<source>/closest`.
pub fn closest_markers(
    header: &Header,
    source: &str,
    nearest: &crate::query::Nearest,
    d: f64,
    level: Level,
) -> Vec<Marker<'static>> {
    let base = Marker {
        header: header.clone(),
        ns: format!("{source}/closest"),
        action: Marker::ADD,
        pose: Pose::default(),
        color: level.color(),
        lifetime: Duration { sec: 1, nanosec: 0 },
        ..Marker::default()
    };
    let n = nearest;
    let mid = [0, 1, 2].map(|k| 0.5 * (n.point_root[k] + n.robot_point_root[k]));
    vec![
        Marker {
            id: 0,
            r#type: Marker::LINE_LIST,
            scale: Vector3 {
                x: 0.005,
                ..Vector3::default()
            },
            points: vec![point(n.robot_point_root), point(n.point_root)],
            ..base.clone()
        },
        Marker {
            id: 1,
            r#type: Marker::TEXT_VIEW_FACING,
            pose: Pose {
                position: point(mid),
                ..Pose::default()
            },
            scale: Vector3 {
                z: 0.04,
                ..Vector3::default()
            },
            text: format!("{} {d:.3} m", n.link),
            ..base
        },
    ]
}

/// The exclusion volumes (grey) and attached objects (blue) as RViz shapes, each in its own
/// frame (a volume's TF frame, an object's link) at `stamp`.
pub fn shape_markers(config: &Config, stamp: Time) -> Vec<Marker<'static>> {
    use crate::geometry::{Primitive, Shape};
    let marker = |ns: &str, id: usize, frame: &str, shape: &Shape, pose: &Isometry3<f64>| {
        let mut mesh_resource = String::new();
        let (r#type, scale) = match shape {
            Shape::Primitive(Primitive::Box { size }) => (Marker::CUBE, *size),
            Shape::Primitive(Primitive::Sphere { radius }) => (Marker::SPHERE, [2.0 * radius; 3]),
            Shape::Primitive(Primitive::Cylinder { radius, length }) => {
                (Marker::CYLINDER, [2.0 * radius, 2.0 * radius, *length])
            }
            // RViz loads the file itself (on the machine it runs on).
            Shape::Mesh { file, scale } => {
                let file = std::fs::canonicalize(file).unwrap_or_else(|_| file.clone());
                mesh_resource = format!("file://{}", file.display());
                (Marker::MESH_RESOURCE, *scale)
            }
        };
        let t = pose.translation.vector;
        Marker {
            header: Header {
                stamp,
                frame_id: frame.to_owned(),
            },
            ns: ns.to_owned(),
            id: id as i32,
            r#type,
            action: Marker::ADD,
            pose: Pose {
                position: point([t.x, t.y, t.z]),
                orientation: Quaternion::from_unit(&pose.rotation),
            },
            scale: Vector3 {
                x: scale[0],
                y: scale[1],
                z: scale[2],
            },
            lifetime: Duration { sec: 1, nanosec: 0 },
            frame_locked: true,
            mesh_resource,
            ..Marker::default()
        }
    };
    let volumes = config
        .exclusion_volumes
        .iter()
        .enumerate()
        .map(|(k, v)| Marker {
            color: ColorRgba {
                r: 0.5,
                g: 0.5,
                b: 0.5,
                a: 0.3,
            },
            text: v.name.clone(),
            ..marker(
                "exclusion_volumes",
                k,
                &v.frame,
                &v.shape.shape(),
                &v.frame_from_volume,
            )
        });
    let objects = config
        .attached_objects
        .iter()
        .enumerate()
        .map(|(k, o)| Marker {
            color: ColorRgba {
                r: 0.2,
                g: 0.4,
                b: 0.9,
                a: 0.6,
            },
            text: o.name.clone(),
            ..marker(
                "attached_objects",
                k,
                &o.link,
                &o.shape,
                &o.link_from_object,
            )
        });
    volumes.chain(objects).collect()
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
        assert_eq!(names.0.len(), 7);
        assert!(names.0.iter().all(|(_, m)| !m));
    }

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
