//! What a query returns ([`QueryResult`]): how it ended, the nearest obstacle point and link,
//! the per-link minima with their certified lower bounds (m), and how many points each stage
//! left out ([`StageCounts`]). Assembled by `finish.rs`, the same for both backends.

use serde::Serialize;

use super::options::{Backend, Mode};

/// How the query ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// A nearest obstacle point was found within `max_distance_m`.
    Nearest,
    /// The cloud had no valid point.
    NoPoints,
    /// Valid points, but none within `max_distance_m` (after the self-filter).
    NothingWithinMaxDistance,
}

/// How many points each stage dropped. `total = invalid + outside_roi + self_filtered + pruned
/// + evaluated`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StageCounts {
    pub total: u64,
    /// NaN, infinite or (0, 0, 0).
    pub invalid: u64,
    /// Farther than `max_distance_m` from the robot's bounding box.
    pub outside_roi: u64,
    /// The robot itself (within the self-filter padding).
    pub self_filtered: u64,
    /// Dropped by the shared bound before any tree descent.
    pub pruned: u64,
    /// Descended at least one tree.
    pub evaluated: u64,
    /// Obstacle points inside the robot (distance 0): inside an inner sphere (all modes), or
    /// inside a collision mesh among the exact candidates (exact mode).
    pub inside: u64,
    /// Exact point–mesh distances computed (exact mode).
    pub exact_refined: u64,
}

impl std::ops::Add for StageCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            total: self.total + o.total,
            invalid: self.invalid + o.invalid,
            outside_roi: self.outside_roi + o.outside_roi,
            self_filtered: self.self_filtered + o.self_filtered,
            pruned: self.pruned + o.pruned,
            evaluated: self.evaluated + o.evaluated,
            inside: self.inside + o.inside,
            exact_refined: self.exact_refined + o.exact_refined,
        }
    }
}

/// The nearest obstacle point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Nearest {
    /// The mode's distance: the inner-sphere upper bound (fast, certified) or the exact distance.
    pub distance_m: f64,
    /// The certified lower bound over all links (certified), or the exact distance (exact).
    pub lower_m: Option<f64>,
    pub link: String,
    pub point_index: u32,
    /// The cloud point, in the sensor frame.
    pub point_sensor: [f32; 3],
    /// The cloud point and the closest robot point, in the root frame.
    pub point_root: [f64; 3],
    pub robot_point_root: [f64; 3],
}

/// One link's minimum over the obstacle points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinkDistance {
    pub link: String,
    /// Inner-sphere distance (upper bound); `None` when the link was not measured: no point
    /// within `max_distance_m`, or the link lies beyond `per_link_range_m` (then
    /// `farther_than_m` says how far at least).
    pub distance_m: Option<f64>,
    /// Certified lower bound `max(0, d − h)` of the link's true distance (certified and exact
    /// modes); for a link not measured, `max(0, farther_than − h)`.
    pub lower_m: Option<f64>,
    /// For a link not measured: every obstacle point's inner-sphere distance to it exceeds this
    /// (at most `max_distance_m`).
    pub farther_than_m: Option<f64>,
    /// Exact distance, for the nearest link in exact mode.
    pub exact_m: Option<f64>,
    pub point_index: Option<u32>,
    /// For a measured link: the cloud point of its minimum and the closest point of its inner
    /// spheres to it, both in the root frame.
    pub witness: Option<([f64; 3], [f64; 3])>,
}

/// The result of one query.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QueryResult {
    pub mode: Mode,
    /// Where it ran.
    pub backend: Backend,
    pub outcome: Outcome,
    pub max_distance_m: f32,
    pub nearest: Option<Nearest>,
    /// Per-link minima (only when `per_link`), in the engine's link order.
    pub links: Vec<LinkDistance>,
    pub counts: StageCounts,
    /// The links the self-filtered points were taken as (a link within the padding: on the CPU
    /// the one that took the point before it if it does, else the first in engine order; on the
    /// GPU the first in engine order), with their counts; links with none are left out.
    pub self_filtered_by_link: Vec<(String, u64)>,
    /// The spacing of the cloud's f32 coordinates where the robot is, m: every point is known to
    /// within √3/2 of it, and the interval holds for the points as given.
    pub point_spacing_m: f32,
    /// Points the monitor's stray-point filter rejected (`config::StrayFilter`; 0 here).
    pub stray_rejected: u64,
    /// Points the monitor's exclusion volumes dropped before the query, per volume that applies
    /// to the source (`cloud::exclusion`; none here). They are among `counts.invalid`.
    pub excluded: Vec<(String, u64)>,
}
