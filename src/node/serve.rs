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
//!
//! Each turn of the loop is a row of named phases — wait, drain inputs, apply parameters, not
//! monitoring, clock, sources, heartbeat, safety — that wire the node to the monitor and decide
//! nothing: whether a silence or an untrusted clock is a fault, and what "not monitoring"
//! publishes, the monitor says (`monitor::watch`, each source's state in `monitor::Source`).
//! The loop reads the node's start-up config only; what a run-time change alters, the monitor
//! holds. The subscriptions, and who writes each input by discovery, are `wiring`'s.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use super::clock::NodeClock;
use super::error::{lock, Result};
use super::inputs::{Shared, Slot, SourceMessage};
use super::parameters::Safety;
use super::publishers::Publishers;
use super::publishers::PANIC_AFTER_ENV;
use super::ros_args::input_topic;
use super::socket::{mib, warn_burst};
use super::transport::{RosNode, Transport};
use super::up::log_up;
use super::wiring::{Inputs, SourceInput, Wiring};
use crate::config::{Config, SourceConfig, SourceKind};
use crate::monitor::{Heard, Monitor, Outputs};
use crate::msg::{CameraInfo, Writer};

/// Subscribes to the inputs and serves them until `stop` is set: each source's newest message
/// through the monitor, the fused outputs published, silent sources reported, and the fused
/// state published at least every `heartbeat_period`. `config` is the node's, as it started
/// (what a run-time change can alter, the monitor holds).
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
    let (info, camera_info) = std::sync::mpsc::channel::<(usize, CameraInfo, Writer)>();
    let wiring = Wiring {
        config,
        executor,
        shared: Arc::new(Shared {
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
        }),
        info,
    };
    let (inputs, source_inputs) = wiring.subscribe(node, tasks, camera_info)?;
    log_up(config, monitor, node);
    let clock = runtime.clock.clone();
    let mut serving = Serving {
        wiring,
        transport,
        outputs,
        runtime,
        inputs,
        source_inputs,
        heartbeat: Duration::from_secs_f64(config.heartbeat_period_s),
        last_published: Instant::now(),
        published_frames: 0,
        panic_after: std::env::var(PANIC_AFTER_ENV)
            .ok()
            .and_then(|v| v.parse().ok()),
        pending: None,
        clock_jumps: 0,
        clock_fault_logged: false,
    };
    // Each source's silence counts from now.
    monitor.watch_from(clock.monotonic_ns());
    while !stop.load(Ordering::Relaxed) {
        serving.wait();
        serving.drain_inputs(monitor);
        serving.apply_parameters(monitor, node)?;
        serving.refine(monitor);
        if serving.not_monitoring(monitor) || serving.clock(monitor) {
            continue;
        }
        serving.sources(monitor);
        serving.heartbeat(monitor);
        let (raised, in_fault) = monitor.safety(clock.now_ns());
        serving.runtime.safety.set(raised, in_fault);
    }
    Ok(())
}

/// The serving loop's state between its phases.
struct Serving<'a> {
    wiring: Wiring<'a>,
    transport: Transport,
    outputs: &'a Publishers,
    runtime: Runtime,
    inputs: Inputs,
    source_inputs: Vec<SourceInput>,
    heartbeat: Duration,
    last_published: Instant,
    published_frames: u64,
    /// The injected panic's frame count (`PANIC_AFTER_ENV`, tests).
    panic_after: Option<u64>,
    /// A monitor being rebuilt for a change of attached objects, or why it failed.
    pending: Option<Pending>,
    /// The clock's jumps back seen so far.
    clock_jumps: u64,
    clock_fault_logged: bool,
}

