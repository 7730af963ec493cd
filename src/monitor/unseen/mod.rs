//! The cell's unseen space (issues 45 and 55), fused over every enabled source's latest
//! measured frame as the distances are: a certified lower bound of the distance from the robot
//! to a body of the detection capability that no source has seen, inside the monitored volume.
//! The algorithm is the `unseen` stage's (its module doc); [`UnseenSpace`] owns what the monitor
//! needs of it, as a Nav2 collision-monitor polygon owns its parameters, state and messages:
//!
//! - its **config slice**: the `unobserved*` parameters, each source's range noise and limits,
//!   the exclusion volumes that apply to every source, the query options for the hidden places;
//! - its **per-source views** (`views`): each measured frame leaves its source's view, made and
//!   prepared (free distances, the robot rendered at that frame's poses, pyramids) as the pass's
//!   first stage (before the query where the GPU judges its cells in the query's submission); a source in fault, disabled or restarted leaves none;
//! - its **steps** (`pass`): the volume placed at the frame's stamp, the robot placed at its
//!   poses, the search with the engine's certified distance, the causes of what is nearest;
//! - its **GPU part** (`gpu`): a depth image measured on the GPU has the lattice's cells judged in
//!   the same submission, the verdicts kept with its view;
//! - its **typed error** ([`UnseenFault`]) and its **messages** (`messages`).
//!
//! **Counted, never in the way.** The seen outputs go first: the monitor publishes a frame's
//! distances, level, stop and speed factor the moment its query is done, then runs the pass
//! (its first stage the frame's view), then the frame's last word (`monitor::measure`). Under
//! `report` the pass moves neither level nor factor, so nothing waits for it. Under `protect` the
//! seen outputs take the previous frame's pass and may only raise the level and lower the
//! factor; the release, and the factor's rise, are the last word's, whose processing (so the
//! speed factor's reaction time, and the latency budget) includes the pass. Under `protect` a
//! frame later than the budget with the pass is a fault ([`UnseenSpace::check_late`]); before
//! any pass, or after one that failed, the pass runs before any output.
//!
//! **The robot's own shadow** (`unobserved_self_shadow`): `count` treats it as any hidden space:
//! with one camera the unseen distance beside the arm is then 0, which a safety engineer should
//! read as "one camera cannot watch behind the arm". `apart` reports it on its own and leaves it
//! out of `~/unseen_distance` and of `protect`: the stated assumption that nothing of the
//! detection capability hides there.

mod error;
mod facts;
mod gpu;
mod messages;
mod pass;
mod space;
mod views;

pub use error::UnseenFault;
pub use facts::{Unseen, UnseenFacts};
pub use messages::{cause_colour, unseen_messages, UnseenMessages};
pub use pass::{At, PassInputs};
pub use space::UnseenSpace;
pub use views::{cloud_view, depth_view};
