//! The serving loop of the node's processing thread: each source's newest message through the
//! monitor, the fused outputs published, silent sources reported, the fused state published at
//! least every `heartbeat_period`, and the parameters set at run time applied between frames.
//!
//! A change of thresholds, the stray filter, sources' enabled flags or exclusion volumes is
//! applied at once (`Monitor::reconfigure`); a source enabled then is subscribed to then, one
//! disabled is left. A change of attached objects changes the robot: the monitor is rebuilt on
//! a thread of its own (`Monitor::robot_without_objects`, then `Monitor::with_model`: the robot's trees from the cache, the objects'
//! built unless cached; transforms, joint states and camera models kept) while the node
//! publishes "not monitoring" (ERROR, the safety stop, no distance); a change that arrives
//! meanwhile restarts the build with it, and a build that fails leaves the node not
//! monitoring, with the reason, until the next change.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use super::inputs::{forward, source_task, Shared, Slot, SourceMessage};
use super::parameters::Safety;
use super::publishers::Publishers;
use super::{
    input_topic, lock, log_up, mib, warn_burst, History, QosProfile, Result, RosNode, Transport,
    PANIC_AFTER_ENV, RELIABLE_QOS, SENSOR_QOS, TF_STATIC_QOS,
};
use crate::config::{Config, SourceConfig, SourceKind};
use crate::monitor::{Monitor, Outputs};
use crate::msg::{CameraInfo, Image, JointState, PointCloud2, TfMessage};

