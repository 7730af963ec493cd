//! `control_msgs`: the speed-scaling command that `joint_trajectory_controller` reads.

use serde::{Deserialize, Serialize};

use super::message::ros_message;

/// `control_msgs/msg/SpeedScalingFactor`: 1 runs a trajectory at its own speed, 0 pauses it;
/// negative values are not allowed. `joint_trajectory_controller` takes it on
/// `~/speed_scaling_input` (reliable, transient local) for on-controller scaling.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SpeedScalingFactor {
    pub factor: f64,
}
ros_message!(
    SpeedScalingFactor,
    "control_msgs/msg/SpeedScalingFactor",
    "float64 factor\n"
);
