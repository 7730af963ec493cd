//! The two ROS 2 transports the node and its tools speak, chosen at start the way ROS 2 chooses
//! its middleware: DDS (RustDDS through ros2-client, the default) or zenoh with the wire protocol
//! of ROS 2's `rmw_zenoh` ([`super::rmw_zenoh`]; `RMW_IMPLEMENTATION=rmw_zenoh_cpp`, or
//! `--transport zenoh`). [`RosNode`] hides which one a node runs on, so that the node, `play` and
//! `record` are written once. Also the DDS side's own: the domain, the participant with its
//! socket buffers and its SROS2 security ([`super::security`]), and a source's subscription on
//! a topic that keeps few samples. A node and a tool alike take the security the environment
//! asks for, so that `play` and `record` are peers of a secured cell too.

use futures::StreamExt;
use ros2_client::dds::{Context, Node, Publisher, Server, ServiceMapping, Subscription};
use ros2_client::qos::{History, QosProfile, WhenFull};
use ros2_client::{MessageInfo, NodeName, NodeOptions, ServiceTypeName};
use serde::Serialize;

use super::error::{entity, NodeError};
use super::qos::{source_topic_qos, SOURCE_SAMPLES};
use super::rmw_zenoh::{config_from_env, ConfigFor, ZenohEntities, ZenohNode, ZenohPub};
use super::ros_args::{topic_name, type_name};
use super::security::{zenoh_endpoints, Security, SecurityEnv, SecurityError};
use super::socket::{self, SOCKET_BUFFER};
use crate::choice::Choice;
use crate::msg::{Owned, OwnedMessage, RosMessage, Writer};

/// Which middleware a node runs on (each one's meaning: its [`Choice::about`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    Dds,
    Zenoh,
}

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
}

impl Choice for Transport {
    const ALL: &'static [Self] = &[Transport::Dds, Transport::Zenoh];

    fn name(self) -> &'static str {
        match self {
            Transport::Dds => "dds",
            Transport::Zenoh => "zenoh",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Transport::Dds => "DDS (RustDDS), as rmw_fastrtps_cpp and rmw_cyclonedds_cpp speak it",
            Transport::Zenoh => "Zenoh, as rmw_zenoh_cpp speaks it",
        }
    }
}

/// A ROS 2 node on either transport.
pub struct RosNode {
    inner: Inner,
    /// What the node runs on, for its start line.
    pub describe: String,
    /// Its SROS2 security, for its start line.
    pub security: Security,
}

enum Inner {
    // Fields drop in order: the node before its context, whose participant (or session) must
    // outlive it (a DDS reader dropped after its participant stopped logs an error).
    Dds {
        node: Box<ros2_client::dds::Node>,
        ctx: ros2_client::dds::Context,
        name: NodeName,
    },
    Zenoh(Box<ZenohNode>),
}

/// A publisher on either transport.
pub enum Pub<T: Serialize> {
    Dds(Publisher<T>),
    Zenoh(ZenohPub<T>),
}

impl<T: RosMessage + std::fmt::Debug> Pub<T> {
    pub fn publish(&self, m: T) -> Result<(), String> {
        match self {
            Pub::Dds(p) => p.publish(m).map_err(|e| format!("{e:?}")),
            Pub::Zenoh(p) => p.publish(&m),
        }
    }
}

impl RosNode {
    /// A node `namespace`/`name` on `transport`, in the enclave the environment names (else
    /// `/`); on DDS its spinner runs on `executor`.
    pub fn new(
        transport: Transport,
        namespace: &str,
        name: &str,
        executor: &smol::Executor<'static>,
    ) -> Result<Self, NodeError> {
        Self::in_enclave(transport, namespace, name, None, executor)
    }