/// Subscribes to the inputs and serves them until `stop` is set: each source's newest message
/// through the monitor, the fused outputs published, silent sources reported, and the fused
/// state published at least every `heartbeat_period`.
#[allow(clippy::too_many_arguments)]
pub(super) fn serve(
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
        clock: runtime.clock.clone(),
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
            subscribe_source(node, executor, k, s, config, &shared, &info_tx)
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
        let topic = input_topic(config, name);
        let qos = if is_static {
            TF_STATIC_QOS
        } else {
            RELIABLE_QOS.history(History::KeepLast { depth: 100 })
        };
        tasks.push(forward(
            node,
            &topic,
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
        &input_topic(config, &config.joint_states_topic),
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
    let clock = runtime.clock.clone();
    let started = Instant::now();
    // Since when each source is enabled (the node's monotonic clock): its silence counts from
    // then.
    let mut enabled_at = vec![clock.monotonic_ns(); n];
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
    let mut last_fault_report = vec![None::<i64>; n];
    let mut pending: Option<Pending> = None;
    let mut clock_jumps = 0;
    let mut clock_fault_logged = false;
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
        // Parameters set at run time (`parameters`), applied before the next frame; a change
        // of attached objects rebuilds the monitor meanwhile.
        let was: Vec<bool> = monitor.config.sources.iter().map(|s| s.enabled).collect();
        while let Ok(new) = runtime.apply.try_recv() {
            if pending.is_some() || new.attached_objects != monitor.config.attached_objects {
                pending = Some(Pending::start(monitor, new)?);
            } else {
                monitor.reconfigure(new);
            }
        }
        if let Some(Pending::Building { done, config }) = &pending {
            match done.try_recv() {
                Ok(Ok(mut rebuilt)) => {
                    rebuilt.take_inputs(monitor);
                    log::info!(
                        "the monitor is rebuilt with the attached objects [{}]: monitoring",
                        object_names(&rebuilt.config)
                    );
                    *monitor = rebuilt;
                    pending = None;
                }
                Ok(Err(e)) => pending = Some(Pending::failed(config, e.to_string())),
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    pending = Some(Pending::failed(config, "the build thread stopped".into()))
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
            }
        }
        for (k, s) in monitor.config.sources.iter().enumerate() {
            if s.enabled && !was[k] {
                log::info!(
                    "source {}: enabled on {}",
                    s.name,
                    input_topic(config, &s.topic)
                );
                source_tasks[k] = subscribe(node, k, s)?;
                (heard[k], silent_logged[k]) = (false, false);
                (enabled_at[k], last_fault_report[k]) = (clock.monotonic_ns(), None);
                *lock(&shared.slots[k]) = Slot::default();
            } else if !s.enabled && was[k] {
                log::info!("source {}: disabled", s.name);
                source_tasks[k].clear();
                *lock(&shared.slots[k]) = Slot::default();
            }
        }
        if let Some(p) = &pending {
            // Not monitoring while the monitor is rebuilt (or after a build failed): the
            // sources' messages are dropped, "not monitoring" goes out every heartbeat.
            for slot in &shared.slots {
                lock(slot).cloud = None;
            }
            if last_published.elapsed() >= heartbeat {
                let (config, reason) = p.describe();
                outputs.publish_outputs(Outputs::not_monitoring(config, &reason, clock.now_ns()));
                last_published = Instant::now();
            }
            let (_, in_fault) = monitor.safety(clock.now_ns());
            runtime.safety.set(true, in_fault);
            continue;
        }
        // Simulated time: a jump back forgets what was received; a silent /clock is a fault
        // of every source (`clock`).
        if clock.jumps() != clock_jumps {
            clock_jumps = clock.jumps();
            let (from, to) = clock.last_jump();
            log::warn!(
                "/clock went back from {:.3} s to {:.3} s: the transforms, joint states and \
                 results received before are forgotten; each source is in fault until its next \
                 frame",
                from as f64 * 1e-9,
                to as f64 * 1e-9
            );
            monitor.on_clock_jump();
            enabled_at.fill(clock.monotonic_ns());
            last_fault_report.fill(None);
            for slot in &shared.slots {
                *lock(slot) = Slot::default();
            }
        }
        if let Some(reason) = clock.fault(monitor.config.clock_timeout_s) {
            if !clock_fault_logged {
                log::error!("{reason}: ERROR until it ticks");
                clock_fault_logged = true;
            }
            for slot in &shared.slots {
                lock(slot).cloud = None;
            }
            if last_published.elapsed() >= heartbeat {
                let now_ns = clock.now_ns();
                let enabled = (monitor.config.sources.iter().enumerate())
                    .filter(|(_, s)| s.enabled)
                    .map(|(k, _)| k)
                    .collect::<Vec<_>>();
                let mut last = None;
                for k in enabled {
                    let fault = crate::monitor::Fault::Clock(reason.clone());
                    last = Some(monitor.on_source_fault(k, fault, now_ns).outputs);
                }
                let beat = last.unwrap_or_else(|| monitor.heartbeat(now_ns));
                let (d, e) = counts();
                outputs.publish(beat, d, e);
                last_published = Instant::now();
            }
            let (_, in_fault) = monitor.safety(clock.now_ns());
            runtime.safety.set(true, in_fault);
            continue;
        }
        if clock_fault_logged {
            log::info!("/clock ticks again");
            clock_fault_logged = false;
            enabled_at.fill(clock.monotonic_ns());
        }
        let sources = monitor.config.sources.clone();
        let now = clock.monotonic_ns();
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
                        input_topic(config, &s.topic),
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
            // Seconds by the node's clock since the last message (or since enabled).
            let silent = (now - last.unwrap_or(enabled_at[k])).max(0) as f64 * 1e-9;
            let timeout = s.source_timeout_s;
            let due = last_fault_report[k].is_none_or(|t| (now - t) as f64 * 1e-9 >= timeout / 2.0);
            if silent > timeout && due {
                if !silent_logged[k] {
                    log::warn!(
                        "source {}: no cloud on {} for {:.1} s (source_timeout {} s): ERROR \
                         until one arrives",
                        s.name,
                        input_topic(config, &s.topic),
                        silent,
                        s.source_timeout_s
                    );
                    silent_logged[k] = true;
                }
                let frame = monitor.on_source_timeout(k, silent, last.is_none(), clock.now_ns());
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
            outputs.publish(monitor.heartbeat(clock.now_ns()), d, e);
            last_published = Instant::now();
        }
        let (raised, in_fault) = monitor.safety(clock.now_ns());
        runtime.safety.set(raised, in_fault);
    }
    Ok(())
}

/// What the processing thread shares with the parameter services: the changes they took, and
/// the safety they check the next one against.
pub(super) struct Runtime {
    pub(super) apply: std::sync::mpsc::Receiver<Config>,
    pub(super) safety: Arc<Safety>,
    /// The node's clock (`clock`).
    pub(super) clock: Arc<super::NodeClock>,
}

/// Subscribes to source `k`'s messages (and a depth source's camera info).
fn subscribe_source(
    node: &mut RosNode,
    executor: &Arc<smol::Executor<'static>>,
    k: usize,
    s: &SourceConfig,
    config: &Config,
    shared: &Arc<Shared>,
    info_tx: &std::sync::mpsc::Sender<(usize, CameraInfo)>,
) -> Result<Vec<smol::Task<()>>> {
    let mut tasks = Vec::new();
    let topic = input_topic(config, &s.topic);
    let qos = if s.reliable {
        RELIABLE_QOS.history(History::KeepLast { depth: 1 })
    } else {
        SENSOR_QOS
    };
    match s.kind {
        SourceKind::PointCloud => tasks.push(source_task::<PointCloud2<'static>>(
            node,
            &topic,
            qos,
            executor,
            k,
            shared,
            SourceMessage::Cloud,
        )?),
        SourceKind::DepthImage => {
            tasks.push(source_task::<Image<'static>>(
                node,
                &topic,
                qos.clone(),
                executor,
                k,
                shared,
                SourceMessage::Depth,
            )?);
            // The camera model, with the image's QoS as image_transport's CameraSubscriber
            // gives both; a latched (transient local) publisher is matched too.
            let topic = input_topic(config, s.camera_info_topic.as_deref().unwrap_or_default());
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

/// The names of `config`'s attached objects, for the log.
fn object_names(config: &Config) -> String {
    let names: Vec<&str> = (config.attached_objects.iter())
        .map(|o| o.name.as_str())
        .collect();
    names.join(", ")
}

/// A monitor being rebuilt with the attached objects of `config`, or the reason its build
/// failed.
enum Pending {
    Building {
        done: std::sync::mpsc::Receiver<std::result::Result<Monitor, crate::monitor::MonitorError>>,
        config: Config,
    },
    Failed {
        config: Config,
        reason: String,
    },
}

impl Pending {
    /// Starts building the monitor of `config` from `monitor`'s robot and inputs.
    fn start(monitor: &Monitor, config: Config) -> Result<Self> {
        let Some(model) = monitor.robot_without_objects() else {
            return Ok(Self::failed(
                &config,
                "this monitor's robot came with its objects attached".into(),
            ));
        };
        log::info!(
            "attached objects set to [{}]: rebuilding the monitor; not monitoring until it is \
             ready",
            object_names(&config)
        );
        let (tx, done) = std::sync::mpsc::channel();
        let build = config.clone();
        std::thread::Builder::new()
            .name("monitor rebuild".into())
            .spawn(move || {
                let _ = tx.send(Monitor::with_model(build, model, &|_| {}));
            })?;
        Ok(Self::Building { done, config })
    }

    fn failed(config: &Config, reason: String) -> Self {
        log::error!(
            "the attached objects set at run time could not be built: {reason}; not monitoring \
             until they are changed"
        );
        Self::Failed {
            config: config.clone(),
            reason,
        }
    }

    /// The config being built and why the node is not monitoring.
    fn describe(&self) -> (&Config, String) {
        match self {
            Self::Building { config, .. } => (
                config,
                "building the monitor with the attached objects set at run time".into(),
            ),
            Self::Failed { config, reason } => (
                config,
                format!("the attached objects set at run time could not be built: {reason}"),
            ),
        }
    }
}
