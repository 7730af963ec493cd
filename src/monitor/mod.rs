//! The monitor: the one pipeline that `replay` and the live node run. Inputs are ROS messages,
//! decoded, as they come off a bag or DDS — `/tf`, `/tf_static`, `/joint_states` and each
//! source's PointCloud2, or depth Image with its CameraInfo (`cloud::depth`) — one entry point
//! per kind (`pipeline`), and every cloud or depth image gives a [`Frame`]: the query result or
//! the fault that stopped it, and the node's output messages (`outputs`).
//!
//! Per cloud (`measure`): decode (a depth image: its points made with the source's last camera
//! model, into a buffer the monitor keeps) → the stamp against the clock (0, older than the
//! source's `source_timeout` or ahead by more than `future_stamp_tolerance` is a fault) → drop
//! points outside the source's `min_range`/`max_range` (they become invalid points) → the
//! joint values at the cloud's stamp (`tf::JointStateBuffer`) → forward kinematics → the
//! sensor frame in the robot's root frame at the stamp (`tf::root_from_sensor`) → the points
//! of the source's exclusion volumes dropped (`cloud::exclusion`, each volume placed in the
//! sensor frame at the stamp) → the query (`query::Engine`; with `stray_filter` on, `stray`
//! rejects isolated nearest points) → the separation stage (`crate::separation`: joint
//! velocities at the stamp, link twists, the speed-scaling factor through
//! [`SpeedScaler`](crate::separation::SpeedScaler)) → the source's report (`report`, its own
//! `level`) → the outputs, fused over every source's latest result (`fusion` decides the
//! picture, `outputs` renders it, with `markers`). A decode error, a missing or stale
//! transform or joint, and a failed query are faults of that frame: reported with their reason
//! and an ERROR level, never as a distance (and a speed-scaling factor of 0; the kinds are in
//! `fault`). The next message is processed as usual.
//!
//! Each configured source is a [`Source`] that owns its state: its latest result, its level,
//! its camera model and how the node watches it. Between frames the live node asks the monitor
//! for the faults that are no frame of their own (`watch`: a silent source, an untrusted clock,
//! "not monitoring"). After each measured frame's query, [`unseen::UnseenSpace`] runs the
//! unseen-space pass over every source's latest view, inside the frame's processing time.
//! `setup` starts a monitor; `replay` feeds a bag through this pipeline in
//! log-time order, as the node (`crate::node`) feeds it from DDS.

mod fault;
pub mod fusion;
mod level;
mod markers;
mod measure;
pub mod outputs;
mod pipeline;
pub mod replay;
mod report;
mod setup;
mod source;
mod stamped;
mod stray;
pub mod unseen;
mod watch;

pub use fault::{Fault, InputError};
pub use level::{Level, LevelTracker};
pub use outputs::Outputs;
pub use pipeline::{Frame, Monitor};
pub use setup::{MonitorError, Refinement};
pub use source::{Heard, Latest, Part, Silence, Source};
