//! The cell's unobserved space (issue 45), fused over every enabled source's latest measured
//! frame as the distances are: what no source has seen free inside the monitored volume, and a
//! certified lower bound of the distance from the robot to a body of the detection capability
//! hidden there. The algorithm is the `unseen` stage's (its module doc); this file wires it:
//!
//! 1. Each measured frame leaves its source's [`RangeView`] (`view_of`): a depth image through
//!    its camera model, an organized cloud with the intrinsics fitted from its points (taken
//!    before the exclusion volumes drop theirs: an excluded point is still a return), placed
//!    by the sensor's pose at its stamp. An unorganized cloud observes nothing free, and says
//!    so in `/diagnostics`.
//! 2. After each measured frame (`Monitor::unobserved`): the lattice over `monitored_volume`
//!    (its frame placed at the frame's stamp; by default the robot's reach plus a margin above
//!    the root's z = 0 plane, taken as the floor); the robot's padded cells at the frame's poses
//!    (each inner sphere grown by the self-filter padding and its link's surface gap h) and the
//!    pixels that returned on them; the observation over every live view; the robot's cells and
//!    the exclusion volumes that apply to every source dropped; the opening by the detection
//!    capability; the inner sphere trees' certified lower bound over the opened cells' centres,
//!    less the cell diagonal and the pixel slack (per link, too).
//! 3. **The robot's own shadow** (`unobserved_self_shadow`): `count` treats it as any unseen
//!    space — a cell counts wherever no camera saw it free, so two cameras that see into each
//!    other's shadows close it, and with one camera the unseen distance is about zero beside the
//!    arm (a safety engineer should read that as: one camera cannot watch behind the arm).
//!    `apart` opens the unseen cells outside the shadow on their own, reports the shadow's
//!    distance as `self_shadow_distance`, and leaves it out of `~/unseen_distance` and of
//!    `protect`: the stated assumption that nothing of the detection capability hides in the
//!    robot's shadow (e.g. it could only have come there through space a camera sees).
//!
//! What it gives ([`Unseen`]) goes to the fusion (`protect`: the level takes the smaller of the
//! two distances; a failure here is then a fault) and to the outputs. Cost: see `unseen`; the
//! time of each pass is in [`Unseen::compute_s`] and in `/diagnostics`.

use std::time::Instant;

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::cloud::depth::{DepthView, PinholeCamera};
use crate::cloud::exclusion::Placed;
use crate::config::{SelfShadow, Unobserved};
use crate::query::{Mode, Outcome, QueryOptions, QueryResult};
use crate::robot::Kinematics;
use crate::tf;
use crate::unseen::{
    flag_robot_pixels, observe, open, place, robot_cells, robot_lattice, unseen_distance, Lattice,
    Opened, PaddedSphere, RangeView, RobotCells,
};

use super::pipeline::Monitor;
use super::unseen_state::{Unseen, UnseenFacts};

/// The view of a depth image `depth` of `camera`, or of an organized cloud `points` of `width`
/// per row, placed by `root_from_sensor`; why a cloud observes nothing free otherwise.
pub(super) fn view_of(
    depth: Option<(&DepthView, &PinholeCamera)>,
    cloud: Option<(&[[f32; 3]], Option<usize>)>,
    root_from_sensor: &Isometry3<f64>,
    range_noise_m: f64,
) -> Result<RangeView, String> {
    let made = match (depth, cloud) {
        (Some((d, camera)), _) => {
            RangeView::from_depth(d, camera, *root_from_sensor, range_noise_m)
        }
        (None, Some((points, width))) => {
            let w = width.unwrap_or(points.len());
            let h = points.len().checked_div(w).unwrap_or(0);
            // Its points outside the range limits are NaN already (`measure`).
            RangeView::from_organized_cloud(
                points,
                w as u32,
                h as u32,
                *root_from_sensor,
                None,
                range_noise_m,
            )
        }
        (None, None) => return Err("no points".into()),
    };
    made.map_err(|e| e.to_string())
}

