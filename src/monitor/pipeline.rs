//! The monitor itself: what it holds (the robot, the query engine, the transform and joint
//! buffers, every configured [`Source`], the cell's level, the speed scaler) and its one entry
//! point per input kind, each taking a decoded message: `/tf` and `/tf_static`, the joint
//! states, a depth source's CameraInfo, a source's PointCloud2 or depth Image (or why its
//! payload could not be decoded). Each cloud or image gives a [`Frame`] (`measure`: the stamp,
//! the points, the poses, the query, the separation stage), fused with every source's latest
//! result into the node's outputs (`fusion`, then `outputs`).

use std::time::Instant;

use crate::cloud::depth::PinholeCamera;
use crate::cloud::CloudError;
use crate::config::Config;
use crate::msg::{CameraInfo, Image, JointState, PointCloud2, TfMessage, Writer};
use crate::query::{Backend, Engine, QueryResult};
use crate::robot::RobotModel;
use crate::separation::{SpeedScaler, SpeedScaling};
use crate::tf::{JointStateBuffer, TfBuffer};

use super::fault::{Fault, InputError};
use super::fusion::{fuse, Moment, Step};
use super::level::{Level, LevelTracker};
use super::outputs::Outputs;
use super::source::{Part, Source};
use super::unseen::UnseenSpace;

/// One processed cloud.
#[derive(Debug)]
pub struct Frame {
    pub source: String,
    pub stamp_ns: i64,
    pub result: Result<QueryResult, Fault>,
    /// Decode, poses and query, s.
    pub processing_s: f64,
    /// Speed and separation monitoring (`None` when `speed_scaling.enabled` is off).
    pub speed: Option<SpeedScaling>,
    /// Fusion with the other sources' latest results and the outputs' messages, s (both
    /// times where the seen outputs went first).
    pub outputs_s: f64,
    /// Where the frame's unseen pass followed its seen outputs: those outputs, made (and, in
    /// the node, published) before the pass, and the time from receipt to them, s. `outputs`
    /// is then the frame's last word, of which only the topics that follow the pass are
    /// published (`Outputs::visit_part`). Under `protect` the first outputs take the
    /// previous frame's pass and may only raise the level and lower the speed factor; a
    /// release waits for this frame's pass.
    pub first: Option<(Outputs, f64)>,
    /// The unseen-space pass of this frame, s (`None`: not run), and its stages' times. It is
    /// part of `processing_s`.
    pub unseen_s: Option<f64>,
    pub unseen_stages_s: Vec<(&'static str, f64)>,
    /// The hidden place nearest the robot that the pass found, and why no source saw it.
    pub unseen_nearest: Option<crate::unseen::Spot>,
    /// What the pass's search examined and found.
    pub unseen_counts: Option<crate::unseen::Counts>,
    /// Under `protect`, why this frame's pass gave no distance (a fault of the cell: ERROR, no
    /// distance); late passes included.
    pub unseen_fault: Option<super::unseen::UnseenFault>,
    pub outputs: Outputs,
}

impl Frame {
    /// Whether the frame's seen outputs went first and carried its distance: then only the
    /// topics that follow the pass are published from `outputs` (`Outputs::visit_part`).
    /// Where the first outputs had none (a fault then, as the previous frame's pass under
    /// `protect`, that this frame's pass cleared), `outputs` is published whole.
    pub fn outputs_follow(&self) -> bool {
        (self.first.as_ref()).is_some_and(|(first, _)| first.min_distance.is_some())
    }
}

pub struct Monitor {
    pub config: Config,
    pub model: RobotModel,
    pub(super) engine: Engine,
    pub(super) tf: TfBuffer,
    pub(super) joints: JointStateBuffer,
    /// Every configured source, in the config's order.
    pub(super) sources: Vec<Source>,
    /// The cell's one level, over every enabled source (`fusion`).
    pub(super) fused: LevelTracker,
    pub(super) scaler: SpeedScaler,
    /// The points of the last depth image (kept so that its allocation is reused).
    pub(super) depth_points: Vec<[f32; 3]>,
    /// What a change of attached objects is built from ([`Monitor::robot_without_objects`]).
    pub(super) base: Base,
    /// The unseen space: its settings, per-source views and latest pass.
    pub(super) unseen: UnseenSpace,
}

/// The robot without the config's attached objects.
pub(super) enum Base {
    /// `model` itself: the config attaches none.
    Model,
    /// A copy of the robot taken before they joined it.
    Detached(RobotModel),
    /// Not known: the monitor was made from a model with its objects attached
    /// ([`Monitor::with_trees`]).
    Unknown,
}

impl Monitor {
    /// Loads the GPU driver now when the backend may use it (`gpu`, or `auto`) instead of on
    /// the first cloud that needs it: the live node does this before it goes on the network, so
    /// that no frame's latency carries the probe (about 0.1 s with a software Vulkan driver).
    /// `replay` leaves it lazy, so that clouds below `gpu_min_points` and depth images below
    /// `gpu_min_depth_pixels` never load a driver.
    pub fn probe_gpu(&mut self) {
        if self.config.query.backend != Backend::Cpu {
            self.engine.gpu();
        }
    }

