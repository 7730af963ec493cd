//! Replay: a recorded bag fed through the monitor in log-time order, exactly as the live node
//! would receive it — `/tf_static`, `/tf`, the joint-state topic and every enabled source's
//! clouds or depth images (with their CameraInfo) — one [`ReplayFrame`] per cloud or image and
//! a [`Summary`]. With an output path the node's
//! outputs are written to an MCAP under the live node's topics and types, each at the cloud's
//! log time plus its processing time.
//!
//! Bags made by the scenario generator carry the exact minimum distance of every frame on
//! [`GROUND_TRUTH_TOPIC`] at the cloud's log time, and the separation monitor's truth (approach
//! speed, margin) on [`APPROACH_TRUTH_TOPIC`] and [`MARGIN_TRUTH_TOPIC`]; replay reports them
//! beside the result, with the speed-scaling factor and the margin the monitor found.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use serde::Serialize;

use std::time::Instant;

use crate::bag::{read_messages, writer::Compression, BagError, BagMessage, BagWriter};
use crate::choice::Choice;
use crate::cloud::{pointcloud2, CloudError};
use crate::config::SourceKind;
use crate::msg::{
    self, CameraInfo, Float64, Image, JointState, OwnedMessage, RosMessage, TfMessage,
};
use crate::query::Outcome;
use crate::stats::percentile;

use super::fault::InputError;
use super::level::Level;
use super::outputs::{OutputTopic, OutputVisitor};
use super::pipeline::{Frame, Monitor};
use super::setup::MonitorError;

/// Where generated bags record the exact minimum distance of each cloud (`std_msgs/Float64`).
pub use crate::bag::{APPROACH_TRUTH_TOPIC, GROUND_TRUTH_TOPIC, MARGIN_TRUTH_TOPIC};

