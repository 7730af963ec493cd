//! PCL's PCD format (v0.7; v0.6 headers without VIEWPOINT also read).
//!
//! The header names the fields (`FIELDS x y z rgb`), their byte size, type (`I`, `U`, `F`) and
//! count, the size (`WIDTH`, `HEIGHT`, `POINTS`) and the encoding (`DATA`):
//! - `ascii`: one point per line, values separated by spaces (`nan` allowed);
//! - `binary`: the points one after the other, each the fields' bytes in order (little endian);
//! - `binary_compressed`: two u32 (compressed and uncompressed size) then LZF-compressed bytes
//!   holding the fields one after the other (all x, then all y, …), which compresses better.
//!
//! LZF is decoded by the `lzf-rust` crate.

use std::path::Path;

use super::{read, Cloud, CloudError, Scalar};

struct Field {
    name: String,
    scalar: Scalar,
    count: usize,
}

pub fn load(path: &Path) -> Result<Cloud, CloudError> {
    parse(&read(path)?).map_err(|message| CloudError::Pcd {
        path: path.to_owned(),
        message,
    })
}

/// Parses a PCD file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Cloud, String> {
    let mut names: Vec<String> = Vec::new();
    let mut sizes: Vec<usize> = Vec::new();
    let mut types: Vec<char> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    let (mut width, mut height, mut points) = (None, 1u32, None);
    let mut pos = 0;
    let data = loop {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or("header ends before DATA")?;
        let line = std::str::from_utf8(&bytes[pos..pos + end])
            .map_err(|_| "header is not text")?
            .trim();
        pos += end + 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let rest: Vec<&str> = words.collect();
        let number = |w: &str| {
            w.parse::<usize>()
                .map_err(|_| format!("{key}: {w:?} is not a number"))
        };
        match key.as_str() {
            "VERSION" | "VIEWPOINT" => {}
            "FIELDS" | "COLUMNS" => names = rest.iter().map(|s| s.to_string()).collect(),
            "SIZE" => sizes = rest.iter().map(|w| number(w)).collect::<Result<_, _>>()?,
            "TYPE" => {
                types = rest
                    .iter()
                    .map(|w| w.chars().next().unwrap_or('?').to_ascii_uppercase())
                    .collect()
            }
            "COUNT" => counts = rest.iter().map(|w| number(w)).collect::<Result<_, _>>()?,
            "WIDTH" => width = Some(number(rest.first().ok_or("WIDTH without value")?)? as u32),
            "HEIGHT" => height = number(rest.first().ok_or("HEIGHT without value")?)? as u32,
            "POINTS" => points = Some(number(rest.first().ok_or("POINTS without value")?)?),
            "DATA" => {
                break rest
                    .first()
                    .ok_or("DATA without encoding")?
                    .to_ascii_lowercase()
            }
            other => return Err(format!("unknown header line {other}")),
        }
    };
    if counts.is_empty() {
        counts = vec![1; names.len()];
    }
    if sizes.len() != names.len() || types.len() != names.len() || counts.len() != names.len() {
        return Err(format!(
            "FIELDS has {} entries, SIZE {}, TYPE {}, COUNT {}",
            names.len(),
            sizes.len(),
            types.len(),
            counts.len()
        ));
    }
    let mut fields = Vec::new();
    for i in 0..names.len() {
        let scalar = match (types[i], sizes[i]) {
            ('F', 4) => Scalar::F32,
            ('F', 8) => Scalar::F64,
            ('I', 1) => Scalar::I8,
            ('I', 2) => Scalar::I16,
            ('I', 4) => Scalar::I32,
            ('U', 1) => Scalar::U8,
            ('U', 2) => Scalar::U16,
            ('U', 4) => Scalar::U32,
            (t, s) => {
                return Err(format!(
                    "field {}: TYPE {t} SIZE {s} not supported",
                    names[i]
                ))
            }
        };
        fields.push(Field {
            name: names[i].clone(),
            scalar,
            count: counts[i],
        });
    }
    let width = width.ok_or("no WIDTH")?;
    let n = points.unwrap_or(width as usize * height as usize);
    if n != width as usize * height as usize {
        return Err(format!("POINTS {n} is not WIDTH {width} × HEIGHT {height}"));
    }
    let find = |axis: &str| {
        fields
            .iter()
            .position(|f| f.name == axis)
            .ok_or_else(|| format!("no field {axis}"))
    };
    let xyz = [find("x")?, find("y")?, find("z")?];
    // Byte offset of each field inside one point record.
    let mut offsets = Vec::new();
    let mut record = 0;
    for f in &fields {
        offsets.push(record);
        record += f.scalar.size() * f.count;
    }
    let body = &bytes[pos..];
    let mut out = Vec::with_capacity(n);
    match data.as_str() {
        "ascii" => {
            let text = std::str::from_utf8(body).map_err(|_| "ascii data is not text")?;
            // Column index of each field's first value.
            let mut columns = Vec::new();
            let mut c = 0;
            for f in &fields {
                columns.push(c);
                c += f.count;
            }
            for (row, line) in text.lines().filter(|l| !l.trim().is_empty()).enumerate() {
                let values: Vec<&str> = line.split_whitespace().collect();
                let get = |k: usize| -> Result<f32, String> {
                    let w = values
                        .get(columns[xyz[k]])
                        .ok_or_else(|| format!("point {row}: too few values"))?;
                    w.parse::<f32>()
                        .map_err(|_| format!("point {row}: {w:?} is not a number"))
                };
                out.push([get(0)?, get(1)?, get(2)?]);
            }
        }
        "binary" => {
            if body.len() < n * record {
                return Err(format!(
                    "binary data has {} bytes, {n} points of {record} need {}",
                    body.len(),
                    n * record
                ));
            }
            for i in 0..n {
                let r = &body[i * record..];
                out.push(xyz.map(|f| fields[f].scalar.read(&r[offsets[f]..], false)));
            }
        }
        "binary_compressed" => {
            if body.len() < 8 {
                return Err("binary_compressed data shorter than its 8-byte size header".into());
            }
            let compressed = u32::from_le_bytes(body[0..4].try_into().unwrap()) as usize;
            let size = u32::from_le_bytes(body[4..8].try_into().unwrap()) as usize;
            if body.len() < 8 + compressed {
                return Err(format!(
                    "binary_compressed: {compressed} compressed bytes announced, {} present",
                    body.len() - 8
                ));
            }
            if size != n * record {
                return Err(format!(
                    "binary_compressed: {size} bytes uncompressed, {n} points of {record} need {}",
                    n * record
                ));
            }
            let raw = lzf_rust::decompress_into_vec(&body[8..8 + compressed], size)
                .map_err(|e| format!("LZF: {e}"))?;
            if raw.len() != size {
                return Err(format!("LZF gave {} bytes, expected {size}", raw.len()));
            }
            // Field-major: field f's values start at n × (offset of f).
            let starts = xyz.map(|f| n * offsets[f]);
            let steps = xyz.map(|f| fields[f].scalar.size() * fields[f].count);
            for i in 0..n {
                out.push([0, 1, 2].map(|k| {
                    fields[xyz[k]]
                        .scalar
                        .read(&raw[starts[k] + i * steps[k]..], false)
                }));
            }
        }
        other => return Err(format!("DATA {other} not supported")),
    }
    if out.len() != n {
        return Err(format!("{} points read, header says {n}", out.len()));
    }
    Ok(Cloud {
        points: out,
        width,
        height,
        frame_id: None,
        stamp: None,
    })
}
