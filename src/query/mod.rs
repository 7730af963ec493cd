//! Query stage: the minimum distance between the posed robot and a point cloud, on the CPU
//! (rayon) or the GPU (wgpu), over one data layout.
//!
//! Inputs: the inner sphere trees of the links (`ist`), the link poses `root_from_link` from
//! forward kinematics (f64), a cloud in its sensor frame (f32) and the sensor pose
//! `root_from_sensor` (f64). Three modes:
//! - **fast**: the distance to the union of the inner spheres, the seed's query. Inner spheres
//!   lie inside the link, so this is an upper bound of the true distance.
//! - **certified**: also the lower bound `max(0, d − h_link)`, with h the link's certified
//!   surface gap, so the true distance to the collision meshes lies in `[lower, upper]`.
//! - **exact**: the exact distance to the collision meshes. The sphere pass keeps, as candidates,
//!   the (point, link) pairs whose lower bound `d − h` does not exceed the best upper bound; they
//!   are refined with exact point–triangle distance (parry3d's BVH) in ascending lower bound and
//!   the refinement stops at the first candidate whose lower bound exceeds the best exact value.
//!
//! The traversal is the seed's "atomicMin" query: every point descends the link trees in
//! parallel, and a node is pruned when its lower bound `|p − c| − r` exceeds the shared
//! minimum, kept in atomics that every thread (or GPU invocation) reads and lowers.
//!
//! The module, by concern, in the order a query runs:
//! - `options`, `link`, `input` and `error`: what a query is asked, over which links, and why
//!   it is refused; `engine`, the [`Engine`] that checks a query and sends it to a backend;
//! - `layout`: the `#[repr(C)]` Pod structs (posed links, robot box, dispatch parameters,
//!   counters, candidates) that the CPU walks and the GPU uploads as they are, and the named
//!   constants and codes that the WGSL shader receives generated from them;
//! - `pose` (step 1, both backends): links and robot box composed in f64, rounded once;
//! - `bounds`: the shared minima, global bounds and exact candidates of one query;
//! - `cpu` and `descent` (steps 2 and 3 on the CPU): seeds, blocks, frontiers, the descent;
//!   `self_grid`, the CPU self-filter's per-link grid;
//! - `gpu` (steps 2 and 3 on the GPU): the wgpu host of `shaders/traverse.wgsl`;
//! - `exact` and `finish` (steps 4 and 5, both backends): exact refinement and the result's
//!   assembly; `result`, what a query returns;
//! - `peers`: reference methods for the tests and the benchmarks.
//!
//! Frames and precision: all poses are composed in f64 and the robot is brought into the sensor
//! frame, where the points are usually small numbers; only then are the per-link transforms
//! rounded to f32. A robot and sensor 1000 km from the map origin therefore give the answer they
//! give at the origin (the offsets cancel in f64 before anything is rounded). A cloud whose own
//! frame is far from the robot (a map-frame lidar) runs in a working frame near the robot, the
//! points moved by one exact f32 subtraction (`pose::working_origin`), so that the certified
//! interval holds for its f32 points at any offset; where those points are spaced more coarsely
//! than `pose::MAX_POINT_SPACING_M`, the query is refused rather than certified. The per-point
//! work is f32.
//!
//! Leaving out what the scene does not need, cheapest first:
//! 1. invalid points (NaN, ±Inf, and (0, 0, 0), which drivers use for "no return") are counted
//!    and skipped;
//! 2. the region of interest: points farther than `max_distance_m` from the robot's bounding box
//!    are dropped; whole blocks of 32 consecutive points are dropped at once by their bounding
//!    sphere;
//! 3. links are included or excluded by name when the engine is made;
//! 4. the shared bound: a block, then a sub-block, then a point, then a node is skipped when
//!    its lower bound exceeds the current minimum; organized clouds are taken in tiles of
//!    8 × 4 pixels, whose small spheres prune more ([`Engine::query_image`]);
//! 5. per-link minima (`QueryOptions::per_link`) only where they can change a decision: a
//!    link's own minimum is measured up to `per_link_range_m` (the node's warn distance plus
//!    hysteresis), or up to a range of the link's own below it (`link_ranges_m`: the unseen
//!    space asks only what can still lower each link's best), and for the nearest link; a link
//!    farther away is pruned with the global bound and reported as farther than the final
//!    threshold (`bounds::threshold`), with the certified lower bound that follows. Switching
//!    per-link minima off leaves one shared bound;
//! 6. self-filtering: points whose inner-sphere distance is within `self_filter_padding_m` of a
//!    link are the robot seen by its own sensor; they are counted, not taken as obstacles.
//!    Because the inner-sphere distance is an upper bound, every point filtered is truly within
//!    the padding of the collision mesh: the filter never hides an obstacle farther than that.
//!    On the CPU each link's grid for the padding (`self_grid`) settles most points with one
//!    look-up; only points in the grid's thin shell across the padding descend the tree;
//! 7. repeats: a point equal to the one before it takes its result with no work, and exact
//!    mode refines a repeated point once.
//!
//! Every stage's count is reported in [`StageCounts`].

mod bounds;
mod cpu;
mod descent;
mod engine;
mod error;
pub mod exact;
mod finish;
pub mod gpu;
mod input;
pub mod layout;
mod link;
mod options;
#[cfg(feature = "fixtures")]
pub mod peers;
mod pose;
mod result;
mod self_grid;
mod work;

pub use descent::{nearest_sphere, valid as is_valid_point};
pub use engine::Engine;
pub use error::QueryError;
pub use layout::MAX_LINKS;
pub use link::QueryLink;
pub use options::{
    Backend, Mode, QueryOptions, DEFAULT_GPU_MIN_DEPTH_PIXELS, DEFAULT_GPU_MIN_POINTS,
};
pub use pose::root_from_sensor_via_map;
pub use result::{LinkDistance, Nearest, Outcome, QueryResult, StageCounts};
pub use work::WorkCounts;

pub use crate::robot::LinkSelection;
