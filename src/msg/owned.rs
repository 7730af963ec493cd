//! Messages the node and its tools send and receive whole, decoded into their owned
//! (`'static`) form: a cloud's or an image's byte data stays in the payload's own allocation
//! (moved to its front in place), other byte data is copied out once; and the seed that
//! subscriptions decode through.

use serde::Deserialize;

use super::builtin::{Bool, Clock, Float64, Log, ParameterEvent, StringMessage};
use super::cdr::{decode, decode_with, MsgError};
use super::control::SpeedScalingFactor;
use super::diagnostic::DiagnosticArray;
use super::geometry::TfMessage;
use super::message::RosMessage;
use super::sensor::{CameraInfo, CompressedImage, Image, JointState, PointCloud2, Range};
use super::visualization::{Marker, MarkerArray, MeshFile};

/// Decodes a CDR payload (either byte order, with its encapsulation header) into `T`'s owned
/// form: byte data is copied out of `payload`.
pub fn decode_owned<T: OwnedMessage>(payload: &[u8]) -> Result<T, MsgError> {
    decode_with(T::TYPE, payload, Owned::<T>::default())
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
    use crate::msg::builtin::{Float64, Header, Time};
    use crate::msg::cdr::encode;
    use crate::msg::sensor::PointField;

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
}
