//! Speed and separation monitoring (SSM, ISO/TS 15066 with ISO 13855's approach speeds): from
//! the certified distance of every link and the robot's joint velocities to the speed-scaling
//! factor a `joint_trajectory_controller` obeys.
//!
//! Inputs, per cloud: the query result (per-link minima with their closest points, in the root
//! frame), every link's twist from the joint velocities at the cloud's stamp
//! ([`crate::robot::Kinematics::link_velocities`]), the age of the cloud at the decision, and
//! the factor in effect. Output: the largest factor k ∈ [0, 1] that keeps the protective
//! separation distance within the distance of every link, and the margin, approach speed and
//! time to collision of the link that limits it ([`Separation`]); then [`SpeedScaler`] applies
//! hysteresis and a rate limit to increases, per source, and publishes the smallest.
//!
//! **The protective separation distance** of a link, for the robot moving at k times its
//! nominal speed:
//!
//! S_p(k) = v_h·(T_r + T_s(k·s)) + k·v_r·T_r + S_s(k·s) + C + Z_d + Z_r
//!
//! - v_h: the human approach speed (`human_speed`, 1.6 m/s as ISO 13855 takes for walking);
//! - T_r: the reaction time, `reaction_time` plus the cloud's measured age at the decision
//!   (clock − stamp, plus the processing time): what the scene may have done since it was seen;
//! - v_r: the robot's approach speed, the velocity of the link's closest point projected on the
//!   direction to the obstacle point (negative: moving away, which is then not slowed by it);
//! - s: that point's speed, which the stopping tables are read at: T_s (stopping time) and S_s
//!   (stopping distance), piecewise linear in speed (`stopping.speeds/times/distances`, from the
//!   robot's stopping measurements; extrapolated with the last segment beyond the table);
//! - C: the intrusion distance (`intrusion_distance`, from the sensor's detection capability);
//! - Z_d: the sensor's uncertainty (`sensor_uncertainty`) plus, when the link's distance is the
//!   inner-sphere one, its certified surface gap h (nothing extra in exact mode, where the
//!   distance is the mesh's): so the rule holds for the true mesh distance in every mode;
//! - Z_r: the robot's position uncertainty (`robot_uncertainty`).
//!
//! A link whose minimum was not measured (beyond `per_link_range`, or per-link minima off) has
//! no closest point: its distance is the certified "farther than" bound and its approach speed
//! is bounded by its fastest point, the speed of its bounding ball's centre plus |ω| times the
//! ball's radius (the root node of its tree, grown by h so that it holds the mesh). Both are
//! conservative, so leaving such a link unmeasured never raises the factor.
//!
//! **The factor.** A controller applying k scales every joint velocity by k (the trajectory's
//! time runs k times as fast), so v_r and s scale by k. The joint velocities measured already
//! carry the factor in effect k₀; the nominal motion is the measured one divided by k₀
//! (`velocities_scaled`, on by default; if the controller does not apply the factor the nominal
//! motion is overestimated, which only lowers the factor). k is the largest value such that
//! S_p(k') ≤ d for every k' ∈ [0, k]: S_p is piecewise linear in k, so the segments between the
//! tables' breakpoints are scanned from 0 up and the first crossing solved exactly. When S_p(0)
//! already exceeds d — the person is within the distance a stopped robot needs — k is 0. The
//! factor published is the smallest over the links.
//!
//! **Faults** (no distance: a fault of the frame, a cloud the self-filter emptied; no joint
//! velocity; SSM on with no distance) give 0 at once. Increases are held back: the factor rises
//! only when the allowed value exceeds it by `hysteresis`, and then by at most
//! `max_increase_rate` per second of stamp time; decreases take effect at once.
//!
//! Cost: one twist per link (forward pass over the joints) and a few dozen flops per link,
//! microseconds per cloud (`ist_monitor bench ssm`).

use nalgebra::{Isometry3, Point3, Vector3};

use crate::query::{Mode, QueryLink, QueryResult};
use crate::robot::LinkVelocity;
use crate::tf::VelocitySource;

