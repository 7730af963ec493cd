//! Why an unseen-space pass gave no distance: under `protect` each is a fault of the cell (what
//! no camera sees is not known free), under `report` a warning. Each names the frame, volume or
//! parameter concerned.

use crate::unseen::UnseenError;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnseenFault {
    /// The monitored volume's frame could not be placed at the frame's stamp.
    #[error("monitored_volume.frame {frame}: {reason}")]
    VolumeFrame { frame: String, reason: String },
    /// An exclusion volume's frame could not be placed at the frame's stamp.
    #[error("exclusion volume {volume}: {reason}")]
    ExclusionFrame { volume: String, reason: String },
    /// The default volume needs the robot's reach, which a prismatic joint without limits hides.
    #[error(
        "a prismatic joint has no limits, so the robot's reach is not known: set \
         monitored_volume.size"
    )]
    ReachUnknown,
    /// The robot has no inner sphere to measure from.
    #[error("the robot has no inner spheres")]
    NoSpheres,
    /// The lattice or the ball refused its parameters.
    #[error("{0}")]
    Lattice(UnseenError),
    /// The distance query over the hidden places failed.
    #[error("the query over the hidden places failed: {0}")]
    Query(String),
    /// The frame with the pass took longer than `latency_budget` (`protect`: too late to act on).
    #[error(
        "the frame with the pass took {elapsed_ms:.1} ms, more than latency_budget \
         ({budget_ms:.1} ms)"
    )]
    Late { elapsed_ms: f64, budget_ms: f64 },
}

impl UnseenFault {
    /// A short key for counting faults by kind (as `Fault::kind`), each prefixed `unseen_`.
    pub fn kind(&self) -> &'static str {
        match self {
            UnseenFault::VolumeFrame { .. } => "unseen_volume_tf",
            UnseenFault::ExclusionFrame { .. } => "unseen_exclusion_tf",
            UnseenFault::ReachUnknown => "unseen_reach_unknown",
            UnseenFault::NoSpheres => "unseen_no_spheres",
            UnseenFault::Lattice(_) => "unseen_lattice",
            UnseenFault::Query(_) => "unseen_query",
            UnseenFault::Late { .. } => "unseen_late",
        }
    }
}
