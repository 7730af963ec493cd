//! What the unobserved-space pass (`unobserved`) leaves: the facts of one pass ([`Unseen`]),
//! read by the fusion and the outputs, and what the monitor keeps between passes
//! ([`UnseenState`]). Types only, so that the fusion and the outputs need not know the pass.

/// The unobserved space at one frame.
#[derive(Debug, Clone)]
pub struct Unseen {
    pub stamp_ns: i64,
    /// What was found, or why it is not known.
    pub outcome: Result<UnseenFacts, String>,
    /// The whole pass, s.
    pub compute_s: f64,
}

/// What the pass found.
#[derive(Debug, Clone, Default)]
pub struct UnseenFacts {
    /// The certified lower bound of the distance to a hidden body of the detection capability
    /// (m; the robot's shadow left out with `apart`). `None`: no unseen region can hold one
    /// (published as NaN). `max_distance` where none lies within it.
    pub distance_m: Option<f64>,
    /// The same over the robot's own shadow alone.
    pub self_shadow_m: Option<f64>,
    /// Per link (the engine's order), the same lower bound (`max_distance` beyond it).
    pub per_link: Vec<(String, f64)>,
    /// Cells seen free by some source, over all cells.
    pub observed_fraction: f64,
    /// Per enabled source: the fraction it saw free, or why it observes nothing free.
    pub per_source: Vec<(String, Result<f64, String>)>,
    pub cells: usize,
    pub unseen_cells: usize,
    /// Unseen cells in the robot's shadow.
    pub shadow_cells: usize,
    /// Cells that could hold a hidden body (the opening that `distance_m` is taken over).
    pub opened_cells: usize,
    /// The cell size, m, and the root-frame centres of the opened cells nearest the robot (at
    /// most `unobserved_markers`), for the markers.
    pub resolution_m: f64,
    pub near_cells: Vec<[f32; 3]>,
    /// Each stage's time, s: the robot's cells, the observation, the opening, the distance
    /// query, the markers.
    pub stages_s: Vec<(&'static str, f64)>,
}

/// What the monitor keeps between frames.
#[derive(Debug, Clone, Default)]
pub struct UnseenState {
    /// The robot's reach from its root (m), once computed for the default volume.
    pub(super) reach_m: Option<Result<f64, String>>,
    /// The latest pass.
    pub last: Option<Unseen>,
}