/// Lowest factor in effect that the measured velocities are divided by (a controller at 0
/// still reports the motion of its deceleration, whose nominal speed would be unbounded).
const MIN_FACTOR_IN_EFFECT: f64 = 0.01;

/// Stopping time and distance against speed, piecewise linear.
#[derive(Debug, Clone, PartialEq)]
pub struct StoppingTable {
    /// Speeds of the closest point, m/s: from 0, strictly increasing.
    pub speeds_mps: Vec<f64>,
    /// Stopping time T_s at each speed, s: ≥ 0, non-decreasing.
    pub times_s: Vec<f64>,
    /// Stopping distance S_s at each speed, m: ≥ 0, non-decreasing.
    pub distances_m: Vec<f64>,
}

impl StoppingTable {
    /// Checks the table; the message names the list at fault.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let n = self.speeds_mps.len();
        if n == 0 || self.speeds_mps[0] != 0.0 {
            return Err(("speeds", "must start at 0".into()));
        }
        if self.speeds_mps.windows(2).any(|w| w[1] <= w[0]) {
            return Err(("speeds", "must increase strictly".into()));
        }
        for (name, list) in [("times", &self.times_s), ("distances", &self.distances_m)] {
            if list.len() != n {
                return Err((name, format!("{} values for {n} speeds", list.len())));
            }
            if list.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err((name, "values must be finite and ≥ 0".into()));
            }
            if list.windows(2).any(|w| w[1] < w[0]) {
                return Err((name, "must not decrease with speed".into()));
            }
        }
        Ok(())
    }

    /// A table of one stopping time and distance at every speed.
    pub fn constant(time_s: f64, distance_m: f64) -> Self {
        Self {
            speeds_mps: vec![0.0],
            times_s: vec![time_s],
            distances_m: vec![distance_m],
        }
    }

    /// (T_s, S_s) at `speed` ≥ 0: interpolated, or extrapolated with the last segment.
    pub fn at(&self, speed: f64) -> (f64, f64) {
        let v = &self.speeds_mps;
        let n = v.len();
        if n == 1 {
            return (self.times_s[0], self.distances_m[0]);
        }
        let i = v.partition_point(|&x| x <= speed).clamp(1, n - 1);
        let w = (speed - v[i - 1]) / (v[i] - v[i - 1]);
        let lerp = |y: &[f64]| y[i - 1] + w * (y[i] - y[i - 1]);
        (lerp(&self.times_s), lerp(&self.distances_m))
    }
}

/// The SSM parameters (`speed_scaling.*`).
#[derive(Debug, Clone, PartialEq)]
pub struct SsmParams {
    /// Publish `~/speed_scaling`.
    pub enabled: bool,
    /// v_h, m/s.
    pub human_speed_mps: f64,
    /// T_r without the cloud's age, s.
    pub reaction_time_s: f64,
    pub stopping: StoppingTable,
    /// C, m.
    pub intrusion_distance_m: f64,
    /// Z_d without the surface gap, m.
    pub sensor_uncertainty_m: f64,
    /// Z_r, m.
    pub robot_uncertainty_m: f64,
    /// An increase is applied only when the allowed factor exceeds the current one by this.
    pub hysteresis: f64,
    /// Largest increase per second.
    pub max_increase_rate_per_s: f64,
    /// The measured joint velocities already carry the factor in effect.
    pub velocities_scaled: bool,
}

impl Default for SsmParams {
    /// The declared defaults (`config::PARAMETERS`; a test there checks they agree).
    fn default() -> Self {
        Self {
            enabled: true,
            human_speed_mps: 1.6,
            reaction_time_s: 0.1,
            stopping: StoppingTable {
                speeds_mps: vec![0.0, 1.0],
                times_s: vec![0.0, 0.3],
                distances_m: vec![0.0, 0.15],
            },
            intrusion_distance_m: 0.0,
            sensor_uncertainty_m: 0.02,
            robot_uncertainty_m: 0.01,
            hysteresis: 0.05,
            max_increase_rate_per_s: 0.5,
            velocities_scaled: true,
        }
    }
}

