//! The live ROS 2 node (ros2-client over RustDDS, or zenoh as rmw_zenoh speaks it): the monitor
//! fed from its sources, its outputs published, stale sources reported. `play` and `record` are
//! the bag tools that drive and observe it (tests, benchmarks, demos).
//!
//! Threads: an executor thread runs the ros2-client spinner and one task per subscription.
//! `/tf`, `/tf_static`, the joint states and depth sources' CameraInfo go to the processing
//! thread in order. Each cloud (or depth image) replaces the previous one in its source's slot:
//! only the newest is ever processed, so no queue grows. The DDS reader keeps one sample (KeepLast 1), and a cloud that is overwritten
//! before it is processed counts as dropped, as do gaps in the writer's sequence numbers. The
//! processing thread waits for a slot, runs the monitor and publishes its outputs. It also
//! checks every source: one silent for longer than its `source_timeout` (or never heard) is a
//! fault. The node then publishes ERROR diagnostics with the reason and `safety_stop`, and never
//! a distance. Every output is the cell's fused picture over all sources (`monitor::fusion`); it
//! is also published every `heartbeat_period` when no frame went out, the sources aged by the
//! clock. Whatever ends the serving (a signal, an error, a panic), the node's last word —
//! `safety_stop` true, factor 0, "not monitoring: REASON" — goes out before the participant
//! closes. For what can say nothing (SIGKILL, a power loss), the outputs published on every
//! beat offer the QoS deadline `output_deadline` and every output automatic liveliness (a 3 s
//! lease), so a DDS subscriber that asks for them is told by its own middleware.
//!
//! Here: `lifecycle`, the node's start, "not monitoring" during the build, and its last word
//! and stop; `serve`, the serving loop; `refine`, the fine trees swapped in after a first start
//! on coarse ones; `up`, the line that says it is up. `ros_args`: the
//! command line after `--ros-args`, and the names of topics and types. `qos`: every topic's
//! QoS. `inputs`: the sources' slots and the forwarded TF, joint states and camera info.
//! `publishers`: the output table's publishers. `parameters`: the parameter services; a change
//! they take reaches the processing thread through a channel and is applied before its next
//! frame (a source enabled then is subscribed to then). `wiring`: the subscriptions, and who
//! writes each input by discovery. `transport` and `rmw_zenoh`: DDS or zenoh underneath; `socket`: the DDS sockets' buffers; `security`: SROS2 (the environment, the
//! enclave's files, what the node starts with). `clock`: the node's time. `error`:
//! what stops it.

mod clock;
mod error;
mod inputs;
mod lifecycle;
pub mod parameters;
pub mod play;
mod publishers;
mod qos;
pub mod record;
mod refine;
pub mod rmw_zenoh;
mod ros_args;
pub mod rosout;
pub mod security;
mod serve;
mod socket;
pub mod transport;
mod up;
mod wiring;

pub use error::NodeError;
pub use lifecycle::run;
pub use publishers::PANIC_AFTER_ENV;
pub use ros_args::{parse_ros_args, RosArgs};
pub use transport::Transport;
