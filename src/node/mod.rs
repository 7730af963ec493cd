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

mod inputs;
pub mod parameters;
pub mod play;
mod publishers;
pub mod record;
pub mod rmw_zenoh;
mod ros_args;
pub mod transport;

use inputs::{forward, source_task, Shared, Slot, SourceMessage};
use parameters::{Parameters, Safety};
pub use publishers::PANIC_AFTER_ENV;
use publishers::{last_word, panic_text, Publishers};
pub use ros_args::{expand_topic, parse_ros_args, remap_topic, RosArgs};

pub use transport::{Pub, RosNode, Transport};

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use ros2_client::dds::{Context, Node, Subscription};
use ros2_client::{MessageTypeName, Name, NodeName};

use crate::config::Config;
use crate::config::{RobotSource, SourceConfig, SourceKind};
use crate::monitor::{Monitor, Outputs};
use crate::msg::{
    CameraInfo, Image, JointState, PointCloud2, RosMessage, StringMessage, TfMessage, Time,
};

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

/// A DDS context on `domain`, with [`SOCKET_BUFFER`] socket buffers.
pub fn context(domain: u16) -> Result<Context> {
    let participant = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
        .socket_receive_buffer_size(SOCKET_BUFFER)
        .socket_send_buffer_size(SOCKET_BUFFER)
        .build()
        .map_err(|e| NodeError::Participant(format!("{e:?}")))?;
    Context::from_domain_participant(participant)
        .map_err(|e| NodeError::Participant(format!("{e:?}")))
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

/// What the kernel grants a socket that asks for `requested` receive-buffer bytes with
/// `SO_RCVBUF` (Linux clamps it to `net.core.rmem_max`); `None` where that is not readable.
pub fn granted_receive_buffer(requested: usize) -> Option<usize> {
    let max = std::fs::read_to_string("/proc/sys/net/core/rmem_max").ok()?;
    Some(requested.min(max.trim().parse().ok()?))
}

fn mib(bytes: usize) -> String {
    format!("{:.1} MiB", bytes as f64 / (1 << 20) as f64)
}

/// What the granted socket buffer means for a source's messages of `bytes`: a message larger
/// than the buffer arrives as one burst the kernel cannot hold, so whole messages are lost
/// (measured: 9.8 MB clouds with 4 MiB granted, 12–13 % lost at 30 Hz; README, 'Host setup').
fn warn_burst(source: &str, what: &str, bytes: usize) {
    if let Some(granted) = granted_receive_buffer(SOCKET_BUFFER).filter(|&g| bytes > g) {
        log::warn!(
            "source {source}: each {what} is {}, more than the {} socket receive buffer the \
             kernel grants (net.core.rmem_max): expect lost {what}s and reassembly memory; \
             raise rmem_max to at least {} (README, 'Host setup'), or publish depth images \
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
        .map(|s| format!("{} on {}", s.name, s.topic))
        .collect();
    // The socket buffers are DDS's: zenoh's samples travel over TCP.
    let dds = node.transport() == Transport::Dds;
    let granted = dds.then(|| granted_receive_buffer(SOCKET_BUFFER)).flatten();
    let buffer = if dds {
        format!(
            "; socket receive buffer {} asked, {} granted",
            mib(SOCKET_BUFFER),
            granted.map_or("unknown".into(), mib)
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
             with `sudo sysctl -w net.core.rmem_max={SOCKET_BUFFER}` (README, 'Host setup')",
            mib(g)
        );
    }
}

/// Makes the monitor on its own thread (the robot from its file or text, or from
/// `robot_description_topic` once it arrives; the trees built or loaded), publishing "not
/// monitoring" (ERROR with the reason, the safety stop, no distance) every half second
/// meanwhile; `None` when `stop` is set first.
fn wait_for_monitor(
    config: &Config,
    stop: &AtomicBool,
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    outputs: &Publishers,
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
        outputs.publish_outputs(Outputs::not_monitoring(config, &r, Time::now_nanos()));
        match rx.recv_timeout(Duration::from_millis(500)) {
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
    // The parameters are on the graph from the start; a change taken during the build waits in
    // the channel for the processing thread.
    let safety = Arc::new(Safety::raised());
    let (apply_tx, apply_rx) = std::sync::mpsc::channel::<Config>();
    let events = node.parameter_events()?;
    let params = Arc::new(Parameters::new(
        config.clone(),
        safety.clone(),
        apply_tx,
        events,
    ));
    let param_tasks = parameters::serve(&mut node, &executor, &params)?;
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
        for task in tasks.into_iter().chain(param_tasks) {
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
    let mut monitor = match wait_for_monitor(&config, &stop, &mut node, &executor, &outputs) {
        Ok((Some(m), task)) => {
            if let Some(t) = task {
                smol::block_on(t.cancel());
            }
            m
        }
        Ok((None, task)) => {
            last_word(&outputs, &config, "shutting down");
            shutdown(task.into_iter().collect(), outputs, node);
            return Ok(());
        }
        Err(e) => {
            last_word(&outputs, &config, &format!("stopped by an error: {e}"));
            shutdown(Vec::new(), outputs, node);
            return Err(e);
        }
    };
    monitor.probe_gpu();
    // The subscription tasks, cancelled before the node is dropped: a DDS reader dropped after
    // its participant has stopped makes RustDDS log an error on every normal shutdown.
    let mut tasks: Vec<smol::Task<()>> = Vec::new();
    // Whatever ends the serving — a signal, an error, a panic — the last word goes out before
    // the participant closes; a panic then goes on unwinding (exit status 101).
    let served = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        serve(
            &config,
            &stop,
            transport,
            &mut monitor,
            &mut node,
            &executor,
            &outputs,
            &mut tasks,
            Runtime {
                apply: apply_rx,
                safety,
            },
        )
    }));
    let reason = match &served {
        Ok(Ok(())) => "shutting down".to_string(),
        Ok(Err(e)) => format!("stopped by an error: {e}"),
        Err(panic) => format!("stopped by a panic: {}", panic_text(panic.as_ref())),
    };
    last_word(&outputs, &config, &reason);
    shutdown(tasks, outputs, node);
    match served {
        Ok(r) => r,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

/// Subscribes to the inputs and serves them until `stop` is set: each source's newest message
/// through the monitor, the fused outputs published, silent sources reported, and the fused
/// state published at least every `heartbeat_period`.
#[allow(clippy::too_many_arguments)]
fn serve(
    config: &Config,
    stop: &AtomicBool,
    transport: Transport,
    monitor: &mut Monitor,
    node: &mut RosNode,
    executor: &Arc<smol::Executor<'static>>,
    outputs: &Publishers,
    tasks: &mut Vec<smol::Task<()>>,
    runtime: Runtime,
) -> Result<()> {
    let shared = Arc::new(Shared {
        slots: config
            .sources
            .iter()
            .map(|_| Mutex::new(Slot::default()))
            .collect(),
        wake: Condvar::new(),
        wake_lock: Mutex::new(false),
        dropped: AtomicU64::new(0),
        input_errors: AtomicU64::new(0),
    });
    // Inputs: clouds into slots; TF and joint states into a queue the processing thread drains
    // (they are small; the monitor is owned by that thread).
    let (tf_tx, tf_rx) = std::sync::mpsc::channel::<(TfMessage, bool)>();
    let (js_tx, js_rx) = std::sync::mpsc::channel::<JointState>();
    let (info_tx, info_rx) = std::sync::mpsc::channel::<(usize, CameraInfo)>();
    // Each source's subscriptions, made while it is enabled (also when it is enabled at run
    // time), dropped when it is disabled.
    let subscribe =
        |node: &mut RosNode, k: usize, s: &SourceConfig| -> Result<Vec<smol::Task<()>>> {
            subscribe_source(node, executor, k, s, &shared, &info_tx)
        };
    let mut source_tasks: Vec<Vec<smol::Task<()>>> = Vec::new();
    for (k, s) in config.sources.iter().enumerate() {
        source_tasks.push(if s.enabled {
            subscribe(node, k, s)?
        } else {
            Vec::new()
        });
    }
    for (name, is_static) in [("/tf", false), ("/tf_static", true)] {
        let qos = if is_static {
            TF_STATIC_QOS
        } else {
            RELIABLE_QOS.history(History::KeepLast { depth: 100 })
        };
        tasks.push(forward(
            node,
            name,
            qos,
            executor,
            name,
            tf_tx.clone(),
            move |m: TfMessage| (m, is_static),
            &shared,
        )?);
    }
    let joint_qos = QosProfile::subscription_default()
        .reliability_best_effort()
        .history(History::KeepLast { depth: 100 });
    tasks.push(forward(
        node,
        &config.joint_states_topic,
        joint_qos,
        executor,
        "joint states",
        js_tx,
        |m: JointState| m,
        &shared,
    )?);
    log_up(config, monitor, node);
    let n = config.sources.len();
    let mut heard = vec![false; n];
    let mut silent_logged = vec![false; n];
    let started = Instant::now();
    // Since when each source is enabled: its silence counts from then.
    let mut enabled_at = vec![started; n];
    let heartbeat = Duration::from_secs_f64(config.heartbeat_period_s);
    let mut last_published = started;
    let mut published_frames = 0u64;
    let panic_after: Option<u64> = std::env::var(PANIC_AFTER_ENV)
        .ok()
        .and_then(|v| v.parse().ok());
    let counts = || {
        (
            shared.dropped.load(Ordering::Relaxed),
            shared.input_errors.load(Ordering::Relaxed),
        )
    };
    let mut last_fault_report = vec![None::<Instant>; n];
    while !stop.load(Ordering::Relaxed) {
        {
            let mut woken = lock(&shared.wake_lock);
            if !*woken {
                woken = shared
                    .wake
                    .wait_timeout(woken, Duration::from_millis(20))
                    .unwrap_or_else(|poisoned| poisoned.into_inner())
                    .0;
            }
            *woken = false;
        }
        while let Ok((m, is_static)) = tf_rx.try_recv() {
            let topic = if is_static { "/tf_static" } else { "/tf" };
            if let Err(e) = monitor.on_tf_message(topic, &m, is_static) {
                log::warn!("{e}");
                shared.input_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
        while let Ok((k, m)) = info_rx.try_recv() {
            if let Err(e) = monitor.on_camera_info_message(k, &m) {
                log::warn!("{e}");
                shared.input_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
        while let Ok(m) = js_rx.try_recv() {
            if let Err(e) = monitor.on_joint_state_message(&config.joint_states_topic, &m) {
                log::warn!("{e}");
                shared.input_errors.fetch_add(1, Ordering::Relaxed);
            }
        }
        // Parameters set at run time (`parameters`), applied before the next frame.
        while let Ok(new) = runtime.apply.try_recv() {
            let was: Vec<bool> = monitor.config.sources.iter().map(|s| s.enabled).collect();
            monitor.reconfigure(new);
            for (k, s) in monitor.config.sources.iter().enumerate() {
                if s.enabled && !was[k] {
                    log::info!("source {}: enabled on {}", s.name, s.topic);
                    source_tasks[k] = subscribe(node, k, s)?;
                    (heard[k], silent_logged[k]) = (false, false);
                    (enabled_at[k], last_fault_report[k]) = (Instant::now(), None);
                    *lock(&shared.slots[k]) = Slot::default();
                } else if !s.enabled && was[k] {
                    log::info!("source {}: disabled", s.name);
                    source_tasks[k].clear();
                    *lock(&shared.slots[k]) = Slot::default();
                }
            }
        }
        let sources = monitor.config.sources.clone();
        let now = Instant::now();
        for (k, s) in sources.iter().enumerate().filter(|(_, s)| s.enabled) {
            let (cloud, last) = {
                let mut slot = lock(&shared.slots[k]);
                (slot.cloud.take(), slot.last_received)
            };
            if let Some((cloud, received, clock_ns)) = cloud {
                if !heard[k] || silent_logged[k] {
                    let (width, height, frame_id, bytes) = cloud.describe();
                    let what = match s.kind {
                        SourceKind::PointCloud => "cloud",
                        SourceKind::DepthImage => "depth image",
                    };
                    log::info!(
                        "source {}: {} {what} on {} ({width}×{height}, {}, frame '{frame_id}')",
                        s.name,
                        if heard[k] { "again a" } else { "first" },
                        s.topic,
                        mib(bytes),
                    );
                    if !heard[k] && transport == Transport::Dds {
                        warn_burst(&s.name, what, bytes);
                    }
                    (heard[k], silent_logged[k]) = (true, false);
                }
                let frame = match &cloud {
                    SourceMessage::Cloud(c) => monitor.on_cloud_message(k, c, received, clock_ns),
                    SourceMessage::Depth(i) => {
                        monitor.on_depth_image_message(k, i, received, clock_ns)
                    }
                };
                {
                    let (d, e) = counts();
                    outputs.publish(frame.outputs, d, e);
                }
                last_published = Instant::now();
                published_frames += 1;
                if panic_after.is_some_and(|n| published_frames >= n) {
                    panic!("injected after {published_frames} frames ({PANIC_AFTER_ENV})");
                }
                last_fault_report[k] = None;
                continue;
            }
            let silent = now.duration_since(last.unwrap_or(enabled_at[k]));
            let timeout = Duration::from_secs_f64(s.source_timeout_s);
            let due = last_fault_report[k].is_none_or(|t| now.duration_since(t) >= timeout / 2);
            if silent > timeout && due {
                if !silent_logged[k] {
                    log::warn!(
                        "source {}: no cloud on {} for {:.1} s (source_timeout {} s): ERROR \
                         until one arrives",
                        s.name,
                        s.topic,
                        silent.as_secs_f64(),
                        s.source_timeout_s
                    );
                    silent_logged[k] = true;
                }
                let frame = monitor.on_source_timeout(k, silent.as_secs_f64(), last.is_none());
                {
                    let (d, e) = counts();
                    outputs.publish(frame.outputs, d, e);
                }
                last_published = Instant::now();
                last_fault_report[k] = Some(now);
            }
        }
        // The heartbeat: the fused state, aged by the clock, when no frame went out for a
        // heartbeat period (a subscriber can tell a quiet monitor from a dead one).
        if last_published.elapsed() >= heartbeat {
            let (d, e) = counts();
            outputs.publish(monitor.heartbeat(Time::now_nanos()), d, e);
            last_published = Instant::now();
        }
        let (raised, in_fault) = monitor.safety(Time::now_nanos());
        runtime.safety.set(raised, in_fault);
    }
    Ok(())
}

/// What the processing thread shares with the parameter services: the changes they took, and
/// the safety they check the next one against.
struct Runtime {
    apply: std::sync::mpsc::Receiver<Config>,
    safety: Arc<Safety>,
}

/// Subscribes to source `k`'s messages (and a depth source's camera info).
fn subscribe_source(
    node: &mut RosNode,
    executor: &Arc<smol::Executor<'static>>,
    k: usize,
    s: &SourceConfig,
    shared: &Arc<Shared>,
    info_tx: &std::sync::mpsc::Sender<(usize, CameraInfo)>,
) -> Result<Vec<smol::Task<()>>> {
    let mut tasks = Vec::new();
    let qos = if s.reliable {
        RELIABLE_QOS.history(History::KeepLast { depth: 1 })
    } else {
        SENSOR_QOS
    };
    match s.kind {
        SourceKind::PointCloud => tasks.push(source_task::<PointCloud2<'static>>(
            node,
            &s.topic,
            qos,
            executor,
            k,
            shared,
            SourceMessage::Cloud,
        )?),
        SourceKind::DepthImage => {
            tasks.push(source_task::<Image<'static>>(
                node,
                &s.topic,
                qos.clone(),
                executor,
                k,
                shared,
                SourceMessage::Depth,
            )?);
            // The camera model, with the image's QoS as image_transport's CameraSubscriber
            // gives both; a latched (transient local) publisher is matched too.
            let topic = s.camera_info_topic.clone().unwrap_or_default();
            tasks.push(forward(
                node,
                &topic,
                qos,
                executor,
                "camera info",
                info_tx.clone(),
                move |m: CameraInfo| (k, m),
                shared,
            )?);
        }
    }
    Ok(tasks)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::DiagnosticArray;

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
