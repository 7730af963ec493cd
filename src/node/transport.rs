//! The two ROS 2 transports the node and its tools speak, chosen at start the way ROS 2 chooses
//! its middleware: DDS (RustDDS, the default) or zenoh with the wire protocol of ROS 2's
//! `rmw_zenoh` (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`, or `--transport zenoh`). Both come from
//! ros2-client; [`RosNode`] hides which one a node runs on, so that the node, `play` and
//! `record` are written once.
//!
//! **Zenoh sessions follow rmw_zenoh's conventions.** The session config is the file named by
//! `ZENOH_SESSION_CONFIG_URI`, else rmw_zenoh's default for a node: a peer that connects to a
//! router at `tcp/localhost:7447`, listens on a free loopback port, learns the other peers from
//! the router's gossip and never scouts by multicast; `ZENOH_CONFIG_OVERRIDE` (`key=value;…`,
//! JSON5 values) is applied on top. Without a router, peers find each other only where the
//! config says (`connect/endpoints`). `ZENOH_ROUTER_CHECK_ATTEMPTS` as in rmw_zenoh: N > 0 waits
//! up to N seconds for a router and fails without one; a negative value skips the check; unset or
//! 0 checks once and warns (a safety node starts and reports rather than hang).
//!
//! On zenoh, samples travel over the TCP connections between sessions (the router only
//! introduces them), so a camera-sized message is neither fragmented into datagrams nor lost in
//! a kernel buffer, and nothing is reassembled: the DDS host setup does not apply.

use std::time::{Duration, Instant};

use futures::StreamExt;
use ros2_client::dds::{Publisher, Subscription};
use ros2_client::{MessageInfo, NodeName, NodeOptions};
use serde::Serialize;

use super::{entity, type_name, NodeError, QosProfile};
use crate::msg::{Owned, OwnedMessage, RosMessage};

/// Which middleware a node runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Transport {
    /// DDS (RustDDS), as rmw_fastrtps_cpp and rmw_cyclonedds_cpp speak it.
    Dds,
    /// Zenoh, as rmw_zenoh_cpp speaks it.
    Zenoh,
}

/// rmw_zenoh's router endpoint.
pub const ZENOH_ROUTER: &str = "tcp/localhost:7447";

impl Transport {
    /// `flag` where given, else from `RMW_IMPLEMENTATION` (unset: DDS).
    pub fn choose(flag: Option<Transport>) -> Result<Self, NodeError> {
        if let Some(t) = flag {
            return Ok(t);
        }
        match std::env::var("RMW_IMPLEMENTATION").as_deref() {
            Err(_) | Ok("") => Ok(Transport::Dds),
            Ok("rmw_zenoh_cpp") => Ok(Transport::Zenoh),
            Ok(
                "rmw_fastrtps_cpp"
                | "rmw_cyclonedds_cpp"
                | "rmw_connextdds"
                | "rmw_fastrtps_dynamic_cpp",
            ) => Ok(Transport::Dds),
            Ok(other) => Err(NodeError::Transport(format!(
                "RMW_IMPLEMENTATION '{other}': this node speaks DDS (rmw_fastrtps_cpp, \
                 rmw_cyclonedds_cpp, …) and zenoh (rmw_zenoh_cpp)"
            ))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Transport::Dds => "dds",
            Transport::Zenoh => "zenoh",
        }
    }
}

/// Sets `key` to the JSON5 `value` in `config`; an error names `what` config and the key.
fn set_json5(
    config: &mut zenoh::Config,
    what: &str,
    key: &str,
    value: &str,
) -> Result<(), NodeError> {
    config
        .insert_json5(key, value)
        .map_err(|e| NodeError::Transport(format!("{what} {key}: {e}")))
}

/// A zenoh config of these keys set, over zenoh's defaults.
fn zenoh_config(what: &str, keys: &[(&str, String)]) -> Result<zenoh::Config, NodeError> {
    let mut c = zenoh::Config::default();
    for (key, value) in keys {
        set_json5(&mut c, what, key, value)?;
    }
    Ok(c)
}

/// rmw_zenoh's default session config of a node (see the module's documentation).
fn rmw_zenoh_default_config() -> Result<zenoh::Config, NodeError> {
    zenoh_config(
        "zenoh config",
        &[
            ("mode", "\"peer\"".into()),
            ("connect/endpoints", format!("[\"{ZENOH_ROUTER}\"]")),
            ("listen/endpoints", "[\"tcp/localhost:0\"]".into()),
            ("scouting/multicast/enabled", "false".into()),
            ("scouting/gossip/enabled", "true".into()),
        ],
    )
}

/// The session config by rmw_zenoh's rules, and where it came from.
pub fn zenoh_session_config() -> Result<(zenoh::Config, String), NodeError> {
    let (mut config, mut from) = match std::env::var("ZENOH_SESSION_CONFIG_URI") {
        Ok(uri) if !uri.trim().is_empty() => (
            zenoh::Config::from_file(uri.trim()).map_err(|e| {
                NodeError::Transport(format!("ZENOH_SESSION_CONFIG_URI {uri}: {e}"))
            })?,
            format!("session config {uri}"),
        ),
        _ => (
            rmw_zenoh_default_config()?,
            format!("rmw_zenoh's default session config (router at {ZENOH_ROUTER})"),
        ),
    };
    if let Ok(overrides) = std::env::var("ZENOH_CONFIG_OVERRIDE") {
        for entry in overrides
            .split(';')
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            let (key, value) = entry.split_once('=').ok_or_else(|| {
                NodeError::Transport(format!("ZENOH_CONFIG_OVERRIDE: '{entry}' is not key=value"))
            })?;
            set_json5(
                &mut config,
                "ZENOH_CONFIG_OVERRIDE",
                key.trim(),
                value.trim(),
            )?;
        }
        from.push_str(&format!(", with ZENOH_CONFIG_OVERRIDE '{overrides}'"));
    }
    Ok((config, from))
}