/// One cloud of the replay.
#[derive(Debug, Clone, Serialize)]
pub struct ReplayFrame {
    pub index: usize,
    pub source: String,
    pub stamp_ns: i64,
    pub level: Level,
    /// `nearest`, `no_points`, `nothing_within_max_distance` or `fault`.
    pub outcome: &'static str,
    /// The mode's distance (inner-sphere upper bound, or exact).
    pub distance_m: Option<f64>,
    /// The certified lower bound (certified, exact).
    pub lower_m: Option<f64>,
    /// What `~/min_distance` carries.
    pub min_distance_m: Option<f64>,
    pub link: Option<String>,
    /// Where the query ran (`None` for a fault).
    pub backend: Option<crate::query::Backend>,
    pub processing_ms: f64,
    pub fault: Option<String>,
    /// The recorded exact minimum distance, when the bag has one.
    pub truth_m: Option<f64>,
    /// What `~/speed_scaling` carries (`None` with the separation monitor off).
    pub speed_scaling: Option<f64>,
    /// The factor this frame allowed before hysteresis and rate limit.
    pub allowed_factor: Option<f64>,
    /// Separation margin, distance, protective separation distance and approach speed of the
    /// link that limits the factor, and which link.
    pub separation_margin_m: Option<f64>,
    pub ssm_distance_m: Option<f64>,
    pub protective_m: Option<f64>,
    pub approach_mps: Option<f64>,
    /// The approach speed at the nearest link's closest point.
    pub nearest_approach_mps: Option<f64>,
    pub ssm_link: Option<String>,
    /// Time of the separation stage, ms.
    pub ssm_ms: Option<f64>,
    /// Time of the fusion across sources and the output messages, ms.
    pub outputs_ms: f64,
    /// Why the separation monitor gave 0, when it did.
    pub ssm_fault: Option<String>,
    /// The recorded approach speed and separation margin, when the bag has them.
    pub truth_approach_mps: Option<f64>,
    pub truth_margin_m: Option<f64>,
    /// What `~/unseen_distance` carries where finite (`None`: not published, the pass failed,
    /// or +∞: no hidden body can lie in the volume, which `unseen_all_seen` tells).
    pub unseen_m: Option<f64>,
    pub unseen_all_seen: bool,
    /// Why no source saw the hidden place nearest the robot (`unseen::Cause::name`), and where
    /// it is (root frame, m).
    pub unseen_cause: Option<&'static str>,
    pub unseen_point: Option<[f32; 3]>,
    /// What the search counted: among them the hidden places it found, counted and in the
    /// robot's shadow apart (`apart`: all of the volume's where nothing counted is hidden, as
    /// the search then examines it whole), and the views whose cells the GPU judged.
    pub unseen_counts: Option<crate::unseen::Counts>,
    /// Under `protect`, why the pass gave no distance: a fault of the cell (ERROR, no
    /// distance), a late pass among them.
    pub unseen_fault: Option<String>,
    /// The unobserved-space pass, ms, and each of its stages.
    pub unseen_ms: Option<f64>,
    pub unseen_stages_ms: Vec<(&'static str, f64)>,
    /// Where the seen outputs went before the pass (`Frame::first`): the time to them, ms, and
    /// whether they carried the distance (then only the topics that follow the pass are
    /// written again: `Frame::outputs_follow`).
    pub first_ms: Option<f64>,
    pub outputs_follow: bool,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    pub frames: usize,
    /// Clouds that gave a fault instead of a distance, by kind; under `protect` an unseen-space
    /// pass that gave none (`unseen_late`, …) counts as its frame's fault.
    pub faults: BTreeMap<String, usize>,
    /// Clouds not processed (a replay processes every cloud; the live node drops old ones).
    pub dropped: usize,
    /// TF and joint-state messages refused.
    pub input_errors: usize,
    pub processing_p50_ms: f64,
    pub processing_p99_ms: f64,
    /// Largest |min_distance − truth| over the frames with a recorded truth.
    pub max_error_vs_truth_m: Option<f64>,
    /// Frames with a recorded truth whose smaller of `~/min_distance` and `~/unseen_distance`
    /// (what `protect` takes) exceeds it by more than 0.1 mm, and how many were checked: the
    /// unseen distance's promise where the obstacle hides. The promise is for a body inside the
    /// monitored volume: the bag's truth does not say where its body is, so a frame whose body
    /// lies outside the volume may count here without a broken promise.
    pub protected_above_truth: usize,
    pub protected_checked: usize,
    /// The unobserved-space pass, ms (median and 99th percentile over the frames that ran it).
    pub unseen_p50_ms: Option<f64>,
    pub unseen_p99_ms: Option<f64>,
}

/// A replay that cannot run: the monitor's reset, or the bag in or out (each names its file).
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error(transparent)]
    Monitor(#[from] MonitorError),
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error(
        "{bag}: no message on the enabled sources' topics ({sources}); the bag has: {found} \
         (set <source>.topic to the cloud topic, and <source>.type to depth_image for a \
         sensor_msgs/Image depth topic)"
    )]
    NoClouds {
        bag: std::path::PathBuf,
        sources: String,
        found: String,
    },
}

/// What a replayed cloud's stamp is checked against (`Fault::StaleCloud`, `FutureCloud`); each
/// one's meaning: its [`Choice::about`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Clock {
    #[default]
    Log,
    Stamp,
}

impl Choice for Clock {
    const ALL: &'static [Self] = &[Clock::Log, Clock::Stamp];
    fn name(self) -> &'static str {
        match self {
            Clock::Log => "log",
            Clock::Stamp => "stamp",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Clock::Log => {
                "The message's log time: when the recorder received it, as the node's clock \
                 would have read (what `ros2 bag play --clock` gives a node with `use_sim_time`)"
            }
            Clock::Stamp => {
                "The cloud's own stamp, which turns the stamp check off: for bags whose log times \
                 are not when the data was taken (converted, or recorded from a replay). Say so \
                 when used"
            }
        }
    }
}

/// Writes a frame's outputs into a bag, each on its topic of the output table.
struct BagSink<'a> {
    writer: &'a mut BagWriter,
    node_path: &'a str,
    at: u64,
}

impl OutputVisitor for BagSink<'_> {
    type Error = BagError;
    fn visit<T: OwnedMessage>(
        &mut self,
        topic: OutputTopic,
        message: Option<T>,
    ) -> Result<(), BagError> {
        match message {
            Some(m) => self.writer.write(&topic.topic(self.node_path), self.at, &m),
            None => Ok(()),
        }
    }
}