    /// [`RosNode::new`] in `enclave` (`--enclave`; `ROS_SECURITY_ENCLAVE_OVERRIDE` wins, as in
    /// rcl): with `ROS_SECURITY_ENABLE=true` the node is secured by the enclave's files or, on
    /// zenoh, by its config's TLS; without them it refuses to start (Enforce) or starts
    /// unsecured with a WARN (Permissive).
    pub fn in_enclave(
        transport: Transport,
        namespace: &str,
        name: &str,
        enclave: Option<&str>,
        executor: &smol::Executor<'static>,
    ) -> Result<Self, NodeError> {
        let env = SecurityEnv::from_process();
        let node_name = NodeName::new(namespace, name)
            .map_err(|e| entity("node name", &format!("{namespace} {name}"), e))?;
        // The parameter services are the node's own (`parameters`), from its declarations.
        let options = || {
            NodeOptions::new()
                .enable_rosout(false)
                .start_parameter_services(false)
        };
        let domain = domain_id()?;
        match transport {
            Transport::Dds => {
                let security = Security::for_dds(&env, enclave)?;
                security.warn_if_unsecured(name);
                let ctx = context(domain, &security)?;
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
                Ok(Self {
                    describe: format!("DDS (RustDDS) on domain {domain}"),
                    security,
                    inner: Inner::Dds {
                        ctx,
                        node: Box::new(node),
                        name: node_name,
                    },
                })
            }
            Transport::Zenoh => {
                let security = zenoh_security(&env)?;
                security.warn_if_unsecured(name);
                let (node, describe) = ZenohNode::open(domain, namespace, name)?;
                Ok(Self {
                    describe,
                    security,
                    inner: Inner::Zenoh(Box::new(node)),
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
            Inner::Zenoh(node) => {
                node.close();
                Box::new(())
            }
        }
    }

    pub fn transport(&self) -> Transport {
        match self.inner {
            Inner::Dds { .. } => Transport::Dds,
            Inner::Zenoh(_) => Transport::Zenoh,
        }
    }

    /// A publisher of `T` on `topic`.
    pub fn publisher<T: RosMessage>(
        &mut self,
        topic: &str,
        qos: QosProfile,
    ) -> Result<Pub<T>, NodeError> {
        match &mut self.inner {
            Inner::Dds { node, .. } => {
                let t = dds_topic::<T>(node, topic, &qos)?;
                node.create_publisher(&t, Some(qos))
                    .map(Pub::Dds)
                    .map_err(|e| entity("publisher", topic, e))
            }
            Inner::Zenoh(node) => node.publisher(topic, &qos).map(Pub::Zenoh),
        }
    }

    /// Subscribes to `T` on `topic`; each message (or read error) goes to `on` in a task on
    /// `executor`, until `on` returns false. `bounded`: a source's topic, whose DDS cache keeps
    /// at most [`SOURCE_SAMPLES`] (zenoh keeps no cache).
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
                    source_subscription(ctx, node, name, topic, qos)?
                } else {
                    let t = dds_topic::<T>(node, topic, &qos)?;
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
            Inner::Zenoh(node) => {
                let depth = if bounded {
                    SOURCE_SAMPLES as usize
                } else {
                    100
                };
                node.subscribe(topic, &qos, depth, executor, on)
            }
        }
    }
}

/// A topic as DDS discovery names it, watched on the node's participant.
pub struct DdsTopic {
    participant: ros2_client::dds::rustdds::DomainParticipant,
    /// The topic and type as DDS names them (`rt/…`, `pkg::msg::dds_::T_`).
    topic: String,
    type_name: String,
}

impl DdsTopic {
    fn new<T: RosMessage>(ctx: &Context, name: &NodeName, topic: &str) -> Result<Self, NodeError> {
        Ok(Self {
            participant: ctx.domain_participant(),
            topic: topic_name(topic)?.to_dds_name("rt", name, ""),
            type_name: type_name::<T>().dds_msg_type(),
        })
    }
}

/// Who publishes a topic now, by the transport's discovery: on DDS the remote writers that SEDP
/// announced on the topic with its type (named by GUID, as a message's writer is), on zenoh the
/// publishers' liveliness tokens (named by node and session). A writer leaves when it is deleted,
/// or when its participant's lease runs out or its zenoh session drops (a killed process).
pub enum TopicWriters {
    Dds(DdsTopic),
    Zenoh(ZenohEntities),
}

impl TopicWriters {
    /// The writers of the topic now, by name.
    pub fn writers(&self) -> Vec<String> {
        match self {
            TopicWriters::Zenoh(z) => z.names(),
            TopicWriters::Dds(_) => (self.gids().unwrap_or_default().iter())
                .map(Writer::to_string)
                .collect(),
        }
    }

