//! Reading rosbag2 MCAP: the files of a bag, and its messages in log-time order.
//!
//! A rosbag2 folder lists its files in `metadata.yaml` (`relative_file_paths`); a folder without
//! it is read as its `.mcap` files in name order, and a path to a file as that file. Each file is
//! read whole and its chunks decompressed by the `mcap` crate (zstd, lz4); the messages of all
//! files are sorted by log time (stable, so equal times keep their file order), which is the
//! order a live node would have received them in.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use yaml_rust2::YamlLoader;

use super::error::BagError;

/// One message of a bag.
#[derive(Debug, Clone)]
pub struct BagMessage {
    pub topic: Arc<str>,
    /// Schema name, e.g. `sensor_msgs/msg/PointCloud2` (empty when the channel has none).
    pub schema: Arc<str>,
    /// Message encoding of the channel (`cdr` for rosbag2).
    pub encoding: Arc<str>,
    pub log_time_ns: u64,
    pub data: Vec<u8>,
}

type Names = (Arc<str>, Arc<str>, Arc<str>);

fn io(path: &Path) -> impl Fn(std::io::Error) -> BagError + '_ {
    move |source| BagError::Io {
        path: path.to_owned(),
        source,
    }
}

/// The `.mcap` files of a bag path, in order.
pub fn files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if !path.is_dir() {
        return Ok(vec![path.to_owned()]);
    }
    let metadata = path.join("metadata.yaml");
    if metadata.exists() {
        let text = std::fs::read_to_string(&metadata).map_err(io(&metadata))?;
        let bad = |message: String| BagError::Metadata {
            path: path.to_owned(),
            message,
        };
        let docs = YamlLoader::load_from_str(&text).map_err(|e| bad(e.to_string()))?;
        let info =
            &docs.first().ok_or_else(|| bad("empty file".into()))?["rosbag2_bagfile_information"];
        let storage = info["storage_identifier"].as_str().unwrap_or("mcap");
        if storage != "mcap" {
            return Err(bad(format!("storage {storage} (only mcap is read)")));
        }
        let names = info["relative_file_paths"]
            .as_vec()
            .ok_or_else(|| bad("no relative_file_paths".into()))?;
        return names
            .iter()
            .map(|n| {
                n.as_str()
                    .map(|n| path.join(n))
                    .ok_or_else(|| bad("relative_file_paths holds a non-string".into()))
            })
            .collect();
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(io(path))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(BagError::Metadata {
            path: path.to_owned(),
            message: "a folder without metadata.yaml nor .mcap files".into(),
        });
    }
    Ok(files)
}

/// The messages of the bag at `path` whose channel passes `keep(topic, schema)` (asked once per
/// channel record), in log-time order. Only those are kept in memory. A file that ends early or has a broken record after its
/// first message (a recorder that crashed) gives the messages before the break, with a warning
/// that says where it ends; a file with no readable message is an error.
pub fn read_messages(
    path: &Path,
    keep: &dyn Fn(&str, &str) -> bool,
) -> Result<Vec<BagMessage>, BagError> {
    let mut out = Vec::new();
    for file in files(path)? {
        let bytes = std::fs::read(&file).map_err(io(&file))?;
        if let Some(end) = read_mcap(&file, &bytes, keep, &mut out)? {
            log::warn!("{}", end);
        }
    }
    out.sort_by_key(|m| m.log_time_ns);
    Ok(out)
}

/// Where a damaged file's readable part ends.
#[derive(Debug, Clone)]
pub struct Truncated {
    pub path: PathBuf,
    /// Messages read from the file before the break (of every channel).
    pub messages: usize,
    /// Log time of the last of them, ns.
    pub last_log_time_ns: u64,
    pub error: String,
}

impl std::fmt::Display for Truncated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: the bag ends early (a recorder that stopped?): read up to message {} at log time \
             {:.6} s, then: {}",
            self.path.display(),
            self.messages,
            self.last_log_time_ns as f64 * 1e-9,
            self.error
        )
    }
}