impl Serving<'_> {
    /// Waits for a source's message, at most 20 ms.
    fn wait(&self) {
        let shared = &self.wiring.shared;
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

    /// The dropped messages and the refused inputs so far.
    fn counts(&self) -> (u64, u64) {
        let shared = &self.wiring.shared;
        (
            shared.dropped.load(Ordering::Relaxed),
            shared.input_errors.load(Ordering::Relaxed),
        )
    }

    /// Publishes `o` with the counts.
    fn publish(&mut self, o: Outputs) {
        self.publish_part(o, false);
    }

    /// Publishes `o`, only the topics that follow a frame's pass where `following`.
    fn publish_part(&mut self, o: Outputs, following: bool) {
        let (d, e) = self.counts();
        self.outputs.publish(o, d, e, following);
        self.last_published = Instant::now();
    }

    fn heartbeat_due(&self) -> bool {
        self.last_published.elapsed() >= self.heartbeat
    }

    /// TF, camera info and joint states received since, into the monitor.
    fn drain_inputs(&self, monitor: &mut Monitor) {
        let refused = |e: crate::monitor::InputError| {
            log::warn!("{e}");
            (self.wiring.shared.input_errors).fetch_add(1, Ordering::Relaxed);
        };
        while let Ok((m, is_static, w)) = self.inputs.tf.try_recv() {
            let topic = if is_static { "/tf_static" } else { "/tf" };
            (monitor.on_tf_from(topic, &m, is_static, w)).unwrap_or_else(refused);
        }
        while let Ok((k, m, w)) = self.inputs.camera_info.try_recv() {
            (monitor.on_camera_info_from(k, &m, w)).unwrap_or_else(refused);
        }
        let topic = &self.wiring.config.joint_states_topic;
        while let Ok((m, w)) = self.inputs.joints.try_recv() {
            (monitor.on_joint_state_from(topic, &m, w)).unwrap_or_else(refused);
        }
    }

    /// Parameters set at run time (`parameters`), applied before the next frame; a change of
    /// attached objects rebuilds the monitor meanwhile. A source enabled is subscribed to, one
    /// disabled left.
    fn apply_parameters(&mut self, monitor: &mut Monitor, node: &mut RosNode) -> Result<()> {
        let was = monitor.enabled_sources();
        while let Ok(new) = self.runtime.apply.try_recv() {
            if self.pending.is_some() || monitor.needs_rebuild(&new) {
                self.pending = Some(Pending::start(monitor, new)?);
            } else {
                monitor.reconfigure(new);
            }
        }
        if let Some(Pending::Building { done, objects }) = &self.pending {
            match done.try_recv() {
                Ok(Ok(mut rebuilt)) => {
                    rebuilt.take_inputs(monitor);
                    log::info!(
                        "the monitor is rebuilt with the attached objects [{objects}]: monitoring"
                    );
                    *monitor = rebuilt;
                    self.pending = None;
                }
                Ok(Err(e)) => self.pending = Some(Pending::failed(e.to_string())),
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    self.pending = Some(Pending::failed("the build thread stopped".into()))
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
            }
        }
        let config = self.wiring.config;
        let now = monitor.enabled_sources();
        for (k, s) in config.sources.iter().enumerate() {
            if now[k] && !was[k] {
                log::info!(
                    "source {}: enabled on {}",
                    s.name,
                    input_topic(config, &s.topic)
                );
                self.source_inputs[k] = self.wiring.subscribe_source(node, k, s)?;
                monitor.enable_source(k, self.runtime.clock.monotonic_ns());
                *lock(&self.wiring.shared.slots[k]) = Slot::default();
            } else if !now[k] && was[k] {
                log::info!("source {}: disabled", s.name);
                self.source_inputs[k] = SourceInput::default();
                *lock(&self.wiring.shared.slots[k]) = Slot::default();
            }
        }
        Ok(())
    }

    /// Swaps in the trees of the config's options once they are built (`refine`).
    fn refine(&mut self, monitor: &mut Monitor) {
        super::refine::swap_in(&mut self.runtime.refined, monitor);
    }

    /// Not monitoring while the monitor is rebuilt (or after a build failed): the sources'
    /// messages are dropped, "not monitoring" goes out every heartbeat. Whether it is so.
    fn not_monitoring(&mut self, monitor: &Monitor) -> bool {
        let Some(p) = &self.pending else {
            return false;
        };
        self.wiring.clear_slots(false);
        let clock = &self.runtime.clock;
        if self.heartbeat_due() {
            let reason = p.reason();
            self.outputs
                .publish_outputs(monitor.not_monitoring(&reason, clock.now_ns()));
            self.last_published = Instant::now();
        }
        let (_, in_fault) = monitor.safety(clock.now_ns());
        self.runtime.safety.set(true, in_fault);
        true
    }

    /// Simulated time: a jump back forgets what was received; a silent /clock is a fault of
    /// every source (`clock`), its outputs every heartbeat. Whether the clock is in fault.
    fn clock(&mut self, monitor: &mut Monitor) -> bool {
        let clock = self.runtime.clock.clone();
        if clock.jumps() != self.clock_jumps {
            self.clock_jumps = clock.jumps();
            let (from, to) = clock.last_jump();
            log::warn!(
                "/clock went back from {:.3} s to {:.3} s: the transforms, joint states and \
                 results received before are forgotten; each source is in fault until its next \
                 frame",
                from as f64 * 1e-9,
                to as f64 * 1e-9
            );
            monitor.on_clock_jump(clock.monotonic_ns());
            self.wiring.clear_slots(true);
        }
        if let Some(reason) = clock.fault(self.wiring.config.clock_timeout_s) {
            if !self.clock_fault_logged {
                log::error!("{reason}: ERROR until it ticks");
                self.clock_fault_logged = true;
            }
            self.wiring.clear_slots(false);
            if self.heartbeat_due() {
                let beat = monitor.clock_fault(&reason, clock.now_ns());
                self.publish(beat);
            }
            let (_, in_fault) = monitor.safety(clock.now_ns());
            self.runtime.safety.set(true, in_fault);
            return true;
        }
        if self.clock_fault_logged {
            log::info!("/clock ticks again");
            self.clock_fault_logged = false;
            monitor.watch_from(clock.monotonic_ns());
        }
        false
    }

    /// Each enabled source: its newest message through the monitor, or its silence reported.
    fn sources(&mut self, monitor: &mut Monitor) {
        let config = self.wiring.config;
        let clock = self.runtime.clock.clone();
        let now = clock.monotonic_ns();
        let enabled = monitor.enabled_sources();
        for (k, s) in config
            .sources
            .iter()
            .enumerate()
            .filter(|(k, _)| enabled[*k])
        {
            let (message, last, writers) = {
                let mut slot = lock(&self.wiring.shared.slots[k]);
                let writers = std::mem::take(&mut slot.writers);
                (slot.cloud.take(), slot.last_received, writers)
            };
            for (writer, stamp_ns) in writers {
                monitor.hear_writer(k, writer, stamp_ns);
            }
            self.source_inputs[k].tell_writers(monitor, k, &s.name);
            if let Some((message, received, clock_ns)) = message {
                // Who writes the joint states and TF matters to the frame's lookups alone;
                // whether anyone reads the markers, to its unseen pass.
                self.inputs.tell_writers(monitor);
                monitor.markers_read(|| self.outputs.markers_read());
                self.frame(monitor, k, s, &message, received, clock_ns);
                continue;
            }
            if let Some((silence, frame)) = monitor.silence(k, last, now, clock.now_ns()) {
                if silence.first {
                    log::warn!(
                        "source {}: no cloud on {} for {:.1} s (source_timeout {} s): ERROR \
                         until one arrives",
                        s.name,
                        input_topic(config, &s.topic),
                        silence.silent_s,
                        s.source_timeout_s
                    );
                }
                self.publish(frame.outputs);
            }
        }
    }

    /// Source `k`'s message, received at `received` (the node's clock then: `clock_ns`),
    /// through the monitor and published.
    fn frame(
        &mut self,
        monitor: &mut Monitor,
        k: usize,
        s: &SourceConfig,
        message: &SourceMessage,
        received: Instant,
        clock_ns: i64,
    ) {
        if let Some(heard) = monitor.hear(k) {
            let (width, height, frame_id, bytes) = message.describe();
            let what = match s.kind {
                SourceKind::PointCloud => "cloud",
                SourceKind::DepthImage => "depth image",
            };
            log::info!(
                "source {}: {} {what} on {} ({width}×{height}, {}, frame '{frame_id}')",
                s.name,
                if heard == Heard::Again {
                    "again a"
                } else {
                    "first"
                },
                input_topic(self.wiring.config, &s.topic),
                mib(bytes),
            );
            if heard == Heard::First && self.transport == Transport::Dds {
                warn_burst(&s.name, what, bytes);
            }
        }
        let now_ns = Some(clock_ns);
        // The seen outputs are published the moment they are made, before the unseen pass.
        let mut early = |seen: &Outputs| self.publish(seen.clone());
        let frame = match message {
            SourceMessage::Cloud(c) => monitor.on_cloud_early(k, c, received, now_ns, &mut early),
            SourceMessage::Depth(i) => {
                monitor.on_depth_image_early(k, i, received, now_ns, &mut early)
            }
        };
        let following = frame.outputs_follow();
        self.publish_part(frame.outputs, following);
        self.published_frames += 1;
        let published = self.published_frames;
        if self.panic_after.is_some_and(|n| published >= n) {
            panic!("injected after {published} frames ({PANIC_AFTER_ENV})");
        }
    }

    /// The heartbeat: the fused state, aged by the clock, when no frame went out for a
    /// heartbeat period (a subscriber can tell a quiet monitor from a dead one).
    fn heartbeat(&mut self, monitor: &mut Monitor) {
        if self.heartbeat_due() {
            let beat = monitor.heartbeat(self.runtime.clock.now_ns());
            self.publish(beat);
        }
    }
}