/// A ROS 2 node on either transport.
pub struct RosNode {
    inner: Inner,
    /// What the node runs on, for its start line.
    pub describe: String,
}

enum Inner {
    // Fields drop in order: the node before its context, whose participant (or session) must
    // outlive it (a DDS reader dropped after its participant stopped logs an error).
    Dds {
        node: Box<ros2_client::dds::Node>,
        ctx: ros2_client::dds::Context,
        name: NodeName,
    },
    Zenoh {
        node: Box<ros2_client::zenoh::Node>,
        ctx: ros2_client::zenoh::Context,
    },
}

/// A publisher on either transport.
pub enum Pub<T: Serialize> {
    Dds(Publisher<T>),
    Zenoh(
        ros2_client::zenoh::Publisher<PreEncoded>,
        std::marker::PhantomData<fn(T)>,
    ),
}

impl<T: RosMessage + std::fmt::Debug> Pub<T> {
    pub fn publish(&self, m: T) -> Result<(), String> {
        match self {
            Pub::Dds(p) => p.publish(m).map_err(|e| format!("{e:?}")),
            Pub::Zenoh(p, _) => {
                let payload = crate::msg::encode(&m).map_err(|e| e.to_string())?;
                p.publish(PreEncoded(payload[4..].to_vec()))
                    .map_err(|e| format!("{:?}", e.to_string()))
            }
        }
    }
}

/// A message body already encoded as CDR by `crate::msg` (the encapsulation header left off).
///
/// ros2-client's zenoh backend encodes with cdr-encoding 0.10, which writes a `uint8[]`
/// (serde bytes) without its length and reads it back as something else: a PointCloud2 or an
/// Image would not survive it. So the node encodes and decodes its messages itself (the same
/// CDR as on DDS and in bags) and hands the publisher the finished body, which that encoder
/// writes as it is; the encapsulation header is the backend's (`00 01 00 00`, little endian,
/// as the body). `tests/node.rs` reads these bytes with an independent zenoh peer.
pub struct PreEncoded(Vec<u8>);

impl Serialize for PreEncoded {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(&self.0)
    }
}

/// `T` decoded into its owned form.
struct OwnedDe<T>(T);

/// A CDR payload (with its encapsulation header, either byte order) decoded into `T`'s owned
/// form.
fn decode_owned<T: OwnedMessage>(payload: &[u8]) -> Result<T, String> {
    use byteorder::{BigEndian, LittleEndian};
    if payload.len() < 4 {
        return Err(format!("{}: payload of {} bytes", T::TYPE, payload.len()));
    }
    let body = &payload[4..];
    let decoded = match payload[1] {
        1 => cdr_encoding::from_bytes::<OwnedDe<T>, LittleEndian>(body),
        0 => cdr_encoding::from_bytes::<OwnedDe<T>, BigEndian>(body),
        k => {
            return Err(format!(
                "{}: encapsulation {k:#04x} is not plain CDR",
                T::TYPE
            ))
        }
    };
    decoded
        .map(|(m, _)| m.0)
        .map_err(|e| format!("{}: CDR: {e}", T::TYPE))
}

/// The rmw_zenoh attachment of a sample: sequence number, source timestamp (ns), source gid,
/// little endian.
fn attachment_info(sample: &zenoh::sample::Sample) -> MessageInfo {
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

impl<'de, T: OwnedMessage> serde::Deserialize<'de> for OwnedDe<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        T::deserialize_owned(d).map(OwnedDe)
    }
}

