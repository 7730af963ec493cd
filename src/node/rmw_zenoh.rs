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
//! `tcp/localhost:7447`, with `ZENOH_CONFIG_OVERRIDE` on top.
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

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use ros2_client::qos::{Durability, History, Liveliness, Reliability};
use ros2_client::MessageInfo;
use zenoh::Wait;
use zenoh_ext::{
    AdvancedPublisherBuilderExt, AdvancedSubscriberBuilderExt, CacheConfig, HistoryConfig,
    MissDetectionConfig, RecoveryConfig,
};

use super::{entity, type_name, NodeError, QosProfile};
use crate::msg::{OwnedMessage, RosMessage};

/// rmw_zenoh's router endpoint.
pub const ZENOH_ROUTER: &str = "tcp/localhost:7447";

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
            // Samples are timestamped: a transient-local cache orders by them.
            ("timestamping/enabled", "true".into()),
        ],
    )
}

/// Which zenoh config: a node's session, or the router's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigFor {
    Session,
    Router,
}

impl ConfigFor {
    /// The variable that names its config file, as rmw_zenoh reads it.
    pub fn uri_variable(self) -> &'static str {
        match self {
            ConfigFor::Session => "ZENOH_SESSION_CONFIG_URI",
            ConfigFor::Router => "ZENOH_ROUTER_CONFIG_URI",
        }
    }
}

