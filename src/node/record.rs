//! `ist_monitor record`: the node's outputs, every topic of the output table
//! (`monitor::outputs::OutputTopic`: `~/min_distance`, `~/link_distances`, `~/closest_points`,
//! `/diagnostics`, `~/safety_stop`), received over DDS or zenoh and written to an MCAP, each at its
//! receive time, for tests and for looking at a live node afterwards.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::error::NodeError;
use super::qos::RELIABLE_QOS;
use super::transport::{RosNode, Transport};
use crate::bag::{writer::Compression, BagWriter};
use crate::monitor::outputs::{visit_output_topics, OutputTopic, OutputVisitor};
use crate::msg::{OwnedMessage, Time};

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
