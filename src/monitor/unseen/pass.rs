//! The pass's steps, run after each measured frame with the robot at that frame's poses:
//!
//! 1. **The volume** (`place_volume`): the lattice over `monitored_volume`, its frame placed at
//!    the frame's stamp; by default the robot's reach plus a margin above the root's z = 0
//!    plane, taken as the floor; the ball each centre stands for ([`BallSize`]).
//! 2. **The robot**: the centres whose ball meets an inner sphere (the spheres its view was
//!    prepared with at the same poses, else placed now), and each link's bounding sphere.
//! 3. **The search** (`unseen::Search`) over every live view, the exclusion volumes that apply
//!    to every source placed at the stamp, with the certified lower bound over the hidden
//!    centres, per link as configured: measured best first (`unseen::Measure`), or in exact
//!    mode by the engine's query (refined on the meshes; no self-filter).
//! 4. **The causes** of the nearest hidden place and of those kept for the markers: each view's
//!    robot image rendered in the rows their tests read (where the search did not need it
//!    whole: `unseen::prepared`), then each view's word on them.
//! 5. **The facts**: the distances less the ball's margin, the nearest hidden place and why.
//!
//! No enabled source observes anything free (only unorganized clouds, no frame yet): the whole
//! volume is hidden, and the unseen distance is 0 at once, without the search's cost.

use std::time::Instant;

use nalgebra::{Isometry3, Point3};

use crate::cloud::exclusion::Placed;
use crate::query::{Engine, Mode, Outcome, QueryLink, QueryResult};
use crate::robot::Kinematics;
use crate::tf::{self, TfBuffer};
use crate::unseen::{BallSize, Batch, Lattice, Measure, PreparedView, RobotBody, Search};

use super::error::UnseenFault;
use super::facts::{Unseen, UnseenFacts};
use super::space::UnseenSpace;

/// Where a pass places its frames: the frame's stamp, the robot's poses then, and TF.
#[derive(Clone, Copy)]
pub struct At<'a> {
    pub stamp_ns: i64,
    /// `root_from_link` at the stamp, the kinematics' order.
    pub poses: &'a [Isometry3<f64>],
    pub kinematics: &'a Kinematics,
    pub tf: &'a TfBuffer,
}

/// What a pass reads besides its own state, all at the frame's stamp.
pub struct PassInputs<'a> {
    pub at: At<'a>,
    /// The query engine: its links, and the certified distance over the hidden centres.
    pub engine: &'a mut Engine,
}

impl UnseenSpace {
    /// The pass after a measured frame (see the module doc); kept as the latest. Its time
    /// includes the frame's view ([`UnseenSpace::observe`]), its first stage.
    pub fn run(&mut self, mut input: PassInputs) -> &Unseen {
        let start = Instant::now();
        let view_s = std::mem::take(&mut self.view_s);
        let mut outcome = self.facts(&mut input);
        if let Ok(f) = &mut outcome {
            f.stages_s.insert(0, ("view", view_s));
        }
        self.last = Some(Unseen {
            stamp_ns: input.at.stamp_ns,
            outcome,
            compute_s: view_s + start.elapsed().as_secs_f64(),
        });
        self.last.as_ref().expect("just set")
    }