/// The largest record a bag may hold: 1 GiB (a PointCloud2 of 33 million 32-byte points),
/// and no more than 1024 bytes per byte of the file (a zstd chunk of a real cloud inflates
/// far less). The `mcap` crate sizes its buffers by the lengths the file declares, so a record
/// of 5·10¹⁸ bytes in a 4 KB file (found by fuzzing) would otherwise abort the process.
pub fn record_length_limit(file_len: usize) -> usize {
    file_len.saturating_mul(1024).clamp(64 << 20, 1 << 30)
}

/// The messages of one MCAP file's bytes (`file` names it in errors) that pass `keep`, appended
/// to `out` in file order. `Some` when the file breaks after at least one message: what was
/// read before the break is kept. Records longer than [`record_length_limit`] are refused
/// before anything of their size is allocated.
pub fn read_mcap(
    file: &Path,
    bytes: &[u8],
    keep: &dyn Fn(&str, &str) -> bool,
    out: &mut Vec<BagMessage>,
) -> Result<Option<Truncated>, BagError> {
    use mcap::records::{op, Record};
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let bad = |message: String| BagError::Mcap {
        path: file.to_owned(),
        message,
    };
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(record_length_limit(bytes.len())),
    );
    let mut rest = bytes;
    // Schema id → name; channel id → (topic, schema, encoding), shared by its messages, and
    // whether `keep` wants them (asked once per channel).
    let mut schemas: HashMap<u16, Arc<str>> = HashMap::new();
    let mut channels: HashMap<u16, (Names, bool)> = HashMap::new();
    let (mut read, mut last) = (0usize, 0u64);
    let broken = |error: String, read: usize, last: u64| {
        if read > 0 {
            Ok(Some(Truncated {
                path: file.to_owned(),
                messages: read,
                last_log_time_ns: last,
                error,
            }))
        } else {
            Err(bad(error))
        }
    };
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                // The reader asks again, forever, when nothing is left to give it.
                if rest.is_empty() {
                    let e = format!(
                        "the file ends in the middle of a record ({need} more bytes needed)"
                    );
                    return broken(e, read, last);
                }
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
                continue;
            }
            Ok(LinearReadEvent::Record { opcode, data }) => (opcode, data),
            Err(e) => return broken(e.to_string(), read, last),
        };
        // Only the records a replay uses are parsed: the others (attachments, indexes,
        // metadata) are skipped unread, and mcap 0.26 panics on a short attachment (found by
        // fuzzing).
        if ![op::SCHEMA, op::CHANNEL, op::MESSAGE].contains(&opcode) {
            continue;
        }
        match mcap::parse_record(opcode, data) {
            Ok(Record::Schema { header, .. }) => {
                schemas.insert(header.id, Arc::from(header.name.as_str()));
            }
            Ok(Record::Channel(c)) => {
                let schema = schemas
                    .get(&c.schema_id)
                    .cloned()
                    .unwrap_or_else(|| "".into());
                let kept = keep(&c.topic, &schema);
                let names = (
                    Arc::from(c.topic.as_str()),
                    schema,
                    Arc::from(c.message_encoding.as_str()),
                );
                channels.insert(c.id, (names, kept));
            }
            Ok(Record::Message { header, data }) => {
                let Some(((topic, schema, encoding), kept)) = channels.get(&header.channel_id)
                else {
                    let e = format!(
                        "message on channel {} before its Channel record",
                        header.channel_id
                    );
                    return broken(e, read, last);
                };
                read += 1;
                last = header.log_time;
                if *kept {
                    out.push(BagMessage {
                        topic: topic.clone(),
                        schema: schema.clone(),
                        encoding: encoding.clone(),
                        log_time_ns: header.log_time,
                        data: data.into_owned(),
                    });
                }
            }
            Ok(_) => {}
            Err(e) => return broken(e.to_string(), read, last),
        }
    }
    Ok(None)
}
