//! The node's subscriptions, and who writes its inputs by discovery: each enabled source's
//! messages into its slot (a depth source's CameraInfo beside it), TF and the joint states into
//! queues the processing thread drains; with `writers_from_discovery`, each of those topics'
//! writers as discovery matches them now (`TopicWriters`), told to the monitor every turn of
//! the serving loop: a source's topic and a depth source's CameraInfo topic by count (two or
//! more is the fault `second_publisher`), the joint states and TF by GID (a joint's or a
//! frame's writer stays its voice while it is matched: `tf::JointStateBuffer::set_matched`).

use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;

use super::error::{lock, Result};
use super::inputs::{forward, source_task, Shared, Slot, SourceMessage};
use super::qos::{RELIABLE_QOS, SENSOR_QOS, TF_STATIC_QOS};
use super::ros_args::input_topic;
use super::transport::{RosNode, TopicWriters};
use crate::config::{Config, SourceConfig, SourceKind};
use crate::monitor::Monitor;
use crate::msg::{CameraInfo, Image, JointState, PointCloud2, TfMessage, Writer};
use ros2_client::qos::{History, QosProfile};

/// The subscriptions' side: what the node's inputs are subscribed with.
pub(super) struct Wiring<'a> {
    pub(super) config: &'a Config,
    pub(super) executor: &'a Arc<smol::Executor<'static>>,
    /// Each source's slot, the wake-up, the counts.
    pub(super) shared: Arc<Shared>,
    /// Where depth sources' CameraInfo goes.
    pub(super) info: Sender<(usize, CameraInfo, Writer)>,
}

/// TF, joint states and depth sources' CameraInfo, in queues the processing thread drains
/// (they are small; the monitor is owned by that thread).
pub(super) struct Inputs {
    pub(super) tf: Receiver<(TfMessage, bool, Writer)>,
    pub(super) joints: Receiver<(JointState, Writer)>,
    pub(super) camera_info: Receiver<(usize, CameraInfo, Writer)>,
    /// Who publishes `/tf` and `/tf_static`, and the joint states, by discovery
    /// (`writers_from_discovery`; empty and `None` without).
    tf_writers: Vec<TopicWriters>,
    joint_writers: Option<TopicWriters>,
}

impl Wiring<'_> {
    /// Subscribes to every input: each enabled source's messages into its slot, TF and joint
    /// states (their tasks into `tasks`); the queues (`camera_info`: where `info` goes), and
    /// the sources' subscriptions, per source.
    pub(super) fn subscribe(
        &self,
        node: &mut RosNode,
        tasks: &mut Vec<smol::Task<()>>,
        camera_info: Receiver<(usize, CameraInfo, Writer)>,
    ) -> Result<(Inputs, Vec<SourceInput>)> {
        let config = self.config;
        let (tf_tx, tf) = std::sync::mpsc::channel::<(TfMessage, bool, Writer)>();
        let (js_tx, joints) = std::sync::mpsc::channel::<(JointState, Writer)>();
        // Each source's subscriptions, made while it is enabled (also when it is enabled at run
        // time), dropped when it is disabled.
        let mut source_inputs: Vec<SourceInput> = Vec::new();
        for (k, s) in config.sources.iter().enumerate() {
            source_inputs.push(if s.enabled {
                self.subscribe_source(node, k, s)?
            } else {
                SourceInput::default()
            });
        }
        let discovery = config.writers_from_discovery;
        let mut tf_writers = Vec::new();
        for (name, is_static) in [("/tf", false), ("/tf_static", true)] {
            let topic = input_topic(config, name);
            if discovery {
                tf_writers.push(node.publishers::<TfMessage>(&topic)?);
            }
            let qos = if is_static {
                TF_STATIC_QOS
            } else {
                RELIABLE_QOS.history(History::KeepLast { depth: 100 })
            };
            tasks.push(forward(
                node,
                &topic,
                qos,
                self.executor,
                name,
                tf_tx.clone(),
                move |m: TfMessage, w| (m, is_static, w),
                &self.shared,
            )?);
        }
        let joint_qos = QosProfile::subscription_default()
            .reliability_best_effort()
            .history(History::KeepLast { depth: 100 });
        let joint_topic = input_topic(config, &config.joint_states_topic);
        let joint_writers = (discovery)
            .then(|| node.publishers::<JointState>(&joint_topic))
            .transpose()?;
        tasks.push(forward(
            node,
            &joint_topic,
            joint_qos,
            self.executor,
            "joint states",
            js_tx,
            |m: JointState, w| (m, w),
            &self.shared,
        )?);
        let inputs = Inputs {
            tf,
            joints,
            camera_info,
            tf_writers,
            joint_writers,
        };
        Ok((inputs, source_inputs))
    }

    /// Subscribes to source `k`'s messages (and a depth source's camera info), and watches who
    /// publishes them (`writers_from_discovery`).
    pub(super) fn subscribe_source(
        &self,
        node: &mut RosNode,
        k: usize,
        s: &SourceConfig,
    ) -> Result<SourceInput> {
        let (executor, shared) = (self.executor, &self.shared);
        let mut tasks = Vec::new();
        let topic = input_topic(self.config, &s.topic);
        let qos = if s.reliable {
            RELIABLE_QOS.history(History::KeepLast { depth: 1 })
        } else {
            SENSOR_QOS
        };
        let discovery = self.config.writers_from_discovery;
        let writers = match (discovery, s.kind) {
            (false, _) => None,
            (true, SourceKind::PointCloud) => Some(node.publishers::<PointCloud2>(&topic)?),
            (true, SourceKind::DepthImage) => Some(node.publishers::<Image>(&topic)?),
        };
        let writers = writers.map(|w| WatchedTopic::new(w, &topic));
        let mut camera_writers = None;
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
                let info_topic = s.camera_info_topic.as_deref().unwrap_or_default();
                let info_topic = input_topic(self.config, info_topic);
                if discovery {
                    let w = node.publishers::<CameraInfo>(&info_topic)?;
                    camera_writers = Some(WatchedTopic::new(w, &info_topic));
                }
                tasks.push(forward(
                    node,
                    &info_topic,
                    qos,
                    executor,
                    "camera info",
                    self.info.clone(),
                    move |m: CameraInfo, w| (k, m, w),
                    shared,
                )?);
            }
        }
        Ok(SourceInput {
            _tasks: tasks,
            writers,
            camera_writers,
        })
    }

    /// Empties every source's slot (`whole`: also forgets when it last received).
    pub(super) fn clear_slots(&self, whole: bool) {
        for slot in &self.shared.slots {
            let mut slot = lock(slot);
            if whole {
                *slot = Slot::default();
            } else {
                slot.cloud = None;
            }
        }
    }
}

