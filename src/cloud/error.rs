//! The cloud stage's error: the file, bag or frame it concerns, and what in it could not be
//! read.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CloudError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: PCD: {message}")]
    Pcd { path: PathBuf, message: String },
    #[error("{path}: PLY: {message}")]
    Ply { path: PathBuf, message: String },
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error("{path}: {count} PointCloud2 message(s), none with index {index}")]
    NoMessage {
        path: PathBuf,
        count: usize,
        index: usize,
    },
    #[error("PointCloud2: {0}")]
    Decode(#[from] crate::msg::MsgError),
    #[error("PointCloud2 in frame '{frame}': {message}")]
    Layout { frame: String, message: String },
    #[error("depth image in frame '{frame}': {message}")]
    DepthImage { frame: String, message: String },
    #[error("CameraInfo of frame '{frame}': {message}")]
    Camera { frame: String, message: String },
    #[error("{path}: topic {topic}: {source}")]
    InBag {
        path: PathBuf,
        topic: String,
        source: Box<CloudError>,
    },
    #[error("{path}: unknown cloud format (expected .pcd, .ply, .mcap or a rosbag2 folder)")]
    UnknownFormat { path: PathBuf },
}