/// One link as SSM sees it, at the nominal motion (factor 1).
#[derive(Debug, Clone, PartialEq)]
pub struct LinkConstraint {
    pub link: String,
    /// The distance the rule is held against: the inner-sphere distance, the exact one, or a
    /// certified "farther than" bound, m.
    pub distance_m: f64,
    /// Z_d: the sensor's uncertainty, plus h where `distance_m` is an inner-sphere distance.
    pub z_d_m: f64,
    /// v_r at the nominal motion, m/s (positive: approaching).
    pub approach_mps: f64,
    /// The closest point's speed at the nominal motion, m/s.
    pub speed_mps: f64,
    /// Whether v_r comes from the link's closest point (else: bounded by its fastest point).
    pub witnessed: bool,
    /// The link of the nearest obstacle point.
    pub nearest: bool,
    /// Held to the distance to unseen space (`protect`), nearer than the seen one.
    pub unseen: bool,
}

impl SsmParams {
    /// S_p for a link moving with approach speed `approach` and point speed `speed` (m/s, the
    /// motion as it is), reaction time `reaction_s`, sensor term `z_d`.
    pub fn protective_distance(&self, reaction_s: f64, approach: f64, speed: f64, z_d: f64) -> f64 {
        let (t_s, s_s) = self.stopping.at(speed.max(0.0));
        self.human_speed_mps * (reaction_s + t_s)
            + approach * reaction_s
            + s_s
            + self.intrusion_distance_m
            + z_d
            + self.robot_uncertainty_m
    }

    /// The largest k ∈ [0, 1] with S_p(k') ≤ `c.distance_m` for every k' ∈ [0, k], the link
    /// moving at k times its nominal motion.
    pub fn allowed_factor(&self, c: &LinkConstraint, reaction_s: f64) -> f64 {
        let g = |k: f64| {
            self.protective_distance(reaction_s, k * c.approach_mps, k * c.speed_mps, c.z_d_m)
                - c.distance_m
        };
        // Breakpoints of the piecewise-linear S_p: where k·s crosses a table speed.
        let mut ks: Vec<f64> = vec![0.0, 1.0];
        if c.speed_mps > 0.0 {
            ks.extend(
                self.stopping
                    .speeds_mps
                    .iter()
                    .map(|v| v / c.speed_mps)
                    .filter(|k| *k > 0.0 && *k < 1.0),
            );
        }
        ks.sort_by(f64::total_cmp);
        // Exceeds d, or cannot be told (NaN): not allowed.
        let exceeds = |g: f64| g > 0.0 || g.is_nan();
        let mut k0 = 0.0;
        let mut g0 = g(0.0);
        if exceeds(g0) {
            return 0.0;
        }
        for &k1 in &ks[1..] {
            let g1 = g(k1);
            if exceeds(g1) {
                // Linear on [k0, k1]: the crossing, rounded down by a hair so that S_p at the
                // factor never exceeds d by rounding.
                let k = k0 + (k1 - k0) * (g0 / (g0 - g1));
                return (k * (1.0 - 1e-9)).clamp(k0, k1);
            }
            (k0, g0) = (k1, g1);
        }
        1.0
    }
}

/// What SSM found in one frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Separation {
    /// The factor every link allows (before hysteresis and rate limit).
    pub allowed: f64,
    /// The link that sets it (the least margin when every link allows 1).
    pub link: String,
    /// That link's distance the rule is held against (see [`LinkConstraint::distance_m`]), m.
    pub distance_m: f64,
    /// S_p of that link at the motion as measured, m.
    pub protective_m: f64,
    /// Its distance minus S_p, m: negative is a violation at the present speed.
    pub margin_m: f64,
    /// Its v_r as measured, m/s.
    pub approach_mps: f64,
    /// v_r as measured at the closest point of the link nearest to the obstacles (which need
    /// not be the link that limits the factor), m/s.
    pub nearest_approach_mps: Option<f64>,
    /// Its distance less Z_d, over v_h + v_r: when the gap closes if the person comes at v_h and
    /// the robot keeps its motion (infinite when they separate), s.
    pub time_to_collision_s: f64,
    pub reaction_s: f64,
    pub velocity_source: VelocitySource,
    /// That link's distance is to unseen space (`unobserved: protect`), not to a point seen.
    pub unseen: bool,
}

