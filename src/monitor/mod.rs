//! The monitor: the one pipeline that `replay` and the live node run. Inputs are CDR payloads
//! as they come off a bag or DDS — `/tf`, `/tf_static`, `/joint_states` and each source's
//! PointCloud2, or depth Image with its CameraInfo (`cloud::depth`) — and every cloud or depth
//! image gives a [`Frame`]: the query result or the fault that stopped
//! it, and the node's output messages (`outputs`).
//!
//! Per cloud: decode (a depth image: its points made with the source's last camera model, into a
//! buffer the monitor keeps) → the stamp against the clock (0, older than the source's
//! `source_timeout` or ahead by more than `future_stamp_tolerance` is a fault) → drop points
//! outside the source's `min_range`/`max_range` (they become invalid points) → the joint values
//! at the cloud's stamp (`tf::JointStateBuffer`) → forward kinematics → the sensor frame in the
//! robot's root frame at the stamp (`tf::root_from_sensor`) → the points of the source's
//! exclusion volumes dropped (`cloud::exclusion`, each volume placed in the sensor frame at the
//! stamp) → the query (`query::Engine`; with
//! `stray_filter` on, `stray` rejects isolated nearest points) → the
//! separation stage (`crate::separation`: joint velocities at the stamp, link twists, the
//! speed-scaling factor through [`SpeedScaler`]) → the outputs, fused over every source's latest
//! result (`fusion`). A decode error, a missing or stale
//! transform or joint, and a failed query are faults of that frame: reported with their reason
//! and an ERROR level, never as a distance (and a speed-scaling factor of 0; the kinds are in
//! `fault`). The next message is processed as usual.
//!
//! `replay` feeds a bag through this pipeline in log-time order, as the node (`crate::node`)
//! feeds it from DDS.

mod fault;
pub mod fusion;
pub mod outputs;
pub mod replay;
mod setup;
mod stray;

pub use fault::{Fault, InputError};
pub use fusion::Fusion;
pub use outputs::{Level, LevelTracker, Outputs};
pub use setup::MonitorError;

use std::time::Instant;

use nalgebra::Isometry3;

use crate::cloud::depth::{self, PinholeCamera};
use crate::cloud::exclusion::{self, ExclusionVolume};
use crate::cloud::{pointcloud2, CloudError, RangeLimits};
use crate::config::{Config, SourceKind};
use crate::msg::{self, CameraInfo, Image, JointState, PointCloud2, TfMessage};
use crate::query::{Backend, Engine, Outcome, QueryResult};
use crate::robot::RobotModel;
use crate::separation::{self, SpeedScaler, SpeedScaling};
use crate::tf::{self, JointStateBuffer, TfBuffer};

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
    /// Fusion with the other sources' latest results and the outputs' messages, s.
    pub outputs_s: f64,
    pub outputs: Outputs,
}

/// What a processed cloud leaves for the separation stage.
struct Motion {
    poses: Vec<Isometry3<f64>>,
    stamp_ns: i64,
    /// Clock minus stamp, s (0 without a clock).
    age_s: f64,
}

pub struct Monitor {
    pub config: Config,
    pub model: RobotModel,
    engine: Engine,
    tf: TfBuffer,
    joints: JointStateBuffer,
    /// Every source's latest result, and the cell's one level (`fusion`).
    fusion: Fusion,
    scaler: SpeedScaler,
    /// Per source: the camera model of its last CameraInfo, or why that one was refused
    /// (depth image sources; `None` until one arrives).
    cameras: Vec<Option<Result<PinholeCamera, String>>>,
    /// The points of the last depth image (kept so that its allocation is reused).
    depth_points: Vec<[f32; 3]>,
    /// What a change of attached objects is built from ([`Monitor::robot_without_objects`]).
    base: Base,
}

/// What a source's message gives its query: a cloud's points, or a depth image with the buffer
/// its points are made into where they are made on the host.
enum Points<'a, 'b> {
    Cloud {
        points: &'a mut [[f32; 3]],
        width: Option<usize>,
    },
    Depth {
        view: &'a depth::DepthView<'b>,
        points: &'a mut Vec<[f32; 3]>,
    },
}

