//! A node on a zenoh session, as rmw_zenoh makes one: the session opened by rmw_zenoh's rules,
//! the node's liveliness token, and the keys (data and liveliness) of each entity made on it.
//! The entities themselves are made in `publish`, `subscribe` and `service`.

use std::sync::atomic::{AtomicU64, Ordering};

use ros2_client::qos::QosProfile;
use zenoh::Wait;

use super::config::{check_router, check_tls_files, config_from_env, ConfigFor};
use super::keys::{mangle, qos_key, NODE_ID};
use crate::msg::RosMessage;
use crate::node::error::{entity, NodeError};
use crate::node::ros_args::{topic_name, type_name};

/// A node on a zenoh session, as rmw_zenoh makes one: the session and the node's liveliness
/// token, and the publishers and subscriptions made on it.
pub struct ZenohNode {
    pub(super) session: zenoh::Session,
    pub(super) domain: u16,
    /// The start of every entity's liveliness key: `@ros2_lv/<domain>/<zid>/<node id>`.
    pub(super) lv_prefix: String,
    /// The end of it: `<enclave>/<namespace>/<node>`.
    pub(super) lv_node: String,
    pub(super) next_entity: AtomicU64,
    /// The node's fully qualified name, `/ns/name`.
    path: String,
    _token: zenoh::liveliness::LivelinessToken,
}

/// What a publisher or subscription is keyed by.
pub(super) struct Keys {
    /// The data key (with the type's hash, or `*`).
    pub(super) data: String,
    /// The liveliness key of the entity.
    pub(super) liveliness: String,
}

impl ZenohNode {
    /// Opens a session by rmw_zenoh's rules and declares node `namespace`/`name` of ROS domain
    /// `domain` on it; also returns what the node runs on, for its start line.
    pub fn open(domain: u16, namespace: &str, name: &str) -> Result<(Self, String), NodeError> {
        let (config, from) = config_from_env(ConfigFor::Session)?;
        check_tls_files(&config, &format!("zenoh session ({from})"))?;
        let endpoints = config.get_json("connect/endpoints").unwrap_or_default();
        let session = zenoh::open(config).wait().map_err(|e| {
            NodeError::Transport(format!(
                "zenoh session ({from}) connecting to {endpoints}: {e}"
            ))
        })?;
        let routers = check_router(&session, &endpoints)?;
        let zid = session.zid().to_string();
        let lv_prefix = format!("@ros2_lv/{domain}/{zid}/{NODE_ID}");
        let namespace = if namespace == "/" { "" } else { namespace };
        let lv_node = format!("%/{}/{}", mangle(namespace), mangle(name));
        let token = session
            .liveliness()
            .declare_token(format!("{lv_prefix}/{NODE_ID}/NN/{lv_node}"))
            .wait()
            .map_err(|e| entity("node", name, e))?;
        let describe =
            format!("zenoh (rmw_zenoh) on domain {domain}, {from}, {routers} router(s) connected");
        Ok((
            Self {
                session,
                domain,
                lv_prefix,
                lv_node,
                next_entity: AtomicU64::new(NODE_ID + 1),
                path: format!("{namespace}/{name}"),
                _token: token,
            },
            describe,
        ))
    }

    /// The node's fully qualified name, `/ns/name`.
    pub fn node_path(&self) -> &str {
        &self.path
    }

    /// Declares the liveliness token `key` of the `what` (publisher, subscription) on `topic`.
    pub(super) fn token(
        &self,
        key: String,
        what: &'static str,
        topic: &str,
    ) -> Result<zenoh::liveliness::LivelinessToken, NodeError> {
        self.session
            .liveliness()
            .declare_token(key)
            .wait()
            .map_err(|e| entity(what, topic, e))
    }

    /// The keys of an entity of `kind` (`MP`, `MS`) for `T` on `topic` (absolute).
    pub(super) fn keys<T: RosMessage>(
        &self,
        kind: &str,
        topic: &str,
        qos: &QosProfile,
        any_hash: bool,
    ) -> Result<Keys, NodeError> {
        topic_name(topic)?; // a ROS name, as on DDS
        let hash = crate::msg::type_hash(T::TYPE).ok_or_else(|| {
            NodeError::Transport(format!("{}: no type description for its hash", T::TYPE))
        })?;
        let dds_type = type_name::<T>().dds_msg_type();
        let topic = format!("/{}", topic.trim_matches('/'));
        let id = self.next_entity.fetch_add(1, Ordering::Relaxed);
        Ok(Keys {
            data: format!(
                "{}{topic}/{dds_type}/{}",
                self.domain,
                if any_hash { "*" } else { &hash }
            ),
            liveliness: format!(
                "{}/{id}/{kind}/{}/{}/{dds_type}/{hash}/{}",
                self.lv_prefix,
                self.lv_node,
                mangle(&topic),
                qos_key(qos)
            ),
        })
    }

    /// Closes the session (its tokens go with it: peers see the node leave at once).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}
