//! `sensor_msgs/msg/PointCloud2` and the messages it contains, as serde structs that follow the
//! `.msg` files field by field (ros2-client ships no `sensor_msgs`), decoded from CDR with
//! `cdr-encoding`, and the extraction of `x y z`.
//!
//! A CDR payload (rosbag2, DDS) starts with a 4-byte encapsulation header: `00 01` little
//! endian, `00 00` big endian, then two option bytes.

use byteorder::{BigEndian, LittleEndian};
use serde::{Deserialize, Serialize};

use super::{Cloud, CloudError, Scalar};

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/msg/PointField`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

impl PointField {
    pub const INT8: u8 = 1;
    pub const UINT8: u8 = 2;
    pub const INT16: u8 = 3;
    pub const UINT16: u8 = 4;
    pub const INT32: u8 = 5;
    pub const UINT32: u8 = 6;
    pub const FLOAT32: u8 = 7;
    pub const FLOAT64: u8 = 8;
}

/// `sensor_msgs/msg/PointCloud2`, borrowing its data from the payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2<'a> {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    #[serde(borrow)]
    pub data: &'a [u8],
    pub is_dense: bool,
}

/// Decodes a CDR payload (with its encapsulation header).
pub fn decode(payload: &[u8]) -> Result<PointCloud2<'_>, CloudError> {
    if payload.len() < 4 {
        return Err(CloudError::Message(
            "payload shorter than the CDR header".into(),
        ));
    }
    let body = &payload[4..];
    let r = match payload[1] {
        1 => cdr_encoding::from_bytes::<PointCloud2, LittleEndian>(body),
        0 => cdr_encoding::from_bytes::<PointCloud2, BigEndian>(body),
        k => {
            return Err(CloudError::Message(format!(
                "CDR encapsulation {k} is not plain CDR"
            )))
        }
    };
    r.map(|(m, _)| m)
        .map_err(|e| CloudError::Message(format!("CDR: {e}")))
}

impl PointCloud2<'_> {
    /// The points' `x y z` in order, row by row.
    pub fn to_cloud(&self) -> Result<Cloud, CloudError> {
        let err = |m: String| CloudError::Message(format!("frame {}: {m}", self.header.frame_id));
        let field = |name: &str| -> Result<(usize, Scalar), CloudError> {
            let f = self
                .fields
                .iter()
                .find(|f| f.name == name)
                .ok_or_else(|| err(format!("no field {name}")))?;
            let scalar = match f.datatype {
                PointField::FLOAT32 => Scalar::F32,
                PointField::FLOAT64 => Scalar::F64,
                PointField::INT8 => Scalar::I8,
                PointField::UINT8 => Scalar::U8,
                PointField::INT16 => Scalar::I16,
                PointField::UINT16 => Scalar::U16,
                PointField::INT32 => Scalar::I32,
                PointField::UINT32 => Scalar::U32,
                k => return Err(err(format!("field {name}: datatype {k} unknown"))),
            };
            if f.offset as usize + scalar.size() > self.point_step as usize {
                return Err(err(format!(
                    "field {name}: offset {} + size {} exceeds point_step {}",
                    f.offset,
                    scalar.size(),
                    self.point_step
                )));
            }
            Ok((f.offset as usize, scalar))
        };
        let xyz = [field("x")?, field("y")?, field("z")?];
        let (w, h) = (self.width as usize, self.height as usize);
        let step = self.point_step as usize;
        let row = self.row_step as usize;
        if w > 0 && row < w * step {
            return Err(err(format!(
                "row_step {row} is less than width {w} × point_step {step}"
            )));
        }
        if h > 0 && w > 0 && self.data.len() < (h - 1) * row + w * step {
            return Err(err(format!(
                "data has {} bytes, {h} rows of {row} need {}",
                self.data.len(),
                (h - 1) * row + w * step
            )));
        }
        let big = self.is_bigendian;
        let mut points = Vec::with_capacity(w * h);
        if xyz.iter().all(|f| f.1 == Scalar::F32) && !big && cfg!(target_endian = "little") {
            for r in 0..h {
                let line = &self.data[r * row..];
                for c in 0..w {
                    let p = &line[c * step..];
                    points.push(
                        xyz.map(|(o, _)| f32::from_le_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]])),
                    );
                }
            }
        } else {
            for r in 0..h {
                let line = &self.data[r * row..];
                for c in 0..w {
                    let p = &line[c * step..];
                    points.push(xyz.map(|(o, s)| s.read(&p[o..], big)));
                }
            }
        }
        Ok(Cloud {
            points,
            width: self.width,
            height: self.height,
            frame_id: Some(self.header.frame_id.clone()),
            stamp: Some((self.header.stamp.sec, self.header.stamp.nanosec)),
        })
    }
}