    /// The writers of the topic now by GID, as its messages name their writer: on DDS their
    /// GUIDs; `None` on zenoh, whose liveliness tokens name a node and a session, not the GID
    /// its messages carry.
    pub fn gids(&self) -> Option<Vec<Writer>> {
        match self {
            TopicWriters::Dds(d) => Some(
                (d.participant.discovered_writers().iter())
                    .filter(|w| {
                        let t = &w.publication_topic_data;
                        t.topic_name == d.topic && t.type_name == d.type_name
                    })
                    .map(|w| {
                        let gid = ros2_client::Gid::from(w.writer_proxy.remote_writer_guid);
                        Writer(gid.to_bytes16())
                    })
                    .collect(),
            ),
            TopicWriters::Zenoh(_) => None,
        }
    }
}

/// Whether anyone subscribes to a topic now, by the transport's discovery: on DDS the remote
/// readers that SEDP announced on the topic with its type, on zenoh the subscriptions'
/// liveliness tokens. An output nobody reads (the unseen space's markers without RViz) need not
/// be computed.
pub enum TopicReaders {
    Dds(DdsTopic),
    Zenoh(ZenohEntities),
}

impl TopicReaders {
    /// Whether a reader of the topic is discovered now.
    pub fn any(&self) -> bool {
        match self {
            TopicReaders::Dds(d) => (d.participant.discovered_readers().iter()).any(|r| {
                let t = &r.subscription_topic_data;
                t.topic_name == d.topic && *t.type_name() == d.type_name
            }),
            TopicReaders::Zenoh(z) => !z.names().is_empty(),
        }
    }
}

impl RosNode {
    /// Watches who subscribes to `T` on `topic` ([`TopicReaders`]).
    pub fn subscribers<T: RosMessage>(&self, topic: &str) -> Result<TopicReaders, NodeError> {
        match &self.inner {
            Inner::Dds { ctx, name, .. } => {
                DdsTopic::new::<T>(ctx, name, topic).map(TopicReaders::Dds)
            }
            Inner::Zenoh(z) => z.subscribers(topic).map(TopicReaders::Zenoh),
        }
    }

    /// Watches who publishes `T` on `topic` ([`TopicWriters`]).
    pub fn publishers<T: RosMessage>(&self, topic: &str) -> Result<TopicWriters, NodeError> {
        match &self.inner {
            Inner::Dds { ctx, name, .. } => {
                DdsTopic::new::<T>(ctx, name, topic).map(TopicWriters::Dds)
            }
            Inner::Zenoh(z) => z.publishers(topic).map(TopicWriters::Zenoh),
        }
    }

    /// Answers the node's service `~/<service>` of type `rcl_interfaces/srv/<ty>` with
    /// `answer`: on DDS in a task on `executor`, on zenoh on zenoh's threads for as long as the
    /// task returned lives.
    pub fn service<Req, Resp>(
        &mut self,
        service: &str,
        ty: &str,
        executor: &smol::Executor<'static>,
        answer: impl Fn(Req) -> Resp + Send + Sync + 'static,
    ) -> Result<Option<smol::Task<()>>, NodeError>
    where
        Req: ros2_client::Message + Clone + Send + Sync + 'static,
        Resp: ros2_client::Message + Send + Sync + 'static,
    {
        let (node, name) = match &mut self.inner {
            Inner::Dds { node, name, .. } => (node, name),
            Inner::Zenoh(z) => {
                let full = format!("{}/{service}", z.node_path());
                let hash = crate::msg::service_hash(ty).ok_or_else(|| {
                    NodeError::Transport(format!("rcl_interfaces/srv/{ty}: no type hash"))
                })?;
                let server = z.service(&full, ty, hash, answer)?;
                // The server answers on zenoh's threads; the task keeps it until cancelled.
                return Ok(Some(executor.spawn(async move {
                    let _server = server;
                    futures::future::pending::<()>().await
                })));
            }
        };
        let full = format!("{}/{service}", name.fully_qualified_name());
        // rclcpp's services: reliable, volatile, the last 10.
        let qos = QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        let server: Server<Req, Resp> = node
            .create_server(
                ServiceMapping::Enhanced,
                &topic_name(&full)?,
                &ServiceTypeName::new("rcl_interfaces", ty),
                qos.clone(),
                qos,
            )
            .map_err(|e| entity("service", &full, e))?;
        Ok(Some(executor.spawn(async move {
            let mut requests = server.receive_request_stream();
            while let Some(request) = requests.next().await {
                match request {
                    Ok((id, req)) => {
                        if let Err(e) = server.async_send_response(id, answer(req)).await {
                            log::warn!("service {full}: answering: {e:?}");
                        }
                    }
                    Err(e) => log::warn!("service {full}: reading a request: {e:?}"),
                }
            }
        })))
    }