    /// The latest unseen-space pass (`None` with `unobserved: ignore`, or before the first).
    pub fn unseen(&self) -> Option<&super::unseen::Unseen> {
        self.unseen.last()
    }

    /// The unseen space: its settings, its sources' latest views, its latest pass.
    pub fn unseen_space(&self) -> &UnseenSpace {
        &self.unseen
    }

    /// Source `source`'s latest unseen-space view with the robot's image rendered whole (the
    /// pass renders only the rows it reads unless the shadow is apart), to draw it.
    pub fn unseen_view_whole(&mut self, source: usize) -> Option<&crate::unseen::PreparedView> {
        self.unseen.view_whole(source)
    }

    /// How many links the engine monitors (after `links`/`exclude_links`).
    pub fn links(&self) -> usize {
        self.engine.links().len()
    }

    /// Each monitored link's certified surface gap h, m (the width of its certified interval).
    pub fn link_gaps(&self) -> Vec<(String, f64)> {
        (self.engine.links().iter())
            .map(|l| (l.name.clone(), l.gap_m as f64))
            .collect()
    }

    /// Takes `config`, a run-time change of the running one that `Config::with_changes` made
    /// (only settable parameters differ: thresholds, the stray filter, sources' enabled flags,
    /// exclusion volumes). Levels held stay held; a source enabled now is in fault until its
    /// first frame, and its speed factor starts at 0.
    pub fn reconfigure(&mut self, config: Config) {
        let old = &self.config.sources;
        for (k, source) in self.sources.iter_mut().enumerate() {
            source.reconfigure(&config, old[k].enabled != config.sources[k].enabled);
        }
        self.fused.set_thresholds(&config);
        self.unseen.reconfigure(&config);
        let was = self.enabled_sources();
        self.scaler.set_enabled(&was, &enabled(&config));
        self.config = config;
    }

    /// Whether the run-time change `config` changes the robot (its attached objects): then a
    /// monitor is built for it (`Monitor::with_model`) instead of reconfiguring this one.
    pub fn needs_rebuild(&self, config: &Config) -> bool {
        config.attached_objects != self.config.attached_objects
    }

    /// Whether each source is enabled.
    pub fn enabled_sources(&self) -> Vec<bool> {
        enabled(&self.config)
    }

    /// The robot's own links (its attached objects left out).
    pub fn robot_links(&self) -> Vec<String> {
        let objects = &self.config.attached_objects;
        (self.model.kinematics.link_names().iter())
            .filter(|l| !objects.iter().any(|o| &o.name == *l))
            .cloned()
            .collect()
    }

    /// Whether the cell's safety stop is raised now, and whether each source is in fault at
    /// `now_ns` (what a run-time change is checked against: `Config::weakening`).
    pub fn safety(&self, now_ns: i64) -> (bool, Vec<bool>) {
        let in_fault = (self.config.sources.iter().zip(&self.sources))
            .map(|(s, source)| s.enabled && matches!(source.part(s, now_ns), Part::Fault { .. }))
            .collect();
        (self.fused.level() == Level::Error, in_fault)
    }

    /// Adds a `tf2_msgs/TFMessage` from `/tf` or (`is_static`) `/tf_static`, of no known
    /// writer (a bag's).
    pub fn on_tf(&mut self, topic: &str, m: &TfMessage, is_static: bool) -> Result<(), InputError> {
        self.on_tf_from(topic, m, is_static, Writer::UNKNOWN)
    }

    /// The same, written by `writer` (one authority per frame: `crate::tf`).
    pub fn on_tf_from(
        &mut self,
        topic: &str,
        m: &TfMessage,
        is_static: bool,
        writer: Writer,
    ) -> Result<(), InputError> {
        for t in &m.transforms {
            self.tf
                .insert_from(t, is_static, writer)
                .map_err(|source| InputError::Tf {
                    topic: topic.into(),
                    source,
                })?;
        }
        Ok(())
    }

