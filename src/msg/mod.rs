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
pub use type_hash::{hashed_description, service_hash, type_hash};
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
    decode_with(T::TYPE, payload, std::marker::PhantomData::<T>)
}

/// Decodes a CDR payload (either byte order, with its encapsulation header) into `T`'s owned
/// form: byte data is copied out of `payload`.
pub fn decode_owned<T: OwnedMessage>(payload: &[u8]) -> Result<T, MsgError> {
    decode_with(T::TYPE, payload, Owned::<T>::default())
}

/// Decodes a CDR payload of type `ty` through `seed`.
fn decode_with<'de, S: serde::de::DeserializeSeed<'de>>(
    ty: &'static str,
    payload: &'de [u8],
    seed: S,
) -> Result<S::Value, MsgError> {
    if payload.len() < 4 {
        return Err(MsgError::Short {
            ty,
            len: payload.len(),
        });
    }
    let body = &payload[4..];
    let decoded = match payload[1] {
        1 => seed.deserialize(&mut cdr_encoding::CdrDeserializer::<LittleEndian>::new(
            body,
        )),
        0 => seed.deserialize(&mut cdr_encoding::CdrDeserializer::<BigEndian>::new(body)),
        kind => return Err(MsgError::Encapsulation { ty, kind }),
    };
    decoded.map_err(|e| MsgError::Cdr {
        ty,
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
    (Clock::TYPE, Clock::OWN_DEFINITION),
    (Log::TYPE, Log::OWN_DEFINITION),
    (ParameterValue::TYPE, ParameterValue::OWN_DEFINITION),
    (Parameter::TYPE, Parameter::OWN_DEFINITION),
    (ParameterEvent::TYPE, ParameterEvent::OWN_DEFINITION),
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
    (Range::TYPE, Range::OWN_DEFINITION),
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

    /// A whole CDR payload (with its encapsulation header) that the caller owns, decoded. A
    /// cloud's or an image's byte data stays in `payload`'s own allocation (moved to its front
    /// in place) instead of being copied into a new one: a 9.8 MB cloud costs one pass over
    /// memory already touched, not an allocation, its page faults and a copy.
    fn from_payload(payload: Vec<u8>) -> Result<Self, MsgError> {
        decode_owned(&payload)
    }
}

/// Where `data` lies in `payload`; `None` when it is not part of it (decoded into its own
/// allocation).
fn range_in(payload: &[u8], data: &[u8]) -> Option<std::ops::Range<usize>> {
    let start = (data.as_ptr() as usize).checked_sub(payload.as_ptr() as usize)?;
    (start + data.len() <= payload.len()).then(|| start..start + data.len())
}

/// `payload` cut down to `range`, in place.
fn keep_range(
    mut payload: Vec<u8>,
    range: std::ops::Range<usize>,
) -> std::borrow::Cow<'static, [u8]> {
    let len = range.len();
    payload.copy_within(range, 0);
    payload.truncate(len);
    std::borrow::Cow::Owned(payload)
}

/// The seed that decodes an [`OwnedMessage`] (for subscriptions' `async_stream_seed` and
/// [`decode_owned`]). It holds
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
    StringMessage,
    Range,
    Clock,
    Log,
    ParameterEvent
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

    fn from_payload(payload: Vec<u8>) -> Result<Self, MsgError> {
        let m: PointCloud2<'_> = decode(&payload)?;
        let Some(range) = range_in(&payload, &m.data) else {
            return decode_owned(&payload);
        };
        let rest = PointCloud2 {
            header: m.header,
            height: m.height,
            width: m.width,
            fields: m.fields,
            is_bigendian: m.is_bigendian,
            point_step: m.point_step,
            row_step: m.row_step,
            data: std::borrow::Cow::Borrowed(&[][..]),
            is_dense: m.is_dense,
        };
        Ok(PointCloud2 {
            data: keep_range(payload, range),
            ..rest
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

    fn from_payload(payload: Vec<u8>) -> Result<Self, MsgError> {
        let m: Image<'_> = decode(&payload)?;
        let Some(range) = range_in(&payload, &m.data) else {
            return decode_owned(&payload);
        };
        let rest = Image {
            header: m.header,
            height: m.height,
            width: m.width,
            encoding: m.encoding,
            is_bigendian: m.is_bigendian,
            step: m.step,
            data: std::borrow::Cow::Borrowed(&[][..]),
        };
        Ok(Image {
            data: keep_range(payload, range),
            ..rest
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
    fn a_payload_keeps_its_allocation_for_the_byte_data() {
        let cloud = PointCloud2 {
            header: Header {
                stamp: Time::from_nanos(7),
                frame_id: "camera".into(),
            },
            height: 1,
            width: 3,
            fields: vec![PointField {
                name: "x".into(),
                offset: 0,
                datatype: 7,
                count: 1,
            }],
            is_bigendian: false,
            point_step: 4,
            row_step: 12,
            data: std::borrow::Cow::Owned((0u8..12).collect()),
            is_dense: true,
        };
        let payload = encode(&cloud).unwrap();
        let at = payload.as_ptr();
        let decoded = PointCloud2::from_payload(payload).unwrap();
        assert_eq!(decoded, cloud);
        assert_eq!(decoded.data.as_ptr(), at, "the data was copied elsewhere");
        let image = Image {
            encoding: "16UC1".into(),
            height: 1,
            width: 2,
            step: 4,
            data: std::borrow::Cow::Owned(vec![1, 2, 3, 4]),
            ..Image::default()
        };
        let payload = encode(&image).unwrap();
        let at = payload.as_ptr();
        let decoded = Image::from_payload(payload).unwrap();
        assert_eq!(decoded, image);
        assert_eq!(decoded.data.as_ptr(), at);
        // Others decode as ever; a short payload is an error, not a panic.
        assert_eq!(
            Float64::from_payload(encode(&Float64 { data: 2.0 }).unwrap()).unwrap(),
            Float64 { data: 2.0 }
        );
        assert!(PointCloud2::from_payload(vec![0, 1, 0, 0, 9]).is_err());
    }

    #[test]
    fn round_trip_little_endian() {
        let m = Float64 { data: -2.5 };
        assert_eq!(decode::<Float64>(&encode(&m).unwrap()).unwrap(), m);
    }
}
