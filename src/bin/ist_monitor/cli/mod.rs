//! Command line: `build` (trees, quality table, cache, export), `poses` (forward kinematics),
//! `query` (one cloud against the posed robot), `replay` (a bag through the monitor), `generate`
//! (scenario bags), `node` (the live ROS 2 node), `play` and `record` (DDS bag tools), `params`
//! (the parameter table), and `bench packing`, `bench query`, `bench gpu` and `bench ssm` (in
//! `crate::bench`).
//!
//! Every option is defined once, in the module of its subcommand or in the binary's `args.rs` when several
//! share it; the options that are also node parameters take the parameter table's default and
//! its validation.

mod build;
mod command;
mod query;
mod replay;
mod ros;

pub use command::{args, ros_log_level, run};