/// Every link's constraint at the nominal motion, from a query result. `twists` are the links'
/// velocities as measured (indexed like the kinematics' links), `poses` their poses, `scale`
/// the factor the measured motion is divided by.
pub fn constraints(
    params: &SsmParams,
    result: &QueryResult,
    links: &[QueryLink],
    poses: &[Isometry3<f64>],
    twists: &[LinkVelocity],
    scale: f64,
) -> Vec<LinkConstraint> {
    let nearest = result.nearest.as_ref();
    let exact = result.mode == Mode::Exact;
    let z = params.sensor_uncertainty_m;
    links
        .iter()
        .enumerate()
        .map(|(l, link)| {
            let h = f64::from(link.gap_m);
            let twist = &twists[link.pose_index];
            let is_nearest = nearest.is_some_and(|n| n.link == link.name);
            let nearest_witness = nearest
                .filter(|_| is_nearest)
                .map(|n| (n.point_root, n.robot_point_root));
            // (distance, Z_d, closest points).
            let (distance_m, z_d_m, witness) = match (result.links.get(l), nearest) {
                (Some(ld), _) => match (ld.exact_m, ld.distance_m, ld.farther_than_m) {
                    (Some(e), _, _) => (e, z, nearest_witness),
                    (None, Some(d), _) => (d, z + h, ld.witness),
                    (None, None, Some(f)) => (f, z + h, None),
                    _ => (f64::from(result.max_distance_m), z + h, None),
                },
                // Per-link minima off: every link is at least as far as the nearest one.
                (None, Some(n)) => {
                    let z_d = if exact { z } else { z + h };
                    (n.distance_m, z_d, nearest_witness)
                }
                (None, None) => (f64::from(result.max_distance_m), z + h, None),
            };
            let (approach, speed, witnessed) = match witness {
                Some((obstacle, robot)) => {
                    let (o, r) = (Vector3::from(obstacle), Vector3::from(robot));
                    let v = twist.at(&r);
                    match (o - r).try_normalize(1e-9) {
                        Some(n) => (v.dot(&n), v.norm(), true),
                        None => (v.norm(), v.norm(), true),
                    }
                }
                None => {
                    let b = fastest_point_speed(link, &poses[link.pose_index], twist);
                    (b, b, false)
                }
            };
            LinkConstraint {
                link: link.name.clone(),
                distance_m,
                z_d_m,
                approach_mps: approach / scale,
                speed_mps: speed / scale,
                witnessed,
                nearest: is_nearest,
                unseen: false,
            }
        })
        .collect()
}

/// A bound of the speed of `link`'s fastest point (m/s): its root sphere's centre's speed plus
/// the rotation's over the sphere's radius and h.
fn fastest_point_speed(link: &QueryLink, pose: &Isometry3<f64>, twist: &LinkVelocity) -> f64 {
    let root = &link.nodes[0];
    let c = pose * Point3::from(root.center.map(f64::from));
    let h = f64::from(link.gap_m);
    twist.at(&c.coords).norm() + twist.angular.norm() * (f64::from(root.radius) + h)
}

/// Holds each link to its distance to unseen space (`unseen`, m, the engine's order) where
/// that is nearer than its constraint's (`unobserved: protect`, issue 55). The unseen distance
/// is a certified lower bound (h already subtracted), so Z_d is the sensor's uncertainty alone;
/// a hidden body may lie in any direction, so v_r is the link's fastest point's speed, not a
/// witness's.
pub fn tighten_by_unseen(
    params: &SsmParams,
    constraints: &mut [LinkConstraint],
    unseen: &[f64],
    links: &[QueryLink],
    poses: &[Isometry3<f64>],
    twists: &[LinkVelocity],
    scale: f64,
) {
    for ((c, &d), link) in constraints.iter_mut().zip(unseen).zip(links) {
        if d < c.distance_m {
            let b = fastest_point_speed(link, &poses[link.pose_index], &twists[link.pose_index]);
            c.distance_m = d;
            c.z_d_m = params.sensor_uncertainty_m;
            c.approach_mps = b / scale;
            c.speed_mps = b / scale;
            c.witnessed = false;
            c.unseen = true;
        }
    }
}

