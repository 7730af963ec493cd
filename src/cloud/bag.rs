//! rosbag2 MCAP: a `.mcap` file, or a rosbag2 folder (its `.mcap` files in name order), read
//! with the `mcap` crate; messages are CDR.

use std::path::{Path, PathBuf};

use super::{msg, read, Cloud, CloudError};

/// The schema name rosbag2 writes for PointCloud2.
pub const POINT_CLOUD2: &str = "sensor_msgs/msg/PointCloud2";

/// The `.mcap` files of a bag path.
pub fn files(path: &Path) -> Result<Vec<PathBuf>, CloudError> {
    if !path.is_dir() {
        return Ok(vec![path.to_owned()]);
    }
    let io = |source| CloudError::Io {
        path: path.to_owned(),
        source,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(CloudError::Bag {
            path: path.to_owned(),
            message: "rosbag2 folder without .mcap files".into(),
        });
    }
    Ok(files)
}

/// The `index`-th PointCloud2 message (0 first) of the bag, on `topic` when given.
pub fn point_cloud(path: &Path, topic: Option<&str>, index: usize) -> Result<Cloud, CloudError> {
    let mut seen = 0;
    for file in files(path)? {
        let bytes = read(&file)?;
        let bag = |message: String| CloudError::Bag {
            path: file.clone(),
            message,
        };
        let stream = mcap::MessageStream::new(&bytes).map_err(|e| bag(e.to_string()))?;
        for message in stream {
            let message = message.map_err(|e| bag(e.to_string()))?;
            let channel = &message.channel;
            let is_cloud = channel
                .schema
                .as_ref()
                .is_some_and(|s| s.name == POINT_CLOUD2);
            if !is_cloud || topic.is_some_and(|t| t != channel.topic) {
                continue;
            }
            if channel.message_encoding != "cdr" {
                return Err(bag(format!(
                    "topic {}: encoding {} (expected cdr)",
                    channel.topic, channel.message_encoding
                )));
            }
            if seen == index {
                let cloud = msg::decode(&message.data)
                    .and_then(|m| m.to_cloud())
                    .map_err(|e| bag(format!("topic {}: {e}", channel.topic)))?;
                return Ok(cloud);
            }
            seen += 1;
        }
    }
    Err(CloudError::Bag {
        path: path.to_owned(),
        message: format!(
            "{} PointCloud2 message(s){}, none with index {index}",
            seen,
            topic.map(|t| format!(" on {t}")).unwrap_or_default()
        ),
    })
}
