//! Who publishes a topic, by the graph rmw_zenoh keeps in liveliness tokens: every publisher
//! declares one of kind `MP` (`@ros2_lv/<domain>/<session>/<node id>/<entity id>/MP/<enclave>/
//! <namespace>/<node>/<topic>/<type>/<hash>/<qos>`) and undeclares it when it goes, or its
//! session does (a killed process: when the router sees the link drop). A liveliness subscriber
//! with history on the topic's tokens keeps the set current: the source's writers from
//! discovery, for the one-voice rule (`crate::monitor`'s `Source::set_matched`). A subscription
//! declares one of kind `MS` the same way: whether anyone reads an output.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use zenoh::sample::SampleKind;
use zenoh::Wait;

use super::keys::mangle;
use super::node::ZenohNode;
use crate::node::error::{entity, NodeError};

/// The publishers (or subscriptions) of one topic, kept by a liveliness subscriber.
pub struct ZenohEntities {
    /// Token key → the entity's name for a report (`/namespace/node (session id)`).
    names: Arc<Mutex<BTreeMap<String, String>>>,
    _subscriber: zenoh::pubsub::Subscriber<()>,
}

impl ZenohEntities {
    /// The entities declared on the topic now, by name.
    pub fn names(&self) -> Vec<String> {
        let names = self.names.lock().unwrap_or_else(|e| e.into_inner());
        names.values().cloned().collect()
    }
}

/// The name of the writer behind publisher token `key`: its node's `/namespace/node` and its
/// session id; the key itself where it is not rmw_zenoh's form.
fn writer_name(key: &str) -> String {
    let parts: Vec<&str> = key.split('/').collect();
    if parts.len() < 10 || !matches!(parts[5], "MP" | "MS") {
        return key.to_string();
    }
    let unmangle = |s: &str| {
        if s == "%" {
            String::new()
        } else {
            s.replace('%', "/")
        }
    };
    format!(
        "{}/{} ({})",
        unmangle(parts[7]),
        unmangle(parts[8]),
        parts[2]
    )
}

impl ZenohNode {
    /// Watches the publishers of `topic` (absolute, any type): the tokens declared before are
    /// taken at once (history), later ones as they come and go.
    pub fn publishers(&self, topic: &str) -> Result<ZenohEntities, NodeError> {
        self.entities(topic, "MP")
    }

    /// Watches the subscriptions of `topic` (absolute, any type), as [`ZenohNode::publishers`].
    pub fn subscribers(&self, topic: &str) -> Result<ZenohEntities, NodeError> {
        self.entities(topic, "MS")
    }

    /// The entities of kind `kind` (`MP`, `MS`) on `topic`.
    fn entities(&self, topic: &str, kind: &str) -> Result<ZenohEntities, NodeError> {
        let topic = format!("/{}", topic.trim_matches('/'));
        let key = format!(
            "@ros2_lv/{}/*/*/*/{kind}/*/*/*/{}/**",
            self.domain,
            mangle(&topic)
        );
        let names = Arc::new(Mutex::new(BTreeMap::new()));
        let kept = names.clone();
        let subscriber = self
            .session
            .liveliness()
            .declare_subscriber(key)
            .history(true)
            .callback(move |sample| {
                let key = sample.key_expr().as_str().to_string();
                let mut names = kept.lock().unwrap_or_else(|e| e.into_inner());
                match sample.kind() {
                    SampleKind::Put => {
                        let name = writer_name(&key);
                        names.insert(key, name);
                    }
                    SampleKind::Delete => {
                        names.remove(&key);
                    }
                }
            })
            .wait()
            .map_err(|e| {
                let what = match kind {
                    "MP" => "publishers' liveliness subscriber",
                    _ => "subscriptions' liveliness subscriber",
                };
                entity(what, &topic, e)
            })?;
        Ok(ZenohEntities {
            names,
            _subscriber: subscriber,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_publisher_token_names_its_node_and_session() {
        let key = "@ros2_lv/0/8f3a/12/14/MP/%/%cell/camera_driver/%camera%points/\
                   sensor_msgs::msg::dds_::PointCloud2_/RIHS01_abc/::,5:,:,:,,";
        assert_eq!(writer_name(key), "/cell/camera_driver (8f3a)");
        let root = "@ros2_lv/0/8f3a/12/14/MP/%/%/cam/%points/T/H/Q";
        assert_eq!(writer_name(root), "/cam (8f3a)");
        assert_eq!(writer_name("not/a/token"), "not/a/token");
    }
}
