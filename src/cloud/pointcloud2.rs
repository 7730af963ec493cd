//! `sensor_msgs/msg/PointCloud2` → [`Cloud`]: the checks that make a message usable, and the
//! extraction of `x y z` as f32 in the sensor frame.
//!
//! Accepted: x/y/z of any numeric datatype (FLOAT32 and FLOAT64 are the usual ones) at any
//! offsets, any `point_step`, `row_step` padding after each row, either byte order
//! (`is_bigendian`), organized (`height > 1`) or not, NaN holes (`is_dense` false). Rejected, with
//! an error that names the frame and the field: data shorter than `row_step × height`, a missing
//! x, y or z, an unknown datatype, a `count` other than 1 on x/y/z, a field that ends past
//! `point_step`, and fields whose bytes overlap. A rejected message is an error for that message
//! only; the caller goes on with the next one.
//!
//! Cost: one pass over the points. The common layout (FLOAT32 little endian on a little-endian
//! machine) reads three 4-byte words per point; a 640×480 cloud of 32-byte points decodes in
//! well under a millisecond (`cargo bench --bench decode`).

use rayon::prelude::*;

use crate::msg::{self, PointCloud2, PointField};

use super::{Cloud, CloudError, Scalar};

/// Decodes a CDR payload (with its encapsulation header) into the message, borrowing its data.
pub fn decode(payload: &[u8]) -> Result<PointCloud2<'_>, CloudError> {
    msg::decode(payload).map_err(|e| CloudError::Message(e.to_string()))
}

/// Decodes a CDR payload straight into a cloud.
pub fn cloud_from_cdr(payload: &[u8]) -> Result<Cloud, CloudError> {
    decode(payload)?.to_cloud()
}

fn scalar(datatype: u8) -> Option<Scalar> {
    Some(match datatype {
        PointField::FLOAT32 => Scalar::F32,
        PointField::FLOAT64 => Scalar::F64,
        PointField::INT8 => Scalar::I8,
        PointField::UINT8 => Scalar::U8,
        PointField::INT16 => Scalar::I16,
        PointField::UINT16 => Scalar::U16,
        PointField::INT32 => Scalar::I32,
        PointField::UINT32 => Scalar::U32,
        _ => return None,
    })
}

impl PointCloud2<'_> {
    fn error(&self, message: String) -> CloudError {
        CloudError::Message(format!("frame '{}': {message}", self.header.frame_id))
    }

    /// Checks the layout; returns the offset and type of x, y and z.
    fn xyz_layout(&self) -> Result<[(usize, Scalar); 3], CloudError> {
        let step = self.point_step as usize;
        let mut extents: Vec<(usize, usize, &str)> = Vec::with_capacity(self.fields.len());
        for f in &self.fields {
            let size = PointField::datatype_size(f.datatype).ok_or_else(|| {
                self.error(format!("field {}: datatype {} unknown", f.name, f.datatype))
            })?;
            let end = f.offset as usize + size * (f.count.max(1) as usize);
            if end > step {
                return Err(self.error(format!(
                    "field {}: bytes {}..{end} exceed point_step {step}",
                    f.name, f.offset
                )));
            }
            if let Some((_, _, other)) = extents
                .iter()
                .find(|(s, e, _)| (f.offset as usize) < *e && *s < end)
            {
                return Err(self.error(format!("fields {other} and {} overlap", f.name)));
            }
            extents.push((f.offset as usize, end, &f.name));
        }
        let field = |name: &str| -> Result<(usize, Scalar), CloudError> {
            let f = self
                .fields
                .iter()
                .find(|f| f.name == name)
                .ok_or_else(|| self.error(format!("no field {name}")))?;
            if f.count != 1 {
                return Err(self.error(format!("field {name}: count {} (expected 1)", f.count)));
            }
            // Checked above: every datatype here is known.
            let s = scalar(f.datatype)
                .ok_or_else(|| self.error(format!("field {name}: datatype unknown")))?;
            Ok((f.offset as usize, s))
        };
        Ok([field("x")?, field("y")?, field("z")?])
    }

    /// The points' `x y z` in order, row by row.
    pub fn to_cloud(&self) -> Result<Cloud, CloudError> {
        let xyz = self.xyz_layout()?;
        let (w, h) = (self.width as usize, self.height as usize);
        let step = self.point_step as usize;
        let row = self.row_step as usize;
        if w > 0 && row < w * step {
            return Err(self.error(format!(
                "row_step {row} is less than width {w} × point_step {step}"
            )));
        }
        if self.data.len() < h * row {
            return Err(self.error(format!(
                "data has {} bytes, less than row_step {row} × height {h}",
                self.data.len()
            )));
        }
        let big = self.is_bigendian;
        // Rows in parallel: each output row is written by one task, straight from its row of
        // bytes (the zeroed vector is calloc'd, so its pages are touched by the tasks too).
        let mut points = vec![[0.0f32; 3]; w * h];
        if w == 0 || h == 0 {
            return Ok(self.cloud(points));
        }
        let rows = self.data.par_chunks(row).take(h);
        let out = points.par_chunks_mut(w);
        if xyz.iter().all(|f| f.1 == Scalar::F32) && big == cfg!(target_endian = "big") {
            let [ox, oy, oz] = xyz.map(|(o, _)| o);
            let word =
                |p: &[u8], o: usize| f32::from_ne_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]]);
            out.zip(rows).for_each(|(out, line)| {
                for (q, p) in out.iter_mut().zip(line.chunks_exact(step)) {
                    *q = [word(p, ox), word(p, oy), word(p, oz)];
                }
            });
        } else {
            out.zip(rows).for_each(|(out, line)| {
                for (q, p) in out.iter_mut().zip(line.chunks_exact(step)) {
                    *q = xyz.map(|(o, s)| s.read(&p[o..], big));
                }
            });
        }
        Ok(self.cloud(points))
    }

    fn cloud(&self, points: Vec<[f32; 3]>) -> Cloud {
        Cloud {
            points,
            width: self.width,
            height: self.height,
            frame_id: Some(self.header.frame_id.clone()),
            stamp: Some((self.header.stamp.sec, self.header.stamp.nanosec)),
        }
    }
}
