//! PLY point clouds: the `vertex` element's `x y z`, in `ascii`, `binary_little_endian` or
//! `binary_big_endian`. The vertex element must come first (as every point-cloud writer puts
//! it); elements after it (faces) are ignored.

use std::path::Path;

use super::error::CloudError;
use super::header::{header_line, read};
use super::points::{Cloud, MAX_POINTS};
use super::scalar::Scalar;

pub fn load(path: &Path) -> Result<Cloud, CloudError> {
    parse(&read(path)?).map_err(|message| CloudError::Ply {
        path: path.to_owned(),
        message,
    })
}

fn scalar(name: &str) -> Result<Scalar, String> {
    Ok(match name {
        "char" | "int8" => Scalar::I8,
        "uchar" | "uint8" => Scalar::U8,
        "short" | "int16" => Scalar::I16,
        "ushort" | "uint16" => Scalar::U16,
        "int" | "int32" => Scalar::I32,
        "uint" | "uint32" => Scalar::U32,
        "float" | "float32" => Scalar::F32,
        "double" | "float64" => Scalar::F64,
        other => return Err(format!("property type {other} not supported")),
    })
}

/// Parses a PLY file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Cloud, String> {
    let mut pos = 0;
    let mut format = None;
    let mut vertices = None;
    let mut in_vertex = false;
    let mut seen_element = false;
    let mut elements_after_vertex = false;
    let mut properties: Vec<(String, Scalar)> = Vec::new();
    let mut first = true;
    loop {
        let line = header_line(bytes, &mut pos, "end_header")?;
        if first {
            if line != "ply" {
                return Err("does not start with \"ply\"".into());
            }
            first = false;
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", f, _] => format = Some(f.to_string()),
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                if *name == "vertex" {
                    if seen_element {
                        return Err("element vertex must come first".into());
                    }
                    let n = count
                        .parse::<u64>()
                        .map_err(|_| format!("vertex count {count:?}"))?;
                    if n > MAX_POINTS {
                        return Err(format!(
                            "element vertex {n}: more than the {MAX_POINTS} points a cloud may have"
                        ));
                    }
                    vertices = Some(n as usize);
                } else if vertices.is_some() {
                    elements_after_vertex = true;
                }
                in_vertex = *name == "vertex";
                seen_element = true;
            }
            ["property", "list", ..] if in_vertex => {
                return Err("list properties on vertices are not supported".into())
            }
            ["property", kind, name] if in_vertex => {
                properties.push((name.to_string(), scalar(kind)?))
            }
            ["property", ..] => {}
            ["end_header"] => break,
            _ => return Err(format!("unexpected header line {line:?}")),
        }
    }
    let n = vertices.ok_or("no vertex element")?;
    let find = |axis: &str| {
        properties
            .iter()
            .position(|p| p.0 == axis)
            .ok_or_else(|| format!("vertex has no property {axis}"))
    };
    let xyz = [find("x")?, find("y")?, find("z")?];
    let body = &bytes[pos..];
    let mut points = Vec::new();
    match format.as_deref() {
        Some("ascii") => {
            let text = std::str::from_utf8(body).map_err(|_| "ascii body is not text")?;
            // A vertex takes at least one character and one separator per property.
            if n > body.len() / (2 * properties.len()) {
                return Err(format!(
                    "element vertex {n}: the {} bytes of data hold fewer vertices",
                    body.len()
                ));
            }
            points.reserve_exact(n);
            let mut lines = text.lines().filter(|l| !l.trim().is_empty());
            for i in 0..n {
                let line = lines.next().ok_or(format!("vertex {i} missing"))?;
                let values: Vec<&str> = line.split_whitespace().collect();
                let get = |k: usize| -> Result<f32, String> {
                    values
                        .get(xyz[k])
                        .and_then(|w| w.parse::<f32>().ok())
                        .ok_or_else(|| format!("vertex {i}: bad value"))
                };
                points.push([get(0)?, get(1)?, get(2)?]);
            }
            if !elements_after_vertex && lines.next().is_some() {
                return Err(format!(
                    "more data lines than the {n} vertices of the header, and no other element"
                ));
            }
        }
        Some(f @ ("binary_little_endian" | "binary_big_endian")) => {
            let big = f == "binary_big_endian";
            let mut offsets = Vec::new();
            let mut record = 0;
            for p in &properties {
                offsets.push(record);
                record += p.1.size();
            }
            let need = n
                .checked_mul(record)
                .ok_or_else(|| format!("element vertex {n}: size overflows"))?;
            if body.len() < need || (!elements_after_vertex && body.len() > need) {
                return Err(format!(
                    "{} bytes of data, {n} vertices of {record} bytes need {need}{}",
                    body.len(),
                    if body.len() > need {
                        " (and no other element follows)"
                    } else {
                        ""
                    }
                ));
            }
            points.reserve_exact(n);
            for i in 0..n {
                let r = &body[i * record..];
                points.push(xyz.map(|k| properties[k].1.read(&r[offsets[k]..], big)));
            }
        }
        other => return Err(format!("format {other:?} not supported")),
    }
    Ok(Cloud {
        width: n as u32,
        height: 1,
        points,
        frame_id: None,
        stamp: None,
    })
}