/// An enabled source's subscriptions, and who publishes its topic by discovery (`None` with
/// `writers_from_discovery` false); dropped when the source is disabled.
#[derive(Default)]
pub(super) struct SourceInput {
    /// Its subscriptions' tasks, held for as long as it is enabled.
    _tasks: Vec<smol::Task<()>>,
    writers: Option<WatchedTopic>,
    /// The same on a depth image source's CameraInfo topic.
    camera_writers: Option<WatchedTopic>,
}

/// Who writes one of a source's topics by discovery, and who did at the last look (for the
/// log).
struct WatchedTopic {
    writers: TopicWriters,
    topic: String,
    last: Vec<String>,
}

impl Inputs {
    /// Tells the monitor who writes the joint states and TF now, by GID where discovery gives
    /// it (DDS): a writer whose messages are lost stays a joint's or a frame's voice while it
    /// is matched.
    pub(super) fn tell_writers(&self, monitor: &mut Monitor) {
        let gids = |w: &TopicWriters| w.gids().unwrap_or_default();
        let joints = self.joint_writers.as_ref().map_or_else(Vec::new, gids);
        monitor.matched_joint_state_writers(joints);
        monitor.matched_tf_writers(self.tf_writers.iter().flat_map(gids).collect());
    }
}

impl SourceInput {
    /// Tells the monitor who writes source `k` (named `name`)'s topic, and a depth source's
    /// CameraInfo topic, now by discovery.
    pub(super) fn tell_writers(&mut self, monitor: &mut Monitor, k: usize, name: &str) {
        if let Some(w) = &mut self.writers {
            monitor.matched_writers(k, Some(w.now(name)));
        }
        if let Some(w) = &mut self.camera_writers {
            monitor.matched_camera_writers(k, Some(w.now(name)));
        }
    }
}

impl WatchedTopic {
    fn new(writers: TopicWriters, topic: &str) -> Self {
        Self {
            writers,
            topic: topic.to_owned(),
            last: Vec::new(),
        }
    }

    /// Its writers now; says so in the log when they differ from the last look's: one writer
    /// or none at INFO, a second one at WARN with the names (source `source`'s).
    fn now(&mut self, source: &str) -> Vec<String> {
        let writers = self.writers.writers();
        if writers == self.last {
            return writers;
        }
        let topic = &self.topic;
        match writers.len() {
            0 | 1 => log::info!(
                "source {source}: {} writer(s) on {topic} by discovery{}",
                writers.len(),
                writers
                    .first()
                    .map(|w| format!(": {w}"))
                    .unwrap_or_default()
            ),
            n => log::warn!(
                "source {source}: {n} writers on {topic} by discovery ({}): second_publisher, \
                 ERROR until only one is left",
                writers.join(", ")
            ),
        }
        self.last.clone_from(&writers);
        writers
    }
}