/// The robot without the config's attached objects.
enum Base {
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

    /// How many links the engine monitors (after `links`/`exclude_links`).
    pub fn links(&self) -> usize {
        self.engine.links().len()
    }

    /// Takes `config`, a run-time change of the running one that `Config::with_changes` made
    /// (only settable parameters differ: thresholds, the stray filter, sources' enabled flags,
    /// exclusion volumes). Levels held stay held; a source enabled now is in fault until its
    /// first frame, and its speed factor starts at 0.
    pub fn reconfigure(&mut self, config: Config) {
        self.fusion.reconfigure(&self.config, &config);
        let flags = |c: &Config| c.sources.iter().map(|s| s.enabled).collect::<Vec<_>>();
        self.scaler
            .set_enabled(&flags(&self.config), &flags(&config));
        self.config = config;
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
        (
            self.fusion.stop_raised(),
            self.fusion.in_fault(&self.config, now_ns),
        )
    }

    /// Forgets every transform, joint state and level received, as at start-up (a replay of
    /// another bag starts from here).
    pub fn reset(&mut self) -> Result<(), MonitorError> {
        (self.tf, self.joints) = Self::inputs(&self.config, &self.model)?;
        self.fusion = Fusion::new(&self.config);
        self.scaler = Self::scaler(&self.config);
        self.cameras = vec![None; self.config.sources.len()];
        Ok(())
    }

    /// Adds a `tf2_msgs/TFMessage` from `/tf` or (`is_static`) `/tf_static`.
    pub fn on_tf(
        &mut self,
        topic: &str,
        payload: &[u8],
        is_static: bool,
    ) -> Result<(), InputError> {
        let m: TfMessage = msg::decode(payload).map_err(|source| InputError::Msg {
            topic: topic.into(),
            source,
        })?;
        self.on_tf_message(topic, &m, is_static)
    }

    /// Adds a decoded `tf2_msgs/TFMessage`.
    pub fn on_tf_message(
        &mut self,
        topic: &str,
        m: &TfMessage,
        is_static: bool,
    ) -> Result<(), InputError> {
        for t in &m.transforms {
            self.tf
                .insert(t, is_static)
                .map_err(|source| InputError::Tf {
                    topic: topic.into(),
                    source,
                })?;
        }
        Ok(())
    }

    /// Adds a `sensor_msgs/JointState`.
    pub fn on_joint_state(&mut self, topic: &str, payload: &[u8]) -> Result<(), InputError> {
        let m: JointState = msg::decode(payload).map_err(|source| InputError::Msg {
            topic: topic.into(),
            source,
        })?;
        self.on_joint_state_message(topic, &m)
    }

