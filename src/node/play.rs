//! `ist_monitor play`: a bag's PointCloud2, depth Image, CameraInfo, JointState and TF messages
//! published on DDS at their recorded pace, as `ros2 bag play` would. Stamps are moved so that
//! each loop starts now, and with `rate` they run as fast as the messages are published (a cloud
//! played three times faster is not stamped in the future); all move alike, which keeps them
//! consistent with each other. It can also measure the node: with a `measure`
//! topic (the node's `~/link_distances`, whose stamp is the cloud's), each output is matched to
//! the cloud it answers, and the delivered rate and latency (cloud published → output received)
//! are reported.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;

use ros2_client::qos::{History, QosProfile};

use super::error::{lock, NodeError};
use super::qos::{RELIABLE_QOS, TF_STATIC_QOS};
use super::transport::{Pub, RosNode, Transport};
use crate::bag::{read_messages, BagMessage};
use crate::msg::{self, CameraInfo, Image, JointState, PointCloud2, RosMessage, TfMessage, Time};

#[derive(Debug, Clone)]
pub struct PlayOptions {
    pub transport: Transport,
    pub rate: f64,
    pub loops: usize,
    /// Wait for discovery before the first message, s.
    pub wait_s: f64,
    /// Topic of `sensor_msgs/JointState` outputs stamped with the cloud's stamp.
    pub measure: Option<String>,
    /// After the last message, wait this long for outputs, s.
    pub linger_s: f64,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct PlaySummary {
    /// Clouds and depth images.
    pub clouds_published: usize,
    pub messages_published: usize,
    pub outputs_received: usize,
    /// Outputs received per second over the play time.
    pub output_rate_hz: f64,
    pub latency_p50_ms: Option<f64>,
    pub latency_p99_ms: Option<f64>,
    pub latency_max_ms: Option<f64>,
}

enum Out {
    Cloud(Pub<PointCloud2<'static>>),
    Depth(Pub<Image<'static>>),
    CameraInfo(Pub<CameraInfo>),
    Joints(Pub<JointState>),
    Tf(Pub<TfMessage>),
}

/// How a loop moves the bag's stamps onto the clock: the bag's first log time `t0` becomes
/// `now_ns`, and time since it runs `rate` times faster, as the messages are published.
#[derive(Clone, Copy)]
struct Retime {
    t0: i64,
    now_ns: i64,
    rate: f64,
}

/// Moves a stamp onto the clock; a stamp of 0 (never set) stays 0, as `ros2 bag play` leaves
/// it.
fn shift(t: &mut Time, r: Retime) {
    if t.as_nanos() == 0 {
        return;
    }
    let since = (t.as_nanos() - r.t0) as f64 / r.rate;
    *t = Time::from_nanos(r.now_ns + since.round() as i64);
}

/// Published clouds (and depth images) by stamp, and the latencies (ms) of the outputs that
/// answer them.
#[derive(Default)]
struct Answers {
    sent: Mutex<HashMap<i64, Instant>>,
    latencies: Mutex<Vec<f64>>,
}

impl Answers {
    /// A cloud or depth image stamped `stamp_ns` goes out now: its answer's latency counts from
    /// here, and the summary counts it.
    fn sent_at(&self, stamp_ns: i64, summary: &mut PlaySummary) {
        lock(&self.sent).insert(stamp_ns, Instant::now());
        summary.clouds_published += 1;
    }
}

/// Plays `bag`; returns what was published and, with `measure`, what came back.
pub fn play(bag: &Path, options: &PlayOptions) -> Result<PlaySummary, NodeError> {
    let known = [
        PointCloud2::TYPE,
        Image::TYPE,
        CameraInfo::TYPE,
        JointState::TYPE,
        TfMessage::TYPE,
    ];
    let messages = read_messages(bag, &|_, schema| known.contains(&schema))?;
    if messages.is_empty() {
        return Err(NodeError::NothingToPlay(bag.to_owned()));
    }
    let executor = Arc::new(smol::Executor::new());
    let mut node = RosNode::tool(options.transport, "ist_monitor_play", &executor)?;
    let outs = open_publishers(&mut node, &messages)?;
    let answers: Arc<Answers> = Arc::default();
    let measuring = match &options.measure {
        Some(topic) => Some(measure(&mut node, &executor, topic, answers.clone())?),
        None => None,
    };
    let ex = executor.clone();
    let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let done_ex = done.clone();
    let spin = std::thread::spawn(move || {
        smol::block_on(ex.run(async {
            while !done_ex.load(std::sync::atomic::Ordering::Relaxed) {
                smol::Timer::after(Duration::from_millis(20)).await;
            }
        }))
    });
    std::thread::sleep(Duration::from_secs_f64(options.wait_s));
    let mut summary = PlaySummary::default();
    let started = Instant::now();
    for _ in 0..options.loops.max(1) {
        play_loop(&messages, &outs, options.rate, &answers, &mut summary)?;
    }
    let played = started.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_secs_f64(options.linger_s));
    if let Some(task) = measuring {
        smol::block_on(task.cancel());
    }
    drop(outs);
    let ctx = node.close();
    std::thread::sleep(Duration::from_millis(50));
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = spin.join();
    drop(ctx);
    let mut l = lock(&answers.latencies).clone();
    l.sort_by(f64::total_cmp);
    summary.outputs_received = l.len();
    summary.output_rate_hz = l.len() as f64 / played.max(1e-9);
    let q = |f: f64| crate::stats::percentile(&l, f);
    summary.latency_p50_ms = q(0.5);
    summary.latency_p99_ms = q(0.99);
    summary.latency_max_ms = l.last().copied();
    Ok(summary)
}

/// A publisher per topic of `messages`, with the QoS its publisher would offer.
fn open_publishers(
    node: &mut RosNode,
    messages: &[BagMessage],
) -> Result<HashMap<String, Out>, NodeError> {
    let mut outs: HashMap<String, Out> = HashMap::new();
    for m in messages {
        if outs.contains_key(&*m.topic) {
            continue;
        }
        // Sensor data as drivers publish it: best effort, the newest only.
        let sensor = QosProfile::publisher_default()
            .reliability_best_effort()
            .history(History::KeepLast { depth: 1 });
        let out = match &*m.schema {
            s if s == PointCloud2::TYPE => Out::Cloud(node.publisher(&m.topic, sensor)?),
            s if s == Image::TYPE => Out::Depth(node.publisher(&m.topic, sensor)?),
            s if s == CameraInfo::TYPE => Out::CameraInfo(node.publisher(&m.topic, sensor)?),
            s if s == JointState::TYPE => Out::Joints(node.publisher(&m.topic, RELIABLE_QOS)?),
            _ if &*m.topic == "/tf_static" => Out::Tf(node.publisher(&m.topic, TF_STATIC_QOS)?),
            _ => Out::Tf(node.publisher(&m.topic, RELIABLE_QOS)?),
        };
        outs.insert(m.topic.to_string(), out);
    }
    Ok(outs)
}

/// Subscribes to the node's outputs on `topic`, each matched to the cloud it answers.
fn measure(
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    topic: &str,
    answers: Arc<Answers>,
) -> Result<smol::Task<()>, NodeError> {
    node.subscribe::<JointState>(topic, RELIABLE_QOS, false, executor, move |item| {
        if let Ok((m, _)) = item {
            let now = Instant::now();
            // The first output with a cloud's stamp answers it; the node's heartbeat repeats
            // the stamp of the state it holds.
            let at = lock(&answers.sent).remove(&m.header.stamp.as_nanos());
            if let Some(at) = at {
                lock(&answers.latencies).push(now.duration_since(at).as_secs_f64() * 1e3);
            }
        }
        true
    })
}

/// One pass over the bag at `rate` times its pace, its stamps moved so that it starts now; it
/// lasts as long as the bag, even when its last message is early.
fn play_loop(
    messages: &[BagMessage],
    outs: &HashMap<String, Out>,
    rate: f64,
    answers: &Answers,
    summary: &mut PlaySummary,
) -> Result<(), NodeError> {
    let (t0, t1) = (
        messages.first().map_or(0, |m| m.log_time_ns),
        messages.last().map_or(0, |m| m.log_time_ns),
    );
    let loop_start = Instant::now();
    let offset = Retime {
        t0: t0 as i64,
        now_ns: Time::now_nanos(),
        rate,
    };
    for m in messages {
        let due = Duration::from_secs_f64((m.log_time_ns - t0) as f64 * 1e-9 / rate);
        if let Some(wait) = due.checked_sub(loop_start.elapsed()) {
            std::thread::sleep(wait);
        }
        match publish(&outs[&*m.topic], &m.data, offset, answers, summary)? {
            Ok(()) => summary.messages_published += 1,
            Err(e) => log::warn!("{}: {e}", m.topic),
        }
    }
    let span = Duration::from_secs_f64((t1 - t0) as f64 * 1e-9 / rate);
    if let Some(wait) = span.checked_sub(loop_start.elapsed()) {
        std::thread::sleep(wait);
    }
    Ok(())
}

/// Publishes one bag message `data` on `out`, its stamps moved by `offset`; a cloud or depth
/// image is noted as sent. The outer error: the message does not decode; the inner: the
/// middleware's.
fn publish(
    out: &Out,
    data: &[u8],
    offset: Retime,
    answers: &Answers,
    summary: &mut PlaySummary,
) -> Result<Result<(), String>, NodeError> {
    Ok(match out {
        Out::Cloud(p) => {
            let mut c: PointCloud2 = msg::decode(data)?;
            shift(&mut c.header.stamp, offset);
            let c = PointCloud2 {
                data: std::borrow::Cow::Owned(c.data.into_owned()),
                ..c
            };
            answers.sent_at(c.header.stamp.as_nanos(), summary);
            p.publish(c)
        }
        Out::Depth(p) => {
            let mut i: Image = msg::decode(data)?;
            shift(&mut i.header.stamp, offset);
            let i = Image {
                data: std::borrow::Cow::Owned(i.data.into_owned()),
                ..i
            };
            answers.sent_at(i.header.stamp.as_nanos(), summary);
            p.publish(i)
        }
        Out::CameraInfo(p) => {
            let mut c: CameraInfo = msg::decode(data)?;
            shift(&mut c.header.stamp, offset);
            p.publish(c)
        }
        Out::Joints(p) => {
            let mut j: JointState = msg::decode(data)?;
            shift(&mut j.header.stamp, offset);
            p.publish(j)
        }
        Out::Tf(p) => {
            let mut t: TfMessage = msg::decode(data)?;
            for ts in &mut t.transforms {
                shift(&mut ts.header.stamp, offset);
            }
            p.publish(t)
        }
    })
}
