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

use super::error::CloudError;
use super::points::Cloud;
use super::scalar::Scalar;

/// Decodes a CDR payload (with its encapsulation header) into the message, borrowing its data.
pub fn decode(payload: &[u8]) -> Result<PointCloud2<'_>, CloudError> {
    Ok(msg::decode(payload)?)
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
        CloudError::Layout {
            frame: self.header.frame_id.clone(),
            message,
        }
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
            // FLOAT64 and 32-bit integer coordinates may not fit f32: the largest rounding
            // (and the value it happened at) is kept, and beyond MAX_ROUNDING_M the cloud is
            // refused rather than measured at points that are not the ones published.
            let worst = out
                .zip(rows)
                .map(|(out, line)| {
                    let mut worst = (0.0f64, 0.0f64);
                    for (q, p) in out.iter_mut().zip(line.chunks_exact(step)) {
                        *q = xyz.map(|(o, s)| {
                            let v = s.read_f64(&p[o..], big);
                            let r = v as f32;
                            let loss = (v - r as f64).abs();
                            if loss > worst.0 {
                                worst = (loss, v);
                            }
                            r
                        });
                    }
                    worst
                })
                .reduce(|| (0.0, 0.0), |a, b| if a.0 >= b.0 { a } else { b });
            if worst.0 > MAX_ROUNDING_M {
                return Err(self.error(format!(
                    "x/y/z value {} moves by {:.2e} m when rounded to f32 (at most \
                     {MAX_ROUNDING_M} m is taken): publish the cloud in a frame near the robot",
                    worst.1, worst.0
                )));
            }
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

/// The most a FLOAT64 (or 32-bit integer) coordinate may move when rounded to the f32 the
/// query works in, m: about the rounding of the query's own f32 transforms. A FLOAT64 cloud in a
/// frame far from the robot (beyond ~256 m from its origin) moves by more and is refused; an
/// f32 cloud there is measured exactly as published (`query::pose`).
pub const MAX_ROUNDING_M: f64 = 1e-5;

/// The colour [`encode`] gives a point (red, green, blue).
pub type Colour = fn([f32; 3]) -> [u8; 3];

/// The layout of a PointCloud2 that [`encode`] writes: `x y z` of one datatype at offsets 0,
/// s and 2s (s = 4 for FLOAT32, 8 for FLOAT64), then padding up to `point_step`, with an
/// optional packed `rgb` FLOAT32 field; `row_padding` bytes after each row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    pub width: u32,
    pub height: u32,
    /// `PointField::FLOAT32` or `PointField::FLOAT64`.
    pub datatype: u8,
    pub big_endian: bool,
    pub point_step: u32,
    pub row_padding: u32,
    /// An `rgb` field at this offset, its colour made from the point (FLOAT32, the packed
    /// `0x00RRGGBB` bits that RGB-D drivers publish).
    pub rgb: Option<(u32, Colour)>,
    /// The value of padding bytes.
    pub pad: u8,
}

impl Layout {
    /// An unorganized cloud of `n` points, FLOAT32 little endian, 16-byte points.
    pub fn unorganized(n: u32) -> Self {
        Self {
            width: n,
            height: 1,
            datatype: PointField::FLOAT32,
            big_endian: false,
            point_step: 16,
            row_padding: 0,
            rgb: None,
            pad: 0,
        }
    }
}

/// Encodes `points` (row by row, `width × height` of them) as a PointCloud2 of `layout`.
/// Refused with an error: a count that does not match, an unknown datatype, fields that do not
/// fit in `point_step`.
pub fn encode(
    header: msg::Header,
    points: &[[f32; 3]],
    layout: &Layout,
) -> Result<PointCloud2<'static>, CloudError> {
    let bad = |message: String| CloudError::Layout {
        frame: header.frame_id.clone(),
        message: format!("cannot encode: {message}"),
    };
    let size: u32 = match layout.datatype {
        PointField::FLOAT32 => 4,
        PointField::FLOAT64 => 8,
        other => return Err(bad(format!("datatype {other} (FLOAT32 or FLOAT64 only)"))),
    };
    let n = layout.width as u64 * layout.height as u64;
    if n != points.len() as u64 {
        return Err(bad(format!(
            "{} points for {}×{}",
            points.len(),
            layout.width,
            layout.height
        )));
    }
    let end = layout.rgb.map_or(3 * size, |(o, _)| (o + 4).max(3 * size));
    if layout.point_step < end || layout.rgb.is_some_and(|(o, _)| o < 3 * size) {
        return Err(bad(format!(
            "fields need {end} bytes without overlap; point_step is {}",
            layout.point_step
        )));
    }
    let step = layout.point_step as usize;
    let row_step = step * layout.width as usize + layout.row_padding as usize;
    let mut data = vec![layout.pad; row_step * layout.height as usize];
    let put = |at: &mut [u8], v: f64| match (layout.datatype, layout.big_endian) {
        (PointField::FLOAT64, true) => at[..8].copy_from_slice(&v.to_be_bytes()),
        (PointField::FLOAT64, false) => at[..8].copy_from_slice(&v.to_le_bytes()),
        (_, true) => at[..4].copy_from_slice(&(v as f32).to_be_bytes()),
        (_, false) => at[..4].copy_from_slice(&(v as f32).to_le_bytes()),
    };
    for (i, p) in points.iter().enumerate() {
        let (row, col) = (i / layout.width as usize, i % layout.width as usize);
        let point = &mut data[row * row_step + col * step..][..step];
        for (k, &v) in p.iter().enumerate() {
            put(&mut point[k * size as usize..], v as f64);
        }
        if let Some((offset, color)) = layout.rgb {
            let [r, g, b] = color(*p);
            let bits = (r as u32) << 16 | (g as u32) << 8 | b as u32;
            let v = f32::from_bits(bits);
            let at = &mut point[offset as usize..offset as usize + 4];
            at.copy_from_slice(&if layout.big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            });
        }
    }
    let field = |name: &str, offset: u32, datatype: u8| PointField {
        name: name.into(),
        offset,
        datatype,
        count: 1,
    };
    let mut fields = vec![
        field("x", 0, layout.datatype),
        field("y", size, layout.datatype),
        field("z", 2 * size, layout.datatype),
    ];
    if let Some((offset, _)) = layout.rgb {
        fields.push(field("rgb", offset, PointField::FLOAT32));
    }
    Ok(PointCloud2 {
        header,
        height: layout.height,
        width: layout.width,
        fields,
        is_bigendian: layout.big_endian,
        point_step: layout.point_step,
        row_step: row_step as u32,
        // ROS's meaning: no NaN or infinite coordinate.
        is_dense: points.iter().flatten().all(|v| v.is_finite()),
        data: std::borrow::Cow::Owned(data),
    })
}
