//! One frame of a source, measured: the stamp against the clock (0, older than the source's
//! `source_timeout` or ahead by more than `future_stamp_tolerance` is a fault) → the points
//! (a cloud's, outside the source's `min_range`/`max_range` made invalid; a depth image's made
//! with the source's last camera model, into a buffer the monitor keeps) → the joint values at
//! the stamp (`tf::JointStateBuffer`) → forward kinematics → the sensor frame in the robot's
//! root frame at the stamp (`tf::root_from_sensor`) → the points of the source's exclusion
//! volumes dropped (`cloud::exclusion`, each volume placed in the sensor frame at the stamp) →
//! the query (`query::Engine`; with `stray_filter` on, `stray` rejects isolated nearest
//! points) → the separation stage (`crate::separation`: joint velocities at the stamp, link
//! twists, the speed-scaling factor through `SpeedScaler`) → the source's report and the fused
//! outputs. Every stage up to the separation is in the frame's processing time, which the
//! reaction time and the latency budget take. Any step that fails makes the frame a fault with
//! its reason (`fault`).
//!
//! With the unseen space on (`unseen`), those are the frame's **seen outputs**, handed to the
//! caller at once (the node publishes them), and then come: the frame's view (made from its
//! points as they came, before the exclusion volumes dropped theirs; made before the query
//! where the GPU judges its cells in the query's submission) → the pass over every source's
//! latest view → the frame's **last word**, whose processing includes the pass. Under `report`
//! the last word keeps the level and the factor. Under `protect` the seen outputs take the
//! previous frame's pass and may only raise the level (`LevelTracker::raise_for`) and lower the
//! factor (`SpeedScaler::lower`); the last word takes this frame's pass, the level and the factor
//! as a whole frame's (`fusion::Step`). Before any pass, or after one that gave no distance,
//! the pass runs before any output: the seen outputs could only say ERROR.

use std::time::Instant;

use nalgebra::Isometry3;

use crate::cloud::depth::{self, PinholeCamera};
use crate::cloud::exclusion::{self, ExclusionVolume};
use crate::cloud::RangeLimits;
use crate::msg::{Image, PointCloud2, Writer};
use crate::query::{Outcome, QueryLink, QueryResult};
use crate::separation::{self, SpeedScaling};
use crate::tf;

use super::fault::Fault;
use super::fusion::{Moment, Step};
use super::outputs::Outputs;
use super::pipeline::{Frame, Monitor};
use super::report::{published_distance, FrameFacts};
use super::stray;
use super::unseen::{cloud_view, depth_view, At, PassInputs, UnseenSpace};

/// What a processed cloud leaves for the separation stage and the unseen pass.
pub(super) struct Motion<'a> {
    poses: Vec<Isometry3<f64>>,
    stamp_ns: i64,
    /// Clock minus stamp, s (0 without a clock).
    age_s: f64,
    /// The frame's points for the unseen pass's view, made after the seen outputs went out
    /// (`None`: made before the query, where the GPU judges its cells in the same submission,
    /// or no pass).
    view: Option<PendingView<'a>>,
}

/// A frame's points kept for the unseen pass's view (see [`Motion::view`]): all its returns,
/// those in exclusion volumes included (they block rays as any other).
enum PendingView<'a> {
    Depth {
        view: depth::DepthView<'a>,
        camera: PinholeCamera,
        root_from_sensor: Isometry3<f64>,
    },
    /// A cloud's points (range limits applied), `None` until the cloud hands them over
    /// (`process`: moved, where no exclusion volume changed them).
    Cloud {
        points: Option<Vec<[f32; 3]>>,
        width: Option<usize>,
        root_from_sensor: Isometry3<f64>,
    },
}

