//! CDR payloads: a 4-byte encapsulation header (`00 01` little endian, `00 00` big endian, then
//! two option bytes) followed by the message in plain CDR, encoded and decoded by
//! `cdr-encoding` through the serde derive. Decoding borrows byte sequences from the payload.

use byteorder::{BigEndian, LittleEndian};
use serde::Deserialize;

use super::message::RosMessage;

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

/// Decodes a CDR payload of type `ty` through `seed`.
pub(super) fn decode_with<'de, S: serde::de::DeserializeSeed<'de>>(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::builtin::Float64;

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
