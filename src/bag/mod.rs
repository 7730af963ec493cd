//! Bags: rosbag2 MCAP in and out, over the messages of `crate::msg` (replay through the
//! monitor is `crate::monitor::replay`).
//!
//! - `reader`: a `.mcap` file, or a rosbag2 folder (`metadata.yaml` names its files; without
//!   one, its `.mcap` files in name order); chunks compressed with zstd or lz4 or not at all;
//!   messages in log-time order across files.
//! - `writer`: MCAP with the `ros2msg` schemas of `crate::msg`, CDR messages and the rosbag2
//!   profile, readable by Foxglove, rosbags and `ros2 bag`; optionally the rosbag2 folder's
//!   `metadata.yaml`.

mod error;
pub mod reader;
mod truth;
pub mod writer;

pub use error::BagError;
pub use reader::{read_messages, BagMessage};
pub use truth::{APPROACH_TRUTH_TOPIC, GROUND_TRUTH_TOPIC, MARGIN_TRUTH_TOPIC};
pub use writer::BagWriter;