impl RosNode {
    /// A node `namespace`/`name` on `transport`; on DDS its spinner runs on `executor`.
    pub fn new(
        transport: Transport,
        namespace: &str,
        name: &str,
        executor: &smol::Executor<'static>,
    ) -> Result<Self, NodeError> {
        let node_name = NodeName::new(namespace, name)
            .map_err(|e| entity("node name", &format!("{namespace} {name}"), e))?;
        let options = || NodeOptions::new().enable_rosout(false);
        match transport {
            Transport::Dds => {
                let ctx = super::context()?;
                let mut node = ctx
                    .new_node(node_name.clone(), options())
                    .map_err(|e| entity("node", name, e))?;
                executor
                    .spawn(
                        node.spinner()
                            .map_err(|e| entity("spinner of node", name, e))?
                            .spin(),
                    )
                    .detach();
                let domain = std::env::var("ROS_DOMAIN_ID").unwrap_or_else(|_| "0".into());
                Ok(Self {
                    describe: format!("DDS (RustDDS) on domain {domain}"),
                    inner: Inner::Dds {
                        ctx,
                        node: Box::new(node),
                        name: node_name,
                    },
                })
            }
            Transport::Zenoh => {
                let domain = match std::env::var("ROS_DOMAIN_ID") {
                    Ok(d) => d.parse::<u16>().map_err(|_| NodeError::DomainId(d))?,
                    Err(_) => 0,
                };
                let (config, from) = zenoh_session_config()?;
                let ctx = ros2_client::zenoh::Context::with_options(
                    ros2_client::zenoh::ContextOptions::new()
                        .domain_id(domain)
                        .zenoh_config(config),
                )
                .map_err(|e| NodeError::Transport(format!("zenoh session ({from}): {e:?}")))?;
                let routers = check_router(&ctx)?;
                let node = ctx
                    .new_node(node_name, options())
                    .map_err(|e| entity("node", name, e))?;
                Ok(Self {
                    describe: format!(
                        "zenoh (rmw_zenoh) on domain {domain}, {from}, {routers} router(s) \
                         connected"
                    ),
                    inner: Inner::Zenoh {
                        ctx,
                        node: Box::new(node),
                    },
                })
            }
        }
    }

    /// The node of a command-line tool, `/<prefix>_<pid>`.
    pub fn tool(
        transport: Transport,
        prefix: &str,
        executor: &smol::Executor<'static>,
    ) -> Result<Self, NodeError> {
        Self::new(
            transport,
            "/",
            &format!("{prefix}_{}", std::process::id()),
            executor,
        )
    }

    /// Drops the node and returns its context, to be dropped once the executor that spins the
    /// node has stopped (the DDS spinner holds readers of the context's participant).
    pub fn close(self) -> Box<dyn std::any::Any> {
        match self.inner {
            Inner::Dds { node, ctx, .. } => {
                drop(node);
                Box::new(ctx)
            }
            Inner::Zenoh { node, ctx } => {
                drop(node);
                Box::new(ctx)
            }
        }
    }

    pub fn transport(&self) -> Transport {
        match self.inner {
            Inner::Dds { .. } => Transport::Dds,
            Inner::Zenoh { .. } => Transport::Zenoh,
        }
    }

    /// A publisher of `T` on `topic`.
    pub fn publisher<T: RosMessage>(
        &mut self,
        topic: &str,
        qos: QosProfile,
    ) -> Result<Pub<T>, NodeError> {
        let name = super::topic_name(topic)?;
        match &mut self.inner {
            Inner::Dds { node, .. } => {
                let t = node
                    .create_topic(&name, type_name::<T>(), &qos)
                    .map_err(|e| entity("topic", topic, e))?;
                node.create_publisher(&t, Some(qos))
                    .map(Pub::Dds)
                    .map_err(|e| entity("publisher", topic, e))
            }
            Inner::Zenoh { node, .. } => {
                let t = node.create_topic(&name, type_name::<T>(), &qos);
                node.create_publisher::<PreEncoded>(&t, Some(qos))
                    .map(|p| Pub::Zenoh(p, std::marker::PhantomData))
                    .map_err(|e| entity("publisher", topic, e))
            }
        }
    }

