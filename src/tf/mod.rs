//! Poses stage, inputs: the TF buffer (`/tf`, `/tf_static`, static transforms from the config)
//! and the joint-state buffer (`joints`), and the lookup of a sensor frame in the robot's root
//! frame at a cloud's stamp.
//!
//! **TF buffer.** Every child frame has one parent and a short history of `parent_from_child`
//! (f64), sorted by stamp; static transforms hold one value for all time. A lookup walks both
//! frames up to their common ancestor and composes the edges, each sampled at the stamp: between
//! two samples, translation is interpolated linearly and rotation by slerp; past either end, the
//! nearest sample is used when it lies within the tolerance, otherwise the lookup fails — as
//! stale when the newest sample is too old, as too old when the stamp precedes the history.
//! Quaternions are normalized on the way in; zero, near-zero or non-finite ones are refused.
//!
//! **Sensor in the robot.** [`root_from_sensor`] walks up from the sensor frame; at the first
//! frame that is a link of the URDF it composes the forward kinematics of that link (so the
//! joint states, not `/tf`, decide where the robot's own links are, and a camera on the wrist
//! moves with the arm). A sensor frame with no URDF link above it (a camera whose transform
//! names the world as its child, say) is looked up against the root frame in the TF tree.
//!
//! Cost: a lookup is O(depth · log history), microseconds; it runs once per cloud.
//!
//! Files: `buffer` (the TF buffer and its lookup), `sensor` (the sensor in the robot), `joints`
//! (the joint-state buffer), `history` (the time series behind both buffers).

mod buffer;
mod history;
pub mod joints;
mod sensor;

pub use buffer::{interpolate, TfBuffer, TfError, VOICE_WINDOW_S};
pub use joints::{JointError, JointStateBuffer, VelocitySource};
pub use sensor::root_from_sensor;
