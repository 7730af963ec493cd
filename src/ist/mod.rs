//! Inner sphere tree (IST) stage: per link, the inner spheres from `packing` (the budget grown
//! from `start_spheres` while h is above the link's target, `target_gap_m` or a share of a large
//! link's size, up to `max_spheres`), a hierarchy of bounding spheres over them (`build`), the measured quality
//! (coverage and surface gap h), the checks every tree passes before it is used or cached
//! (`validate`: they refuse a wrong tree, and the h they measure is the h reported) and the
//! cache (`cache`).
//!
//! Output, per link and in the link frame: two flat `#[repr(C)]` Pod arrays, `nodes` (root at 0)
//! and `spheres`, which the CPU traversal walks and the GPU uploads as they are. Building a link
//! costs its packing (seconds); loading it from the cache costs a file read.
//!
//! Files: `link_tree` (what the stage hands on), `options` (what decides a tree), `link` (one
//! link's tree, built and validated), `measure` (the f64 surface gap `validate` reports),
//! `robot` (every link's, cached), `error`.

pub mod build;
pub mod cache;
mod error;
mod link;
mod link_tree;
mod measure;
mod options;
mod robot;
pub mod validate;

pub use crate::packing::InnerSphere;
pub use build::TreeBuilder;
pub use error::IstError;
pub use link::{
    absurd_gap, build_link, describe_uncovered, target_gap, uncovered_fate, ABSURD_GAP_M,
    VALIDATION_TOLERANCE_M,
};
pub use link_tree::{IstNode, LinkQuality, LinkTree, StageTimes, Uncovered};
pub use options::BuildOptions;
pub use robot::{build_links, build_robot, Origin};
