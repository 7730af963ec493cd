//! The node's life cycle: its start (on the network at once: publishers, log, clock,
//! parameters, the executor's thread), "not monitoring" while the monitor is built, the serving
//! (`serve`), and — whatever ends it: a signal, an error, a panic — the last word (`safety_stop`
//! true, factor 0, "not monitoring: REASON") before the participant closes.

use std::any::Any;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::clock::NodeClock;
use super::error::{lock, NodeError, Result};
use super::parameters::{self, Parameters, RobotLinks, Safety};
use super::publishers::Publishers;
use super::qos::{CLOCK_QOS, OUTPUT_QOS, ROBOT_DESCRIPTION_QOS, ROSOUT_QOS};
use super::ros_args::input_topic;
use super::rosout;
use super::security::SecurityEnv;
use super::serve;
use super::transport::{RosNode, Transport};
use crate::config::{Config, RobotSource};
use crate::monitor::{Monitor, Outputs};
use crate::msg::{Clock, Log, StringMessage};

/// Runs the node until `stop` is set. The node is on the network from the start: while `build`
/// makes the monitor (loads the robot, builds or loads its trees) it reports "not monitoring"
/// (ERROR with the reason, the safety stop), and a stop during the build ends it at once.
pub fn run(mut config: Config, stop: Arc<AtomicBool>, transport: Transport) -> Result<()> {
    // A secured cell's default: nobody on the network lowers its thresholds.
    if let Some(warning) = config.secure_parameter_changes(SecurityEnv::from_process().enabled()) {
        log::warn!("{warning}");
    }
    let Started {
        executor,
        mut node,
        outputs,
        clock,
        apply,
        safety,
        robot_links,
        shutdown,
    } = start(&config, transport)?;
    let (mut monitor, refined) =
        match wait_for_monitor(&config, &stop, &mut node, &executor, &outputs, &clock) {
            Ok((Some(m), task)) => {
                if let Some(t) = task {
                    smol::block_on(t.cancel());
                }
                m
            }
            Ok((None, task)) => {
                last_word(&outputs, &config, "shutting down", &clock);
                shutdown.close(task.into_iter().collect(), outputs, node);
                return Ok(());
            }
            Err(e) => {
                last_word(
                    &outputs,
                    &config,
                    &format!("stopped by an error: {e}"),
                    &clock,
                );
                shutdown.close(Vec::new(), outputs, node);
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
                apply,
                safety,
                clock: clock.clone(),
                refined: Some(refined),
            },
        )
    }));
    let reason = match &served {
        Ok(Ok(())) => "shutting down".to_string(),
        Ok(Err(e)) => format!("stopped by an error: {e}"),
        Err(panic) => format!("stopped by a panic: {}", panic_text(panic.as_ref())),
    };
    last_word(&outputs, &config, &reason, &clock);
    shutdown.close(tasks, outputs, node);
    match served {
        Ok(r) => r,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

/// The node as [`start`] puts it on the network, before it has a monitor.
struct Started {
    executor: Arc<smol::Executor<'static>>,
    node: RosNode,
    outputs: Publishers,
    /// The node's clock: `/clock`'s with `use_sim_time`.
    clock: Arc<NodeClock>,
    /// The parameter changes taken, for the processing thread.
    apply: Receiver<Config>,
    /// The safety the parameter services check a change against.
    safety: Arc<Safety>,
    /// The robot's links, once the monitor has them, for the parameter services.
    robot_links: RobotLinks,
    shutdown: Shutdown,
}

/// Puts the node on the network: its outputs, its log on `/rosout`, its clock, its parameter
/// services and the executor's thread that runs the subscriptions and services.
fn start(config: &Config, transport: Transport) -> Result<Started> {
    let executor = Arc::new(smol::Executor::new());
    let mut node = RosNode::in_enclave(
        transport,
        &config.namespace,
        &config.node_name,
        config.enclave.as_deref(),
        &executor,
    )?;
    let outputs = Publishers::new(&mut node, config, OUTPUT_QOS)?;
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
    let (apply_tx, apply) = std::sync::mpsc::channel::<Config>();
    let events = (node.parameter_events()?, clock.clone());
    let robot_links: RobotLinks = Arc::new(Mutex::new(None));
    let params = Arc::new(Parameters::new(
        config.clone(),
        safety.clone(),
        robot_links.clone(),
        apply_tx,
        Some(events),
    ));
    let mut tasks = parameters::serve(&mut node, &executor, &params)?;
    if config.use_sim_time {
        tasks.push(subscribe_clock(config, &mut node, &executor, &clock)?);
    }
    let ex = executor.clone();
    // The executor outlives the node: dropping the node tells its spinner to stop.
    let stop_spinner = Arc::new(AtomicBool::new(false));
    let stop_ex = stop_spinner.clone();
    let spin_thread = std::thread::Builder::new()
        .name("ros2 executor".into())
        .spawn(move || {
            smol::block_on(ex.run(async {
                while !stop_ex.load(Ordering::Relaxed) {
                    smol::Timer::after(Duration::from_millis(50)).await;
                }
            }))
        })?;
    Ok(Started {
        executor,
        node,
        outputs,
        clock,
        apply,
        safety,
        robot_links,
        shutdown: Shutdown {
            rosout,
            tasks,
            params,
            stop_spinner,
            spin_thread,
        },
    })
}

/// With `use_sim_time`: the node's clock ticks with `/clock` (remapped as any input).
fn subscribe_clock(
    config: &Config,
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    clock: &Arc<NodeClock>,
) -> Result<smol::Task<()>> {
    let ticks = clock.clone();
    let topic = input_topic(config, "/clock");
    log::info!("use_sim_time: the clock is {topic}'s");
    node.subscribe::<Clock>(&topic, CLOCK_QOS, false, executor, move |item| {
        match item {
            Ok((m, _)) => ticks.tick(m.clock),
            Err(e) => log::warn!("/clock: {e}"),
        }
        true
    })
}

/// What [`start`] opened that the node closes after its last word, in order.
struct Shutdown {
    rosout: Option<rosout::Forwarding>,
    /// The parameter services' tasks and the `/clock` subscription's.
    tasks: Vec<smol::Task<()>>,
    params: Arc<Parameters>,
    stop_spinner: Arc<AtomicBool>,
    spin_thread: std::thread::JoinHandle<()>,
}

impl Shutdown {
    /// Closes the node: the log forwarding stopped, every task cancelled (`tasks`, the
    /// subscriptions', first), the publishers and the node dropped, then the executor stopped
    /// and, last, the participant (or session) closed.
    fn close(self, tasks: Vec<smol::Task<()>>, outputs: Publishers, node: RosNode) {
        let Shutdown {
            rosout,
            tasks: own,
            params,
            stop_spinner,
            spin_thread,
        } = self;
        drop(rosout);
        for task in tasks.into_iter().chain(own) {
            smol::block_on(task.cancel());
        }
        drop(params);
        drop(outputs);
        let ctx = node.close();
        std::thread::sleep(Duration::from_millis(50));
        stop_spinner.store(true, Ordering::Relaxed);
        let _ = spin_thread.join();
        drop(ctx);
    }
}

/// Makes the monitor on its own thread (the robot from its file or text, or from
/// `robot_description_topic` once it arrives; the trees built or loaded), publishing "not
/// monitoring" (ERROR with the reason, the safety stop, no distance) every `heartbeat_period`
/// meanwhile; `None` when `stop` is set first. Where trees had to be built and the budget may
/// grow, the monitor comes on coarse trees (a fixed budget of `start_spheres`, validated, h
/// certified), and the same thread then builds the config's trees, which arrive on the
/// `refine::Refined` receiver for the serving loop to swap in.
fn wait_for_monitor(
    config: &Config,
    stop: &AtomicBool,
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    outputs: &Publishers,
    clock: &NodeClock,
) -> Result<(Option<(Monitor, super::refine::Refined)>, RobotTask)> {
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
    let (refined_tx, refined) = std::sync::mpsc::channel();
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
            let model = match source {
                RobotSource::Topic(topic) => match urdf_rx.recv() {
                    Ok(xml) => {
                        log::info!("robot description received on {topic}");
                        say("loading the robot".into());
                        Monitor::model_from_text(&build_config, &xml, &topic)
                    }
                    Err(_) => return,
                },
                _ => {
                    say("loading the robot".into());
                    Monitor::model(&build_config)
                }
            };
            // Trees missing from the cache: coarse ones first, then the config's, swapped in
            // by the serving loop when they are ready.
            let first = model
                .and_then(|model| Monitor::with_model_first(build_config, model, &progress, true));
            let refinement = match first {
                Ok((monitor, refinement)) => {
                    if refinement.is_some() {
                        log_coarse(&monitor);
                    }
                    let _ = tx.send(Ok(monitor));
                    refinement
                }
                Err(e) => {
                    let _ = tx.send(Err(e));
                    None
                }
            };
            if let Some(refinement) = refinement {
                let started = std::time::Instant::now();
                let trees = super::refine::build(&refinement);
                if trees.is_ok() {
                    log::info!(
                        "the trees of the config's packing options are built ({:.1} s)",
                        started.elapsed().as_secs_f64()
                    );
                }
                let _ = refined_tx.send((trees, refinement.attached));
            }
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
            Ok(monitor) => return Ok((Some((monitor?, refined)), task)),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(NodeError::BuildLost)
            }
        }
    }
}

/// The subscription to `robot_description_topic`, where the robot comes from there.
type RobotTask = Option<smol::Task<()>>;

/// Says that the monitor runs on coarse trees, with their largest h.
fn log_coarse(monitor: &Monitor) {
    let (link, h) = (monitor.link_gaps().into_iter())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or_default();
    log::info!(
        "monitoring on coarse trees (start_spheres each, validated; h up to {:.3} mm, on {link}) \
         while the trees of the config's packing options are built",
        h * 1e3
    );
}

/// A panic's message.
pub(super) fn panic_text(panic: &(dyn Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

/// The node's last word before it leaves the network: `~/safety_stop` true, `~/speed_scaling` 0
/// and an ERROR status "not monitoring: REASON", published twice 0.1 s apart on the reliable
/// outputs so that it is delivered before the participant closes (a controller keeps the last
/// factor it received: it must be 0).
pub(super) fn last_word(outputs: &Publishers, config: &Config, reason: &str, clock: &NodeClock) {
    log::info!("not monitoring: {reason}: safety_stop and a speed-scaling factor of 0 published");
    for _ in 0..2 {
        outputs.publish_outputs(Outputs::not_monitoring(config, reason, clock.now_ns()));
        std::thread::sleep(Duration::from_millis(100));
    }
}
