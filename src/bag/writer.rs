//! Writing rosbag2 MCAP: each topic a channel with message encoding `cdr` and the `ros2msg`
//! schema of its type (the full definition from `crate::msg::definition`), under the `ros2`
//! profile, in zstd or lz4 chunks. A path ending in `.mcap` is written as that one file; any
//! other path becomes a rosbag2 folder with `<name>_0.mcap` and a `metadata.yaml` (version 8, as
//! `ros2 bag` and rosbags write it), so `ros2 bag info`, rosbags and Foxglove all open it.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::msg::{self, RosMessage};

use super::BagError;

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Compression {
    None,
    Zstd,
    Lz4,
}

struct Topic {
    channel: u16,
    ty: String,
    count: u64,
}

pub struct BagWriter {
    writer: mcap::Writer<BufWriter<File>>,
    file: PathBuf,
    /// The rosbag2 folder, when writing one.
    folder: Option<PathBuf>,
    topics: BTreeMap<String, Topic>,
    first_ns: u64,
    last_ns: u64,
}

impl BagWriter {
    /// Creates `path`: a `.mcap` file, or a rosbag2 folder (which must not exist yet).
    pub fn create(path: &Path, compression: Compression) -> Result<Self, BagError> {
        let io = |path: &Path| {
            let path = path.to_owned();
            move |source| BagError::Io { path, source }
        };
        let (file, folder) = if path.extension().is_some_and(|e| e == "mcap") {
            (path.to_owned(), None)
        } else {
            std::fs::create_dir_all(path).map_err(io(path))?;
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "bag".into());
            (path.join(format!("{name}_0.mcap")), Some(path.to_owned()))
        };
        let out = BufWriter::new(File::create(&file).map_err(io(&file))?);
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(match compression {
                Compression::None => None,
                Compression::Zstd => Some(mcap::Compression::Zstd),
                Compression::Lz4 => Some(mcap::Compression::Lz4),
            })
            .create(out)
            .map_err(|e| BagError::Mcap {
                path: file.clone(),
                message: e.to_string(),
            })?;
        Ok(Self {
            writer,
            file,
            folder,
            topics: BTreeMap::new(),
            first_ns: u64::MAX,
            last_ns: 0,
        })
    }

    fn mcap_error(&self, e: mcap::McapError) -> BagError {
        BagError::Mcap {
            path: self.file.clone(),
            message: e.to_string(),
        }
    }

    /// Writes `message` on `topic` at `log_time_ns` (also its publish time).
    pub fn write<T: RosMessage>(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        message: &T,
    ) -> Result<(), BagError> {
        let payload = msg::encode(message).map_err(|e| BagError::Topic {
            path: self.file.clone(),
            topic: topic.to_owned(),
            message: e.to_string(),
        })?;
        self.write_cdr(topic, T::TYPE, log_time_ns, &payload)
    }

    /// Writes a CDR payload of type `ty` (`pkg/msg/Type`, one of `crate::msg`'s) on `topic`.
    pub fn write_cdr(
        &mut self,
        topic: &str,
        ty: &str,
        log_time_ns: u64,
        payload: &[u8],
    ) -> Result<(), BagError> {
        if !self.topics.contains_key(topic) {
            let definition = msg::definition(ty).ok_or_else(|| BagError::Topic {
                path: self.file.clone(),
                topic: topic.to_owned(),
                message: format!("no message definition for {ty}"),
            })?;
            let schema = self
                .writer
                .add_schema(ty, "ros2msg", definition.as_bytes())
                .map_err(|e| self.mcap_error(e))?;
            let metadata = BTreeMap::from([("offered_qos_profiles".to_owned(), String::new())]);
            let channel = self
                .writer
                .add_channel(schema, topic, "cdr", &metadata)
                .map_err(|e| self.mcap_error(e))?;
            self.topics.insert(
                topic.to_owned(),
                Topic {
                    channel,
                    ty: ty.to_owned(),
                    count: 0,
                },
            );
        }
        let Some(t) = self.topics.get_mut(topic) else {
            unreachable!("inserted above")
        };
        if t.ty != ty {
            return Err(BagError::Topic {
                path: self.file.clone(),
                topic: topic.to_owned(),
                message: format!("type {ty}, but the topic already carries {}", t.ty),
            });
        }
        let header = mcap::records::MessageHeader {
            channel_id: t.channel,
            sequence: t.count as u32,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        t.count += 1;
        self.first_ns = self.first_ns.min(log_time_ns);
        self.last_ns = self.last_ns.max(log_time_ns);
        self.writer
            .write_to_known_channel(&header, payload)
            .map_err(|e| self.mcap_error(e))
    }

    /// Closes the MCAP (summary, index) and, for a folder, writes `metadata.yaml`.
    pub fn finish(mut self) -> Result<(), BagError> {
        self.writer.finish().map_err(|e| self.mcap_error(e))?;
        let Some(folder) = &self.folder else {
            return Ok(());
        };
        let file_name = self
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let total: u64 = self.topics.values().map(|t| t.count).sum();
        let start = if total == 0 { 0 } else { self.first_ns };
        let duration = self.last_ns.saturating_sub(start);
        let mut topics = String::new();
        for (name, t) in &self.topics {
            topics.push_str(&format!(
                "  - message_count: {}\n    topic_metadata:\n      name: {name}\n      offered_qos_profiles: ''\n      serialization_format: cdr\n      type: {}\n      type_description_hash: ''\n",
                t.count, t.ty
            ));
        }
        let yaml = format!(
            "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  duration:\n    nanoseconds: {duration}\n  starting_time:\n    nanoseconds_since_epoch: {start}\n  message_count: {total}\n  topics_with_message_count:\n{topics}  compression_format: ''\n  compression_mode: ''\n  relative_file_paths:\n  - {file_name}\n  files:\n  - path: {file_name}\n    starting_time:\n      nanoseconds_since_epoch: {start}\n    duration:\n      nanoseconds: {duration}\n    message_count: {total}\n  custom_data: {{}}\n  ros_distro: ''\n"
        );
        let path = folder.join("metadata.yaml");
        std::fs::write(&path, yaml).map_err(|source| BagError::Io { path, source })
    }
}