    /// Adds a `sensor_msgs/JointState` of no known writer (a bag's).
    pub fn on_joint_state(&mut self, topic: &str, m: &JointState) -> Result<(), InputError> {
        self.on_joint_state_from(topic, m, Writer::UNKNOWN)
    }

    /// The same, published by `writer` (one voice per joint: `crate::tf::joints`).
    pub fn on_joint_state_from(
        &mut self,
        topic: &str,
        m: &JointState,
        writer: Writer,
    ) -> Result<(), InputError> {
        self.joints
            .insert_from(m, writer)
            .map_err(|source| InputError::Joints {
                topic: topic.into(),
                source,
            })
    }

    /// Source `source`'s topic had a message from `writer` stamped `stamp_ns` (every message
    /// received, before the newest is processed: one voice per source, [`Source::hear_writer`]).
    pub fn hear_writer(&mut self, source: usize, writer: Writer, stamp_ns: i64) {
        self.sources[source].hear_writer(writer, stamp_ns);
    }

    /// The writers that discovery matches on source `source`'s topic now (`None`: no
    /// discovery): two or more is the fault `second_publisher` ([`Source::set_matched`]).
    pub fn matched_writers(&mut self, source: usize, writers: Option<Vec<String>>) {
        self.sources[source].set_matched(writers);
    }

    /// The writers that discovery matches on the joint states' topic now, by GID (empty: no
    /// discovery, or one that does not give GIDs): a joint's writer stays its voice while it is
    /// matched ([`JointStateBuffer::set_matched`]).
    pub fn matched_joint_state_writers(&mut self, writers: Vec<Writer>) {
        self.joints.set_matched(writers);
    }

    /// The same on `/tf` and `/tf_static` ([`TfBuffer::set_matched`]).
    pub fn matched_tf_writers(&mut self, writers: Vec<Writer>) {
        self.tf.set_matched(writers);
    }

    /// Whether anyone reads `~/closest_points` now by discovery (`read`: `None` where unknown),
    /// asked only where the unseen pass draws markers: they are made only where someone reads
    /// them ([`UnseenSpace::set_markers_read`]).
    pub fn markers_read(&mut self, read: impl FnOnce() -> Option<bool>) {
        if self.unseen.draws_markers() {
            self.unseen.set_markers_read(read());
        }
    }

    /// The writers that discovery matches on depth image source `source`'s CameraInfo topic
    /// now: two or more is the fault `second_publisher` of its images
    /// ([`Source::set_matched_camera`]).
    pub fn matched_camera_writers(&mut self, source: usize, writers: Option<Vec<String>>) {
        self.sources[source].set_matched_camera(writers);
    }

    /// Which source, if any, publishes on `topic`.
    pub fn source_of(&self, topic: &str) -> Option<usize> {
        self.config
            .sources
            .iter()
            .position(|s| s.enabled && s.topic == topic)
    }

    /// The enabled depth image sources whose CameraInfo comes on `topic`.
    pub fn camera_info_sources(&self, topic: &str) -> Vec<usize> {
        (self.config.sources.iter().enumerate())
            .filter(|(_, s)| s.enabled && s.camera_info_topic.as_deref() == Some(topic))
            .map(|(k, _)| k)
            .collect()
    }

    /// The CameraInfo topic of depth image source `source` (for messages).
    pub(super) fn camera_info_topic(&self, source: usize) -> String {
        let s = &self.config.sources[source];
        s.camera_info_topic.clone().unwrap_or_default()
    }

    /// Takes a `sensor_msgs/CameraInfo` of depth image source `source`: its camera model is
    /// used for the source's next depth images; a refused one (the error names the field)
    /// makes them faults that say why, until a good one arrives.
    pub fn on_camera_info(&mut self, source: usize, m: &CameraInfo) -> Result<(), InputError> {
        self.on_camera_info_from(source, m, Writer::UNKNOWN)
    }

    /// The same, published by `writer` (one voice per camera model: [`Source::one_camera`]).
    pub fn on_camera_info_from(
        &mut self,
        source: usize,
        m: &CameraInfo,
        writer: Writer,
    ) -> Result<(), InputError> {
        let camera = PinholeCamera::from_camera_info(m);
        let stamp_ns = m.header.stamp.as_nanos();
        let model = camera.as_ref().map_err(|e| e.to_string()).copied();
        self.sources[source].set_camera(model, writer, stamp_ns);
        camera.map(|_| ()).map_err(|e| InputError::Camera {
            topic: self.camera_info_topic(source),
            source: Box::new(e),
        })
    }