/// The factor every link allows, and the figures of the link that limits it. `scale` is the
/// factor the constraints' nominal motion was divided by (the measured motion is `scale` times
/// it).
pub fn separation(
    params: &SsmParams,
    constraints: &[LinkConstraint],
    reaction_s: f64,
    scale: f64,
    velocity_source: VelocitySource,
) -> Option<Separation> {
    let measured = |c: &LinkConstraint| {
        let sp = params.protective_distance(
            reaction_s,
            scale * c.approach_mps,
            scale * c.speed_mps,
            c.z_d_m,
        );
        (sp, c.distance_m - sp)
    };
    // (link, allowed factor, S_p and margin as measured), the least factor, then least margin.
    let (c, allowed, (protective_m, margin_m)) = constraints
        .iter()
        .map(|c| (c, params.allowed_factor(c, reaction_s), measured(c)))
        .min_by(|(_, ka, (_, ma)), (_, kb, (_, mb))| ka.total_cmp(kb).then(ma.total_cmp(mb)))?;
    let approach = scale * c.approach_mps;
    let closing = params.human_speed_mps + approach;
    let gap = (c.distance_m - c.z_d_m).max(0.0);
    Some(Separation {
        allowed,
        link: c.link.clone(),
        distance_m: c.distance_m,
        protective_m,
        margin_m,
        approach_mps: approach,
        nearest_approach_mps: constraints
            .iter()
            .find(|c| c.nearest && c.witnessed)
            .map(|c| scale * c.approach_mps),
        time_to_collision_s: if closing > 0.0 {
            gap / closing
        } else {
            f64::INFINITY
        },
        reaction_s,
        velocity_source,
        unseen: c.unseen,
    })
}

/// One frame's speed scaling: the factor published and what set it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpeedScaling {
    /// Published on `~/speed_scaling`: after hysteresis and rate limit, the smallest over the
    /// sources.
    pub factor: f64,
    /// This frame's separation, or why there is none (the factor is then 0).
    pub separation: Result<Separation, String>,
    /// Time of the SSM stage (velocities, twists, constraints, factor), s.
    pub stage_s: f64,
}

/// The factor the measured motion is divided by, given the factor in effect.
pub fn nominal_scale(params: &SsmParams, in_effect: f64) -> f64 {
    if params.velocities_scaled {
        in_effect.max(MIN_FACTOR_IN_EFFECT)
    } else {
        1.0
    }
}

/// The published factor: per source, decreases at once and increases held back (hysteresis,
/// rate limit); the smallest over the enabled sources is published. An enabled source starts
/// at 0, so the robot is released only by a frame that allows it; a disabled one never limits.
#[derive(Debug, Clone)]
pub struct SpeedScaler {
    hysteresis: f64,
    rate_per_s: f64,
    /// Per source: the factor and the stamp it was set at.
    state: Vec<(f64, Option<i64>)>,
}

impl SpeedScaler {
    /// A scaler for sources that are `enabled` or not.
    pub fn new(params: &SsmParams, enabled: &[bool]) -> Self {
        let mut state: Vec<(f64, Option<i64>)> = enabled
            .iter()
            .map(|&on| (if on { 0.0 } else { 1.0 }, None))
            .collect();
        if !enabled.iter().any(|&on| on) {
            // Nothing watches the scene: nothing may release the robot.
            state.push((0.0, None));
        }
        Self {
            hysteresis: params.hysteresis,
            rate_per_s: params.max_increase_rate_per_s,
            state,
        }
    }

