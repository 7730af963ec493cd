//! The live ROS 2 node (ros2-client over RustDDS, or zenoh as rmw_zenoh speaks it): the monitor
//! fed from its sources, its outputs published, stale sources reported. `play` and `record` are
//! the bag tools that drive and observe it (tests, benchmarks, demos).
//!
//! Threads: an executor thread runs the ros2-client spinner and one task per subscription.
//! `/tf`, `/tf_static`, the joint states and depth sources' CameraInfo go to the processing
//! thread in order. Each cloud (or depth image) replaces the previous one in its source's slot:
//! only the newest is ever processed, so no queue grows. The DDS reader keeps one sample (KeepLast 1), and a cloud that is overwritten
//! before it is processed counts as dropped, as do gaps in the writer's sequence numbers. The
//! processing thread waits for a slot, runs the monitor and publishes its outputs. It also
//! checks every source: one silent for longer than its `source_timeout` (or never heard) is a
//! fault. The node then publishes ERROR diagnostics with the reason and `safety_stop`, and never
//! a distance. Every output is the cell's fused picture over all sources (`monitor::fusion`); it
//! is also published every `heartbeat_period` when no frame went out, the sources aged by the
//! clock. Whatever ends the serving (a signal, an error, a panic), the node's last word —
//! `safety_stop` true, factor 0, "not monitoring: REASON" — goes out before the participant
//! closes. For what can say nothing (SIGKILL, a power loss), the outputs published on every
//! beat offer the QoS deadline `output_deadline` and every output automatic liveliness (a 3 s
//! lease), so a DDS subscriber that asks for them is told by its own middleware.
//!
//! Here: the node's start, serving loop and stop. `ros_args`: the command line after
//! `--ros-args`. `inputs`: the sources' slots and the forwarded TF, joint states and camera
//! info. `publishers`: the output table's publishers and the last word. `parameters`: the
//! parameter services; a change they take reaches the processing thread through a channel and
//! is applied before its next frame (a source enabled then is subscribed to then). `transport` and
//! `rmw_zenoh`: DDS or zenoh underneath.

mod clock;
mod inputs;
pub mod parameters;
pub mod play;
mod publishers;
pub mod record;
pub mod rmw_zenoh;
mod ros_args;
pub mod rosout;
mod serve;
mod socket;
pub mod transport;

pub use clock::NodeClock;
use parameters::{Parameters, Safety};
pub use publishers::PANIC_AFTER_ENV;
use publishers::{last_word, panic_text, Publishers};
pub use ros_args::{expand_topic, parse_ros_args, remap_topic, resolve_topic, RosArgs};
pub use socket::granted_receive_buffer;

pub use transport::{Pub, RosNode, Transport};

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ros2_client::dds::{Context, Node, Subscription};
use ros2_client::{MessageTypeName, Name, NodeName};

use crate::config::{Config, RobotSource};
use crate::monitor::{Monitor, Outputs};
use crate::msg::{Clock, Log, RosMessage, StringMessage};

pub use ros2_client::qos::{Durability, History, QosProfile, Reliability, WhenFull};

/// The ROS 2 package and type name of a message type (`pkg/msg/Type`).
pub fn type_name<T: RosMessage>() -> MessageTypeName {
    let package = T::TYPE.split('/').next().unwrap_or_default();
    let name = T::TYPE.rsplit('/').next().unwrap_or_default();
    MessageTypeName::new(package, name)
}

/// QoS of sensor data: best effort, newest only.
pub const SENSOR_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_best_effort()
    .history(History::KeepLast { depth: 1 });
/// QoS of `/tf_static`: reliable, transient local (late joiners get the transforms).
pub const TF_STATIC_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 100 });
/// QoS of `/robot_description`, as robot_state_publisher offers it: reliable, transient local,
/// the last one.
pub const ROBOT_DESCRIPTION_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1 });
/// QoS of `/clock`, as rclcpp's TimeSource subscribes (`ClockQoS`: best effort, the last one):
/// a reliable publisher (rosbag2, Gazebo) is matched too.
pub const CLOCK_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_best_effort()
    .history(History::KeepLast { depth: 1 });
/// QoS of `/rosout`, as rcl publishes a node's log: reliable, transient local, the last 1000
/// kept for 10 s.
pub const ROSOUT_QOS: QosProfile = QosProfile::publisher_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1000 })
    .lifespan(Some(Duration::from_secs(10)));
