//! ist_monitor: minimum distance between a robot and point clouds with inner sphere trees.
//!
//! The library's modules follow the data, and each depends only on the ones before it:
//!
//! ```text
//! robot ─▶ packing ─▶ ist ─▶ query ─▶ separation ─▶ config ─▶ monitor ─▶ node
//! (URDF,   (inner     (tree,  (CPU and  (SSM: speed   (params)  (pipeline,  (ROS 2 node,
//!  meshes,  spheres,   cache)  GPU over   scaling)              sources,    play, record)
//!  FK)      gap h)             one layout)                      fusion,
//!   │                            ▲                               outputs,
//!   │                            │ depth images                  replay)
//!   ▼                            │                                 ▲
//! msg ─▶ bag (MCAP in/out) ─▶ cloud (PCD, PLY, PointCloud2, ──────┤
//!  │                          depth images, exclusion volumes)     │
//!  └───▶ tf (TF buffer, joint states and their velocities) ────────┘
//! ```
//!
//! - `robot` (URDF, collision meshes, kinematics) → `packing` (Protosphere inner spheres, the
//!   certified surface gap) → `ist` (tree, quality, cache, validation)
//!   → `query` (the layout shared with the GPU, posing, the CPU traversal, the GPU host, exact
//!   refinement and one result assembly for both) → `separation` (speed and separation
//!   monitoring: the speed-scaling factor from the per-link distances and the link velocities)
//!   → `config` (the parameters, each declared once) → `monitor` (each source's state, the
//!   per-frame pipeline, the fusion that decides the cell's level and the outputs that render
//!   it, replay) → `node` (the live ROS 2 node, and the `play` and `record` tools);
//! - `msg` (the ROS 2 messages) → `bag` (rosbag2 MCAP in and out) → `cloud` (PCD, PLY,
//!   PointCloud2 with one encoder, depth images, exclusion volumes: these take `robot`'s meshes)
//!   and `msg` → `tf` (TF buffer, joint states), both into `monitor`; `query` unprojects depth
//!   images with `cloud::depth`;
//! - after `query` and `cloud`: `unseen` (the places of the monitored volume where a body of the
//!   detection capability can hide from every source, judged by each ball's whole footprint,
//!   and the certified distance to them through the caller's query; it takes `cloud::depth`),
//!   run by `monitor::unseen` over every source's latest view;
//! - beside them: `geometry` (mesh helpers, under `robot`), `choice` (the enums a parameter or a
//!   flag picks by name), `stats` (percentiles of timings), and behind the default feature
//!   `fixtures` the test fixtures: `scenario` (the bag generator, on the meshes, clouds and
//!   bags) and `query::peers` (the reference methods the benchmarks and tests compare against).
//!
//! Each folder's `mod.rs` is its face (its doc, its modules, what it re-exports); a file imports
//! its siblings, never its parent (`tools/layout_check.py`).
//!
//! The `ist_monitor` command, its benchmarks and the demo paths live on top, in the binary
//! (`src/bin/ist_monitor/`); nothing here knows the command line or the checkout.

pub mod bag;
pub mod choice;
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
#[cfg(feature = "fixtures")]
pub mod scenario;
pub mod separation;
pub mod stats;
pub mod tf;
pub mod unseen;