    /// Processes one cloud of source `source`, received at `received`; `now_ns` is the clock
    /// the cloud's stamp is checked against (the node's clock at receipt; in replay, the bag's
    /// log time), `None` where there is none (a replay that takes each cloud's stamp as its
    /// time: only a stamp of 0 is then refused).
    pub fn on_cloud(
        &mut self,
        source: usize,
        m: &PointCloud2,
        received: Instant,
        now_ns: Option<i64>,
    ) -> Frame {
        self.on_cloud_early(source, m, received, now_ns, &mut |_| {})
    }

    /// The same, handing `early` the frame's seen outputs the moment they are made where the
    /// unseen pass follows them ([`Frame::first`]): the node publishes them then.
    pub fn on_cloud_early(
        &mut self,
        source: usize,
        m: &PointCloud2,
        received: Instant,
        now_ns: Option<i64>,
        early: &mut dyn FnMut(&Outputs),
    ) -> Frame {
        let stamp_ns = m.header.stamp.as_nanos();
        let process = |me: &mut Self| me.process(source, m, now_ns);
        self.finish_frame(source, received, stamp_ns, now_ns, process, early)
    }

    /// Processes one depth image of source `source` (as [`Monitor::on_cloud`]).
    pub fn on_depth_image(
        &mut self,
        source: usize,
        m: &Image,
        received: Instant,
        now_ns: Option<i64>,
    ) -> Frame {
        self.on_depth_image_early(source, m, received, now_ns, &mut |_| {})
    }

    /// The same, handing `early` the seen outputs (as [`Monitor::on_cloud_early`]).
    pub fn on_depth_image_early(
        &mut self,
        source: usize,
        m: &Image,
        received: Instant,
        now_ns: Option<i64>,
        early: &mut dyn FnMut(&Outputs),
    ) -> Frame {
        let stamp_ns = m.header.stamp.as_nanos();
        let process = |me: &mut Self| me.process_depth(source, m, now_ns);
        self.finish_frame(source, received, stamp_ns, now_ns, process, early)
    }

    /// A message of source `source` whose payload could not be decoded (`error`): a decode
    /// fault, stamped 0 (as [`Monitor::on_cloud`]).
    pub fn on_undecodable(
        &mut self,
        source: usize,
        error: CloudError,
        received: Instant,
        now_ns: Option<i64>,
    ) -> Frame {
        let process = |_: &mut Self| Err(error.into());
        self.finish_frame(source, received, 0, now_ns, process, &mut |_| {})
    }

    /// The clock went back (a bag played again, a simulation reset) at `watch_ns` by the
    /// node's monotonic clock: everything received is from another time line. Forgets the
    /// dynamic transforms, the joint states, the sources' results (each source is in fault
    /// until its next frame, its silence counted from now) and the speed scaler's history.
    /// Levels held stay held, so nothing is released by the jump; static transforms and camera
    /// models, which hold for all time, are kept.
    pub fn on_clock_jump(&mut self, watch_ns: i64) {
        self.tf.forget_dynamic();
        self.joints.forget();
        self.sources.iter_mut().for_each(|s| s.restart(watch_ns));
        self.unseen.forget_all();
        self.scaler = Self::scaler(&self.config);
    }

    /// The cell's fused outputs at `now_ns` without a new frame (the node's heartbeat): every
    /// source's latest result aged by the clock, so a source gone stale shows at once.
    pub fn heartbeat(&mut self, now_ns: i64) -> Outputs {
        let moment = Moment {
            source: self
                .config
                .sources
                .iter()
                .position(|s| s.enabled)
                .unwrap_or(0),
            stamp_ns: now_ns,
            now_ns,
            over_budget: false,
            factor: self.config.ssm.enabled.then(|| self.scaler.factor()),
            step: Step::Keep,
        };
        self.outputs(&moment, true)
    }

    /// The fused picture at `moment`, rendered; the latest pass's own topics (`~/unseen_*`,
    /// its markers and status) only where `unseen_topics` (not in the seen outputs that go
    /// before a frame's pass: they would repeat the previous frame's).
    pub(super) fn outputs(&mut self, moment: &Moment, unseen_topics: bool) -> Outputs {
        let unseen = self.unseen.last();
        let mut fused = fuse(&self.config, &self.sources, unseen, &mut self.fused, moment);
        if !unseen_topics {
            fused.unseen = None;
        }
        let root = self.model.kinematics.root_link();
        Outputs::render(&self.config, root, &self.model.name, fused)
    }
}

/// Whether each of `config`'s sources is enabled.
fn enabled(config: &Config) -> Vec<bool> {
    config.sources.iter().map(|s| s.enabled).collect()
}
