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

mod builtin;
mod control;
mod diagnostic;
mod geometry;
mod sensor;
mod type_hash;
mod visualization;

pub use builtin::*;
pub use control::*;
pub use diagnostic::*;
pub use geometry::*;
pub use sensor::*;
pub use type_hash::{hashed_description, type_hash};
pub use visualization::*;

use byteorder::{BigEndian, LittleEndian};
use serde::{Deserialize, Serialize};

/// A message type: its ROS 2 name and its own `.msg` text (constants first, then fields).
pub trait RosMessage: Serialize {
    /// `pkg/msg/Type`.
    const TYPE: &'static str;
    /// The `.msg` text without comments, as rosbags prints it.
    const OWN_DEFINITION: &'static str;
}

macro_rules! ros_message {
    ($ty:ty, $name:literal, $definition:literal) => {
        impl $crate::msg::RosMessage for $ty {
            const TYPE: &'static str = $name;
            const OWN_DEFINITION: &'static str = $definition;
        }
    };
}
pub(crate) use ros_message;

#[derive(Debug, thiserror::Error)]
pub enum MsgError {
    #[error("{ty}: payload of {len} bytes is shorter than the CDR encapsulation header")]
    Short { ty: &'static str, len: usize },
    #[error("{ty}: encapsulation {kind:#04x} is not plain CDR")]
    Encapsulation { ty: &'static str, kind: u8 },
    #[error("{ty}: CDR: {message}")]
    Cdr { ty: &'static str, message: String },
}

/// Encodes a message as a little-endian CDR payload with its encapsulation header.
pub fn encode<T: RosMessage>(message: &T) -> Result<Vec<u8>, MsgError> {
    let mut out = vec![0u8, 1, 0, 0];
    cdr_encoding::to_writer::<T, LittleEndian, _>(&mut out, message).map_err(|e| {
        MsgError::Cdr {
            ty: T::TYPE,
            message: e.to_string(),
        }
    })?;
    Ok(out)
}

/// Decodes a CDR payload (either byte order) with its encapsulation header. Byte sequences
/// borrow from `payload`.
pub fn decode<'de, T: RosMessage + Deserialize<'de>>(payload: &'de [u8]) -> Result<T, MsgError> {
    if payload.len() < 4 {
        return Err(MsgError::Short {
            ty: T::TYPE,
            len: payload.len(),
        });
    }
    let body = &payload[4..];
    let decoded = match payload[1] {
        1 => cdr_encoding::from_bytes::<T, LittleEndian>(body),
        0 => cdr_encoding::from_bytes::<T, BigEndian>(body),
        kind => return Err(MsgError::Encapsulation { ty: T::TYPE, kind }),
    };
    decoded.map(|(m, _)| m).map_err(|e| MsgError::Cdr {
        ty: T::TYPE,
        message: e.to_string(),
    })
}

/// The own definitions of every message here and of the nested types they use.
const OWN_DEFINITIONS: &[(&str, &str)] = &[
    (Time::TYPE, Time::OWN_DEFINITION),
    (Duration::TYPE, Duration::OWN_DEFINITION),
    (Header::TYPE, Header::OWN_DEFINITION),
    (Float64::TYPE, Float64::OWN_DEFINITION),
    (StringMessage::TYPE, StringMessage::OWN_DEFINITION),
    (Bool::TYPE, Bool::OWN_DEFINITION),
    (ColorRgba::TYPE, ColorRgba::OWN_DEFINITION),
    (Vector3::TYPE, Vector3::OWN_DEFINITION),
    (Quaternion::TYPE, Quaternion::OWN_DEFINITION),
    (Point::TYPE, Point::OWN_DEFINITION),
    (Pose::TYPE, Pose::OWN_DEFINITION),
    (Transform::TYPE, Transform::OWN_DEFINITION),
    (TransformStamped::TYPE, TransformStamped::OWN_DEFINITION),
    (TfMessage::TYPE, TfMessage::OWN_DEFINITION),
    (PointField::TYPE, PointField::OWN_DEFINITION),
    (PointCloud2::TYPE, PointCloud2::OWN_DEFINITION),
    (JointState::TYPE, JointState::OWN_DEFINITION),
    (Image::TYPE, Image::OWN_DEFINITION),
    (CompressedImage::TYPE, CompressedImage::OWN_DEFINITION),
    (RegionOfInterest::TYPE, RegionOfInterest::OWN_DEFINITION),
    (CameraInfo::TYPE, CameraInfo::OWN_DEFINITION),
    (UvCoordinate::TYPE, UvCoordinate::OWN_DEFINITION),
    (MeshFile::TYPE, MeshFile::OWN_DEFINITION),
    (Marker::TYPE, Marker::OWN_DEFINITION),
    (MarkerArray::TYPE, MarkerArray::OWN_DEFINITION),
    (KeyValue::TYPE, KeyValue::OWN_DEFINITION),
    (DiagnosticStatus::TYPE, DiagnosticStatus::OWN_DEFINITION),
    (DiagnosticArray::TYPE, DiagnosticArray::OWN_DEFINITION),
    (SpeedScalingFactor::TYPE, SpeedScalingFactor::OWN_DEFINITION),
];

/// Every message type this module defines, by ROS 2 name.
pub fn types() -> impl Iterator<Item = &'static str> {
    OWN_DEFINITIONS.iter().map(|(t, _)| *t)
}

/// The full `ros2msg` definition of `ty` (`pkg/msg/Type`): its own text, then each nested type
/// once, depth first in field order, after a line of 80 `=` and `MSG: pkg/Type`.
pub fn definition(ty: &str) -> Option<String> {
    fn own(ty: &str) -> Option<&'static str> {
        OWN_DEFINITIONS
            .iter()
            .find(|(t, _)| *t == ty)
            .map(|(_, d)| *d)
    }
    // A field line `pkg/Type name` or `pkg/Type[] name` → `pkg/msg/Type`; constants and
    // basic types have no `/`.
    fn nested(line: &str) -> Option<String> {
        let ty = line.split_whitespace().next()?.split('[').next()?;
        let (pkg, name) = ty.split_once('/').filter(|_| !line.contains('='))?;
        Some(format!("{pkg}/msg/{name}"))
    }
    fn visit(ty: &str, seen: &mut Vec<String>, out: &mut String) -> Option<()> {
        for line in own(ty)?.lines() {
            if let Some(n) = nested(line) {
                if !seen.contains(&n) {
                    seen.push(n.clone());
                    out.push_str(&"=".repeat(80));
                    out.push_str("\nMSG: ");
                    out.push_str(&n.replace("/msg/", "/"));
                    out.push('\n');
                    out.push_str(own(&n)?);
                    visit(&n, seen, out)?;
                }
            }
        }
        Some(())
    }
    let mut out = own(ty)?.to_owned();
    let mut seen = vec![ty.to_owned()];
    visit(ty, &mut seen, &mut out)?;
    Some(out)
}

/// A message the node and its tools send and receive whole: it decodes into its owned
/// (`'static`) form; messages that borrow their byte data from the sample (`PointCloud2`,
/// `MarkerArray`) copy it out once.
pub trait OwnedMessage: RosMessage + std::fmt::Debug + Send + Sync + Sized + 'static {
    fn deserialize_owned<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error>;
}

