//! ist_monitor: minimum distance between a robot and point clouds with inner sphere trees.
//!
//! The data flows through the modules in this order: `robot` (URDF, collision meshes,
//! kinematics) → `packing` (Protosphere inner spheres, surface gap) → `ist` (tree, quality,
//! cache, validation) → `cloud` (PCD, PLY, PointCloud2, rosbag2 MCAP) → `query` (the parallel
//! traversal: fast, certified and exact distances). `cli` wires them into the `ist_monitor`
//! command; `bench` holds the error-against-run-time benchmark and its real scenarios.

pub mod bag;
pub mod bench;
pub mod cli;
pub mod cloud;
pub mod config;
pub mod geometry;
pub mod ist;
pub mod monitor;
pub mod msg;
pub mod packing;
pub mod query;
pub mod robot;
pub mod scenario;
pub mod tf;