/// A config by rmw_zenoh's rules, and where it came from: the file named by `uri` (the value of
/// [`ConfigFor::uri_variable`]), else rmw_zenoh's default (a node's: see the module's
/// documentation; the router's: listens on [`ZENOH_ROUTER`], no multicast scouting), then the
/// `key=value;…` entries of `overrides` (`ZENOH_CONFIG_OVERRIDE`) on top.
pub fn rmw_zenoh_config(
    what: ConfigFor,
    uri: Option<&str>,
    overrides: Option<&str>,
) -> Result<(zenoh::Config, String), NodeError> {
    let (mut config, mut from) = match uri.map(str::trim).filter(|u| !u.is_empty()) {
        Some(uri) => (
            zenoh::Config::from_file(uri)
                .map_err(|e| NodeError::Transport(format!("{} {uri}: {e}", what.uri_variable())))?,
            format!("config {uri} ({})", what.uri_variable()),
        ),
        None => match what {
            ConfigFor::Session => (
                rmw_zenoh_default_config()?,
                format!("rmw_zenoh's default session config (router at {ZENOH_ROUTER})"),
            ),
            ConfigFor::Router => (
                zenoh_config(
                    "zenoh router config",
                    &[
                        ("mode", "\"router\"".into()),
                        ("listen/endpoints", format!("[\"{ZENOH_ROUTER}\"]")),
                        ("scouting/multicast/enabled", "false".into()),
                        ("timestamping/enabled", "true".into()),
                    ],
                )?,
                format!("rmw_zenoh's default router config ({ZENOH_ROUTER})"),
            ),
        },
    };
    if let Some(overrides) = overrides {
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

/// [`rmw_zenoh_config`] from the environment.
pub fn config_from_env(what: ConfigFor) -> Result<(zenoh::Config, String), NodeError> {
    let uri = std::env::var(what.uri_variable()).ok();
    let overrides = std::env::var("ZENOH_CONFIG_OVERRIDE").ok();
    rmw_zenoh_config(what, uri.as_deref(), overrides.as_deref())
}

/// The node id in this session's liveliness tokens (one node per session).
const NODE_ID: u64 = 0;

/// How often a reliable transient-local publisher announces its last sequence number, so that
/// subscribers notice missed samples and fetch them from its cache (rmw_zenoh's period).
const HEARTBEAT: Duration = Duration::from_millis(500);

/// The depth of a QoS profile's history (keep all: 1000).
fn depth(q: &QosProfile) -> usize {
    match q.history {
        History::KeepLast { depth } => depth.max(1),
        History::KeepAll => 1000,
    }
}

/// `name` as rmw_zenoh writes names in liveliness keys: `/` as `%`, empty as `%`.
fn mangle(name: &str) -> String {
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

/// The 32-byte attachment of a message (see the module's documentation).
fn attachment(sequence_number: i64, gid: &[u8; 16]) -> Vec<u8> {
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

/// A node on a zenoh session, as rmw_zenoh makes one: the session and the node's liveliness
/// token, and the publishers and subscriptions made on it.
pub struct ZenohNode {
    session: zenoh::Session,
    domain: u16,
    /// The start of every entity's liveliness key: `@ros2_lv/<domain>/<zid>/<node id>`.
    lv_prefix: String,
    /// The end of it: `<enclave>/<namespace>/<node>`.
    lv_node: String,
    next_entity: AtomicU64,
    /// The node's fully qualified name, `/ns/name`.
    path: String,
    _token: zenoh::liveliness::LivelinessToken,
}

/// What a publisher or subscription is keyed by.
struct Keys {
    /// The data key (with the type's hash, or `*`).
    data: String,
    /// The liveliness key of the entity.
    liveliness: String,
}

impl ZenohNode {
    /// Opens a session by rmw_zenoh's rules and declares node `namespace`/`name` of ROS domain
    /// `domain` on it; also returns what the node runs on, for its start line.
    pub fn open(domain: u16, namespace: &str, name: &str) -> Result<(Self, String), NodeError> {
        let (config, from) = config_from_env(ConfigFor::Session)?;
        let session = zenoh::open(config)
            .wait()
            .map_err(|e| NodeError::Transport(format!("zenoh session ({from}): {e}")))?;
        let routers = check_router(&session)?;
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
    fn token(
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
    fn keys<T: RosMessage>(
        &self,
        kind: &str,
        topic: &str,
        qos: &QosProfile,
        any_hash: bool,
    ) -> Result<Keys, NodeError> {
        super::topic_name(topic)?; // a ROS name, as on DDS
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

    /// Answers service `service` (absolute) of type `rcl_interfaces/srv/<ty>` (REP-2016 hash
    /// `hash`) with `answer`, on zenoh's own threads, until the returned server is dropped.
    pub fn service<Req, Resp>(
        &self,
        service: &str,
        ty: &str,
        hash: &str,
        answer: impl Fn(Req) -> Resp + Send + Sync + 'static,
    ) -> Result<ZenohService, NodeError>
    where
        Req: serde::de::DeserializeOwned + 'static,
        Resp: serde::Serialize + 'static,
    {
        super::topic_name(service)?; // a ROS name, as on DDS
        let service = format!("/{}", service.trim_matches('/'));
        let dds_type = format!("rcl_interfaces::srv::dds_::{ty}_");
        let id = self.next_entity.fetch_add(1, Ordering::Relaxed);
        // rclcpp's services: reliable, volatile, the last 10.
        let qos = QosProfile::publisher_default()
            .reliability_reliable(ros2_client::qos::WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        let liveliness = format!(
            "{}/{id}/SS/{}/{}/{dds_type}/{hash}/{}",
            self.lv_prefix,
            self.lv_node,
            mangle(&service),
            qos_key(&qos)
        );
        let name = service.clone();
        let queryable = self
            .session
            .declare_queryable(format!("{}{service}/{dds_type}/*", self.domain))
            .complete(true)
            .callback(move |query| {
                let Some(request) = query.payload().map(|p| p.to_bytes()) else {
                    log::warn!("service {name}: a request without a payload");
                    return;
                };
                let request: Req = match decode_cdr(&request) {
                    Ok(r) => r,
                    Err(e) => {
                        log::warn!("service {name}: a request that does not decode: {e}");
                        return;
                    }
                };
                let mut response = vec![0u8, 1, 0, 0];
                if let Err(e) = cdr_encoding::to_writer::<_, byteorder::LittleEndian, _>(
                    &mut response,
                    &answer(request),
                ) {
                    log::warn!("service {name}: encoding the answer: {e}");
                    return;
                }
                // The client pairs the reply by the request's sequence number and its own gid.
                let (seq, gid) = query.attachment().map_or((0, [0; 16]), |a| {
                    let b = a.to_bytes();
                    let seq = b.get(0..8).and_then(|s| s.try_into().ok());
                    let gid = b.get(16..32).and_then(|g| g.try_into().ok());
                    (seq.map_or(0, i64::from_le_bytes), gid.unwrap_or([0; 16]))
                });
                if let Err(e) = query
                    .reply(query.key_expr().clone(), response)
                    .attachment(attachment(seq, &gid))
                    .wait()
                {
                    log::warn!("service {name}: answering: {e}");
                }
            })
            .wait()
            .map_err(|e| entity("service", &service, e))?;
        let token = self.token(liveliness, "service", &service)?;
        Ok(ZenohService {
            _queryable: queryable,
            _token: token,
        })
    }

    /// Closes the session (its tokens go with it: peers see the node leave at once).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}

/// A zenoh publisher: plain, or with the cache of a transient-local one.
enum Put {
    Plain(zenoh::pubsub::Publisher<'static>),
    Latched(zenoh_ext::AdvancedPublisher<'static>),
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

/// A service answered on zenoh, until dropped.
pub struct ZenohService {
    _queryable: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
}

/// A CDR payload with its encapsulation header (either byte order) as `T`.
fn decode_cdr<T: serde::de::DeserializeOwned>(payload: &[u8]) -> Result<T, String> {
    let (header, body) = payload
        .split_at_checked(4)
        .ok_or_else(|| format!("{} bytes, no CDR header", payload.len()))?;
    match header[1] {
        1 => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        0 => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        kind => return Err(format!("encapsulation {kind}")),
    }
    .map(|(t, _)| t)
    .map_err(|e| e.to_string())
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

/// How many routers the session is connected to, by `ZENOH_ROUTER_CHECK_ATTEMPTS` (see the
/// module's documentation).
fn check_router(session: &zenoh::Session) -> Result<usize, NodeError> {
    let count = || session.info().routers_zid().wait().count();
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
                 the session config names (docs/node.md)"
            );
            return Ok(0);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// A zenoh router, as `rmw_zenohd` runs one for ROS 2: its config by rmw_zenoh's rules
/// (`ZENOH_ROUTER_CONFIG_URI`, else listening on [`ZENOH_ROUTER`] without multicast scouting;
/// `ZENOH_CONFIG_OVERRIDE` on top), `listen` replacing its endpoints where given. It introduces
/// the peers that connect to it to each other. Runs until `stop` is set.
pub fn zenoh_router(
    listen: Option<&str>,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<(), NodeError> {
    let (mut c, from) = config_from_env(ConfigFor::Router)?;
    if let Some(listen) = listen {
        set_json5(
            &mut c,
            "zenoh router config",
            "listen/endpoints",
            &format!("[\"{listen}\"]"),
        )?;
    }
    let endpoints = c.get_json("listen/endpoints").unwrap_or_default();
    let session = zenoh::open(c)
        .wait()
        .map_err(|e| NodeError::Transport(format!("zenoh router on {endpoints} ({from}): {e}")))?;
    log::info!(
        "zenoh router {} listening on {endpoints} ({from})",
        session.zid()
    );
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
    fn the_default_session_config_is_rmw_zenohs() {
        let c = rmw_zenoh_default_config().unwrap();
        let connect = c.get_json("connect/endpoints").unwrap();
        assert!(connect.contains("tcp/localhost:7447"), "{connect}");
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
    }

    #[test]
    fn configs_follow_rmw_zenohs_variables() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("router.json5");
        std::fs::write(
            &file,
            r#"{ mode: "router", listen: { endpoints: ["tcp/127.0.0.1:7455"] } }"#,
        )
        .unwrap();
        let (c, from) =
            rmw_zenoh_config(ConfigFor::Router, Some(file.to_str().unwrap()), None).unwrap();
        assert!(c.get_json("listen/endpoints").unwrap().contains("7455"));
        assert!(from.contains("ZENOH_ROUTER_CONFIG_URI"), "{from}");
        let (c, _) = rmw_zenoh_config(ConfigFor::Router, None, None).unwrap();
        assert!(c.get_json("listen/endpoints").unwrap().contains("7447"));
        assert_eq!(c.get_json("mode").unwrap(), "\"router\"");
        let (c, from) = rmw_zenoh_config(
            ConfigFor::Session,
            Some("  "),
            Some("connect/endpoints=[\"tcp/127.0.0.1:7450\"]; scouting/gossip/enabled=false"),
        )
        .unwrap();
        assert!(c.get_json("connect/endpoints").unwrap().contains("7450"));
        assert_eq!(c.get_json("scouting/gossip/enabled").unwrap(), "false");
        assert!(from.contains("default session config"), "{from}");
        // A missing file and a malformed override are errors that name the variable.
        let e = rmw_zenoh_config(ConfigFor::Session, Some("/nonexistent.json5"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ZENOH_SESSION_CONFIG_URI"), "{e}");
        let e = rmw_zenoh_config(ConfigFor::Router, None, Some("mode"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("ZENOH_CONFIG_OVERRIDE"), "{e}");
    }

    #[test]
    fn qos_keys_are_rmw_zenohs() {
        // ROS 2's default profile (reliable, volatile, keep last 10) is all defaults.
        let default = QosProfile::subscription_default()
            .reliability_reliable(ros2_client::qos::WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        assert_eq!(qos_key(&default), "::,10:,:,:,,");
        assert_eq!(qos_key(&super::super::SENSOR_QOS), "2::,1:,:,:,,");
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
