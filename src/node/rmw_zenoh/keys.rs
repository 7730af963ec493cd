//! The names and bytes of rmw_zenoh's wire protocol (the folder's **Keys**, **Liveliness
//! tokens** and **Messages**): names as liveliness keys write them, a QoS profile in its
//! compact form, the history depth a cache keeps, and the 32-byte attachment every message and
//! reply carries.

use std::time::Duration;

use ros2_client::qos::{Durability, History, Liveliness, QosProfile, Reliability};
use ros2_client::MessageInfo;

/// The node id in this session's liveliness tokens (one node per session).
pub(super) const NODE_ID: u64 = 0;

/// The depth of a QoS profile's history (keep all: 1000).
pub(super) fn depth(q: &QosProfile) -> usize {
    match q.history {
        History::KeepLast { depth } => depth.max(1),
        History::KeepAll => 1000,
    }
}

/// `name` as rmw_zenoh writes names in liveliness keys: `/` as `%`, empty as `%`.
pub(super) fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// A QoS profile in rmw_zenoh's compact form:
/// `reliability:durability:history,depth:deadline:lifespan:liveliness,lease`, each policy empty
/// where it is ROS 2's default (reliable, volatile, keep last; infinite durations; automatic).
pub fn qos_key(q: &QosProfile) -> String {
    let reliability = match q.reliability {
        Reliability::Reliable { .. } => "",
        Reliability::BestEffort => "2",
    };
    let durability = match q.durability {
        Durability::Volatile => "",
        Durability::TransientLocal => "1",
    };
    let (history, depth) = match q.history {
        History::KeepLast { depth } => ("", depth.to_string()),
        History::KeepAll => ("2", String::new()),
    };
    let duration = |d: Option<Duration>| match d {
        None => ",".to_string(),
        Some(d) => format!("{},{}", d.as_secs(), d.subsec_nanos()),
    };
    let liveliness = match q.liveliness {
        Liveliness::Automatic => "",
        Liveliness::ManualByTopic => "3",
    };
    format!(
        "{reliability}:{durability}:{history},{depth}:{}:{}:{liveliness},{}",
        duration(q.deadline),
        duration(q.lifespan),
        duration(q.liveliness_lease)
    )
}

/// The 32-byte attachment of a message (see the folder's documentation, `rmw_zenoh`).
pub(super) fn attachment(sequence_number: i64, gid: &[u8; 16]) -> Vec<u8> {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as i64)
        .unwrap_or(0);
    let mut a = Vec::with_capacity(32);
    a.extend_from_slice(&sequence_number.to_le_bytes());
    a.extend_from_slice(&now.to_le_bytes());
    a.extend_from_slice(gid);
    a
}

/// The rmw_zenoh attachment of a sample: sequence number, source timestamp (ns), source gid,
/// little endian.
pub(super) fn attachment_info(sample: &zenoh::sample::Sample) -> MessageInfo {
    let parsed = sample.attachment().and_then(|a| {
        let b = a.to_bytes();
        (b.len() >= 32).then(|| {
            let seq = i64::from_le_bytes(b[0..8].try_into().unwrap_or_default());
            let gid: [u8; 16] = b[16..32].try_into().unwrap_or_default();
            (seq, gid)
        })
    });
    let (seq, gid) = parsed.unwrap_or((0, [0; 16]));
    MessageInfo::new(None, None, seq, ros2_client::Gid::from(gid), None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn qos_keys_are_rmw_zenohs() {
        // ROS 2's default profile (reliable, volatile, keep last 10) is all defaults.
        let default = QosProfile::subscription_default()
            .reliability_reliable(ros2_client::qos::WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        assert_eq!(qos_key(&default), "::,10:,:,:,,");
        assert_eq!(qos_key(&crate::node::qos::SENSOR_QOS), "2::,1:,:,:,,");
        let latched = default
            .durability(Durability::TransientLocal)
            .history(History::KeepLast { depth: 1 });
        assert_eq!(qos_key(&latched), ":1:,1:,:,:,,");
        assert_eq!(
            mangle("/ist_monitor/min_distance"),
            "%ist_monitor%min_distance"
        );
        assert_eq!(mangle(""), "%");
    }

    #[test]
    fn attachments_are_32_bytes() {
        let a = attachment(7, &[0xab; 16]);
        assert_eq!(a.len(), 32);
        assert_eq!(&a[..8], &7i64.to_le_bytes());
        assert_eq!(&a[16..], &[0xab; 16]);
    }
}