impl Monitor {
    /// The unobserved space after a measured frame stamped `stamp_ns`, the robot at `poses`.
    pub(super) fn unobserved(&mut self, stamp_ns: i64, poses: &[Isometry3<f64>]) -> Unseen {
        let start = Instant::now();
        let outcome = self.unobserved_facts(stamp_ns, poses);
        Unseen {
            stamp_ns,
            outcome,
            compute_s: start.elapsed().as_secs_f64(),
        }
    }

    fn unobserved_facts(
        &mut self,
        stamp_ns: i64,
        poses: &[Isometry3<f64>],
    ) -> Result<UnseenFacts, String> {
        let u = self.config.unobserved.clone();
        let lattice = self.lattice(&u, stamp_ns, poses)?;
        if let Some(blind) = self.all_blind(&lattice) {
            return Ok(blind);
        }
        let clock = Instant::now();
        let mut stages = Vec::with_capacity(5);
        let mut lap = |name: &'static str| stages.push((name, clock.elapsed().as_secs_f64()));
        let spheres = self.padded_spheres(poses);
        // The robot's cells over its own box: its pixels wherever it reaches, and the
        // monitored cells its padded body takes (a cell centre in a robot cell).
        let robot_lattice = match robot_lattice(&spheres, u.resolution_m) {
            Some(l) => l.map_err(|e| format!("the robot's own lattice: {e}"))?,
            None => return Err("the robot has no inner spheres".into()),
        };
        let robot = robot_cells(&robot_lattice, &spheres);
        lap("robot");
        // Every enabled source's view, its robot pixels flagged at these poses.
        let mut per_source = Vec::new();
        let mut seeing = Vec::new();
        for (k, s) in self.config.sources.iter().enumerate() {
            if !s.enabled {
                continue;
            }
            match self.sources[k].view_mut() {
                Some(Ok(view)) => {
                    flag_robot_pixels(view, &robot_lattice, &robot);
                    seeing.push(per_source.len());
                    per_source.push((s.name.clone(), Ok(0.0)));
                }
                Some(Err(e)) => per_source.push((s.name.clone(), Err(e.clone()))),
                None => per_source.push((s.name.clone(), Err("no measured frame".into()))),
            }
        }
        let views: Vec<&RangeView> = (self.config.sources.iter().zip(&self.sources))
            .filter(|(s, _)| s.enabled)
            .filter_map(|(_, source)| source.view().and_then(|v| v.as_ref().ok()))
            .collect();
        let mut obs = observe(&lattice, &views);
        lap("observe");
        for (&k, f) in seeing.iter().zip(&obs.observed_fraction_per_view) {
            per_source[k].1 = Ok(*f);
        }
        let body = RobotCells::new(&robot_lattice, &robot);
        obs.drop_where(&lattice, |_, c| body.contains(c));
        let volumes = self.shared_volumes(stamp_ns, poses)?;
        obs.drop_excluded(&lattice, &volumes);
        lap("drop");
        let unseen_cells = obs.unseen_count();
        let shadow_cells = obs.self_shadow.iter().filter(|&&s| s).count();
        let pitch = obs.pixel_pitch_m;
        let capability = u.detection_capability_m;
        let all = open(&lattice, &obs.unseen, pitch, capability).map_err(|e| e.to_string())?;
        let counted = match u.self_shadow {
            SelfShadow::Count => all.clone(),
            SelfShadow::Apart => open(&lattice, &obs.beyond_self_shadow(), pitch, capability)
                .map_err(|e| e.to_string())?,
        };
        lap("open");
        let options = self.unseen_query_options();
        let max = f64::from(options.max_distance_m);
        let engine = &mut self.engine;
        // The distance over `opened` (∩ `subset`), and per link: one query over its centres.
        let mut bound = |opened: &Opened, subset: &[bool]| -> Result<Bound, String> {
            let mut result = None;
            let d = unseen_distance(&lattice, opened, Some(subset), |centres| {
                let r = engine.query(centres, &Isometry3::identity(), poses, &options);
                let d = r.as_ref().ok().map_or(0.0, |r| lower_bound(r, max));
                result = Some(r);
                d
            });
            let per_link = match result {
                Some(r) => (r
                    .map_err(|e| format!("the query over the unseen cells failed: {e}"))?)
                .links
                .iter()
                .map(|l| {
                    let lower = l.lower_m.or(l.farther_than_m).unwrap_or(max);
                    (l.link.clone(), (lower - opened.margin_m).max(0.0))
                })
                .collect(),
                None => Vec::new(),
            };
            Ok(Bound {
                distance_m: d,
                per_link,
            })
        };
        // The shadow and the rest apart, so that `count` queries each opened cell once.
        let shadow = bound(&all, &obs.self_shadow)?;
        let rest = match u.self_shadow {
            SelfShadow::Count => bound(&all, &negated(&obs.self_shadow))?,
            SelfShadow::Apart => bound(&counted, &vec![true; lattice.len()])?,
        };
        let (distance_m, per_link) = match u.self_shadow {
            SelfShadow::Count => rest.min(&shadow),
            SelfShadow::Apart => (rest.distance_m, rest.per_link),
        };
        let self_shadow_m = shadow.distance_m;
        lap("distance");
        let bounds = link_bounds(self.engine.links(), poses);
        let near_cells = near_robot(&lattice, &counted.cells, &bounds, u.markers);
        Ok(UnseenFacts {
            distance_m,
            self_shadow_m,
            per_link,
            observed_fraction: obs.observed_fraction,
            per_source,
            cells: lattice.len(),
            unseen_cells,
            shadow_cells,
            opened_cells: counted.count,
            resolution_m: lattice.resolution_m(),
            near_cells,
            stages_s: {
                lap("markers");
                // Each stage's own time, from the laps.
                let mut last = 0.0;
                stages
                    .into_iter()
                    .map(|(n, t)| {
                        let d = t - last;
                        last = t;
                        (n, d)
                    })
                    .collect()
            },
        })
    }

