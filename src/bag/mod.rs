//! Bags: rosbag2 MCAP in and out, and the replay of a bag through the monitor.
//!
//! - `reader`: a `.mcap` file, or a rosbag2 folder (`metadata.yaml` names its files; without
//!   one, its `.mcap` files in name order); chunks compressed with zstd or lz4 or not at all;
//!   messages in log-time order across files.
//! - `writer`: MCAP with the `ros2msg` schemas of `crate::msg`, CDR messages and the rosbag2
//!   profile, readable by Foxglove, rosbags and `ros2 bag`; optionally the rosbag2 folder's
//!   `metadata.yaml`.
//! - `replay`: the monitor (`crate::monitor`) fed from a bag, per-frame lines and a summary, the
//!   node's outputs written to an MCAP.

pub mod reader;
pub mod replay;
pub mod writer;

pub use reader::{read_messages, BagMessage};
pub use writer::BagWriter;

use std::path::PathBuf;

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
