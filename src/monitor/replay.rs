//! Replay: a recorded bag fed through the monitor in log-time order, exactly as the live node
//! would receive it — `/tf_static`, `/tf`, the joint-state topic and every enabled source's
//! clouds — one [`ReplayFrame`] per cloud and a [`Summary`]. With an output path the node's
//! outputs are written to an MCAP under the live node's topics and types, each at the cloud's
//! log time plus its processing time.
//!
//! Bags made by the scenario generator carry the exact minimum distance of every frame on
//! [`GROUND_TRUTH_TOPIC`] at the cloud's log time; replay reports it beside the result.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use serde::Serialize;

use crate::msg::{self, Float64, OwnedMessage};
use crate::query::Outcome;
use crate::stats::percentile;

use super::outputs::{OutputTopic, OutputVisitor};
use super::{Level, Monitor};
use crate::bag::{read_messages, writer::Compression, BagError, BagWriter};

/// Where generated bags record the exact minimum distance of each cloud (`std_msgs/Float64`).
pub use crate::bag::GROUND_TRUTH_TOPIC;

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
    pub processing_ms: f64,
    pub fault: Option<String>,
    /// The recorded exact minimum distance, when the bag has one.
    pub truth_m: Option<f64>,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    pub frames: usize,
    /// Clouds that gave a fault instead of a distance, by kind.
    pub faults: BTreeMap<String, usize>,
    /// Clouds not processed (a replay processes every cloud; the live node drops old ones).
    pub dropped: usize,
    /// TF and joint-state messages refused.
    pub input_errors: usize,
    pub processing_p50_ms: f64,
    pub processing_p99_ms: f64,
    /// Largest |min_distance − truth| over the frames with a recorded truth.
    pub max_error_vs_truth_m: Option<f64>,
}

/// A replay that cannot run: the monitor's reset, or the bag in or out (each names its file).
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error(transparent)]
    Monitor(#[from] super::MonitorError),
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error(
        "{bag}: no message on the enabled sources' topics ({sources}); the bag has: {found} \
         (set <source>.topic to the cloud topic)"
    )]
    NoClouds {
        bag: std::path::PathBuf,
        sources: String,
        found: String,
    },
}

/// What a replayed cloud's stamp is checked against (`Fault::StaleCloud`, `FutureCloud`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Clock {
    /// The message's log time: when the recorder received it, as the node's clock would have
    /// read (what `ros2 bag play --clock` gives a node with `use_sim_time`).
    #[default]
    Log,
    /// The cloud's own stamp, which turns the stamp check off: for bags whose log times are
    /// not when the data was taken (converted, or recorded from a replay). Say so when used.
    Stamp,
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
    monitor.reset()?;
    let joint_topic = monitor.config.joint_states_topic.clone();
    let source_topics: Vec<String> = monitor
        .config
        .sources
        .iter()
        .map(|s| s.topic.clone())
        .collect();
    // Every channel of the bag, to say what it has when it has no cloud for the sources.
    let channels = std::cell::RefCell::new(std::collections::BTreeSet::new());
    let keep = |t: &str, schema: &str| {
        channels.borrow_mut().insert(format!("{t} ({schema})"));
        t == "/tf"
            || t == "/tf_static"
            || t == joint_topic
            || t == GROUND_TRUTH_TOPIC
            || source_topics.iter().any(|s| s == t)
    };
    let messages = read_messages(bag, &keep)?;
    // A bag with no cloud for any enabled source replays nothing: say so, with what it has,
    // rather than report "0 frames, 0 faults" as if all were well.
    if !messages
        .iter()
        .any(|m| monitor.source_of(&m.topic).is_some())
    {
        let found: Vec<String> = channels.into_inner().into_iter().collect();
        return Err(ReplayError::NoClouds {
            bag: bag.to_owned(),
            sources: monitor
                .config
                .sources
                .iter()
                .filter(|s| s.enabled)
                .map(|s| s.topic.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            found: if found.is_empty() {
                "no messages".into()
            } else {
                found.join(", ")
            },
        });
    }
    let truth: HashMap<u64, f64> = messages
        .iter()
        .filter(|m| &*m.topic == GROUND_TRUTH_TOPIC)
        .filter_map(|m| {
            msg::decode::<Float64>(&m.data)
                .ok()
                .map(|f| (m.log_time_ns, f.data))
        })
        .collect();
    let mut writer = out
        .map(|(path, compression)| BagWriter::create(path, compression))
        .transpose()?;
    let node_path = monitor.config.node_path();
    let mut summary = Summary::default();
    let mut times = Vec::new();
    for m in &messages {
        let t = &*m.topic;
        let input = match t {
            "/tf" | "/tf_static" => monitor.on_tf(t, &m.data, t == "/tf_static"),
            _ if t == joint_topic => monitor.on_joint_state(t, &m.data),
            _ => Ok(()),
        };
        if let Err(e) = input {
            log::warn!("{e}");
            summary.input_errors += 1;
        }
        let Some(source) = monitor.source_of(t) else {
            continue;
        };
        let now_ns = (clock == Clock::Log).then_some(m.log_time_ns as i64);
        let frame = monitor.on_cloud(source, &m.data, now_ns);
        let index = summary.frames;
        summary.frames += 1;
        times.push(frame.processing_s * 1e3);
        let o = &frame.outputs;
        let (outcome, nearest) = match &frame.result {
            Err(f) => {
                *summary.faults.entry(f.kind().into()).or_default() += 1;
                ("fault", None)
            }
            Ok(r) => (
                match r.outcome {
                    Outcome::Nearest => "nearest",
                    Outcome::NoPoints => "no_points",
                    Outcome::NothingWithinMaxDistance => "nothing_within_max_distance",
                },
                r.nearest.as_ref(),
            ),
        };
        let row = ReplayFrame {
            index,
            source: frame.source.clone(),
            stamp_ns: frame.stamp_ns,
            level: o.level,
            outcome,
            distance_m: nearest.map(|n| n.distance_m),
            lower_m: nearest.and_then(|n| n.lower_m),
            min_distance_m: o.min_distance.map(|f| f.data),
            link: nearest.map(|n| n.link.clone()),
            processing_ms: frame.processing_s * 1e3,
            fault: frame.result.as_ref().err().map(|f| f.to_string()),
            truth_m: truth.get(&m.log_time_ns).copied(),
        };
        if let (Some(d), Some(t)) = (row.min_distance_m, row.truth_m) {
            let e = summary
                .max_error_vs_truth_m
                .unwrap_or(0.0)
                .max((d - t).abs());
            summary.max_error_vs_truth_m = Some(e);
        }
        on_frame(&row);
        if let Some(w) = writer.as_mut() {
            let at = m.log_time_ns + (frame.processing_s * 1e9) as u64;
            frame.outputs.visit(&mut BagSink {
                writer: w,
                node_path: &node_path,
                at,
            })?;
        }
    }
    if let Some(w) = writer {
        w.finish()?;
    }
    times.sort_by(f64::total_cmp);
    summary.processing_p50_ms = percentile(&times, 0.5).unwrap_or(0.0);
    summary.processing_p99_ms = percentile(&times, 0.99).unwrap_or(0.0);
    Ok(summary)
}
