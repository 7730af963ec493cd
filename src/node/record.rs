//! `ist_monitor record`: the node's outputs, every topic of the output table
//! (`monitor::outputs::OutputTopic`: `~/min_distance`, `~/link_distances`, `~/closest_points`,
//! `/diagnostics`, `~/safety_stop`), received over DDS or zenoh and written to an MCAP, each at its
//! receive time, for tests and for looking at a live node afterwards. Afterwards, the latency of
//! each frame's answer ([`distance_latencies`]): the time `~/distance` was received less the
//! frame's stamp it carries (the first message of each stamp; a heartbeat repeats one), so that a
//! publisher that stamps its clouds when it sends them (`play`) measures the path through the
//! middleware and the node and back.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::error::NodeError;
use super::qos::RELIABLE_QOS;
use super::transport::{RosNode, Transport};
use crate::bag::{writer::Compression, BagWriter};
use crate::monitor::outputs::{visit_output_topics, OutputTopic, OutputVisitor};
use crate::msg::{OwnedMessage, Range, Time};

/// The bag being written and how many messages went into it.
type Sink = Arc<Mutex<(Option<BagWriter>, usize)>>;

/// Subscribes to every output topic, each message written to the sink.
struct Subscribe<'a> {
    node: &'a mut RosNode,
    executor: &'a smol::Executor<'static>,
    node_path: &'a str,
    sink: Sink,
}

impl OutputVisitor for Subscribe<'_> {
    type Error = NodeError;
    fn visit<T: OwnedMessage>(
        &mut self,
        topic: OutputTopic,
        _: Option<T>,
    ) -> Result<(), NodeError> {
        let name = topic.topic(self.node_path);
        let sink = self.sink.clone();
        let topic = name.clone();
        self.node
            .subscribe::<T>(&topic, RELIABLE_QOS, false, self.executor, move |item| {
                if let Ok((m, _)) = item {
                    let now = Time::now_nanos().max(0) as u64;
                    let mut sink = sink.lock().unwrap_or_else(|p| p.into_inner());
                    let (writer, count) = &mut *sink;
                    if let Some(w) = writer.as_mut() {
                        match w.write(&name, now, &m) {
                            Ok(()) => *count += 1,
                            Err(e) => log::warn!("{e}"),
                        }
                    }
                }
                true
            })?
            .detach();
        Ok(())
    }
}

/// Records the outputs of the node `node_path` (`/ns/name`) for `duration_s` into `out`;
/// returns how many messages were written.
pub fn record(
    transport: Transport,
    node_path: &str,
    out: &Path,
    duration_s: f64,
) -> Result<usize, NodeError> {
    // The executor runs the subscriptions' tasks, which borrow it for as long as they live:
    // it lives in a static for the rest of the process (one recording per process).
    static EXECUTOR: std::sync::OnceLock<smol::Executor<'static>> = std::sync::OnceLock::new();
    let executor = EXECUTOR.get_or_init(smol::Executor::new);
    let mut node = RosNode::tool(transport, "ist_monitor_record", executor)?;
    let mut writer = BagWriter::create(out, Compression::Zstd)?;
    for t in OutputTopic::latched(node_path.trim_end_matches('/')) {
        writer.latch(&t);
    }
    let sink: Sink = Arc::new(Mutex::new((Some(writer), 0)));
    visit_output_topics(&mut Subscribe {
        node: &mut node,
        executor,
        node_path: node_path.trim_end_matches('/'),
        sink: sink.clone(),
    })?;
    smol::block_on(executor.run(smol::Timer::after(Duration::from_secs_f64(duration_s))));
    let _ctx = node.close();
    smol::block_on(executor.run(smol::Timer::after(Duration::from_millis(50))));
    let (writer, count) = {
        let mut sink = sink.lock().unwrap_or_else(|p| p.into_inner());
        (sink.0.take(), sink.1)
    };
    if let Some(w) = writer {
        w.finish()?;
    }
    Ok(count)
}

/// The latencies in the recording `out` of the node `node_path`: for each measured frame's stamp
/// on its `~/distance`, the receive time of its first message less the stamp, ms, sorted.
pub fn distance_latencies(out: &Path, node_path: &str) -> Result<Vec<f64>, NodeError> {
    let topic = OutputTopic::Distance.topic(node_path.trim_end_matches('/'));
    let messages = crate::bag::reader::read_messages(out, &|t, _| t == topic)?;
    let mut seen = std::collections::HashSet::new();
    let mut latencies: Vec<f64> = Vec::new();
    for m in messages {
        let Ok(range) = crate::msg::decode::<Range>(&m.data) else {
            continue;
        };
        // A measured frame's answer (a fault or a heartbeat with nothing measured is NaN).
        let stamp = range.header.stamp.as_nanos();
        if range.range.is_finite() && stamp > 0 && seen.insert(stamp) {
            latencies.push((m.log_time_ns as i64 - stamp) as f64 * 1e-6);
        }
    }
    latencies.sort_by(f64::total_cmp);
    Ok(latencies)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Header;

    /// Each measured frame counts once, at its first answer; faults and heartbeats (NaN) and
    /// other topics do not.
    #[test]
    fn latencies_are_first_answers_of_measured_frames() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("r.mcap");
        let mut w = BagWriter::create(&out, Compression::Zstd).unwrap();
        let range = |stamp_ns: i64, d: f32| Range {
            header: Header {
                stamp: Time::from_nanos(stamp_ns),
                frame_id: "world".into(),
            },
            range: d,
            ..Range::default()
        };
        let s = 1_000_000_000_000;
        let ms = 1_000_000u64;
        let at = |t: u64| s as u64 + t * ms;
        w.write("/ist_monitor/distance", at(40), &range(s, 0.5))
            .unwrap();
        // A heartbeat repeating the same stamp later: not a new frame.
        w.write("/ist_monitor/distance", at(140), &range(s, 0.5))
            .unwrap();
        w.write(
            "/ist_monitor/distance",
            at(130),
            &range(s + 100 * ms as i64, 0.4),
        )
        .unwrap();
        // A fault: no distance.
        w.write(
            "/ist_monitor/distance",
            at(260),
            &range(s + 200 * ms as i64, f32::NAN),
        )
        .unwrap();
        w.write("/other/distance", at(400), &range(s, 0.5)).unwrap();
        w.finish().unwrap();
        let l = distance_latencies(&out, "/ist_monitor").unwrap();
        assert_eq!(l.len(), 2, "{l:?}");
        assert!(
            (l[0] - 30.0).abs() < 1e-6 && (l[1] - 40.0).abs() < 1e-6,
            "{l:?}"
        );
    }
}
