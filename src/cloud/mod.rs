//! Cloud stage: point clouds from files and bags into one layout, `Vec<[f32; 3]>` in the
//! sensor frame, in the order the sensor produced them (organized clouds row by row, so that
//! consecutive points lie close together, which the query's block pass relies on).
//!
//! - `pcd`: PCL's PCD through the `pcd-rs` crate, `ascii`, `binary` and `binary_compressed`;
//! - `ply`: PLY vertices, ASCII and binary of either byte order (written here: the PLY crates
//!   are unmaintained and a vertex reader is a page);
//! - `msg`: `sensor_msgs/msg/PointCloud2` as serde structs that follow the `.msg` files, decoded
//!   from CDR, and the extraction of `x y z` (FLOAT32 or FLOAT64, either byte order, any
//!   point_step and row_step);
//! - `bag`: rosbag2 MCAP (a `.mcap` file or a rosbag2 folder), the N-th PointCloud2 message.
//!
//! Invalid points (NaN, Inf, zeros) are kept as they are: the query counts and skips them.

pub mod bag;
pub mod msg;
pub mod pcd;
pub mod ply;

use std::path::{Path, PathBuf};

/// A point cloud in its sensor frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloud {
    pub points: Vec<[f32; 3]>,
    /// Image size for organized clouds (height 1 for unorganized ones).
    pub width: u32,
    pub height: u32,
    /// The frame the points are in, when the source says (PointCloud2 header).
    pub frame_id: Option<String>,
    /// Header stamp (s, ns), when the source has one.
    pub stamp: Option<(i32, u32)>,
}

#[derive(Debug, thiserror::Error)]
pub enum CloudError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: PCD: {message}")]
    Pcd { path: PathBuf, message: String },
    #[error("{path}: PLY: {message}")]
    Ply { path: PathBuf, message: String },
    #[error("{path}: MCAP: {message}")]
    Bag { path: PathBuf, message: String },
    #[error("PointCloud2: {0}")]
    Message(String),
    #[error("{path}: unknown cloud format (expected .pcd, .ply, .mcap or a rosbag2 folder)")]
    UnknownFormat { path: PathBuf },
}

pub(crate) fn read(path: &Path) -> Result<Vec<u8>, CloudError> {
    std::fs::read(path).map_err(|source| CloudError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Loads a cloud by its extension: `.pcd`, `.ply`, `.mcap` or a rosbag2 folder (then `message`
/// picks the N-th PointCloud2, 0 first).
pub fn load(path: &Path, message: usize) -> Result<Cloud, CloudError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("pcd") => pcd::load(path),
        Some("ply") => ply::load(path),
        Some("mcap") => bag::point_cloud(path, None, message),
        _ if path.is_dir() => bag::point_cloud(path, None, message),
        _ => Err(CloudError::UnknownFormat {
            path: path.to_owned(),
        }),
    }
}

/// Reads a scalar of PCD/PLY/PointField type `kind` at `bytes[..]` as f32.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    #[inline]
    pub fn read(self, b: &[u8], big_endian: bool) -> f32 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f32,
            Scalar::U8 => b[0] as f32,
            Scalar::I16 => get!(i16, 2) as f32,
            Scalar::U16 => get!(u16, 2) as f32,
            Scalar::I32 => get!(i32, 4) as f32,
            Scalar::U32 => get!(u32, 4) as f32,
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8) as f32,
        }
    }
}