    /// Takes new enabled flags (a run-time change): a source enabled now starts at 0, as at
    /// start, one disabled no longer limits; a source that stays keeps its factor.
    pub fn set_enabled(&mut self, was: &[bool], enabled: &[bool]) {
        let mut state: Vec<(f64, Option<i64>)> = enabled
            .iter()
            .enumerate()
            .map(
                |(k, &on)| match (on, was.get(k).copied().unwrap_or(false)) {
                    (true, true) => self.state.get(k).copied().unwrap_or((0.0, None)),
                    (true, false) => (0.0, None),
                    (false, _) => (1.0, None),
                },
            )
            .collect();
        if !enabled.iter().any(|&on| on) {
            state.push((0.0, None));
        }
        self.state = state;
    }

    /// The factor published now (the smallest over the sources).
    pub fn factor(&self) -> f64 {
        self.state.iter().map(|s| s.0).fold(1.0, f64::min)
    }

    /// Source `source`'s frame allows at most `allowed` (`None`: a fault, 0), by outputs that go
    /// before the frame's last word (its seen outputs, before the unseen pass under `protect`):
    /// a lower factor is taken at once, a higher one waits for [`SpeedScaler::update`] with the
    /// frame's whole picture. Returns the factor published.
    pub fn lower(&mut self, source: usize, allowed: Option<f64>) -> f64 {
        if let Some((current, _)) = self.state.get_mut(source) {
            let target = allowed.filter(|k| k.is_finite()).unwrap_or(0.0);
            *current = current.min(target.clamp(0.0, 1.0));
        }
        self.factor()
    }

