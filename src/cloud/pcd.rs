//! PCL's PCD format, read with the `pcd-rs` crate: `ascii`, `binary` and `binary_compressed`
//! (LZF, fields stored one after the other), any field layout. The fields named `x`, `y` and `z`
//! are taken, whatever their position and numeric type; the others are skipped.
//!
//! Before `pcd-rs` sees the file, its header is checked against the bytes present
//! ([`check_header`]): `WIDTH × HEIGHT = POINTS ≤ MAX_POINTS`, binary data of exactly
//! `POINTS × record` bytes, a compressed block that lies within the file and inflates to exactly
//! that (and no more than LZF can inflate, 88 bytes per 3), an ascii body of `POINTS` lines.
//! `pcd-rs` allocates what the header says and slices by it, so a lying header would otherwise
//! abort on a huge allocation or panic.

use std::path::Path;

use pcd_rs::record::{DynRecord, Field};

use super::error::CloudError;
use super::header::{header_line, read};
use super::points::{Cloud, MAX_POINTS};

/// The largest LZF inflation: a back reference of 3 bytes gives at most 264 bytes.
const LZF_MAX_RATIO: u64 = 88;

pub fn load(path: &Path) -> Result<Cloud, CloudError> {
    parse(&read(path)?).map_err(|message| CloudError::Pcd {
        path: path.to_owned(),
        message,
    })
}

/// Parses a PCD file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Cloud, String> {
    check_header(bytes)?;
    let reader = pcd_rs::DynReader::from_bytes(bytes).map_err(|e| e.to_string())?;
    let meta = reader.meta().clone();
    let find = |axis: &str| {
        meta.field_defs
            .iter()
            .position(|f| f.name == axis)
            .ok_or_else(|| format!("no field {axis}"))
    };
    let xyz = [find("x")?, find("y")?, find("z")?];
    let mut points = Vec::with_capacity(meta.num_points as usize);
    for (i, record) in reader.enumerate() {
        let record: DynRecord = record.map_err(|e| format!("point {i}: {e}"))?;
        let mut p = [0.0f32; 3];
        for (k, &f) in xyz.iter().enumerate() {
            p[k] =
                record.0.get(f).and_then(first_value).ok_or_else(|| {
                    format!("point {i}: field {} has no value", ["x", "y", "z"][k])
                })?;
        }
        points.push(p);
    }
    if points.len() as u64 != meta.num_points {
        return Err(format!(
            "{} points read, the header says {}",
            points.len(),
            meta.num_points
        ));
    }
    Ok(Cloud {
        points,
        width: meta.width as u32,
        height: meta.height as u32,
        frame_id: None,
        stamp: None,
    })
}

/// The first value of a field, as f32 (coordinates are f32 in the query).
fn first_value(field: &Field) -> Option<f32> {
    Some(match field {
        Field::I8(v) => *v.first()? as f32,
        Field::I16(v) => *v.first()? as f32,
        Field::I32(v) => *v.first()? as f32,
        Field::I64(v) => *v.first()? as f32,
        Field::U8(v) => *v.first()? as f32,
        Field::U16(v) => *v.first()? as f32,
        Field::U32(v) => *v.first()? as f32,
        Field::U64(v) => *v.first()? as f32,
        Field::F32(v) => *v.first()?,
        Field::F64(v) => *v.first()? as f32,
    })
}

/// Checks a PCD file's header against its data (see the module documentation).
pub fn check_header(bytes: &[u8]) -> Result<(), String> {
    let mut pos = 0;
    let mut sizes: Vec<u64> = Vec::new();
    let mut counts: Option<Vec<u64>> = None;
    let (mut width, mut height, mut points) = (None, None, None);
    let data = loop {
        let line = header_line(bytes, &mut pos, "its DATA line")?;
        let words: Vec<&str> = line.split_whitespace().collect();
        let numbers = |what: &str| -> Result<Vec<u64>, String> {
            words[1..]
                .iter()
                .map(|w| w.parse::<u64>().map_err(|_| format!("{what} {w:?}")))
                .collect()
        };
        let one = |what: &str| -> Result<u64, String> {
            match numbers(what)?.as_slice() {
                [n] => Ok(*n),
                _ => Err(format!("{what} line {line:?}")),
            }
        };
        match words.first().copied() {
            Some("SIZE") => sizes = numbers("SIZE")?,
            Some("COUNT") => counts = Some(numbers("COUNT")?),
            Some("WIDTH") => width = Some(one("WIDTH")?),
            Some("HEIGHT") => height = Some(one("HEIGHT")?),
            Some("POINTS") => points = Some(one("POINTS")?),
            Some("DATA") => break words.get(1).copied().unwrap_or_default().to_owned(),
            _ => {}
        }
    };
    let (width, height) = (width.ok_or("no WIDTH")?, height.ok_or("no HEIGHT")?);
    let points = points.ok_or("no POINTS")?;
    if width.checked_mul(height) != Some(points) {
        return Err(format!(
            "WIDTH {width} × HEIGHT {height} is not POINTS {points}"
        ));
    }
    if points > MAX_POINTS {
        return Err(format!(
            "POINTS {points}: more than the {MAX_POINTS} points a cloud may have"
        ));
    }
    let counts = counts.unwrap_or_else(|| vec![1; sizes.len()]);
    if counts.len() != sizes.len() {
        return Err(format!(
            "{} COUNT values for {} SIZE values",
            counts.len(),
            sizes.len()
        ));
    }
    let record = sizes
        .iter()
        .zip(&counts)
        .try_fold(0u64, |r, (s, c)| {
            s.checked_mul(*c).and_then(|b| r.checked_add(b))
        })
        .filter(|&r| r > 0)
        .ok_or("SIZE × COUNT: no bytes per point, or too many")?;
    let need = points
        .checked_mul(record)
        .ok_or_else(|| format!("POINTS {points} × {record} bytes overflows"))?;
    let body = &bytes[pos..];
    let len = body.len() as u64;
    match data.as_str() {
        "ascii" => {
            let lines = body
                .split(|&b| b == b'\n')
                .filter(|l| !l.trim_ascii().is_empty())
                .count() as u64;
            if lines != points {
                return Err(format!("POINTS {points}, but {lines} lines of data"));
            }
        }
        "binary" if len != need => {
            return Err(format!(
                "POINTS {points} × {record} bytes is {need} bytes, the data is {len}"
            ));
        }
        "binary" => {}
        "binary_compressed" => {
            let word = |k: usize| -> Option<u64> {
                Some(u32::from_le_bytes(body.get(4 * k..4 * k + 4)?.try_into().ok()?) as u64)
            };
            let (Some(compressed), Some(inflated)) = (word(0), word(1)) else {
                return Err("binary_compressed data shorter than its 8-byte sizes".into());
            };
            if compressed > len - 8 {
                return Err(format!(
                    "binary_compressed block of {compressed} bytes, {} present",
                    len - 8
                ));
            }
            if inflated != need {
                return Err(format!(
                    "binary_compressed block inflates to {inflated} bytes, \
                     POINTS {points} × {record} bytes is {need}"
                ));
            }
            if inflated > compressed.saturating_mul(LZF_MAX_RATIO) {
                return Err(format!(
                    "binary_compressed: {compressed} bytes cannot inflate to {inflated}"
                ));
            }
        }
        other => {
            return Err(format!(
                "DATA {other:?} (expected ascii, binary or binary_compressed)"
            ))
        }
    }
    Ok(())
}
