//! ROS 2 messages: serde structs whose fields follow the `.msg` files (each struct names its
//! file), their CDR encoding, and the message definitions that MCAP schemas carry.
//!
//! ros2-client ships no `sensor_msgs` and friends, so the messages the node reads and writes are
//! written here: `builtin_interfaces`, `std_msgs`, `geometry_msgs`, `tf2_msgs`, `sensor_msgs`,
//! `visualization_msgs`, `diagnostic_msgs` and `control_msgs`.
//!
//! - **CDR.** A payload (rosbag2, DDS) is a 4-byte encapsulation header — `00 01` little endian,
//!   `00 00` big endian, then two option bytes — followed by the message in plain CDR, encoded and
//!   decoded by `cdr-encoding` through the serde derive. Byte sequences (`uint8[]`) go through
//!   `serde_bytes`, so a 10 MB cloud is one copy, not ten million calls; decoding borrows them.
//! - **Definitions.** Each message states its own `.msg` text ([`RosMessage::OWN_DEFINITION`]);
//!   [`definition`] appends the definitions it depends on in the form `ros2 bag record` and
//!   rosbags write (`====…` then `MSG: pkg/Type`), which Foxglove and rosbags need to decode a
//!   channel. Tests check the bytes and the definitions against the Python `rosbags` package.
//!
//! Files: one per message package (`builtin`, `geometry`, `sensor`, `visualization`,
//! `diagnostic`, `control`), `message` (the trait each states), `cdr` (payloads), `owned` (whole
//! messages, decoded in place), `definition` (schemas), `type_hash` (REP-2016 hashes) and
//! `writer` (who wrote a message: one voice per input).

mod builtin;
mod cdr;
mod control;
mod definition;
mod diagnostic;
mod geometry;
mod message;
mod owned;
mod sensor;
mod type_hash;
mod visualization;
mod writer;

pub use builtin::*;
pub use cdr::{decode, encode, MsgError};
pub use control::*;
pub use definition::{definition, types};
pub use diagnostic::*;
pub use geometry::*;
pub use message::RosMessage;
pub use owned::{decode_owned, Owned, OwnedMessage};
pub use sensor::*;
pub use type_hash::{hashed_description, service_hash, type_hash};
pub use visualization::*;
pub use writer::{Voices, Writer, MAX_WRITERS};