    /// Adds a decoded `sensor_msgs/JointState`.
    pub fn on_joint_state_message(
        &mut self,
        topic: &str,
        m: &JointState,
    ) -> Result<(), InputError> {
        self.joints.insert(m).map_err(|source| InputError::Joints {
            topic: topic.into(),
            source,
        })
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

    /// The range limits of source `source`.
    fn range(&self, source: usize) -> Option<RangeLimits> {
        let s = &self.config.sources[source];
        RangeLimits::new(s.min_range_m, s.max_range_m)
    }

    /// The CameraInfo topic of depth image source `source` (for messages).
    fn camera_info_topic(&self, source: usize) -> String {
        let s = &self.config.sources[source];
        s.camera_info_topic.clone().unwrap_or_default()
    }

    /// Takes a `sensor_msgs/CameraInfo` of depth image source `source`, from its CDR payload.
    pub fn on_camera_info(&mut self, source: usize, payload: &[u8]) -> Result<(), InputError> {
        let m: CameraInfo = msg::decode(payload).map_err(|e| InputError::Msg {
            topic: self.camera_info_topic(source),
            source: e,
        })?;
        self.on_camera_info_message(source, &m)
    }

    /// Takes a decoded CameraInfo of source `source`: its camera model is used for the
    /// source's next depth images; a refused one (the error names the field) makes them faults
    /// that say why, until a good one arrives.
    pub fn on_camera_info_message(
        &mut self,
        source: usize,
        m: &CameraInfo,
    ) -> Result<(), InputError> {
        let camera = PinholeCamera::from_camera_info(m);
        self.cameras[source] = Some(camera.as_ref().map_err(|e| e.to_string()).copied());
        camera.map(|_| ()).map_err(|e| InputError::Camera {
            topic: self.camera_info_topic(source),
            source: Box::new(e),
        })
    }

    /// Processes one message of source `source` from its CDR payload, as the source's type
    /// says (a PointCloud2, or a depth Image); see [`Monitor::on_cloud`].
    pub fn on_source_message(
        &mut self,
        source: usize,
        payload: &[u8],
        now_ns: Option<i64>,
    ) -> Frame {
        match self.config.sources[source].kind {
            SourceKind::PointCloud => self.on_cloud(source, payload, now_ns),
            SourceKind::DepthImage => self.on_depth_image(source, payload, now_ns),
        }
    }

    /// Processes one depth image of source `source`, from its CDR payload (as
    /// [`Monitor::on_cloud`]).
    pub fn on_depth_image(&mut self, source: usize, payload: &[u8], now_ns: Option<i64>) -> Frame {
        let start = Instant::now();
        match msg::decode::<Image>(payload) {
            Ok(m) => self.finish_frame(source, start, m.header.stamp.as_nanos(), now_ns, |me| {
                me.process_depth(source, &m, now_ns)
            }),
            Err(e) => self.finish_frame(source, start, 0, now_ns, |_| {
                Err(Fault::Decode(CloudError::Decode(e)))
            }),
        }
    }

    /// Processes one decoded depth image of source `source` (as
    /// [`Monitor::on_cloud_message`]).
    pub fn on_depth_image_message(
        &mut self,
        source: usize,
        m: &Image,
        start: Instant,
        now_ns: i64,
    ) -> Frame {
        self.finish_frame(
            source,
            start,
            m.header.stamp.as_nanos(),
            Some(now_ns),
            |me| me.process_depth(source, m, Some(now_ns)),
        )
    }

    /// Processes one cloud of source `source`, from its CDR payload; `now_ns` is the clock the
    /// cloud's stamp is checked against (the node's clock at receipt; in replay, the bag's log
    /// time), `None` where there is none (a replay that takes each cloud's stamp as its time:
    /// only a stamp of 0 is then refused).
    pub fn on_cloud(&mut self, source: usize, payload: &[u8], now_ns: Option<i64>) -> Frame {
        let start = Instant::now();
        match pointcloud2::decode(payload) {
            Ok(m) => self.finish_frame(source, start, m.header.stamp.as_nanos(), now_ns, |me| {
                me.process(source, &m, now_ns)
            }),
            Err(e) => self.finish_frame(source, start, 0, now_ns, |_| Err(e.into())),
        }
    }

    /// The outputs of a source silent for `silent_s` (never heard from: `never`) at `now_ns` by
    /// the node's clock: a fault.
    pub fn on_source_timeout(
        &mut self,
        source: usize,
        silent_s: f64,
        never: bool,
        now_ns: i64,
    ) -> Frame {
        let s = &self.config.sources[source];
        let fault = Fault::SourceTimeout {
            source_name: s.name.clone(),
            what: if never {
                "no cloud received yet"
            } else {
                "no cloud"
            },
            silent_s,
            timeout_s: s.source_timeout_s,
        };
        self.on_source_fault(source, fault, now_ns)
    }

    /// The outputs of a fault of source `source` that is not a frame of its own (a silent
    /// source, an unusable clock) at `now_ns` by the node's clock.
    pub fn on_source_fault(&mut self, source: usize, fault: Fault, now_ns: i64) -> Frame {
        self.finish_frame(source, Instant::now(), now_ns, Some(now_ns), |_| Err(fault))
    }

    /// The clock went back (a bag played again, a simulation reset): everything received is
    /// from another time line. Forgets the dynamic transforms, the joint states, the sources'
    /// results (each source is in fault until its next frame) and the speed scaler's history.
    /// Levels held stay held, so nothing is released by the jump; static transforms and camera
    /// models, which hold for all time, are kept.
    pub fn on_clock_jump(&mut self) {
        self.tf.forget_dynamic();
        self.joints.forget();
        self.fusion.forget_results();
        self.scaler = Self::scaler(&self.config);
    }

    /// Processes one decoded cloud of source `source`; `start` is when it was received and
    /// `now_ns` the clock then (as [`Monitor::on_cloud`]).
    pub fn on_cloud_message(
        &mut self,
        source: usize,
        m: &PointCloud2,
        start: Instant,
        now_ns: i64,
    ) -> Frame {
        self.finish_frame(
            source,
            start,
            m.header.stamp.as_nanos(),
            Some(now_ns),
            |me| me.process(source, m, Some(now_ns)),
        )
    }

    fn finish_frame(
        &mut self,
        source: usize,
        start: Instant,
        stamp_ns: i64,
        now_ns: Option<i64>,
        process: impl FnOnce(&mut Self) -> Result<(QueryResult, Motion), Fault>,
    ) -> Frame {
        let processed = process(self);
        let processing_s = start.elapsed().as_secs_f64();
        let speed = self
            .config
            .ssm
            .enabled
            .then(|| self.speed_scaling(source, stamp_ns, &processed, processing_s));
        let result = processed.map(|(r, _)| r);
        let name = self.config.sources[source].name.clone();
        let fusion_start = Instant::now();
        let outputs = self.fusion.frame(
            &self.config,
            self.model.kinematics.root_link(),
            &self.model.name,
            source,
            stamp_ns,
            now_ns,
            &result,
            processing_s,
            speed.as_ref(),
        );
        Frame {
            source: name,
            stamp_ns,
            result,
            processing_s,
            speed,
            outputs_s: fusion_start.elapsed().as_secs_f64(),
            outputs,
        }
    }

    /// The cell's fused outputs at `now_ns` without a new frame (the node's heartbeat, see
    /// `fusion`).
    pub fn heartbeat(&mut self, now_ns: i64) -> Outputs {
        let factor = self.config.ssm.enabled.then(|| self.scaler.factor());
        self.fusion.heartbeat(
            &self.config,
            self.model.kinematics.root_link(),
            &self.model.name,
            now_ns,
            factor,
        )
    }

    /// The separation stage (`crate::separation`): the factor this frame allows, through the
    /// scaler. A frame without a distance, or without joint velocities, allows 0.
    fn speed_scaling(
        &mut self,
        source: usize,
        stamp_ns: i64,
        processed: &Result<(QueryResult, Motion), Fault>,
        processing_s: f64,
    ) -> SpeedScaling {
        let start = Instant::now();
        let ssm = &self.config.ssm;
        let separation = match processed {
            Err(fault) => Err(format!("no distance: {fault}")),
            Ok((r, _)) if outputs::published_distance(r).is_none() => {
                Err("no distance: no valid points, or every valid point self-filtered".into())
            }
            Ok((r, m)) => match self
                .joints
                .velocities_at(Some(m.stamp_ns), self.config.joint_state_tolerance_s)
            {
                Err(e) => Err(format!("no joint velocity: {e}")),
                Ok((q_dot, velocity_source)) => {
                    let twists = self.model.kinematics.link_velocities(&q_dot, &m.poses);
                    let scale = separation::nominal_scale(ssm, self.scaler.factor());
                    let constraints = separation::constraints(
                        ssm,
                        r,
                        self.engine.links(),
                        &m.poses,
                        &twists,
                        scale,
                    );
                    let reaction_s = ssm.reaction_time_s + m.age_s + processing_s;
                    separation::separation(ssm, &constraints, reaction_s, scale, velocity_source)
                        .ok_or_else(|| "no link".to_string())
                }
            },
        };
        let allowed = separation.as_ref().ok().map(|s| s.allowed);
        let factor = self.scaler.update(source, stamp_ns, allowed);
        SpeedScaling {
            factor,
            separation,
            stage_s: start.elapsed().as_secs_f64(),
        }
    }

    /// The stamp against the clock: a cloud with no stamp, one older than the source's
    /// `source_timeout` or one ahead of the clock is a fault before anything else is done.
    fn check_stamp(&self, source: usize, stamp_ns: i64, now_ns: Option<i64>) -> Result<(), Fault> {
        if stamp_ns == 0 {
            return Err(Fault::NoStamp);
        }
        let Some(now_ns) = now_ns else {
            return Ok(());
        };
        let age_s = (now_ns as f64 - stamp_ns as f64) * 1e-9;
        let timeout_s = self.config.sources[source].source_timeout_s;
        let tolerance_s = self.config.future_stamp_tolerance_s;
        if age_s > timeout_s {
            return Err(Fault::StaleCloud { age_s, timeout_s });
        }
        if -age_s > tolerance_s {
            return Err(Fault::FutureCloud {
                ahead_s: -age_s,
                tolerance_s,
            });
        }
        Ok(())
    }

    fn process(
        &mut self,
        source: usize,
        message: &PointCloud2,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion), Fault> {
        let stamp_ns = message.header.stamp.as_nanos();
        self.check_stamp(source, stamp_ns, now_ns)?;
        let mut cloud = message.to_cloud()?;
        let frame = cloud.frame_id.take().filter(|f| !f.is_empty());
        let frame = frame.ok_or(Fault::NoFrame)?;
        if let Some(range) = self.range(source) {
            for p in &mut cloud.points {
                if !range.keeps(*p) {
                    *p = [f32::NAN; 3];
                }
            }
        }
        let width = (cloud.height > 1).then_some(cloud.width as usize);
        let points = Points::Cloud {
            points: &mut cloud.points,
            width,
        };
        self.measure(source, stamp_ns, &frame, points, now_ns)
    }

    /// A depth image: its points made with the source's camera model (`cloud::depth`), then
    /// measured as a cloud's (made on the GPU where the query runs there: `Points::Depth`).
    fn process_depth(
        &mut self,
        source: usize,
        image: &Image,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion), Fault> {
        let stamp_ns = image.header.stamp.as_nanos();
        self.check_stamp(source, stamp_ns, now_ns)?;
        let frame = Some(image.header.frame_id.clone()).filter(|f| !f.is_empty());
        let frame = frame.ok_or(Fault::NoFrame)?;
        let camera = match &self.cameras[source] {
            Some(Ok(c)) => *c,
            other => {
                return Err(Fault::NoCameraInfo {
                    topic: self.camera_info_topic(source),
                    reason: match other {
                        Some(Err(e)) => format!("the last CameraInfo was refused: {e}"),
                        _ => "no CameraInfo received yet".into(),
                    },
                })
            }
        };
        let range = self.range(source);
        let mut points = std::mem::take(&mut self.depth_points);
        let result = depth::DepthView::new(image, &camera, range)
            .map_err(Fault::Decode)
            .and_then(|view| {
                let points = Points::Depth {
                    view: &view,
                    points: &mut points,
                };
                self.measure(source, stamp_ns, &frame, points, now_ns)
            });
        self.depth_points = points;
        result
    }

    /// The query of source `source`'s cloud, its points in `frame` at `stamp_ns` (the
    /// exclusion volumes that apply to it drop theirs first), and the motion the separation
    /// stage needs. A depth image goes to the engine whole (`Engine::query_depth`: on the GPU
    /// its points are made there) unless an exclusion volume or the stray filter needs its
    /// points here.
    fn measure(
        &mut self,
        source: usize,
        stamp_ns: i64,
        frame: &str,
        points: Points,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion), Fault> {
        let stamp = Some(stamp_ns);
        let q = self.joints.at(stamp, self.config.joint_state_tolerance_s)?;
        let poses = self.model.kinematics.link_poses(&q);
        let kinematics = &self.model.kinematics;
        let link_pose = |name: &str| -> Option<Isometry3<f64>> {
            kinematics.link_index(name).map(|i| poses[i])
        };
        let root_from_sensor = tf::root_from_sensor(
            &self.tf,
            frame,
            kinematics.root_link(),
            stamp,
            self.config.tf_tolerance_s,
            &link_pose,
        )?;
        let name = &self.config.sources[source].name;
        let needs_points = self.config.stray.enabled()
            || (self.config.exclusion_volumes.iter()).any(|v| v.applies_to(name));
        let (points, width) = match points {
            Points::Depth { view, points } if !needs_points => {
                let result = self.engine.query_depth(
                    view,
                    points,
                    &root_from_sensor,
                    &poses,
                    &self.config.query,
                )?;
                return self.finish_measure(result, Vec::new(), poses, stamp_ns, now_ns);
            }
            Points::Depth { view, points } => {
                view.unproject_into(points);
                let width = (view.height() > 1).then_some(view.width());
                (points.as_mut_slice(), width)
            }
            Points::Cloud { points, width } => (points, width),
        };
        let excluded = self.exclude(source, points, &root_from_sensor, stamp, &link_pose)?;
        let mut result = self.engine.query_image(
            points,
            width,
            &root_from_sensor,
            &poses,
            &self.config.query,
        )?;
        if self.config.stray.enabled() {
            let input = stray::Input {
                points,
                width,
                root_from_sensor: &root_from_sensor,
                poses: &poses,
                options: &self.config.query,
            };
            result = stray::reject_strays(&mut self.engine, &self.config.stray, input, result)?;
        }
        self.finish_measure(result, excluded, poses, stamp_ns, now_ns)
    }

    /// A measured source's result with the counts of its exclusion volumes, and its motion: a
    /// cloud whose valid points all lay in exclusion volumes has nothing near; one without valid
    /// points is blind.
    fn finish_measure(
        &self,
        mut result: QueryResult,
        excluded: Vec<(String, u64)>,
        poses: Vec<Isometry3<f64>>,
        stamp_ns: i64,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion), Fault> {
        let excluded_any = excluded.iter().any(|(_, n)| *n > 0);
        result.excluded = excluded;
        if result.outcome == Outcome::NoPoints {
            // Valid points that all lay in exclusion volumes: the sensor sees, and what it sees
            // is known. Only a cloud without valid points is blind.
            if !excluded_any {
                return Err(Fault::NoValidPoints {
                    total: result.counts.total,
                });
            }
            result.outcome = Outcome::NothingWithinMaxDistance;
        }
        let motion = Motion {
            poses,
            stamp_ns,
            age_s: now_ns.map_or(0.0, |n| ((n - stamp_ns) as f64 * 1e-9).max(0.0)),
        };
        Ok((result, motion))
    }

    /// Drops the points of source `source` that lie in its exclusion volumes (each placed in
    /// the sensor's frame at `stamp`, as the sensor itself is); the count of each volume that
    /// applies. A volume whose frame cannot be placed is a fault: its points would otherwise
    /// stop the cell, or be dropped in the wrong place.
    fn exclude(
        &self,
        source: usize,
        points: &mut [[f32; 3]],
        root_from_sensor: &Isometry3<f64>,
        stamp: Option<i64>,
        link_pose: &dyn Fn(&str) -> Option<Isometry3<f64>>,
    ) -> Result<Vec<(String, u64)>, Fault> {
        let name = &self.config.sources[source].name;
        let volumes: Vec<&ExclusionVolume> = (self.config.exclusion_volumes.iter())
            .filter(|v| v.applies_to(name))
            .collect();
        if volumes.is_empty() {
            return Ok(Vec::new());
        }
        let sensor_from_root = root_from_sensor.inverse();
        let placed = volumes
            .iter()
            .map(|v| {
                let root_from_frame = tf::root_from_sensor(
                    &self.tf,
                    &v.frame,
                    self.model.kinematics.root_link(),
                    stamp,
                    self.config.tf_tolerance_s,
                    link_pose,
                )
                .map_err(|source| Fault::ExclusionFrame {
                    volume: v.name.clone(),
                    source,
                })?;
                let sensor_from_volume = sensor_from_root * root_from_frame * v.frame_from_volume;
                Ok(exclusion::Placed::new(&v.shape, &sensor_from_volume))
            })
            .collect::<Result<Vec<_>, Fault>>()?;
        let counts = exclusion::exclude(points, &placed);
        Ok(volumes.iter().map(|v| v.name.clone()).zip(counts).collect())
    }
}