/// QoS of `/tf` and outputs: reliable, a short history.
pub const RELIABLE_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .history(History::KeepLast { depth: 10 });

/// Kernel socket buffer asked for, bytes (SO_RCVBUF and SO_SNDBUF; the kernel clamps it to
/// `net.core.rmem_max`/`wmem_max`). A 640×480 cloud of 32-byte points is 9.8 MB, which
/// arrives as one burst of about 150 datagrams: the buffer must hold it while the reader
/// reassembles.
pub const SOCKET_BUFFER: usize = 64 << 20;

/// Why the node or a tool cannot run; each names the entity (topic, node, argument, bag).
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    #[error("ROS_DOMAIN_ID '{0}' is not a domain id")]
    DomainId(String),
    #[error("DDS participant: {0}")]
    Participant(String),
    /// A DDS entity that could not be made: `what` is topic, publisher, subscription, node or
    /// spinner; `message` is the DDS library's own.
    #[error("{what} {name}: {message}")]
    Entity {
        what: &'static str,
        name: String,
        message: String,
    },
    #[error("--ros-args: {0}")]
    RosArgs(String),
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error(transparent)]
    Message(#[from] crate::msg::MsgError),
    #[error("{0}: nothing to play")]
    NothingToPlay(std::path::PathBuf),
    #[error("starting the executor thread: {0}")]
    Thread(#[from] std::io::Error),
    #[error(transparent)]
    Monitor(#[from] crate::monitor::MonitorError),
    #[error("the thread building the monitor stopped without an answer")]
    BuildLost,
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// The transport (`RMW_IMPLEMENTATION`, zenoh's session config or router).
    #[error("{0}")]
    Transport(String),
}

type Result<T, E = NodeError> = std::result::Result<T, E>;

/// Locks `m`; a lock poisoned by a panicking thread still holds consistent data here (slots
/// and flags are replaced whole), so the node goes on rather than panicking in turn.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn entity(what: &'static str, name: &str, e: impl std::fmt::Debug) -> NodeError {
    NodeError::Entity {
        what,
        name: name.to_owned(),
        message: format!("{e:?}"),
    }
}

/// The ROS domain: `ROS_DOMAIN_ID`, 0 when unset.
pub fn domain_id() -> Result<u16> {
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(d) => d.parse::<u16>().map_err(|_| NodeError::DomainId(d)),
        Err(_) => Ok(0),
    }
}

/// A DDS context on `domain`, with [`SOCKET_BUFFER`] socket buffers: forced past
/// `net.core.rmem_max` where the process may (`socket`).
pub fn context(domain: u16) -> Result<Context> {
    let participant = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
        .socket_receive_buffer_size(SOCKET_BUFFER)
        .socket_send_buffer_size(SOCKET_BUFFER)
        .build()
        .map_err(|e| NodeError::Participant(format!("{e:?}")))?;
    if let Err(e) = socket::force_receive_buffers(SOCKET_BUFFER) {
        log::debug!("SO_RCVBUFFORCE: {e} (the kernel's net.core.rmem_max stands)");
    }
    Context::from_domain_participant(participant)
        .map_err(|e| NodeError::Participant(format!("{e:?}")))
}

/// The topic the node subscribes to for the input topic `name` (a topic parameter, `/tf`,
/// `/clock`): expanded in the node's namespace and remapped by `-r FROM:=TO`.
pub fn input_topic(config: &Config, name: &str) -> String {
    resolve_topic(name, &config.remaps, &config.node_path())
}

/// A ROS 2 name from a fully qualified topic name.
pub fn topic_name(full: &str) -> Result<Name> {
    Name::parse(full).map_err(|e| entity("topic", full, e))
}

/// Samples a source's DDS topic cache may hold: the newest, and the one being handed over.
/// RustDDS keeps 64 samples of a topic whose QoS sets no resource limits, whatever the reader's
/// history depth: 627 MB of 9.8 MB clouds.
pub const SOURCE_SAMPLES: i32 = 2;