/// The seed that decodes an [`OwnedMessage`] (for subscriptions' `async_stream_seed`). It holds
/// no `T`, so it is `Copy` whatever `T` is.
pub struct Owned<T>(std::marker::PhantomData<fn() -> T>);

impl<T> Clone for Owned<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Owned<T> {}

impl<T> Default for Owned<T> {
    fn default() -> Self {
        Self(std::marker::PhantomData)
    }
}

impl<'de, T: OwnedMessage> serde::de::DeserializeSeed<'de> for Owned<T> {
    type Value = T;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<T, D::Error> {
        T::deserialize_owned(d)
    }
}

macro_rules! owned_as_is {
    ($($ty:ty),*) => {$(
        impl OwnedMessage for $ty {
            fn deserialize_owned<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                <$ty>::deserialize(d)
            }
        }
    )*};
}
owned_as_is!(
    Float64,
    Bool,
    JointState,
    DiagnosticArray,
    TfMessage,
    SpeedScalingFactor,
    CameraInfo,
    StringMessage
);

/// `data` copied out of the sample.
fn owned_bytes(data: std::borrow::Cow<'_, [u8]>) -> std::borrow::Cow<'static, [u8]> {
    std::borrow::Cow::Owned(data.into_owned())
}

impl OwnedMessage for PointCloud2<'static> {
    fn deserialize_owned<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let m = PointCloud2::deserialize(d)?;
        Ok(PointCloud2 {
            data: owned_bytes(m.data),
            ..m
        })
    }
}

impl OwnedMessage for Image<'static> {
    fn deserialize_owned<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let m = Image::deserialize(d)?;
        Ok(Image {
            data: owned_bytes(m.data),
            ..m
        })
    }
}

impl OwnedMessage for MarkerArray<'static> {
    fn deserialize_owned<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let m = MarkerArray::deserialize(d)?;
        let markers = m
            .markers
            .into_iter()
            .map(|k| Marker {
                texture: CompressedImage {
                    data: owned_bytes(k.texture.data),
                    ..k.texture
                },
                mesh_file: MeshFile {
                    data: owned_bytes(k.mesh_file.data),
                    ..k.mesh_file
                },
                ..k
            })
            .collect();
        Ok(MarkerArray { markers })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_nested_type_has_a_definition() {
        for ty in types() {
            assert!(definition(ty).is_some(), "{ty}");
        }
    }

    #[test]
    fn short_and_foreign_payloads_are_errors() {
        assert!(matches!(
            decode::<Float64>(&[0, 1]),
            Err(MsgError::Short { .. })
        ));
        assert!(matches!(
            decode::<Float64>(&[0, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]),
            Err(MsgError::Encapsulation { kind: 7, .. })
        ));
        assert!(matches!(
            decode::<Float64>(&[0, 1, 0, 0, 1]),
            Err(MsgError::Cdr { .. })
        ));
    }

    #[test]
    fn round_trip_little_endian() {
        let m = Float64 { data: -2.5 };
        assert_eq!(decode::<Float64>(&encode(&m).unwrap()).unwrap(), m);
    }
}