/// What a frame's unseen pass reports into its [`Frame`].
#[derive(Default)]
struct PassReport {
    unseen_s: Option<f64>,
    stages_s: Vec<(&'static str, f64)>,
    nearest: Option<crate::unseen::Spot>,
    counts: Option<crate::unseen::Counts>,
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

impl Monitor {
    /// The frame of source `source` that `process` measures, received at `start`: its
    /// separation stage, its report and the fused outputs. Where the unseen pass runs, the seen
    /// outputs go first (handed to `early` at once, kept in [`Frame::first`]); then the pass;
    /// then the frame's last word, with the pass's time in its processing, its reaction time
    /// and its latency budget.
    pub(super) fn finish_frame<'a>(
        &mut self,
        source: usize,
        start: Instant,
        stamp_ns: i64,
        now_ns: Option<i64>,
        process: impl FnOnce(&mut Self) -> Result<(QueryResult, Motion<'a>), Fault>,
        early: &mut dyn FnMut(&Outputs),
    ) -> Frame {
        let mut processed = process(self);
        if processed.is_err() {
            self.unseen.forget(source);
        }
        let passes = processed.is_ok() && self.unseen.enabled();
        let protects = self.unseen.protects();
        // 1. The seen picture: the source's report and its outputs.
        let seen_s = start.elapsed().as_secs_f64();
        let first_step = if passes && protects {
            Step::Raise
        } else {
            Step::Whole
        };
        let mut speed = (self.config.ssm.enabled)
            .then(|| self.speed_scaling(source, stamp_ns, &processed, seen_s, first_step));
        let name = self.config.sources[source].name.clone();
        let report_start = Instant::now();
        let facts = FrameFacts {
            source: &name,
            result: processed.as_ref().map(|(r, _)| r),
            processing_s: seen_s,
            speed: speed.as_ref(),
        };
        let over_budget =
            self.sources[source].frame(&self.config, &self.model.name, stamp_ns, facts);
        let mut moment = Moment {
            source,
            stamp_ns,
            now_ns: now_ns.unwrap_or(stamp_ns),
            over_budget,
            factor: speed.as_ref().map(|s| s.factor),
            step: first_step,
        };
        let mut outputs_s = report_start.elapsed().as_secs_f64();
        let (mut processing_s, mut first, mut pass, mut unseen_fault) = (seen_s, None, None, None);
        if let (true, Ok((_, motion))) = (passes, processed.as_mut()) {
            // The seen outputs go first: nothing of them waits for the pass. Under `protect`
            // only where the latest pass gave a distance: otherwise they could only say ERROR
            // without one, and the frame's last word follows at once.
            let latest_ok = (self.unseen.last()).is_some_and(|u| u.outcome.is_ok());
            if !protects || latest_ok {
                let (seen, s) = self.timed_outputs(&moment, false);
                outputs_s += s;
                early(&seen);
                first = Some((seen, start.elapsed().as_secs_f64()));
            }
            // 2. The unseen space over every source's latest view (this frame's made now),
            // the robot at this frame's poses.
            if let Some(pending) = motion.view.take() {
                pending.observe(&mut self.unseen, self.engine.links(), source, &motion.poses);
            }
            pass = Some(self.unseen_pass(stamp_ns, motion));
            processing_s = start.elapsed().as_secs_f64();
            unseen_fault = (self.unseen).check_late(processing_s, self.config.latency_budget_s);
            // 3. The frame's last word. Under `protect` the level and the speed factor take
            // this frame's pass (a release is decided here, once); under `report` the pass
            // moves neither.
            if protects && self.config.ssm.enabled {
                let last =
                    self.speed_scaling(source, stamp_ns, &processed, processing_s, Step::Whole);
                moment.factor = Some(last.factor);
                speed = Some(last);
            }
            moment.step = if protects { Step::Whole } else { Step::Keep };
        }
        let (outputs, s) = self.timed_outputs(&moment, true);
        outputs_s += s;
        let pass = pass.unwrap_or_default();
        Frame {
            source: name,
            stamp_ns,
            result: processed.map(|(r, _)| r),
            processing_s,
            speed,
            outputs_s,
            unseen_s: pass.unseen_s,
            unseen_stages_s: pass.stages_s,
            unseen_nearest: pass.nearest,
            unseen_counts: pass.counts,
            unseen_fault,
            first,
            outputs,
        }
    }

    /// [`Monitor::outputs`] and the time it took, s.
    fn timed_outputs(&mut self, moment: &Moment, unseen_topics: bool) -> (Outputs, f64) {
        let start = Instant::now();
        let outputs = self.outputs(moment, unseen_topics);
        (outputs, start.elapsed().as_secs_f64())
    }

    /// Runs the unseen pass after a frame's query, the robot at its poses.
    fn unseen_pass(&mut self, stamp_ns: i64, motion: &Motion) -> PassReport {
        let unseen = self.unseen.run(PassInputs {
            at: At {
                stamp_ns,
                poses: &motion.poses,
                kinematics: &self.model.kinematics,
                tf: &self.tf,
            },
            engine: &mut self.engine,
        });
        let facts = unseen.outcome.as_ref().ok();
        PassReport {
            unseen_s: Some(unseen.compute_s),
            stages_s: facts.map(|f| f.stages_s.clone()).unwrap_or_default(),
            nearest: facts.and_then(|f| f.nearest),
            counts: facts.map(|f| f.counts),
        }
    }

    /// The separation stage (`crate::separation`): the factor this frame allows, through the
    /// scaler (only lowered by a `Step::Raise`: the seen outputs before the pass under
    /// `protect`). A frame without a distance, or without joint velocities, allows 0.
    fn speed_scaling(
        &mut self,
        source: usize,
        stamp_ns: i64,
        processed: &Result<(QueryResult, Motion), Fault>,
        processing_s: f64,
        step: Step,
    ) -> SpeedScaling {
        let start = Instant::now();
        let ssm = &self.config.ssm;
        let separation = match processed {
            Err(fault) => Err(format!("no distance: {fault}")),
            Ok((r, _)) if published_distance(r).is_none() => {
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
                    let links = self.engine.links();
                    let mut constraints =
                        separation::constraints(ssm, r, links, &m.poses, &twists, scale);
                    // `protect`: each link held to its distance to unseen space where nearer.
                    if let Some(unseen) = self.unseen.protecting_links(links.len()) {
                        separation::tighten_by_unseen(
                            ssm,
                            &mut constraints,
                            &unseen,
                            links,
                            &m.poses,
                            &twists,
                            scale,
                        );
                    }
                    let reaction_s = ssm.reaction_time_s + m.age_s + processing_s;
                    separation::separation(ssm, &constraints, reaction_s, scale, velocity_source)
                        .ok_or_else(|| "no link".to_string())
                }
            },
        };
        let allowed = separation.as_ref().ok().map(|s| s.allowed);
        let factor = match step {
            Step::Raise => self.scaler.lower(source, allowed),
            _ => self.scaler.update(source, stamp_ns, allowed),
        };
        SpeedScaling {
            factor,
            separation,
            stage_s: start.elapsed().as_secs_f64(),
        }
    }

    /// The range limits of source `source`.
    fn range(&self, source: usize) -> Option<RangeLimits> {
        let s = &self.config.sources[source];
        RangeLimits::new(s.min_range_m, s.max_range_m)
    }

    /// The stamp against the clock: a cloud with no stamp, one older than the source's
    /// `source_timeout` or one ahead of the clock is a fault before anything else is done.
    fn check_stamp(&self, source: usize, stamp_ns: i64, now_ns: Option<i64>) -> Result<(), Fault> {
        if stamp_ns == 0 {
            return Err(Fault::NoStamp);
        }
        if let Some(writers) = self.sources[source].matched_conflict() {
            return Err(Fault::MatchedWriters {
                topic: self.config.sources[source].topic.clone(),
                count: writers.len(),
                writers: writers.join(", "),
            });
        }
        let window_s = self.config.second_publisher_window_s;
        if let Err(writers) = self.sources[source].one_voice(stamp_ns, window_s) {
            return Err(Fault::SecondPublisher {
                topic: self.config.sources[source].topic.clone(),
                writers: Writer::list(&writers),
                window_s,
            });
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

    /// A cloud: its points (those outside the source's range made invalid), then measured.
    pub(super) fn process(
        &mut self,
        source: usize,
        message: &PointCloud2,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion<'static>), Fault> {
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
        let (result, mut motion) = self.measure(source, stamp_ns, &frame, points, now_ns)?;
        // The points as they came go to the pass's view (a copy was kept where exclusion
        // volumes changed them).
        if let Some(PendingView::Cloud {
            points: p @ None, ..
        }) = &mut motion.view
        {
            *p = Some(std::mem::take(&mut cloud.points));
        }
        Ok((result, motion))
    }

    /// A depth image: its points made with the source's camera model (`cloud::depth`), then
    /// measured as a cloud's (made on the GPU where the query runs there: `Points::Depth`).
    pub(super) fn process_depth<'i>(
        &mut self,
        source: usize,
        image: &'i Image,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion<'i>), Fault> {
        let stamp_ns = image.header.stamp.as_nanos();
        self.check_stamp(source, stamp_ns, now_ns)?;
        let frame = Some(image.header.frame_id.clone()).filter(|f| !f.is_empty());
        let frame = frame.ok_or(Fault::NoFrame)?;
        if let Some(writers) = self.sources[source].matched_camera_conflict() {
            return Err(Fault::MatchedWriters {
                topic: self.camera_info_topic(source),
                count: writers.len(),
                writers: writers.join(", "),
            });
        }
        let window_s = self.config.second_publisher_window_s;
        if let Err(writers) = self.sources[source].one_camera(stamp_ns, window_s) {
            return Err(Fault::SecondPublisher {
                topic: self.camera_info_topic(source),
                writers: Writer::list(&writers),
                window_s,
            });
        }
        let camera = self.sources[source]
            .camera()
            .map_err(|reason| Fault::NoCameraInfo {
                topic: self.camera_info_topic(source),
                reason,
            })?;
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
    fn measure<'b>(
        &mut self,
        source: usize,
        stamp_ns: i64,
        frame: &str,
        points: Points<'_, 'b>,
        now_ns: Option<i64>,
    ) -> Result<(QueryResult, Motion<'b>), Fault> {
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
        let excludes = (self.config.exclusion_volumes.iter()).any(|v| v.applies_to(name));
        let needs_points = self.config.stray.enabled() || excludes;
        // On the GPU the query's submission judges the unseen space's cells in a depth image's
        // view (one it measures whole).
        let gpu_cells = self.unseen.enabled()
            && matches!(&points, Points::Depth { view, .. }
                if !needs_points && self.config.query.wants_gpu_for_depth(view.len()));
        // The unseen pass's view of these points: made after the seen outputs (the pass's
        // first stage), or now where the GPU judges its cells in the query's submission.
        let mut pending = None;
        if self.unseen.enabled() {
            let view = match &points {
                Points::Depth { view, .. } => match self.sources[source].camera() {
                    Ok(camera) => Ok(PendingView::Depth {
                        view: **view,
                        camera,
                        root_from_sensor,
                    }),
                    Err(_) => Err("no camera model".to_string()),
                },
                Points::Cloud { points, width } => Ok(PendingView::Cloud {
                    // Where exclusion volumes change them, a copy of them as they came.
                    points: excludes.then(|| points.to_vec()),
                    width: *width,
                    root_from_sensor,
                }),
            };
            match view {
                Ok(v) if !gpu_cells => pending = Some(v),
                Ok(v) => v.observe(&mut self.unseen, self.engine.links(), source, &poses),
                Err(e) => (self.unseen).observe(source, Err(e), 0.0, self.engine.links(), &poses),
            }
        }
        let (points, width) = match points {
            Points::Depth { view, points } if !needs_points => {
                if gpu_cells {
                    let at = At {
                        stamp_ns,
                        poses: &poses,
                        kinematics: &self.model.kinematics,
                        tf: &self.tf,
                    };
                    self.unseen.request_cells(source, &at, &mut self.engine);
                }
                let result = self.engine.query_depth(
                    view,
                    points,
                    &root_from_sensor,
                    &poses,
                    &self.config.query,
                );
                if gpu_cells {
                    self.unseen.take_cells(source, &mut self.engine);
                }
                let result = result?;
                return self.finish_measure(result, Vec::new(), poses, stamp_ns, now_ns, pending);
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
        self.finish_measure(result, excluded, poses, stamp_ns, now_ns, pending)
    }
}

impl PendingView<'_> {
    /// Source `source`'s view for the unseen pass, made from these points, into `unseen` (its
    /// time counted in the pass's: `UnseenSpace::observe`).
    fn observe(
        self,
        unseen: &mut UnseenSpace,
        links: &[QueryLink],
        source: usize,
        poses: &[Isometry3<f64>],
    ) {
        let start = Instant::now();
        let (limits, noise) = unseen.source_limits(source);
        let view = match &self {
            PendingView::Depth {
                view,
                camera,
                root_from_sensor,
            } => depth_view(view, camera, root_from_sensor, noise),
            PendingView::Cloud {
                points,
                width,
                root_from_sensor,
            } => {
                let known = unseen.known_camera(source);
                let points = points.as_deref().unwrap_or_default();
                cloud_view(
                    points,
                    *width,
                    root_from_sensor,
                    limits,
                    noise,
                    known.as_ref(),
                )
            }
        };
        let made_s = start.elapsed().as_secs_f64();
        unseen.observe(source, view, made_s, links, poses);
    }
}

impl Monitor {
    /// A measured source's result with the counts of its exclusion volumes, and its motion: a
    /// cloud whose valid points all lay in exclusion volumes has nothing near; one without valid
    /// points is blind.
    fn finish_measure<'b>(
        &self,
        mut result: QueryResult,
        excluded: Vec<(String, u64)>,
        poses: Vec<Isometry3<f64>>,
        stamp_ns: i64,
        now_ns: Option<i64>,
        pending: Option<PendingView<'b>>,
    ) -> Result<(QueryResult, Motion<'b>), Fault> {
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
            view: pending,
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