/// The DDS QoS of a source's topic: `qos` with at most [`SOURCE_SAMPLES`] samples kept.
pub fn source_topic_qos(qos: &QosProfile) -> ros2_client::dds::rustdds::QosPolicies {
    use ros2_client::dds::rustdds::{policy::ResourceLimits, QosPolicies, QosPolicyBuilder};
    let limits = QosPolicyBuilder::new()
        .resource_limits(ResourceLimits {
            max_samples: SOURCE_SAMPLES,
            max_instances: 1,
            max_samples_per_instance: SOURCE_SAMPLES,
        })
        .build();
    QosPolicies::from(qos).modify_by(&limits)
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
) -> Result<Subscription<T>> {
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

fn mib(bytes: usize) -> String {
    format!("{:.1} MiB", bytes as f64 / (1 << 20) as f64)
}

/// What the granted socket buffer means for a source's messages of `bytes`: a message larger
/// than the buffer arrives as one burst the kernel cannot hold, so whole messages are lost
/// (measured: 9.8 MB clouds with 4 MiB granted, 12–13 % lost at 30 Hz; docs/host-setup.md).
fn warn_burst(source: &str, what: &str, bytes: usize) {
    if let Some(granted) = granted_receive_buffer(SOCKET_BUFFER).filter(|&g| bytes > g) {
        log::warn!(
            "source {source}: each {what} is {}, more than the {} socket receive buffer the \
             kernel grants (net.core.rmem_max): expect lost {what}s and reassembly memory; \
             raise rmem_max to at least {} (docs/host-setup.md), or publish depth images \
             (type: depth_image)",
            mib(bytes),
            mib(granted),
            mib((2 * bytes).next_power_of_two()),
        );
    }
}

/// The one line that says the node is up and what it watches, and a warning when the kernel
/// grants less socket buffer than a cloud burst needs.
fn log_up(config: &Config, monitor: &Monitor, node: &RosNode) {
    let sources: Vec<String> = config
        .sources
        .iter()
        .filter(|s| s.enabled)
        .map(|s| format!("{} on {}", s.name, input_topic(config, &s.topic)))
        .collect();
    // The socket buffers are DDS's: zenoh's samples travel over TCP.
    let dds = node.transport() == Transport::Dds;
    let granted = dds.then(|| granted_receive_buffer(SOCKET_BUFFER)).flatten();
    let buffer = if dds && socket::forced() {
        format!(
            "; socket receive buffer {} forced (SO_RCVBUFFORCE, CAP_NET_ADMIN)",
            mib(SOCKET_BUFFER)
        )
    } else if dds {
        let short = granted.is_some_and(|g| g < SOCKET_BUFFER);
        format!(
            "; socket receive buffer {} asked, {} granted (net.core.rmem_max{})",
            mib(SOCKET_BUFFER),
            granted.map_or("unknown".into(), mib),
            if short {
                "; no CAP_NET_ADMIN to force it"
            } else {
                ""
            }
        )
    } else {
        String::new()
    };
    log::info!(
        "up: node {} (outputs on ~/ and /diagnostics), robot '{}' ({} links monitored), mode {}, \
         sources: {}; {}{buffer}",
        config.node_path(),
        monitor.model.name,
        monitor.links(),
        format!("{:?}", config.query.mode).to_lowercase(),
        sources.join(", "),
        node.describe,
    );
    if let Some(g) = granted.filter(|&g| g < SOCKET_BUFFER) {
        log::warn!(
            "the kernel grants {} of socket receive buffer (net.core.rmem_max): a cloud larger \
             than that arriving in one burst loses datagrams and is dropped whole; raise it once \
             with `sudo sysctl -w net.core.rmem_max={SOCKET_BUFFER}`, or give the node \
             CAP_NET_ADMIN to force its own (docs/host-setup.md)",
            mib(g)
        );
    }
}

/// Makes the monitor on its own thread (the robot from its file or text, or from
/// `robot_description_topic` once it arrives; the trees built or loaded), publishing "not
/// monitoring" (ERROR with the reason, the safety stop, no distance) every `heartbeat_period`
/// meanwhile; `None` when `stop` is set first.
fn wait_for_monitor(
    config: &Config,
    stop: &AtomicBool,
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    outputs: &Publishers,
    clock: &NodeClock,
) -> Result<(Option<Monitor>, Option<smol::Task<()>>)> {
    let reason = Arc::new(Mutex::new(String::new()));
    let say = {
        let reason = reason.clone();
        move |r: String| *lock(&reason) = r
    };
    let source = config.robot_source()?;
    // The URDF from the topic, forwarded to the build thread; the first one is used.
    let (urdf_tx, urdf_rx) = std::sync::mpsc::channel::<String>();
    let task = match &source {
        RobotSource::Topic(topic) => {
            let topic = &input_topic(config, topic);
            say(format!("waiting for the robot description on {topic}"));
            let name = topic.clone();
            Some(node.subscribe::<StringMessage>(
                topic,
                ROBOT_DESCRIPTION_QOS,
                false,
                executor,
                move |item| match item {
                    Ok((m, _)) => {
                        let _ = urdf_tx.send(m.data);
                        false
                    }
                    Err(e) => {
                        log::warn!("{name}: {e}");
                        true
                    }
                },
            )?)
        }
        _ => None,
    };
    let (tx, rx) = std::sync::mpsc::channel();
    let build_config = config.clone();
    std::thread::Builder::new()
        .name("monitor build".into())
        .spawn(move || {
            let done = AtomicU64::new(0);
            let progress = |_: &str| {
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                say(format!(
                    "building or loading the inner sphere trees ({n} links ready)"
                ));
            };
            let monitor = match source {
                RobotSource::Topic(topic) => match urdf_rx.recv() {
                    Ok(xml) => {
                        log::info!("robot description received on {topic}");
                        say("loading the robot".into());
                        Monitor::model_from_text(&build_config, &xml, &topic)
                            .and_then(|model| Monitor::with_model(build_config, model, &progress))
                    }
                    Err(_) => return,
                },
                _ => {
                    say("loading the robot".into());
                    Monitor::new(build_config, &progress)
                }
            };
            let _ = tx.send(monitor);
        })?;
    log::info!(
        "not monitoring yet: ERROR and safety_stop on {}/... until the robot and its trees are \
         ready",
        config.node_path()
    );
    loop {
        if stop.load(Ordering::Relaxed) {
            log::info!("stopped before the monitor was ready");
            return Ok((None, task));
        }
        let r = lock(&reason).clone();
        outputs.publish_outputs(Outputs::not_monitoring(config, &r, clock.now_ns()));
        // Every heartbeat, as when serving: the offered deadline holds during the build too.
        match rx.recv_timeout(Duration::from_secs_f64(config.heartbeat_period_s)) {
            Ok(monitor) => return Ok((Some(monitor?), task)),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(NodeError::BuildLost)
            }
        }
    }
}

