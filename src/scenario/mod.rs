//! The scenario generator: bags the project makes itself, with the exact answer recorded.
//!
//! A simulated depth camera — pinhole model, range noise, dropped pixels — looks at the demo
//! robot moving along a joint trajectory and at an obstacle: a person-sized capsule that walks
//! up to the arm (`person`; `approach`: up to the swinging arm and back; `table`: with a work
//! table beside the arm), a box the arm reaches over (`shelf`), or a person's forearm reaching
//! in behind the upper arm, hidden in its shadow as the camera sees it (`shadow`). A dark
//! obstacle (`ScenarioParams::dark`) returns no depth; a second camera beside the arm
//! (`ScenarioParams::second_camera`, topics under `/side_camera`) sees into the first one's
//! shadow, with a side wall behind the arm as it sees it. Every frame is ray cast against the
//! robot's collision meshes (the same tessellated meshes the monitor uses), the obstacle and a
//! back wall, and the floor where there is one (`ScenarioParams::floor`); rays that hit nothing
//! within the camera's range give NaN, like a real depth camera. A ray with no return observes
//! nothing, so without a floor and a side wall the space below and behind the arm is never seen
//! free: the floor and the side wall are the background that unobserved space needs.
//!
//! Recorded, as rosbag2 MCAP: `/tf_static` (the camera's optical frame under the URDF's
//! `camera_link`), `/joint_states` at 50 Hz, `/camera/depth/points` (organized PointCloud2,
//! FLOAT32 x y z and 4 bytes of padding) and `/camera/depth/camera_info` at 10 Hz, and on
//! [`GROUND_TRUTH_TOPIC`](crate::bag::GROUND_TRUTH_TOPIC) the exact minimum distance between the robot's collision meshes and
//! the cloud's obstacle points of each frame, at the cloud's log time. Clouds are stamped at
//! joint-state sample times, so the monitor's interpolated joint values are the rendered ones.
//! Joint states carry their velocities (the central difference of the trajectory). For the
//! speed and separation monitor, each frame also records on [`APPROACH_TRUTH_TOPIC`](crate::bag::APPROACH_TRUTH_TOPIC) the
//! robot's approach speed at its closest mesh point — that point moved with its link by the
//! forward kinematics along the trajectory (central difference), projected on the direction
//! to the obstacle point — and on [`MARGIN_TRUTH_TOPIC`](crate::bag::MARGIN_TRUTH_TOPIC) the separation margin: the exact
//! distance minus the protective separation distance with the default parameters
//! (`SsmParams::default`, the cloud taken as seen at once).
//!
//! Where the scene hides its obstacle (dark, shadow), the truth is the exact distance to its
//! whole shape (or to a nearer obstacle point of any camera).
//!
//! The truth is taken over the points that hit the obstacle or the walls; points on the robot
//! itself are what the monitor's self-filter removes, and points on the floor are not obstacles
//! either (the monitor drops them with an exclusion volume). So that the two agree, the range noise is
//! clipped at 2.5 σ (a robot point then lies at most 2.5 σ from its surface, well inside the
//! self-filter padding with the surface gap added), and the obstacle's closest approach stays
//! above the padding. The noise is Gaussian from a fixed SplitMix64 stream (written here, a few
//! lines, so that a seed gives the same bag with every toolchain and crate version).
//!
//! Cost: one ray per pixel against every collision element, then one exact distance per
//! obstacle point (pruned by bounding boxes); about a second for 30 frames of 128×96.
//!
//! `scene`: the scenes, their trajectories and shapes. `params`: the settings, topics and
//! frames. `renderer`: the camera and its frames. `truth`: the exact distance of a frame.
//! `cameras`: each camera's renderer, topics and `/tf_static`. `bag`: the bag written. `error`: why a scenario cannot be generated.

mod bag;
mod cameras;
mod dropouts;
mod error;
mod noise;
mod params;
mod renderer;
mod scene;
mod truth;

pub use bag::{generate, Generated};
pub use error::ScenarioError;
pub use params::{
    ScenarioParams, CAMERA_INFO_TOPIC, CAMERA_LINK, CLOUD_TOPIC, DEPTH_TOPIC, OPTICAL_FRAME,
    SIDE_CAMERA_INFO_TOPIC, SIDE_CAMERA_LINK, SIDE_CAMERA_POSE, SIDE_CLOUD_TOPIC, SIDE_DEPTH_TOPIC,
    SIDE_OPTICAL_FRAME,
};
pub use renderer::{link_from_optical, root_from_side_link, Frame, Hit, Mount, Renderer};
pub use scene::{
    SceneKind, FLOOR_SIZE, SIDE_WALL_CENTER, SIDE_WALL_SIZE, TABLE_CENTER, TABLE_SIZE,
};
pub use truth::Witness;