/// Replays `bag` through `monitor` (reset first), calling `on_frame` for each cloud; writes the outputs to
/// `out` when given. Each cloud's stamp is checked against `clock`.
pub fn replay(
    monitor: &mut Monitor,
    bag: &Path,
    out: Option<(&Path, Compression)>,
    clock: Clock,
    on_frame: &mut dyn FnMut(&ReplayFrame),
) -> Result<Summary, ReplayError> {
    replay_frames(monitor, bag, out, clock, usize::MAX, on_frame)
}

/// [`replay`] up to `frames` clouds: the monitor then holds the state of the last one (its
/// sources' latest results and views, the latest unseen-space pass), for what is drawn of it.
pub fn replay_frames(
    monitor: &mut Monitor,
    bag: &Path,
    out: Option<(&Path, Compression)>,
    clock: Clock,
    frames: usize,
    on_frame: &mut dyn FnMut(&ReplayFrame),
) -> Result<Summary, ReplayError> {
    monitor.reset()?;
    let messages = read(monitor, bag)?;
    let truths = Truths::of(&messages);
    let node_path = monitor.config.node_path();
    let mut writer = out
        .map(|(path, compression)| BagWriter::create(path, compression))
        .transpose()?;
    for t in OutputTopic::latched(&node_path) {
        writer.iter_mut().for_each(|w| w.latch(&t));
    }
    let mut summary = Summary::default();
    let mut times = Vec::new();
    let mut unseen_times = Vec::new();
    for m in &messages {
        if summary.frames >= frames {
            break;
        }
        summary.input_errors += feed(monitor, &m.topic, &m.data);
        let Some(source) = monitor.source_of(&m.topic) else {
            continue;
        };
        let now_ns = (clock == Clock::Log).then_some(m.log_time_ns as i64);
        let frame = source_frame(monitor, source, &m.data, now_ns);
        times.push(frame.processing_s * 1e3);
        if let Err(f) = &frame.result {
            *summary.faults.entry(f.kind().into()).or_default() += 1;
        } else if let Some(f) = &frame.unseen_fault {
            *summary.faults.entry(f.kind().into()).or_default() += 1;
        }
        let row = ReplayFrame::of(summary.frames, &frame, &truths, m.log_time_ns);
        summary.frames += 1;
        if let (Some(d), Some(t)) = (row.min_distance_m, row.truth_m) {
            let e = summary
                .max_error_vs_truth_m
                .unwrap_or(0.0)
                .max((d - t).abs());
            summary.max_error_vs_truth_m = Some(e);
        }
        if let (Some(t), Some(_)) = (row.truth_m, row.unseen_ms) {
            let seen = row.min_distance_m.unwrap_or(f64::INFINITY);
            let unseen = row.unseen_m.unwrap_or(f64::INFINITY);
            summary.protected_checked += 1;
            let faulted = row.fault.is_some() || row.unseen_fault.is_some();
            if seen.min(unseen) > t + 1e-4 && !faulted {
                summary.protected_above_truth += 1;
            }
        }
        unseen_times.extend(row.unseen_ms);
        on_frame(&row);
        if let Some(w) = writer.as_mut() {
            // As the node publishes them: the seen outputs first where the pass followed them.
            let at = |s: f64| m.log_time_ns + (s * 1e9) as u64;
            let following = frame.outputs_follow();
            if let Some((first, first_s)) = frame.first {
                first.visit(&mut BagSink {
                    writer: w,
                    node_path: &node_path,
                    at: at(first_s),
                })?;
            }
            frame.outputs.visit_part(
                following,
                &mut BagSink {
                    writer: w,
                    node_path: &node_path,
                    at: at(frame.processing_s),
                },
            )?;
        }
    }
    if let Some(w) = writer {
        w.finish()?;
    }
    times.sort_by(f64::total_cmp);
    unseen_times.sort_by(f64::total_cmp);
    summary.processing_p50_ms = percentile(&times, 0.5).unwrap_or(0.0);
    summary.processing_p99_ms = percentile(&times, 0.99).unwrap_or(0.0);
    summary.unseen_p50_ms = percentile(&unseen_times, 0.5);
    summary.unseen_p99_ms = percentile(&unseen_times, 0.99);
    Ok(summary)
}