/// The automatic-liveliness lease every output offers: the participant asserts it, so a
/// subscriber that asks for this lease or a longer one learns that the node is gone. RustDDS
/// asserts automatic liveliness on a 1 s tick once half the shortest lease has passed, so a
/// lease under about 3 s could lapse while the node runs.
pub const OUTPUT_LIVELINESS_LEASE: Duration = Duration::from_secs(3);

/// Runs the node until `stop` is set. The node is on the network from the start: while `build`
/// makes the monitor (loads the robot, builds or loads its trees) it reports "not monitoring"
/// (ERROR with the reason, the safety stop), and a stop during the build ends it at once.
pub fn run(config: Config, stop: Arc<AtomicBool>, transport: Transport) -> Result<()> {
    let executor = Arc::new(smol::Executor::new());
    let mut node = RosNode::new(transport, &config.namespace, &config.node_name, &executor)?;
    let out_qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(5)))
        .history(History::KeepLast { depth: 10 })
        .liveliness_lease(Some(OUTPUT_LIVELINESS_LEASE));
    let outputs = Publishers::new(&mut node, &config, out_qos)?;
    // The node's log on /rosout (unless --disable-rosout-logs), from here to its last word.
    let rosout = if config.rosout {
        let publisher = node.publisher::<Log>("/rosout", ROSOUT_QOS)?;
        rosout::forward(
            publisher,
            rosout::logger_name(&config.namespace, &config.node_name),
        )
    } else {
        None
    };
    // The clock, `/clock`'s with use_sim_time: subscribed from the start, so that the stamps of
    // the "not monitoring" reports during the build (and of parameter events) are simulated
    // time too.
    let clock = Arc::new(if config.use_sim_time {
        NodeClock::simulated()
    } else {
        NodeClock::system()
    });
    // The parameters are on the graph from the start; a change taken during the build waits in
    // the channel for the processing thread.
    let safety = Arc::new(Safety::raised());
    let (apply_tx, apply_rx) = std::sync::mpsc::channel::<Config>();
    let events = (node.parameter_events()?, clock.clone());
    let robot_links: parameters::RobotLinks = Arc::new(Mutex::new(None));
    let params = Arc::new(Parameters::new(
        config.clone(),
        safety.clone(),
        robot_links.clone(),
        apply_tx,
        Some(events),
    ));
    let param_tasks = parameters::serve(&mut node, &executor, &params)?;
    let clock_task = if config.use_sim_time {
        let ticks = clock.clone();
        let topic = input_topic(&config, "/clock");
        log::info!("use_sim_time: the clock is {topic}'s");
        Some(
            node.subscribe::<Clock>(&topic, CLOCK_QOS, false, &executor, move |item| {
                match item {
                    Ok((m, _)) => ticks.tick(m.clock),
                    Err(e) => log::warn!("/clock: {e}"),
                }
                true
            })?,
        )
    } else {
        None
    };
    let ex = executor.clone();
    // The executor outlives the node: dropping the node tells its spinner to stop.
    let stop_ex = Arc::new(AtomicBool::new(false));
    let stop_spinner = stop_ex.clone();
    let spin_thread = std::thread::Builder::new()
        .name("ros2 executor".into())
        .spawn(move || {
            smol::block_on(ex.run(async {
                while !stop_ex.load(Ordering::Relaxed) {
                    smol::Timer::after(Duration::from_millis(50)).await;
                }
            }))
        })?;
    let shutdown = move |tasks: Vec<smol::Task<()>>, outputs: Publishers, node: RosNode| {
        drop(rosout);
        for task in tasks.into_iter().chain(param_tasks).chain(clock_task) {
            smol::block_on(task.cancel());
        }
        drop(params);
        drop(outputs);
        let ctx = node.close();
        std::thread::sleep(Duration::from_millis(50));
        stop_spinner.store(true, Ordering::Relaxed);
        let _ = spin_thread.join();
        drop(ctx);
    };
    let mut monitor = match wait_for_monitor(&config, &stop, &mut node, &executor, &outputs, &clock)
    {
        Ok((Some(m), task)) => {
            if let Some(t) = task {
                smol::block_on(t.cancel());
            }
            m
        }
        Ok((None, task)) => {
            last_word(&outputs, &config, "shutting down", &clock);
            shutdown(task.into_iter().collect(), outputs, node);
            return Ok(());
        }
        Err(e) => {
            last_word(
                &outputs,
                &config,
                &format!("stopped by an error: {e}"),
                &clock,
            );
            shutdown(Vec::new(), outputs, node);
            return Err(e);
        }
    };
    monitor.probe_gpu();
    *lock(&robot_links) = Some(monitor.robot_links());
    // The subscription tasks, cancelled before the node is dropped: a DDS reader dropped after
    // its participant has stopped makes RustDDS log an error on every normal shutdown.
    let mut tasks: Vec<smol::Task<()>> = Vec::new();
    // Whatever ends the serving — a signal, an error, a panic — the last word goes out before
    // the participant closes; a panic then goes on unwinding (exit status 101).
    let served = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        serve::serve(
            &config,
            &stop,
            transport,
            &mut monitor,
            &mut node,
            &executor,
            &outputs,
            &mut tasks,
            serve::Runtime {
                apply: apply_rx,
                safety,
                clock: clock.clone(),
            },
        )
    }));
    let reason = match &served {
        Ok(Ok(())) => "shutting down".to_string(),
        Ok(Err(e)) => format!("stopped by an error: {e}"),
        Err(panic) => format!("stopped by a panic: {}", panic_text(panic.as_ref())),
    };
    last_word(&outputs, &config, &reason, &clock);
    shutdown(tasks, outputs, node);
    match served {
        Ok(r) => r,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{DiagnosticArray, PointCloud2};

    #[test]
    fn source_topics_keep_two_samples() {
        use ros2_client::dds::rustdds::policy;
        for qos in [
            SENSOR_QOS,
            RELIABLE_QOS.history(History::KeepLast { depth: 1 }),
        ] {
            let q = source_topic_qos(&qos);
            let limits = q.resource_limits().expect("resource limits set");
            assert_eq!(limits.max_samples, SOURCE_SAMPLES);
            assert_eq!(limits.max_samples_per_instance, SOURCE_SAMPLES);
            // The rest of the profile is kept.
            assert_eq!(q.history(), Some(policy::History::KeepLast { depth: 1 }));
            assert_eq!(
                matches!(q.reliability(), Some(policy::Reliability::BestEffort)),
                qos == SENSOR_QOS
            );
        }
    }

    #[test]
    fn message_type_names_follow_ros() {
        let t = type_name::<PointCloud2>();
        assert_eq!(t.dds_msg_type(), "sensor_msgs::msg::dds_::PointCloud2_");
        assert_eq!(
            type_name::<DiagnosticArray>().dds_msg_type(),
            "diagnostic_msgs::msg::dds_::DiagnosticArray_"
        );
    }
}
