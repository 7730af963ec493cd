//! A subscription on zenoh: any type hash, into a ring that keeps the newest samples; a
//! transient-local one asks every publisher it detects for its history (the folder's
//! **Transient local**). Each sample decoded and handed on with its attachment.

use ros2_client::qos::{Durability, QosProfile, Reliability};
use ros2_client::MessageInfo;
use zenoh::Wait;
use zenoh_ext::{AdvancedSubscriberBuilderExt, HistoryConfig, RecoveryConfig};

use super::keys::{attachment_info, depth};
use super::node::ZenohNode;
use crate::msg::OwnedMessage;
use crate::node::error::{entity, NodeError};

impl ZenohNode {
    /// Subscribes to `T` on `topic` (absolute), any type hash, into a ring of `ring` samples
    /// that keeps the newest (a slow reader never blocks the session, nothing queues without
    /// bound); each message (or decoding error) goes to `on` in a task on `executor`, until `on`
    /// returns false.
    pub fn subscribe<T: OwnedMessage>(
        &self,
        topic: &str,
        qos: &QosProfile,
        ring: usize,
        executor: &smol::Executor<'static>,
        mut on: impl FnMut(Result<(T, MessageInfo), String>) -> bool + Send + 'static,
    ) -> Result<smol::Task<()>, NodeError> {
        let keys = self.keys::<T>("MS", topic, qos, true)?;
        let ring = zenoh::handlers::RingChannel::new(ring);
        let sub = if qos.durability == Durability::TransientLocal {
            let mut b = self
                .session
                .declare_subscriber(keys.data)
                .with(ring)
                .history(
                    HistoryConfig::default()
                        .detect_late_publishers()
                        .max_samples(depth(qos)),
                )
                .subscriber_detection();
            if matches!(qos.reliability, Reliability::Reliable { .. }) {
                b = b.recovery(RecoveryConfig::default().heartbeat());
            }
            b.wait().map(Take::Latched)
        } else {
            self.session
                .declare_subscriber(keys.data)
                .with(ring)
                .wait()
                .map(Take::Plain)
        }
        .map_err(|e| entity("subscription", topic, e))?;
        let token = self.token(keys.liveliness, "subscription", topic)?;
        Ok(executor.spawn(async move {
            let _token = token;
            while let Ok(sample) = sub.recv_async().await {
                // A large message arrives in fragments: joined into one buffer, which the
                // message then keeps (`from_payload`); a small one is one slice, copied out.
                let decoded = match sample.payload().to_bytes() {
                    std::borrow::Cow::Owned(payload) => T::from_payload(payload),
                    std::borrow::Cow::Borrowed(payload) => crate::msg::decode_owned(payload),
                };
                let item = decoded
                    .map(|m| (m, attachment_info(&sample)))
                    .map_err(|e| e.to_string());
                if !on(item) {
                    break;
                }
            }
        }))
    }
}

type Ring = zenoh::handlers::RingChannelHandler<zenoh::sample::Sample>;

/// A zenoh subscriber: plain, or querying the history of transient-local publishers.
enum Take {
    Plain(zenoh::pubsub::Subscriber<Ring>),
    Latched(zenoh_ext::AdvancedSubscriber<Ring>),
}

impl Take {
    async fn recv_async(&self) -> zenoh::Result<zenoh::sample::Sample> {
        match self {
            Take::Plain(s) => s.recv_async().await,
            Take::Latched(s) => s.handler().recv_async().await,
        }
    }
}
