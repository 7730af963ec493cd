//! Writing rosbag2 MCAP: each topic a channel with message encoding `cdr` and the `ros2msg`
//! schema of its type (the full definition from `crate::msg::definition`), under the `ros2`
//! profile, in zstd or lz4 chunks. A path ending in `.mcap` is written as that one file; any
//! other path becomes a rosbag2 folder with `<name>_0.mcap` and a `metadata.yaml` (version 8, as
//! `ros2 bag` and rosbags write it), so `ros2 bag info`, rosbags and Foxglove all open it.
//!
//! Each topic carries what `ros2 bag play` needs to republish it as it was offered: its
//! `offered_qos_profiles` (in the channel's metadata and in `metadata.yaml`, rosbag2's version-8
//! form: a YAML list with the rmw enums as integers) and its REP-2016 `type_description_hash`
//! (the channel's `topic_type_hash`). Topics are offered reliable and volatile; `/tf_static`
//! and the topics marked with [`BagWriter::latch`] (the node's `~/speed_scaling`) transient
//! local with the last message kept, so that rosbag2 republishes them transient local and a
//! late tf2 listener or controller still gets them.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::choice::Choice;
use crate::msg::{self, RosMessage};

use super::error::BagError;

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    None,
    Zstd,
    Lz4,
}

impl Choice for Compression {
    const ALL: &'static [Self] = &[Compression::None, Compression::Zstd, Compression::Lz4];

    fn name(self) -> &'static str {
        match self {
            Compression::None => "none",
            Compression::Zstd => "zstd",
            Compression::Lz4 => "lz4",
        }
    }
}

struct Topic {
    channel: u16,
    ty: String,
    count: u64,
    qos: String,
    hash: String,
}

/// rmw's "infinite" duration as rosbag2 writes it.
const INFINITE: &str = "    sec: 9223372036\n    nsec: 854775807\n";

/// One offered QoS profile in rosbag2's version-8 form (`rmw` enums as integers: history 1
/// keep last, reliability 1 reliable, durability 1 transient local or 2 volatile, liveliness 1
/// automatic; durations infinite).
pub fn offered_qos_yaml(transient_local: bool) -> String {
    let (durability, depth) = if transient_local { (1, 1) } else { (2, 10) };
    format!(
        "- history: 1\n  depth: {depth}\n  reliability: 1\n  durability: {durability}\n  \
         deadline:\n{INFINITE}  lifespan:\n{INFINITE}  liveliness: 1\n  \
         liveliness_lease_duration:\n{INFINITE}  avoid_ros_namespace_conventions: false\n"
    )
}

pub struct BagWriter {
    writer: mcap::Writer<BufWriter<File>>,
    file: PathBuf,
    /// The rosbag2 folder, when writing one.
    folder: Option<PathBuf>,
    topics: BTreeMap<String, Topic>,
    first_ns: u64,
    last_ns: u64,
    /// Topics offered transient local besides `/tf_static`.
    latched: Vec<String>,
}

impl BagWriter {
    /// Offers `topic` transient local (call before its first message).
    pub fn latch(&mut self, topic: &str) {
        self.latched.push(topic.to_owned());
    }

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
            latched: Vec::new(),
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
            let latched = topic == "/tf_static" || self.latched.iter().any(|t| t == topic);
            let qos = offered_qos_yaml(latched);
            let hash = msg::type_hash(ty).unwrap_or_default();
            let metadata = BTreeMap::from([
                ("offered_qos_profiles".to_owned(), qos.clone()),
                ("topic_type_hash".to_owned(), hash.clone()),
            ]);
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
                    qos,
                    hash,
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
            // The profiles as one double-quoted YAML string (JSON's escapes are YAML's).
            let qos = serde_json::to_string(&t.qos).unwrap_or_default();
            topics.push_str(&format!(
                "  - message_count: {}\n    topic_metadata:\n      name: {name}\n      offered_qos_profiles: {qos}\n      serialization_format: cdr\n      type: {}\n      type_description_hash: {}\n",
                t.count, t.ty, t.hash
            ));
        }
        let yaml = format!(
            "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  duration:\n    nanoseconds: {duration}\n  starting_time:\n    nanoseconds_since_epoch: {start}\n  message_count: {total}\n  topics_with_message_count:\n{topics}  compression_format: ''\n  compression_mode: ''\n  relative_file_paths:\n  - {file_name}\n  files:\n  - path: {file_name}\n    starting_time:\n      nanoseconds_since_epoch: {start}\n    duration:\n      nanoseconds: {duration}\n    message_count: {total}\n  custom_data: {{}}\n  ros_distro: ''\n"
        );
        let path = folder.join("metadata.yaml");
        std::fs::write(&path, yaml).map_err(|source| BagError::Io { path, source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Bool, TfMessage};

    #[test]
    fn topics_carry_offered_qos_and_type_hash() {
        let dir = tempfile::tempdir().unwrap();
        let bag = dir.path().join("out");
        let mut w = BagWriter::create(&bag, Compression::None).unwrap();
        w.latch("/ist_monitor/speed_scaling");
        w.write("/tf_static", 1, &TfMessage::default()).unwrap();
        w.write("/tf", 2, &TfMessage::default()).unwrap();
        w.write("/ist_monitor/speed_scaling", 3, &Bool::default())
            .unwrap();
        w.finish().unwrap();
        // metadata.yaml: each topic's profiles as one YAML string, its hash as ROS 2's.
        let meta = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap();
        let doc = &yaml_rust2::YamlLoader::load_from_str(&meta).unwrap()[0];
        let topics = doc["rosbag2_bagfile_information"]["topics_with_message_count"]
            .as_vec()
            .unwrap();
        assert_eq!(topics.len(), 3);
        for t in topics {
            let m = &t["topic_metadata"];
            let name = m["name"].as_str().unwrap();
            let qos = m["offered_qos_profiles"].as_str().unwrap();
            let profiles = yaml_rust2::YamlLoader::load_from_str(qos).unwrap();
            let p = &profiles[0][0];
            let latched = name != "/tf";
            assert_eq!(p["durability"].as_i64(), Some(if latched { 1 } else { 2 }));
            assert_eq!(p["reliability"].as_i64(), Some(1));
            assert_eq!(p["deadline"]["sec"].as_i64(), Some(9223372036));
            let ty = m["type"].as_str().unwrap();
            assert_eq!(
                m["type_description_hash"].as_str(),
                msg::type_hash(ty).as_deref()
            );
            assert!(m["type_description_hash"]
                .as_str()
                .unwrap()
                .starts_with("RIHS01_"));
        }
        // The MCAP channels carry the same, under rosbag2_storage_mcap's keys.
        let data = std::fs::read(bag.join("out_0.mcap")).unwrap();
        let summary = mcap::Summary::read(&data).unwrap().unwrap();
        for c in summary.channels.values() {
            assert_eq!(
                c.metadata["offered_qos_profiles"],
                offered_qos_yaml(c.topic != "/tf")
            );
            assert!(c.metadata["topic_type_hash"].starts_with("RIHS01_"));
        }
    }
}