/// The messages of `bag` that the monitor reads (and the truths), in log-time order. A bag
/// with no cloud for any enabled source replays nothing: that is an error that says what the
/// bag has, rather than "0 frames, 0 faults" as if all were well.
fn read(monitor: &Monitor, bag: &Path) -> Result<Vec<BagMessage>, ReplayError> {
    let config = &monitor.config;
    // Every channel of the bag, to say what it has when it has no cloud for the sources.
    let channels = std::cell::RefCell::new(std::collections::BTreeSet::new());
    let keep = |t: &str, schema: &str| {
        channels.borrow_mut().insert(format!("{t} ({schema})"));
        t == "/tf"
            || t == "/tf_static"
            || t == config.joint_states_topic
            || t == GROUND_TRUTH_TOPIC
            || t == APPROACH_TRUTH_TOPIC
            || t == MARGIN_TRUTH_TOPIC
            || config.sources.iter().any(|s| s.topic == t)
            || (config.sources.iter()).any(|s| s.camera_info_topic.as_deref() == Some(t))
    };
    let messages = read_messages(bag, &keep)?;
    if messages
        .iter()
        .any(|m| monitor.source_of(&m.topic).is_some())
    {
        return Ok(messages);
    }
    let found: Vec<String> = channels.into_inner().into_iter().collect();
    Err(ReplayError::NoClouds {
        bag: bag.to_owned(),
        sources: (config.sources.iter())
            .filter(|s| s.enabled)
            .map(|s| s.topic.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        found: if found.is_empty() {
            "no messages".into()
        } else {
            found.join(", ")
        },
    })
}

/// The recorded truths of a generated bag, each by log time.
struct Truths {
    distance: HashMap<u64, f64>,
    approach: HashMap<u64, f64>,
    margin: HashMap<u64, f64>,
}

impl Truths {
    fn of(messages: &[BagMessage]) -> Self {
        let truth_of = |topic: &str| -> HashMap<u64, f64> {
            messages
                .iter()
                .filter(|m| &*m.topic == topic)
                .filter_map(|m| {
                    msg::decode::<Float64>(&m.data)
                        .ok()
                        .map(|f| (m.log_time_ns, f.data))
                })
                .collect()
        };
        Self {
            distance: truth_of(GROUND_TRUTH_TOPIC),
            approach: truth_of(APPROACH_TRUTH_TOPIC),
            margin: truth_of(MARGIN_TRUTH_TOPIC),
        }
    }
}

/// A message on `topic` decoded from its CDR payload (an error names the topic).
fn decoded<'a, T: RosMessage + serde::Deserialize<'a>>(
    topic: &str,
    payload: &'a [u8],
) -> Result<T, InputError> {
    msg::decode(payload).map_err(|source| InputError::Msg {
        topic: topic.into(),
        source,
    })
}

/// Feeds a message on `topic` that is not a source's (TF, joint states, camera info) to the
/// monitor; how many inputs it refused (each logged).
fn feed(monitor: &mut Monitor, topic: &str, payload: &[u8]) -> usize {
    let mut refused = 0;
    let mut refuse = |e: &InputError| {
        log::warn!("{e}");
        refused += 1;
    };
    let input = match topic {
        "/tf" | "/tf_static" => decoded::<TfMessage>(topic, payload)
            .and_then(|m| monitor.on_tf(topic, &m, topic == "/tf_static")),
        _ if topic == monitor.config.joint_states_topic => {
            decoded::<JointState>(topic, payload).and_then(|m| monitor.on_joint_state(topic, &m))
        }
        _ => Ok(()),
    };
    if let Err(e) = &input {
        refuse(e);
    }
    let sources = monitor.camera_info_sources(topic);
    if !sources.is_empty() {
        // Refused for each source it is meant for, as each would have taken it.
        let info = decoded::<CameraInfo>(topic, payload);
        for source in sources {
            match &info {
                Ok(m) => {
                    if let Err(e) = &monitor.on_camera_info(source, m) {
                        refuse(e);
                    }
                }
                Err(e) => refuse(e),
            }
        }
    }
    refused
}

/// The frame of a message of source `source`, decoded as the source's type says; a payload
/// that does not decode is a decode fault. Its processing time includes the decoding.
fn source_frame(
    monitor: &mut Monitor,
    source: usize,
    payload: &[u8],
    now_ns: Option<i64>,
) -> Frame {
    let start = Instant::now();
    match monitor.config.sources[source].kind {
        SourceKind::PointCloud => match pointcloud2::decode(payload) {
            Ok(m) => monitor.on_cloud(source, &m, start, now_ns),
            Err(e) => monitor.on_undecodable(source, e, start, now_ns),
        },
        SourceKind::DepthImage => match msg::decode::<Image>(payload) {
            Ok(m) => monitor.on_depth_image(source, &m, start, now_ns),
            Err(e) => monitor.on_undecodable(source, CloudError::Decode(e), start, now_ns),
        },
    }
}

impl ReplayFrame {
    /// The row of `frame`, the `index`th of the replay, logged at `log_time_ns`.
    fn of(index: usize, frame: &Frame, truths: &Truths, log_time_ns: u64) -> Self {
        let o = &frame.outputs;
        let (outcome, nearest) = match &frame.result {
            Err(_) => ("fault", None),
            Ok(r) => (
                match r.outcome {
                    Outcome::Nearest => "nearest",
                    Outcome::NoPoints => "no_points",
                    Outcome::NothingWithinMaxDistance => "nothing_within_max_distance",
                },
                r.nearest.as_ref(),
            ),
        };
        let speed = frame.speed.as_ref();
        let separation = speed.and_then(|s| s.separation.as_ref().ok());
        ReplayFrame {
            index,
            source: frame.source.clone(),
            stamp_ns: frame.stamp_ns,
            level: o.level,
            outcome,
            distance_m: nearest.map(|n| n.distance_m),
            lower_m: nearest.and_then(|n| n.lower_m),
            min_distance_m: o.min_distance.map(|f| f.data),
            link: nearest.map(|n| n.link.clone()),
            backend: frame.result.as_ref().ok().map(|r| r.backend),
            processing_ms: frame.processing_s * 1e3,
            fault: frame.result.as_ref().err().map(|f| f.to_string()),
            truth_m: truths.distance.get(&log_time_ns).copied(),
            speed_scaling: speed.map(|s| s.factor),
            allowed_factor: separation.map(|s| s.allowed),
            separation_margin_m: separation.map(|s| s.margin_m),
            ssm_distance_m: separation.map(|s| s.distance_m),
            protective_m: separation.map(|s| s.protective_m),
            approach_mps: separation.map(|s| s.approach_mps),
            nearest_approach_mps: separation.and_then(|s| s.nearest_approach_mps),
            ssm_link: separation.map(|s| s.link.clone()),
            ssm_ms: speed.map(|s| s.stage_s * 1e3),
            outputs_ms: frame.outputs_s * 1e3,
            ssm_fault: speed.and_then(|s| s.separation.as_ref().err().cloned()),
            truth_approach_mps: truths.approach.get(&log_time_ns).copied(),
            truth_margin_m: truths.margin.get(&log_time_ns).copied(),
            unseen_m: (o.unseen_distance.as_ref())
                .map(|r| f64::from(r.range))
                .filter(|d| d.is_finite()),
            unseen_all_seen: (o.unseen_distance.as_ref()).is_some_and(|r| r.range == f32::INFINITY),
            unseen_cause: frame.unseen_nearest.map(|n| n.cause.name()),
            unseen_point: frame.unseen_nearest.map(|n| n.centre),
            unseen_counts: frame.unseen_counts,
            unseen_fault: frame.unseen_fault.as_ref().map(|f| f.to_string()),
            unseen_ms: frame.unseen_s.map(|s| s * 1e3),
            unseen_stages_ms: (frame.unseen_stages_s.iter())
                .map(|(n, s)| (*n, s * 1e3))
                .collect(),
            first_ms: frame.first.as_ref().map(|(_, s)| s * 1e3),
            outputs_follow: frame.outputs_follow(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_clock_parses_back_from_its_name() {
        for c in Clock::ALL {
            assert_eq!(Clock::parse(c.name()), Some(*c));
        }
    }
}
