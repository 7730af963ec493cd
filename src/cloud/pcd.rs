//! PCL's PCD format, read with the `pcd-rs` crate: `ascii`, `binary` and `binary_compressed`
//! (LZF, fields stored one after the other), any field layout. The fields named `x`, `y` and `z`
//! are taken, whatever their position and numeric type; the others are skipped.

use std::path::Path;

use pcd_rs::record::{DynRecord, Field};

use super::{Cloud, CloudError};

pub fn load(path: &Path) -> Result<Cloud, CloudError> {
    let err = |message: String| CloudError::Pcd {
        path: path.to_owned(),
        message,
    };
    let reader = pcd_rs::DynReader::open(path).map_err(|e| err(e.to_string()))?;
    let meta = reader.meta().clone();
    let find = |axis: &str| {
        meta.field_defs
            .iter()
            .position(|f| f.name == axis)
            .ok_or_else(|| err(format!("no field {axis}")))
    };
    let xyz = [find("x")?, find("y")?, find("z")?];
    let mut points = Vec::with_capacity(meta.num_points as usize);
    for (i, record) in reader.enumerate() {
        let record: DynRecord = record.map_err(|e| err(format!("point {i}: {e}")))?;
        let mut p = [0.0f32; 3];
        for (k, &f) in xyz.iter().enumerate() {
            p[k] = record.0.get(f).and_then(first_value).ok_or_else(|| {
                err(format!(
                    "point {i}: field {} has no value",
                    ["x", "y", "z"][k]
                ))
            })?;
        }
        points.push(p);
    }
    if points.len() as u64 != meta.num_points {
        return Err(err(format!(
            "{} points read, the header says {}",
            points.len(),
            meta.num_points
        )));
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
