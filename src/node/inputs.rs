//! The node's inputs on their way to the processing thread: each source's newest message in its
//! slot (an older unprocessed one, and a gap in a writer's sequence numbers, count as dropped),
//! and TF, joint states and camera info forwarded in order through a channel. Each message goes
//! with its writer's GID ([`Writer`]); a source's slot also collects the writers of every message
//! it received, the dropped ones too, for the monitor's one-voice rule (`crate::msg::Voices`).

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use super::clock::NodeClock;
use super::error::{lock, Result};
use super::transport::RosNode;
use crate::msg::{Image, OwnedMessage, PointCloud2, Writer, MAX_WRITERS};
use ros2_client::qos::QosProfile;
use ros2_client::MessageInfo;

/// The writer of a message, from what the transport said of it.
pub(super) fn writer_of(info: &MessageInfo) -> Writer {
    Writer(info.publisher_gid().to_bytes16())
}

/// Samples lost before they reached the reader, from the gaps in sequence numbers. Each writer
/// numbers its own samples, so two publishers on one topic are followed separately.
struct SequenceGaps<K> {
    last: HashMap<K, i64>,
}

impl<K> Default for SequenceGaps<K> {
    fn default() -> Self {
        Self {
            last: HashMap::new(),
        }
    }
}

impl<K: std::hash::Hash + Eq> SequenceGaps<K> {
    /// How many samples of `writer` were skipped before `seq`.
    fn lost(&mut self, writer: K, seq: i64) -> u64 {
        match self.last.insert(writer, seq) {
            Some(prev) if seq > prev + 1 => (seq - prev - 1) as u64,
            _ => 0,
        }
    }
}

/// A source's message: a cloud or a depth image.
pub(super) enum SourceMessage {
    Cloud(PointCloud2<'static>),
    Depth(Image<'static>),
}

impl SourceMessage {
    /// Its stamp, ns since the epoch.
    pub(super) fn stamp_ns(&self) -> i64 {
        match self {
            Self::Cloud(c) => c.header.stamp.as_nanos(),
            Self::Depth(i) => i.header.stamp.as_nanos(),
        }
    }

    /// Width, height, frame and bytes of data.
    pub(super) fn describe(&self) -> (u32, u32, &str, usize) {
        match self {
            Self::Cloud(c) => (c.width, c.height, &c.header.frame_id, c.data.len()),
            Self::Depth(i) => (i.width, i.height, &i.header.frame_id, i.data.len()),
        }
    }
}

/// The newest unprocessed cloud (or depth image) of a source.
#[derive(Default)]
pub(super) struct Slot {
    /// The message, when it was received, and the node's clock then (ns since the epoch).
    pub(super) cloud: Option<(SourceMessage, Instant, i64)>,
    /// When the last one was received, by the node's monotonic clock (`NodeClock`).
    pub(super) last_received: Option<i64>,
    /// The writers of the messages received since the monitor last took them, each with the
    /// newest stamp it gave (at most [`MAX_WRITERS`]).
    pub(super) writers: Vec<(Writer, i64)>,
}

impl Slot {
    /// `writer` sent a message stamped `stamp_ns`.
    fn heard(&mut self, writer: Writer, stamp_ns: i64) {
        if let Some(h) = self.writers.iter_mut().find(|(w, _)| *w == writer) {
            h.1 = h.1.max(stamp_ns);
        } else if self.writers.len() < MAX_WRITERS {
            self.writers.push((writer, stamp_ns));
        }
        // (More writers than the monitor keeps: the conflict is plain already.)
    }
}

/// Subscribes to source `k`'s messages of type `T`: each replaces the slot's unprocessed one
/// (counted as dropped), and gaps in each writer's sequence numbers count as dropped too.
pub(super) fn source_task<T: OwnedMessage>(
    node: &mut RosNode,
    topic: &str,
    qos: QosProfile,
    executor: &smol::Executor<'static>,
    k: usize,
    shared: &Arc<Shared>,
    wrap: fn(T) -> SourceMessage,
) -> Result<smol::Task<()>> {
    let shared = shared.clone();
    let mut gaps = SequenceGaps::default();
    node.subscribe::<T>(topic, qos, true, executor, move |item| {
        match item {
            Ok((m, info)) => {
                let lost = gaps.lost(info.publisher_gid(), info.sequence_number());
                shared.dropped.fetch_add(lost, Ordering::Relaxed);
                let now = Instant::now();
                let clock_ns = shared.clock.now_ns();
                let message = wrap(m);
                let mut slot = lock(&shared.slots[k]);
                slot.heard(writer_of(&info), message.stamp_ns());
                if slot.cloud.replace((message, now, clock_ns)).is_some() {
                    shared.dropped.fetch_add(1, Ordering::Relaxed);
                }
                slot.last_received = Some(shared.clock.monotonic_ns());
                drop(slot);
                *lock(&shared.wake_lock) = true;
                shared.wake.notify_one();
            }
            Err(e) => {
                log::warn!("source message: {e}");
                shared.input_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
        true
    })
}

/// Forwards each message on `topic` with its writer, as `wrap` makes it, to `tx` (the
/// processing thread); a message that fails to decode is counted and skipped.
#[allow(clippy::too_many_arguments)]
pub(super) fn forward<T: OwnedMessage, U: Send + 'static>(
    node: &mut RosNode,
    topic: &str,
    qos: QosProfile,
    executor: &smol::Executor<'static>,
    what: &'static str,
    tx: std::sync::mpsc::Sender<U>,
    wrap: impl Fn(T, Writer) -> U + Send + 'static,
    shared: &Arc<Shared>,
) -> Result<smol::Task<()>> {
    let shared = shared.clone();
    node.subscribe::<T>(topic, qos, false, executor, move |item| match item {
        Ok((m, info)) => tx.send(wrap(m, writer_of(&info))).is_ok(),
        Err(e) => {
            log::warn!("{what}: {e}");
            shared.input_errors.fetch_add(1, Ordering::Relaxed);
            true
        }
    })
}

pub(super) struct Shared {
    pub(super) slots: Vec<Mutex<Slot>>,
    pub(super) clock: Arc<NodeClock>,
    pub(super) wake: Condvar,
    pub(super) wake_lock: Mutex<bool>,
    pub(super) dropped: AtomicU64,
    pub(super) input_errors: AtomicU64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_gaps_are_counted_per_writer() {
        let mut g = SequenceGaps::default();
        // Two writers interleaved, each without a gap: nothing lost.
        let lost: u64 = [(1, 1), (2, 1), (1, 2), (2, 2), (1, 3), (2, 3)]
            .into_iter()
            .map(|(w, s)| g.lost(w, s))
            .sum();
        assert_eq!(lost, 0);
        // Writer 1 skips 4 and 5.
        assert_eq!(g.lost(1, 6), 2);
        assert_eq!(g.lost(2, 4), 0);
        // A restarted writer (its numbers start again) is not a loss.
        assert_eq!(g.lost(2, 1), 0);
    }
}