/// What the processing thread shares with the parameter services: the changes they took, and
/// the safety they check the next one against.
pub(super) struct Runtime {
    pub(super) apply: std::sync::mpsc::Receiver<Config>,
    pub(super) safety: Arc<Safety>,
    /// The node's clock (`clock`).
    pub(super) clock: Arc<NodeClock>,
    /// The trees to swap in where the monitor started on coarse ones; None once handled.
    pub(super) refined: Option<super::refine::Refined>,
}

/// The names of `config`'s attached objects, for the log.
fn object_names(config: &Config) -> String {
    let names: Vec<&str> = (config.attached_objects.iter())
        .map(|o| o.name.as_str())
        .collect();
    names.join(", ")
}

/// A monitor being rebuilt with run-time attached objects, or the reason its build failed.
enum Pending {
    Building {
        done: Receiver<std::result::Result<Monitor, crate::monitor::MonitorError>>,
        /// The attached objects' names, for the log.
        objects: String,
    },
    Failed {
        reason: String,
    },
}

impl Pending {
    /// Starts building the monitor of `config` from `monitor`'s robot and inputs.
    fn start(monitor: &Monitor, config: Config) -> Result<Self> {
        let Some(model) = monitor.robot_without_objects() else {
            return Ok(Self::failed(
                "this monitor's robot came with its objects attached".into(),
            ));
        };
        log::info!(
            "attached objects set to [{}]: rebuilding the monitor; not monitoring until it is \
             ready",
            object_names(&config)
        );
        let (tx, done) = std::sync::mpsc::channel();
        let objects = object_names(&config);
        std::thread::Builder::new()
            .name("monitor rebuild".into())
            .spawn(move || {
                let _ = tx.send(Monitor::with_model(config, model, &|_| {}));
            })?;
        Ok(Self::Building { done, objects })
    }

    fn failed(reason: String) -> Self {
        log::error!(
            "the attached objects set at run time could not be built: {reason}; not monitoring \
             until they are changed"
        );
        Self::Failed { reason }
    }

    /// Why the node is not monitoring.
    fn reason(&self) -> String {
        match self {
            Self::Building { .. } => {
                "building the monitor with the attached objects set at run time".into()
            }
            Self::Failed { reason } => {
                format!("the attached objects set at run time could not be built: {reason}")
            }
        }
    }
}
