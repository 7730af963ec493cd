//! A cloud from a path: the reader its extension names (`.pcd`, `.ply`), or a bag's N-th
//! PointCloud2 (`.mcap` or a rosbag2 folder).

use std::path::Path;

use super::error::CloudError;
use super::points::Cloud;
use super::{pcd, ply, pointcloud2};
use crate::msg::RosMessage;

/// Loads a cloud by its extension: `.pcd`, `.ply`, `.mcap` or a rosbag2 folder (then `message`
/// picks the N-th PointCloud2, 0 first).
pub fn load(path: &Path, message: usize) -> Result<Cloud, CloudError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("pcd") => pcd::load(path),
        Some("ply") => ply::load(path),
        Some("mcap") => point_cloud_from_bag(path, message),
        _ if path.is_dir() => point_cloud_from_bag(path, message),
        _ => Err(CloudError::UnknownFormat {
            path: path.to_owned(),
        }),
    }
}

/// The `index`-th PointCloud2 message (0 first, in log-time order) of a bag.
pub fn point_cloud_from_bag(path: &Path, index: usize) -> Result<Cloud, CloudError> {
    let clouds =
        crate::bag::read_messages(path, &|_, schema| schema == crate::msg::PointCloud2::TYPE)?;
    let m = clouds.get(index).ok_or_else(|| CloudError::NoMessage {
        path: path.to_owned(),
        count: clouds.len(),
        index,
    })?;
    pointcloud2::cloud_from_cdr(&m.data).map_err(|e| CloudError::InBag {
        path: path.to_owned(),
        topic: m.topic.to_string(),
        source: Box::new(e),
    })
}
