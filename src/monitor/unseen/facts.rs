//! What one unseen-space pass leaves ([`Unseen`]): read by the fusion, the separation stage and
//! the messages, so that none of them needs the pass itself.

use crate::unseen::{Counts, Spot};

use super::error::UnseenFault;

/// The unseen space at one frame.
#[derive(Debug, Clone)]
pub struct Unseen {
    pub stamp_ns: i64,
    /// What was found, or why it is not known.
    pub outcome: Result<UnseenFacts, UnseenFault>,
    /// The whole pass with the frame's own view (made and prepared), s.
    pub compute_s: f64,
}

/// What the pass found.
#[derive(Debug, Clone, Default)]
pub struct UnseenFacts {
    /// The certified lower bound of the distance to a hidden body of the detection capability
    /// (m; the robot's shadow left out with `apart`). `None`: no hidden body can lie in the
    /// monitored volume (published as +∞). `max_distance` where none lies within it.
    pub distance_m: Option<f64>,
    /// The same over the robot's own shadow alone (`apart` only).
    pub self_shadow_m: Option<f64>,
    /// Per link (the engine's order), the same lower bound (+∞ where none was found within
    /// `per_link_range`: a link farther than that from every hidden place).
    pub per_link: Vec<(String, f64)>,
    /// The hidden place nearest the robot and why no view saw it.
    pub nearest: Option<Spot>,
    /// Per enabled source: whether it observes, or why it observes nothing free.
    pub per_source: Vec<(String, Result<(), String>)>,
    /// No enabled source observes anything: the whole volume is hidden (distance 0).
    pub blind: bool,
    /// Lattice centres in the monitored volume.
    pub cells: usize,
    pub resolution_m: f64,
    /// What the search examined and found.
    pub counts: Counts,
    /// The hidden places nearest the robot (at most `unobserved_markers`), with their causes.
    pub near: Vec<Spot>,
    /// Each stage's time, s: the frame's view, the volume, the robot, the search.
    pub stages_s: Vec<(&'static str, f64)>,
}