    /// The publisher of `/parameter_events` (reliable, volatile, the last 1000, as rclcpp's).
    pub fn parameter_events(&mut self) -> Result<Pub<crate::msg::ParameterEvent>, NodeError> {
        let qos = QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 1000 });
        self.publisher("/parameter_events", qos)
    }
}

/// The ROS domain: `ROS_DOMAIN_ID`, 0 when unset.
pub fn domain_id() -> Result<u16, NodeError> {
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(d) => d.parse::<u16>().map_err(|_| NodeError::DomainId(d)),
        Err(_) => Ok(0),
    }
}

/// The security of a zenoh session with `env`: its config's endpoints asked for TLS.
fn zenoh_security(env: &SecurityEnv) -> Result<Security, NodeError> {
    if !env.enabled() {
        return Ok(Security::Off);
    }
    let (config, from) = config_from_env(ConfigFor::Session)?;
    let values: Vec<String> = ["connect/endpoints", "listen/endpoints"]
        .iter()
        .filter_map(|k| config.get_json(k).ok())
        .collect();
    Ok(Security::for_zenoh(env, &from, &zenoh_endpoints(&values))?)
}

/// A DDS context on `domain`, with [`SOCKET_BUFFER`] socket buffers (forced past
/// `net.core.rmem_max` where the process may: `socket`) and, for [`Security::Enclave`], RustDDS's
/// built-in security plugins with the enclave's files (no key password, as rcl).
pub fn context(domain: u16, security: &Security) -> Result<Context, NodeError> {
    let builder = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
        .socket_receive_buffer_size(SOCKET_BUFFER)
        .socket_send_buffer_size(SOCKET_BUFFER);
    #[cfg(feature = "security")]
    let builder = match security {
        Security::Enclave { dir, .. } => builder.builtin_security(
            ros2_client::dds::rustdds::DomainParticipantSecurityConfigFiles::with_ros_default_names(
                dir,
                String::new(),
            ),
        ),
        _ => builder,
    };
    let participant = builder.build().map_err(|e| match security {
        Security::Enclave { name, dir, .. } => NodeError::Security(SecurityError::Refused {
            enclave: name.clone(),
            dir: dir.clone(),
            message: e.to_string(),
        }),
        _ => NodeError::Participant(format!("{e:?}")),
    })?;
    if let Err(e) = socket::force_receive_buffers(SOCKET_BUFFER) {
        log::debug!("SO_RCVBUFFORCE: {e} (the kernel's net.core.rmem_max stands)");
    }
    Context::from_domain_participant(participant)
        .map_err(|e| NodeError::Participant(format!("{e:?}")))
}

/// Creates a subscription of a source's messages `T` on `topic`, whose DDS topic holds at most
/// [`SOURCE_SAMPLES`] samples (QoS resource limits). The topic is made on the node's DDS
/// participant directly: ros2-client's QoS profile has no resource limits.
pub fn source_subscription<T: RosMessage + 'static>(
    ctx: &Context,
    node: &mut Node,
    node_name: &NodeName,
    topic: &str,
    qos: QosProfile,
) -> Result<Subscription<T>, NodeError> {
    let dds_qos = source_topic_qos(&qos);
    let t = ctx
        .domain_participant()
        .create_topic(
            topic_name(topic)?.to_dds_name("rt", node_name, ""),
            type_name::<T>().dds_msg_type(),
            &dds_qos,
            ros2_client::dds::rustdds::TopicKind::NoKey,
        )
        .map_err(|e| entity("topic", topic, e))?;
    node.create_subscription(&t, Some(qos))
        .map_err(|e| entity("subscription", topic, e))
}

/// The DDS topic of `T` named `topic`.
fn dds_topic<T: RosMessage>(
    node: &mut ros2_client::dds::Node,
    topic: &str,
    qos: &QosProfile,
) -> Result<ros2_client::dds::rustdds::Topic, NodeError> {
    node.create_topic(&topic_name(topic)?, type_name::<T>(), qos)
        .map_err(|e| entity("topic", topic, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transports_are_named_as_rmw_s() {
        assert_eq!(Transport::parse("zenoh"), Some(Transport::Zenoh));
        assert_eq!(Transport::names(), "dds or zenoh");
    }

    #[test]
    fn the_transport_follows_rmw_implementation() {
        // The environment is the process's: only the flag is exercised here.
        assert_eq!(
            Transport::choose(Some(Transport::Zenoh)).unwrap(),
            Transport::Zenoh
        );
        assert_eq!(
            Transport::choose(Some(Transport::Dds)).unwrap(),
            Transport::Dds
        );
    }
}
