//! Bags: rosbag2 MCAP in and out, over the messages of `crate::msg` (replay through the
//! monitor is `crate::monitor::replay`).
//!
//! - `reader`: a `.mcap` file, or a rosbag2 folder (`metadata.yaml` names its files; without
//!   one, its `.mcap` files in name order); chunks compressed with zstd or lz4 or not at all;
//!   messages in log-time order across files.
//! - `writer`: MCAP with the `ros2msg` schemas of `crate::msg`, CDR messages and the rosbag2
//!   profile, readable by Foxglove, rosbags and `ros2 bag`; optionally the rosbag2 folder's
//!   `metadata.yaml`.

pub mod reader;
pub mod writer;

pub use reader::{read_messages, BagMessage};
pub use writer::BagWriter;

use std::path::PathBuf;

/// Where bags of the scenario generator carry the exact minimum distance of every frame
/// (`std_msgs/Float64`, at the cloud's log time).
pub const GROUND_TRUTH_TOPIC: &str = "/ground_truth/min_distance";

/// Where they carry the robot's approach speed at its closest point (`std_msgs/Float64`, m/s,
/// positive towards the obstacle).
pub const APPROACH_TRUTH_TOPIC: &str = "/ground_truth/approach_speed";

/// Where they carry the separation margin with the default SSM parameters (`std_msgs/Float64`,
/// m: the exact distance minus the protective separation distance).
pub const MARGIN_TRUTH_TOPIC: &str = "/ground_truth/separation_margin";

#[derive(Debug, thiserror::Error)]
pub enum BagError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: MCAP: {message}")]
    Mcap { path: PathBuf, message: String },
    #[error("{path}: metadata.yaml: {message}")]
    Metadata { path: PathBuf, message: String },
    #[error("{path}: topic {topic}: {message}")]
    Topic {
        path: PathBuf,
        topic: String,
        message: String,
    },
}
