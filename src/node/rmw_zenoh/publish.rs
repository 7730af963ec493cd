//! A publisher on zenoh (the folder's **Messages** and **Transient local**): plain, or with
//! the cache a transient-local one keeps for late joiners; each message CDR with its
//! attachment.

use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

use ros2_client::qos::{Durability, QosProfile, Reliability};
use zenoh::Wait;
use zenoh_ext::{AdvancedPublisherBuilderExt, CacheConfig, MissDetectionConfig};

use super::keys::{attachment, depth};
use super::node::ZenohNode;
use crate::msg::RosMessage;
use crate::node::error::{entity, NodeError};

/// How often a reliable transient-local publisher announces its last sequence number, so that
/// subscribers notice missed samples and fetch them from its cache (rmw_zenoh's period).
const HEARTBEAT: Duration = Duration::from_millis(500);

impl ZenohNode {
    /// A publisher of `T` on `topic` (absolute).
    pub fn publisher<T: RosMessage>(
        &self,
        topic: &str,
        qos: &QosProfile,
    ) -> Result<ZenohPub<T>, NodeError> {
        let keys = self.keys::<T>("MP", topic, qos, false)?;
        let reliability = match qos.reliability {
            Reliability::Reliable { .. } => zenoh::qos::Reliability::Reliable,
            Reliability::BestEffort => zenoh::qos::Reliability::BestEffort,
        };
        let builder = self
            .session
            .declare_publisher(keys.data)
            .reliability(reliability);
        let publisher = if qos.durability == Durability::TransientLocal {
            let mut b = builder
                .cache(CacheConfig::default().max_samples(depth(qos)))
                .publisher_detection();
            if matches!(qos.reliability, Reliability::Reliable { .. }) {
                b = b.sample_miss_detection(
                    MissDetectionConfig::default().sporadic_heartbeat(HEARTBEAT),
                );
            }
            b.wait().map(Put::Latched)
        } else {
            builder.wait().map(Put::Plain)
        }
        .map_err(|e| entity("publisher", topic, e))?;
        let gid: [u8; 16] = blake3::hash(keys.liveliness.as_bytes()).as_bytes()[..16]
            .try_into()
            .unwrap_or_default();
        let token = self.token(keys.liveliness, "publisher", topic)?;
        Ok(ZenohPub {
            publisher,
            gid,
            sequence: AtomicI64::new(0),
            _token: token,
            _type: std::marker::PhantomData,
        })
    }
}

/// A zenoh publisher: plain, or with the cache of a transient-local one.
enum Put {
    Plain(zenoh::pubsub::Publisher<'static>),
    Latched(zenoh_ext::AdvancedPublisher<'static>),
}

/// A publisher of `T` on zenoh.
pub struct ZenohPub<T> {
    publisher: Put,
    gid: [u8; 16],
    sequence: AtomicI64,
    _token: zenoh::liveliness::LivelinessToken,
    _type: std::marker::PhantomData<fn(T)>,
}

impl<T: RosMessage> ZenohPub<T> {
    pub fn publish(&self, m: &T) -> Result<(), String> {
        let payload = crate::msg::encode(m).map_err(|e| e.to_string())?;
        let seq = self.sequence.fetch_add(1, Ordering::Relaxed) + 1;
        let a = attachment(seq, &self.gid);
        match &self.publisher {
            Put::Plain(p) => p.put(payload).attachment(a).wait(),
            Put::Latched(p) => p.put(payload).attachment(a).wait(),
        }
        .map_err(|e| e.to_string())
    }
}
