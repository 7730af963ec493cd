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
//!
//! Files: `points` (the cloud, its limits), `load` (by extension), `error`; `header` and
//! `scalar` (what the readers share).

pub mod depth;
mod error;
pub mod exclusion;
mod header;
mod load;
pub mod pcd;
pub mod ply;
pub mod pointcloud2;
mod points;
mod scalar;

pub use error::CloudError;
pub use load::{load, point_cloud_from_bag};
pub use points::{Cloud, RangeLimits, MAX_POINTS};
