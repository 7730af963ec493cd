//! Cloud stage: point clouds from files and bags into one layout, `Vec<[f32; 3]>` in the
//! sensor frame, in the order the sensor produced them (organized clouds row by row, so that
//! consecutive points lie close together, which the query's block pass relies on).
//!
//! - `pcd`: PCL's PCD through the `pcd-rs` crate, `ascii`, `binary` and `binary_compressed`;
//! - `ply`: PLY vertices, ASCII and binary of either byte order (written here: the PLY crates
//!   are unmaintained and a vertex reader is a page);
//! - `pointcloud2`: `sensor_msgs/msg/PointCloud2` (structs in `crate::msg`), decoded
//!   from CDR, and the extraction of `x y z` (FLOAT32 or FLOAT64, either byte order, any
//!   point_step and row_step);
//! - `depth`: `sensor_msgs/Image` depth images (16UC1, 32FC1) with their `CameraInfo`, made
//!   into points as `depth_image_proc` does;
//! - a bag (`crate::bag`, a `.mcap` file or a rosbag2 folder): its N-th PointCloud2 message.
//!
//! Invalid points (NaN, Inf, zeros) are kept as they are: the query counts and skips them.
//!
//! Every reader checks a file's counts against the bytes present, and against [`MAX_POINTS`],
//! before it allocates: a header that claims more points than its data holds (or fewer, which
//! would silently read part of the file) is an error naming the file, never an allocation of
//! what the header says.

pub mod depth;
pub mod exclusion;
pub mod pcd;
pub mod ply;
pub mod pointcloud2;

use std::path::{Path, PathBuf};

use crate::msg::RosMessage;

/// The most points a cloud file may declare (1.2 GB as `[f32; 3]`): ten times a 12-megapixel
/// depth image, a hundred times a 64-beam lidar's sweep.
pub const MAX_POINTS: u64 = 100_000_000;

/// A source's range limits (`min_range`, `max_range`): a point whose distance from the sensor
/// lies outside them is dropped (made invalid), compared as squared f32 ranges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeLimits {
    min2: f32,
    max2: f32,
}

impl RangeLimits {
    /// The limits of `min_m` and `max_m` (none: unbounded); `None` when they drop nothing.
    pub fn new(min_m: f64, max_m: Option<f64>) -> Option<Self> {
        (min_m > 0.0 || max_m.is_some()).then(|| Self {
            min2: (min_m * min_m) as f32,
            max2: max_m.map_or(f32::INFINITY, |m| (m * m) as f32),
        })
    }

    /// The squared limits `(min², max²)`, f32, as [`RangeLimits::keeps`] compares them.
    pub fn squared(&self) -> (f32, f32) {
        (self.min2, self.max2)
    }

    /// Whether `p` lies within the limits (NaN does not).
    #[inline]
    pub fn keeps(&self, p: [f32; 3]) -> bool {
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        r2 >= self.min2 && r2 <= self.max2
    }
}

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
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error("{path}: {count} PointCloud2 message(s), none with index {index}")]
    NoMessage {
        path: PathBuf,
        count: usize,
        index: usize,
    },
    #[error("PointCloud2: {0}")]
    Decode(#[from] crate::msg::MsgError),
    #[error("PointCloud2 in frame '{frame}': {message}")]
    Layout { frame: String, message: String },
    #[error("depth image in frame '{frame}': {message}")]
    DepthImage { frame: String, message: String },
    #[error("CameraInfo of frame '{frame}': {message}")]
    Camera { frame: String, message: String },
    #[error("{path}: topic {topic}: {source}")]
    InBag {
        path: PathBuf,
        topic: String,
        source: Box<CloudError>,
    },
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
        Some("mcap") => point_cloud_from_bag(path, message),
        _ if path.is_dir() => point_cloud_from_bag(path, message),
        _ => Err(CloudError::UnknownFormat {
            path: path.to_owned(),
        }),
    }
}

/// The `index`-th PointCloud2 message (0 first, in log-time order) of a bag.
pub fn point_cloud_from_bag(path: &Path, index: usize) -> Result<Cloud, CloudError> {
    let clouds =
        crate::bag::read_messages(path, &|_, schema| schema == crate::msg::PointCloud2::TYPE)?;
    let m = clouds.get(index).ok_or_else(|| CloudError::NoMessage {
        path: path.to_owned(),
        count: clouds.len(),
        index,
    })?;
    pointcloud2::cloud_from_cdr(&m.data).map_err(|e| CloudError::InBag {
        path: path.to_owned(),
        topic: m.topic.to_string(),
        source: Box::new(e),
    })
}

/// The next line of a PCD or PLY text header at `*pos` (trimmed), moving `*pos` past it;
/// `ends_before` says what the header lacks when it has no more lines.
pub(crate) fn header_line<'a>(
    bytes: &'a [u8],
    pos: &mut usize,
    ends_before: &str,
) -> Result<&'a str, String> {
    let end = bytes[*pos..]
        .iter()
        .position(|&b| b == b'\n')
        .ok_or_else(|| format!("header ends before {ends_before}"))?;
    let line = std::str::from_utf8(&bytes[*pos..*pos + end]).map_err(|_| "header is not text")?;
    *pos += end + 1;
    Ok(line.trim())
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
        self.read_f64(b, big_endian) as f32
    }

    /// The value as stored (every type here is exact in f64).
    #[inline]
    pub fn read_f64(self, b: &[u8], big_endian: bool) -> f64 {
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
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        }
    }
}