    /// Source `source`'s frame stamped `stamp_ns` allows `allowed` (`None`: a fault, 0);
    /// returns the factor published.
    pub fn update(&mut self, source: usize, stamp_ns: i64, allowed: Option<f64>) -> f64 {
        let Some((current, last)) = self.state.get_mut(source) else {
            return self.factor();
        };
        let target = allowed
            .filter(|k| k.is_finite())
            .unwrap_or(0.0)
            .clamp(0.0, 1.0);
        if target < *current {
            *current = target;
        } else if target - *current >= self.hysteresis || (target >= 1.0 && *current < 1.0) {
            let dt_s = last.map_or(0.0, |t| (stamp_ns - t) as f64 * 1e-9).max(0.0);
            *current = (*current + self.rate_per_s * dt_s).min(target);
        }
        *last = Some(stamp_ns);
        self.factor()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(distance: f64, approach: f64, speed: f64) -> LinkConstraint {
        LinkConstraint {
            link: "l".into(),
            distance_m: distance,
            z_d_m: 0.02,
            approach_mps: approach,
            speed_mps: speed,
            witnessed: true,
            nearest: false,
            unseen: false,
        }
    }

    #[test]
    fn stopping_tables_interpolate_extrapolate_and_are_checked() {
        let t = SsmParams::default().stopping;
        assert_eq!(t.at(0.0), (0.0, 0.0));
        let (ts, ss) = t.at(0.5);
        assert!((ts - 0.15).abs() < 1e-12 && (ss - 0.075).abs() < 1e-12);
        let (ts, _) = t.at(2.0);
        assert!(
            (ts - 0.6).abs() < 1e-12,
            "extrapolated with the last segment"
        );
        let bad = StoppingTable {
            speeds_mps: vec![0.0, 1.0],
            times_s: vec![0.3, 0.1],
            distances_m: vec![0.0, 0.1],
        };
        assert_eq!(bad.validate().unwrap_err().0, "times");
        let bad = StoppingTable {
            speeds_mps: vec![0.1],
            ..bad
        };
        assert_eq!(bad.validate().unwrap_err().0, "speeds");
    }

    #[test]
    fn analytic_factor_at_the_boundary() {
        // Constant stopping time and distance: S_p(k) = v_h (T_r + T_s) + k v_r T_r + S_s + C +
        // Z_d + Z_r is linear, so the factor is where it meets d.
        let p = SsmParams {
            stopping: StoppingTable::constant(0.2, 0.05),
            ..SsmParams::default()
        };
        let t_r = 0.15;
        let base = 1.6 * (t_r + 0.2) + 0.05 + 0.0 + 0.02 + 0.01;
        let v_r = 1.2;
        let d = base + 0.4 * v_r * t_r;
        let k = p.allowed_factor(&link(d, v_r, v_r), t_r);
        assert!((k - 0.4).abs() < 1e-6, "{k}");
        // At the factor S_p equals d (within rounding), just above it exceeds d.
        let sp = |k: f64| p.protective_distance(t_r, k * v_r, k * v_r, 0.02);
        assert!(sp(k) <= d && sp(k + 1e-6) > d);
        // Moving away: the approach term is negative, nothing limits it below 1.
        assert_eq!(p.allowed_factor(&link(base, -v_r, v_r), t_r), 1.0);
        // Tangential motion (v_r = 0) at exactly the stopped robot's distance: allowed.
        assert_eq!(p.allowed_factor(&link(base + 1e-12, 0.0, v_r), t_r), 1.0);
        // Nearer than a stopped robot needs: 0, whatever the motion.
        assert_eq!(p.allowed_factor(&link(base - 0.01, -v_r, v_r), t_r), 0.0);
        // Far away: 1.
        assert_eq!(p.allowed_factor(&link(5.0, v_r, v_r), t_r), 1.0);
    }

    #[test]
    fn separation_reports_the_limiting_link_and_its_time_to_collision() {
        let p = SsmParams::default();
        let links = [
            link(2.0, 0.5, 0.5),
            link(0.6, 0.8, 1.0),
            link(0.7, -1.0, 1.0),
        ];
        let s = separation(&p, &links, 0.1, 1.0, VelocitySource::JointStates).unwrap();
        assert_eq!(s.allowed, p.allowed_factor(&links[1], 0.1));
        assert!(s.allowed > 0.0 && s.allowed < 1.0, "{}", s.allowed);
        assert!((s.approach_mps - 0.8).abs() < 1e-12);
        let sp = p.protective_distance(0.1, 0.8, 1.0, 0.02);
        assert!((s.margin_m - (0.6 - sp)).abs() < 1e-12 && s.margin_m < 0.0);
        assert!((s.time_to_collision_s - (0.6 - 0.02) / (1.6 + 0.8)).abs() < 1e-12);
    }

    #[test]
    fn the_scaler_drops_at_once_and_rises_slowly() {
        let p = SsmParams::default();
        let ms = 1_000_000;
        // A disabled source never limits; with none enabled nothing releases the robot.
        let mut s = SpeedScaler::new(&p, &[true, false]);
        s.update(0, 0, Some(1.0));
        s.update(0, 2000 * ms, Some(1.0));
        assert_eq!(s.factor(), 1.0);
        assert_eq!(SpeedScaler::new(&p, &[false]).factor(), 0.0);
        let mut s = SpeedScaler::new(&p, &[true, true]);
        assert_eq!(s.factor(), 0.0, "starts stopped");
        s.update(0, 0, Some(1.0));
        s.update(1, 0, Some(1.0));
        assert_eq!(s.factor(), 0.0, "no time has passed");
        s.update(0, 100 * ms, Some(1.0));
        assert_eq!(
            s.update(1, 100 * ms, Some(1.0)),
            0.05,
            "0.5 per s for 0.1 s"
        );
        for i in 2..=30 {
            s.update(0, i * 100 * ms, Some(1.0));
            s.update(1, i * 100 * ms, Some(1.0));
        }
        assert_eq!(s.factor(), 1.0);
        // A drop on one source is published at once; a fault is 0.
        assert_eq!(s.update(1, 3100 * ms, Some(0.3)), 0.3);
        assert_eq!(s.update(0, 3100 * ms, None), 0.0);
        // Within the hysteresis nothing rises.
        s.update(0, 3200 * ms, Some(0.3));
        s.update(0, 3300 * ms, Some(0.3));
        s.update(1, 3400 * ms, Some(0.33));
        assert_eq!(s.state[1].0, 0.3, "0.33 is within the hysteresis of 0.3");
    }
}
