//! ist_monitor: minimum distance between a robot and point clouds with inner sphere trees.
//!
//! The data flows through the modules in this order: `robot` (URDF, collision meshes,
//! kinematics) → `packing` (Protosphere inner spheres, surface gap) → `ist` (tree, quality,
//! cache, validation) → `tf` (TF buffer, joint states) → `cloud` (PCD, PLY, PointCloud2) →
//! `query` (the parallel traversal on the CPU, or on the GPU in `query::gpu`: fast, certified
//! and exact distances) → `monitor` (the per-cloud pipeline and its output messages) → `bag`
//! (rosbag2 MCAP in and out, replay) and `node` (the live ROS 2 node, and the `play` and
//! `record` tools). `msg` holds the ROS 2 messages, `config` the parameters,
//! `scenario` the bag generator. `cli` wires them into the `ist_monitor` command; `bench`
//! holds the benchmarks and their real scenarios.

pub mod bag;
pub mod bench;
pub mod cli;
pub mod cloud;
pub mod config;
pub mod geometry;
pub mod ist;
pub mod monitor;
pub mod msg;
pub mod node;
pub mod packing;
pub mod query;
pub mod robot;
pub mod scenario;
pub mod tf;