    fn facts(&mut self, input: &mut PassInputs) -> Result<UnseenFacts, UnseenFault> {
        let clock = Instant::now();
        let mut stages = Vec::with_capacity(4);
        let mut last = 0.0;
        let mut lap = |name: &'static str| {
            let now = clock.elapsed().as_secs_f64();
            stages.push((name, now - last));
            last = now;
        };
        // 1. The volume.
        let lattice = self.place_volume(&input.at, input.engine.links())?;
        let ball = BallSize::new(&lattice, self.settings.detection_capability_m)
            .map_err(UnseenFault::Lattice)?;
        let per_source: Vec<(String, Result<(), String>)> = (self.sources.iter())
            .zip(&self.views)
            .filter(|(s, _)| s.enabled)
            .map(|(s, v)| {
                let state = match v {
                    Some(Ok(_)) => Ok(()),
                    Some(Err(e)) => Err(e.clone()),
                    None => Err("no measured frame".into()),
                };
                (s.name.clone(), state)
            })
            .collect();
        if self.live_views(&lattice).0.is_empty() {
            return Ok(UnseenFacts {
                distance_m: Some(0.0),
                per_source,
                blind: true,
                cells: lattice.len(),
                resolution_m: lattice.resolution_m(),
                ..UnseenFacts::default()
            });
        }
        lap("volume");
        // 2. The robot, and the exclusion volumes.
        let volumes = self.place_volumes(&input.at)?;
        let links = input.engine.shared_links();
        if links.iter().all(|l| l.spheres.is_empty()) {
            return Err(UnseenFault::NoSpheres);
        }
        let poses = input.at.poses;
        let spheres = self.take_spheres(&links, poses);
        let robot = RobotBody::from_spheres(&lattice, &links, poses, &spheres, ball.radius_m);
        let (engine, query) = (&mut *input.engine, &self.query);
        lap("robot");
        // 3. The search.
        let names: Vec<String> = links.iter().map(|l| l.name.clone()).collect();
        let excluded = |c: [f32; 3]| volumes.iter().any(|v| v.contains(c));
        let max = f64::from(query.max_distance_m);
        let mut options = query.clone();
        let (views, verdicts) = self.live_views(&lattice);
        // Certified: the pairs best first (`unseen::Measure`); exact: the engine, which
        // refines its candidates on the meshes.
        let best_first = (query.mode == Mode::Certified)
            .then(|| Measure::new(&links, poses, robot.bounds(), max, ball.margin_m));
        let mut found = (self.search(&lattice, &views, &verdicts, &robot, &excluded, ball)).run(
            |centres, need, needs| {
                if let Some(m) = &best_first {
                    return Ok(m.batch(centres, need, needs));
                }
                // Only what may still lower a best is measured exactly: per link, its
                // inner-sphere distance below the link's need plus its h (−∞: final, 0);
                // without per-link needs (the robot's shadow), below the nearest's.
                options.per_link_range_m = match needs.is_empty() {
                    true => query.per_link_range_m.min(need.max(0.0) as f32),
                    false => query.per_link_range_m,
                };
                options.link_ranges_m.clear();
                (options.link_ranges_m).extend(
                    (needs.iter().zip(links.iter())).map(|(&n, l)| (n as f32 + l.gap_m).max(0.0)),
                );
                engine
                    .query(centres, &Isometry3::identity(), poses, &options)
                    .map(|r| batch(&r, max))
                    .map_err(|e| UnseenFault::Query(e.to_string()))
            },
        )?;
        lap("search");
        // 4. Why the places found are hidden: each view's robot image where their tests read it
        // (rendered whole already where the search needed it), then each view's word.
        let spots = Search::spots(&found);
        if !spots.is_empty() {
            for (_, v) in (self.sources.iter().zip(&mut self.views)).filter(|(s, _)| s.enabled) {
                if let Some(Ok(v)) = v {
                    v.render_robot_for(&spots, ball.radius_m);
                }
            }
            let (views, verdicts) = self.live_views(&lattice);
            (self.search(&lattice, &views, &verdicts, &robot, &excluded, ball))
                .name_causes(&mut found);
        }
        lap("causes");
        // 5. The facts.
        let reach = |l: f64| if l.is_finite() { l } else { max };
        Ok(UnseenFacts {
            distance_m: found.lower_m.map(|l| ball.distance(reach(l))),
            self_shadow_m: found.shadow_lower_m.map(|l| ball.distance(reach(l))),
            per_link: names
                .into_iter()
                .zip(&found.per_link)
                .map(|(n, &l)| (n, ball.distance(l)))
                .collect(),
            nearest: found.nearest,
            per_source,
            blind: false,
            cells: lattice.len(),
            resolution_m: lattice.resolution_m(),
            counts: found.counts,
            near: found.near,
            stages_s: stages,
        })
    }

    /// The enabled sources' views, with the GPU's verdicts on `lattice` where it made them.
    fn live_views(&self, lattice: &Lattice) -> (Vec<&PreparedView>, Vec<Option<&[u32]>>) {
        (self.sources.iter().zip(&self.views).zip(&self.gpu_cells))
            .filter(|((s, _), _)| s.enabled)
            .filter_map(|((_, v), g)| {
                let view = v.as_ref().and_then(|v| v.as_ref().ok())?;
                Some((view, g.verdicts_on(lattice)))
            })
            .unzip()
    }

    /// The search over `views` with the settings' capability, shadow and markers.
    fn search<'a>(
        &self,
        lattice: &'a Lattice,
        views: &'a [&'a PreparedView],
        verdicts: &'a [Option<&'a [u32]>],
        robot: &'a RobotBody,
        excluded: &'a (dyn Fn([f32; 3]) -> bool + Sync),
        size: BallSize,
    ) -> Search<'a> {
        Search {
            lattice,
            views,
            verdicts,
            robot,
            excluded,
            size,
            apart: self.settings.self_shadow == crate::config::SelfShadow::Apart,
            per_link_range_m: (self.query.per_link)
                .then_some(f64::from(self.query.per_link_range_m)),
            markers: self.markers(),
        }
    }

    /// Step 1: the lattice over the monitored volume at the frame's stamp.
    pub(super) fn place_volume(
        &mut self,
        at: &At,
        links: &[QueryLink],
    ) -> Result<Lattice, UnseenFault> {
        let (root_from_box, half) = match &self.settings.volume.clone() {
            Some(v) => {
                let root = at.kinematics.root_link().to_owned();
                let frame = v.frame.clone().unwrap_or(root);
                let root_from_frame =
                    place_frame(at, &frame, self.tf_tolerance_s).map_err(|reason| {
                        UnseenFault::VolumeFrame {
                            frame: frame.clone(),
                            reason,
                        }
                    })?;
                (
                    root_from_frame * v.frame_from_box,
                    v.size_m.map(|s| 0.5 * s),
                )
            }
            None => {
                let reach = self.reach(at.kinematics, links)?;
                let e = reach + self.settings.margin_m;
                (Isometry3::translation(0.0, 0.0, 0.5 * e), [e, e, 0.5 * e])
            }
        };
        Lattice::new(root_from_box, half, self.settings.resolution_m).map_err(UnseenFault::Lattice)
    }

    /// The exclusion volumes that apply to every source, placed in the root frame.
    fn place_volumes(&self, at: &At) -> Result<Vec<Placed>, UnseenFault> {
        (self.volumes.iter())
            .map(|v| {
                let root_from_frame =
                    place_frame(at, &v.frame, self.tf_tolerance_s).map_err(|reason| {
                        UnseenFault::ExclusionFrame {
                            volume: v.name.clone(),
                            reason,
                        }
                    })?;
                Ok(Placed::new(
                    &v.shape,
                    &(root_from_frame * v.frame_from_volume),
                ))
            })
            .collect()
    }

    /// The robot's reach from its root, computed once (`Kinematics::reach_m`).
    fn reach(&mut self, kinematics: &Kinematics, links: &[QueryLink]) -> Result<f64, UnseenFault> {
        let reach = *self.reach_m.get_or_insert_with(|| {
            let radii = link_radii(kinematics, links);
            kinematics.reach_m(&radii)
        });
        reach.ok_or(UnseenFault::ReachUnknown)
    }
}