    /// When no enabled source observes anything free (none has a view: unorganized clouds,
    /// no frame yet), the whole volume is unseen: its distance is taken as 0, a lower bound
    /// whatever the robot's pose, without the pass's cost.
    fn all_blind(&self, lattice: &Lattice) -> Option<UnseenFacts> {
        let enabled = || (self.config.sources.iter().zip(&self.sources)).filter(|(s, _)| s.enabled);
        if enabled().any(|(_, source)| matches!(source.view(), Some(Ok(_)))) {
            return None;
        }
        let per_source = enabled()
            .map(|(s, source)| {
                let why = match source.view() {
                    Some(Err(e)) => e.clone(),
                    _ => "no measured frame".into(),
                };
                (s.name.clone(), Err(why))
            })
            .collect();
        Some(UnseenFacts {
            distance_m: Some(0.0),
            self_shadow_m: None,
            per_source,
            cells: lattice.len(),
            unseen_cells: lattice.len(),
            opened_cells: lattice.len(),
            resolution_m: lattice.resolution_m(),
            ..UnseenFacts::default()
        })
    }

    /// The lattice over the monitored volume at `stamp_ns`.
    fn lattice(
        &mut self,
        u: &Unobserved,
        stamp_ns: i64,
        poses: &[Isometry3<f64>],
    ) -> Result<Lattice, String> {
        let (root_from_box, half) = match &u.volume {
            Some(v) => {
                let root = self.model.kinematics.root_link().to_owned();
                let frame = v.frame.clone().unwrap_or_else(|| root.clone());
                let root_from_frame = self
                    .place_frame(&frame, stamp_ns, poses)
                    .map_err(|e| format!("monitored_volume.frame {frame}: {e}"))?;
                (
                    root_from_frame * v.frame_from_box,
                    v.size_m.map(|s| 0.5 * s),
                )
            }
            None => {
                let reach = self.reach()?;
                let e = reach + u.margin_m;
                (Isometry3::translation(0.0, 0.0, 0.5 * e), [e, e, 0.5 * e])
            }
        };
        Lattice::new(root_from_box, half, u.resolution_m).map_err(|e| e.to_string())
    }

