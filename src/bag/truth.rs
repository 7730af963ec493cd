//! The topics on which the scenario generator's bags carry each frame's truth, beside the
//! cloud, for replay to compare the monitor's answer with.

/// Where bags of the scenario generator carry the exact minimum distance of every frame
/// (`std_msgs/Float64`, at the cloud's log time).
pub const GROUND_TRUTH_TOPIC: &str = "/ground_truth/min_distance";

/// Where they carry the robot's approach speed at its closest point (`std_msgs/Float64`, m/s,
/// positive towards the obstacle).
pub const APPROACH_TRUTH_TOPIC: &str = "/ground_truth/approach_speed";

/// Where they carry the separation margin with the default SSM parameters (`std_msgs/Float64`,
/// m: the exact distance minus the protective separation distance).
pub const MARGIN_TRUTH_TOPIC: &str = "/ground_truth/separation_margin";