/// `frame` in the root frame at the stamp (a robot link at the poses, else through TF).
fn place_frame(at: &At, frame: &str, tolerance_s: f64) -> Result<Isometry3<f64>, String> {
    let kinematics = at.kinematics;
    let link_pose = |name: &str| kinematics.link_index(name).map(|i| at.poses[i]);
    tf::root_from_sensor(
        at.tf,
        frame,
        kinematics.root_link(),
        Some(at.stamp_ns),
        tolerance_s,
        &link_pose,
    )
    .map_err(|e| e.to_string())
}

/// A query over hidden centres as the search reads it.
fn batch(r: &QueryResult, max: f64) -> Batch {
    let (lower_m, nearest) = match (&r.outcome, &r.nearest) {
        (Outcome::Nearest, Some(n)) => {
            (Some(n.lower_m.unwrap_or(0.0)), Some(n.point_index as usize))
        }
        _ => (None, None),
    };
    Batch {
        lower_m,
        nearest,
        per_link: (r.links.iter())
            .map(|l| l.lower_m.or(l.farther_than_m).unwrap_or(max))
            .collect(),
    }
}

/// Each link's bounding radius about its own origin (m): the largest `|c| + r + h` of its
/// spheres; 0 for a link the engine does not monitor.
fn link_radii(kinematics: &Kinematics, links: &[QueryLink]) -> Vec<f64> {
    let mut radii = vec![0.0; kinematics.link_names().len()];
    for l in links {
        let r = (l.spheres.iter())
            .map(|s| Point3::from(s.center.map(f64::from)).coords.norm() + f64::from(s.radius))
            .fold(0.0, f64::max);
        radii[l.pose_index] = r + f64::from(l.gap_m);
    }
    radii
}