    /// `frame` in the root frame at `stamp_ns` (a robot link at `poses`, else through TF).
    fn place_frame(
        &self,
        frame: &str,
        stamp_ns: i64,
        poses: &[Isometry3<f64>],
    ) -> Result<Isometry3<f64>, String> {
        let kinematics = &self.model.kinematics;
        let link_pose = |name: &str| kinematics.link_index(name).map(|i| poses[i]);
        tf::root_from_sensor(
            &self.tf,
            frame,
            kinematics.root_link(),
            Some(stamp_ns),
            self.config.tf_tolerance_s,
            &link_pose,
        )
        .map_err(|e| e.to_string())
    }

    /// The robot's reach from its root, computed once (`Kinematics::reach_m`).
    fn reach(&mut self) -> Result<f64, String> {
        if self.unseen.reach_m.is_none() {
            let radii = link_radii(&self.model.kinematics, self.engine.links());
            self.unseen.reach_m = Some(self.model.kinematics.reach_m(&radii).ok_or_else(|| {
                "a prismatic joint has no limits, so the robot's reach is not known: set \
                 monitored_volume.size"
                    .to_string()
            }));
        }
        self.unseen.reach_m.clone().unwrap_or(Err(String::new()))
    }

    /// The inner spheres (those of a quarter cell or more) in the root frame, padded by the
    /// self-filter padding and their link's h.
    fn padded_spheres(&self, poses: &[Isometry3<f64>]) -> Vec<PaddedSphere> {
        let padding = self.config.query.self_filter_padding_m.unwrap_or(0.0);
        // Spheres under a quarter cell add little to cells that reach half a diagonal beyond
        // the padding; leaving them out only leaves a cell unseen, or a pixel not the robot's:
        // the conservative side.
        let smallest = (0.25 * self.config.unobserved.resolution_m) as f32;
        (self.engine.links().iter())
            .flat_map(|l| {
                let pose = poses[l.pose_index];
                let spheres = l.spheres.iter().filter(move |s| s.radius >= smallest);
                spheres.map(move |s| PaddedSphere {
                    centre: place(&pose, s.center),
                    radius: s.radius,
                    padding: padding + l.gap_m,
                })
            })
            .collect()
    }

    /// The exclusion volumes that apply to every source, placed in the root frame.
    fn shared_volumes(
        &self,
        stamp_ns: i64,
        poses: &[Isometry3<f64>],
    ) -> Result<Vec<Placed>, String> {
        (self.config.exclusion_volumes.iter())
            .filter(|v| v.sources.is_empty())
            .map(|v| {
                let root_from_frame = self
                    .place_frame(&v.frame, stamp_ns, poses)
                    .map_err(|e| format!("exclusion volume {}: {e}", v.name))?;
                Ok(Placed::new(
                    &v.shape,
                    &(root_from_frame * v.frame_from_volume),
                ))
            })
            .collect()
    }

    /// The query over the unseen cells: a certified lower bound (the certified mode at least),
    /// no self-filter (the robot's cells are dropped already), per link as configured.
    fn unseen_query_options(&self) -> QueryOptions {
        let mut options = self.config.query.clone();
        if options.mode == Mode::Fast {
            options.mode = Mode::Certified;
        }
        options.self_filter_padding_m = None;
        options
    }
}

/// A distance over opened cells and its per-link values (m).
struct Bound {
    distance_m: Option<f64>,
    per_link: Vec<(String, f64)>,
}