    /// Subscribes to `T` on `topic`; each message (or read error) goes to `on` in a task on
    /// `executor`, until `on` returns false. `bounded`: a source's topic, whose DDS cache keeps
    /// at most [`super::SOURCE_SAMPLES`] (zenoh keeps no cache).
    pub fn subscribe<T: OwnedMessage>(
        &mut self,
        topic: &str,
        qos: QosProfile,
        bounded: bool,
        executor: &smol::Executor<'static>,
        mut on: impl FnMut(Result<(T, MessageInfo), String>) -> bool + Send + 'static,
    ) -> Result<smol::Task<()>, NodeError> {
        match &mut self.inner {
            Inner::Dds { node, ctx, name } => {
                let sub: Subscription<T> = if bounded {
                    super::source_subscription(ctx, node, name, topic, qos)?
                } else {
                    let t = node
                        .create_topic(&super::topic_name(topic)?, type_name::<T>(), &qos)
                        .map_err(|e| entity("topic", topic, e))?;
                    node.create_subscription(&t, Some(qos))
                        .map_err(|e| entity("subscription", topic, e))?
                };
                Ok(executor.spawn(async move {
                    let mut stream = std::pin::pin!(sub.async_stream_seed(Owned::<T>::default()));
                    while let Some(item) = stream.next().await {
                        if !on(item.map_err(|e| format!("{e:?}"))) {
                            break;
                        }
                    }
                }))
            }
            Inner::Zenoh { ctx, .. } => {
                // A subscriber on the session itself, keyed as rmw_zenoh keys topics
                // (`<domain>/<topic>/<DDS type>/<type hash>`, any hash), into a ring that keeps
                // the newest samples only: a source keeps 2 (the node processes the newest),
                // others 100. Nothing queues without bound, and a slow reader never blocks the
                // session.
                use zenoh::Wait;
                let key = format!(
                    "{}/{}/{}/*",
                    ctx.domain_id(),
                    topic.trim_matches('/'),
                    type_name::<T>().dds_msg_type()
                );
                let depth = if bounded {
                    super::SOURCE_SAMPLES as usize
                } else {
                    100
                };
                let sub = ctx
                    .session()
                    .declare_subscriber(key.as_str())
                    .with(zenoh::handlers::RingChannel::new(depth))
                    .wait()
                    .map_err(|e| entity("subscription", topic, e))?;
                Ok(executor.spawn(async move {
                    while let Ok(sample) = sub.recv_async().await {
                        let item = decode_owned::<T>(&sample.payload().to_bytes())
                            .map(|m| (m, attachment_info(&sample)));
                        if !on(item) {
                            break;
                        }
                    }
                }))
            }
        }
    }
}

/// How many routers the session is connected to, by `ZENOH_ROUTER_CHECK_ATTEMPTS` (see the
/// module's documentation).
fn check_router(ctx: &ros2_client::zenoh::Context) -> Result<usize, NodeError> {
    use zenoh::Wait;
    let count = || ctx.session().info().routers_zid().wait().count();
    let attempts: i64 = match std::env::var("ZENOH_ROUTER_CHECK_ATTEMPTS") {
        Ok(v) => v.trim().parse().map_err(|_| {
            NodeError::Transport(format!(
                "ZENOH_ROUTER_CHECK_ATTEMPTS '{v}' is not an integer"
            ))
        })?,
        Err(_) => 0,
    };
    if attempts < 0 {
        return Ok(count());
    }
    let deadline = Instant::now() + Duration::from_secs(attempts as u64);
    loop {
        let n = count();
        if n > 0 {
            return Ok(n);
        }
        if Instant::now() >= deadline {
            if attempts > 0 {
                return Err(NodeError::Transport(format!(
                    "no zenoh router after {attempts} s (ZENOH_ROUTER_CHECK_ATTEMPTS): start \
                     one (rmw_zenohd, or `ist_monitor zenoh-router`) at {ZENOH_ROUTER}"
                )));
            }
            log::warn!(
                "no zenoh router connected: other nodes are found only through a router at \
                 {ZENOH_ROUTER} (rmw_zenohd, or `ist_monitor zenoh-router`) or the endpoints \
                 the session config names (README, 'The live node')"
            );
            return Ok(0);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// A zenoh router, as `rmw_zenohd` runs one for ROS 2: listens on `listen` (default
/// [`ZENOH_ROUTER`]), never scouts by multicast, and introduces the peers that connect to it
/// to each other. Runs until `stop` is set.
pub fn zenoh_router(listen: &str, stop: &std::sync::atomic::AtomicBool) -> Result<(), NodeError> {
    use zenoh::Wait;
    let c = zenoh_config(
        "zenoh router config",
        &[
            ("mode", "\"router\"".into()),
            ("listen/endpoints", format!("[\"{listen}\"]")),
            ("scouting/multicast/enabled", "false".into()),
        ],
    )?;
    let session = zenoh::open(c)
        .wait()
        .map_err(|e| NodeError::Transport(format!("zenoh router on {listen}: {e}")))?;
    log::info!("zenoh router {} listening on {listen}", session.zid());
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = session.close().wait();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transport_follows_rmw_implementation() {
        assert_eq!(
            Transport::choose(Some(Transport::Zenoh)).unwrap(),
            Transport::Zenoh
        );
        // The environment is the process's: only the flag is exercised here; the names are
        // checked through the table itself.
        let c = rmw_zenoh_default_config().unwrap();
        let connect = c.get_json("connect/endpoints").unwrap();
        assert!(connect.contains("tcp/localhost:7447"), "{connect}");
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
    }
}
