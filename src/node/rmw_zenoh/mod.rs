//! ROS 2 over zenoh as `rmw_zenoh` speaks it: the session, the keys, the liveliness tokens and
//! the attachments by which rmw_zenoh nodes see each other and exchange messages.
//!
//! **Sessions.** The session config is the file named by `ZENOH_SESSION_CONFIG_URI`, else
//! rmw_zenoh's default for a node: a peer that connects to a router at `tcp/localhost:7447`,
//! listens on a free loopback port, learns the other peers from the router's gossip and never
//! scouts by multicast; `ZENOH_CONFIG_OVERRIDE` (`key=value;…`, JSON5 values) is applied on top.
//! Without a router, peers find each other only where the config says (`connect/endpoints`).
//! `ZENOH_ROUTER_CHECK_ATTEMPTS` as in rmw_zenoh: N > 0 waits up to N seconds for a router and
//! fails without one; a negative value skips the check; unset or 0 checks once and warns (a
//! safety node starts and reports rather than hang). The router (`ist_monitor zenoh-router`)
//! reads its config as `rmw_zenohd` does: `ZENOH_ROUTER_CONFIG_URI`, else listening on
//! `tcp/localhost:7447`, with `ZENOH_CONFIG_OVERRIDE` on top. TLS, mTLS and access control are
//! zenoh's own, set in these files (`config/zenoh/secure_router.json5` and
//! `secure_session.json5`, docs/security.md); the certificates and keys a config names are
//! checked before the session opens, so that a missing one is an error naming its key and path.
//!
//! **Keys.** A message of type `pkg/msg/T` on topic `/a/b` in domain `d` is put on the key
//! `d/a/b/pkg::msg::dds_::T_/RIHS01_<hash>`, the hash being the type's REP-2016 hash
//! ([`crate::msg::type_hash`]): an rmw_zenoh subscriber declares exactly that key, so a
//! publisher with another hash reaches nobody. The node's subscribers take any hash (`*`), so
//! that peers which write none (ros2-client, Humble) still reach it; a type that does not decode
//! is an input error, as on DDS.
//!
//! **Liveliness tokens** make the node and its publishers and subscriptions visible to
//! `ros2 node list` and `ros2 topic info`: `@ros2_lv/<domain>/<session id>/<node id>/<entity
//! id>/<kind>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`, names with `/` written
//! as `%`, kind `NN` (node), `MP` (publisher) or `MS` (subscription), the QoS in rmw_zenoh's
//! compact form (only what differs from ROS 2's default profile).
//!
//! **Transient local** (the speed-scaling output; `/tf_static` and `/robot_description` in) is
//! rmw_zenoh's: such a publisher keeps its last `depth` messages in a zenoh-ext cache that
//! late-joining subscribers query, and announces itself so that they find it; such a
//! subscription asks every publisher it detects, early or late, for that history (reliable
//! ones also recover missed samples by heartbeat).
//!
//! **Services** (the node's parameter services) are queryables on
//! `d/<node>/<service>/rcl_interfaces::srv::dds_::<Service>_/<hash>` (any hash taken), announced
//! by a liveliness token of kind `SS`: a request is a query with the CDR request as its payload
//! and the client's attachment; the reply carries the CDR response and an attachment with the
//! request's sequence number and the client's gid, by which the client pairs them.
//!
//! **Messages** are CDR with the encapsulation header, as on DDS and in bags; each carries an
//! attachment of 32 bytes: sequence number and source timestamp (ns), little-endian `i64`, then
//! the publisher's 16-byte gid.
//!
//! On zenoh, samples travel over the TCP connections between sessions (the router only
//! introduces them), so a camera-sized message is neither fragmented into datagrams nor lost in
//! a kernel buffer, and nothing is reassembled: the DDS host setup does not apply.
//!
//! Here: `config`, the session's and the router's configs and the router itself; `keys`, the
//! names, QoS strings and attachments of the wire protocol; `node`, the session and the node's
//! tokens; `publish`, `subscribe` and `service`, the entities made on it; `graph`, who
//! publishes a topic, from the publishers' tokens.

mod config;
mod graph;
mod keys;
mod node;
mod publish;
mod service;
mod subscribe;

pub use config::{config_from_env, rmw_zenoh_config, zenoh_router, ConfigFor, ZENOH_ROUTER};
pub use graph::ZenohEntities;
pub use keys::qos_key;
pub use node::ZenohNode;
pub use publish::ZenohPub;
pub use service::ZenohService;