impl Bound {
    /// The smaller of two, link by link (a side without cells has no links).
    fn min(self, other: &Bound) -> (Option<f64>, Vec<(String, f64)>) {
        let distance = match (self.distance_m, other.distance_m) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let per_link = if self.per_link.is_empty() {
            other.per_link.clone()
        } else if other.per_link.is_empty() {
            self.per_link
        } else {
            (self.per_link.into_iter().zip(&other.per_link))
                .map(|((l, a), (_, b))| (l, a.min(*b)))
                .collect()
        };
        (distance, per_link)
    }
}

/// Each flag negated.
fn negated(flags: &[bool]) -> Vec<bool> {
    flags.par_iter().map(|&f| !f).collect()
}

/// The certified lower bound of a query over cell centres (`max` where none lies within it).
fn lower_bound(r: &QueryResult, max: f64) -> f64 {
    match (&r.outcome, &r.nearest) {
        (Outcome::Nearest, Some(n)) => n.lower_m.unwrap_or(0.0),
        (Outcome::NothingWithinMaxDistance, _) => max,
        // No centre: nothing to bound (not reached: the caller gives at least one).
        _ => 0.0,
    }
}

/// Each link's bounding radius about its own origin (m): the largest `|c| + r + h` of its
/// spheres; 0 for a link the engine does not monitor.
fn link_radii(kinematics: &Kinematics, links: &[crate::query::QueryLink]) -> Vec<f64> {
    let mut radii = vec![0.0; kinematics.link_names().len()];
    for l in links {
        let r = (l.spheres.iter())
            .map(|s| Point3::from(s.center.map(f64::from)).coords.norm() + f64::from(s.radius))
            .fold(0.0, f64::max);
        radii[l.pose_index] = r + f64::from(l.gap_m);
    }
    radii
}

/// At most `most` centres of opened cells, the nearest the robot first by a cheap bound (the
/// distance to each link's bounding sphere), of a large set an even sample: for drawing only.
fn near_robot(
    lattice: &Lattice,
    opened: &[bool],
    links: &[([f32; 3], f32)],
    most: usize,
) -> Vec<[f32; 3]> {
    if most == 0 || links.is_empty() {
        return Vec::new();
    }
    // At most about `SAMPLE` cells are ranked: a large opened set is drawn thinned, evenly.
    const SAMPLE: usize = 50_000;
    let count = opened.par_iter().filter(|&&o| o).count();
    let step = count.div_ceil(SAMPLE).max(1);
    let mut near: Vec<(f32, [f32; 3])> = (opened.iter().enumerate())
        .filter(|(_, &o)| o)
        .step_by(step)
        .map(|(i, _)| {
            let c = lattice.centre(i);
            let d = (links.iter())
                .map(|(centre, radius)| {
                    let d2: f32 = (0..3).map(|a| (c[a] - centre[a]).powi(2)).sum();
                    d2.sqrt() - radius
                })
                .fold(f32::INFINITY, f32::min);
            (d, c)
        })
        .collect();
    if near.len() > most {
        near.select_nth_unstable_by(most, |a, b| a.0.total_cmp(&b.0));
        near.truncate(most);
    }
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.into_iter().map(|(_, c)| c).collect()
}

/// Each monitored link's bounding sphere in the root frame at `poses` (centre, radius).
fn link_bounds(
    links: &[crate::query::QueryLink],
    poses: &[Isometry3<f64>],
) -> Vec<([f32; 3], f32)> {
    (links.iter())
        .filter(|l| !l.spheres.is_empty())
        .map(|l| {
            let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
            for s in &l.spheres {
                for a in 0..3 {
                    lo[a] = lo[a].min(s.center[a] - s.radius);
                    hi[a] = hi[a].max(s.center[a] + s.radius);
                }
            }
            let mid: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
            let radius = (0..3).map(|a| (hi[a] - mid[a]).powi(2)).sum::<f32>().sqrt();
            (place(&poses[l.pose_index], mid), radius)
        })
        .collect()
}
