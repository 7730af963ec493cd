//! GPU backend of the query (wgpu; `shaders/traverse.wgsl` with `shaders/minima_u64.wgsl` or
//! `shaders/minima_u32.wgsl`): the CPU's block pipeline as GPU passes over the same layout, the
//! shared bounds in storage atomics.
//!
//! - **Once per robot**: the device is created (with 64-bit atomics where the adapter has
//!   them, [`Minima`], and subgroup operations likewise, [`Reduce`]), the trees are checked (every child index inside its array: the shader is
//!   compiled without runtime bounds checks) and every link's `IstNode` and `InnerSphere` arrays
//!   are uploaded as they are, concatenated in link order (the CPU walks the same arrays; each
//!   posed link carries its offsets into them). Buffers, bind groups and pipelines are made once
//!   and grown with the cloud.
//! - **Per query**: the links are posed by the code the CPU uses (`Bounds::prepare`: f64,
//!   rounded once); the posed links, one `layout::QueryParams` uniform and the points are
//!   written (the points into the staging memory, in parallel; a depth image's bytes instead,
//!   whose points the first pass makes: `unproject`). One submission runs the
//!   passes the shader's header describes (`passes::steps`: seeds, cull, blocks, plan, measure,
//!   tally, and arg-min without 64-bit atomics) with no readback between them; the measure and
//!   tally passes are dispatched indirectly, sized by the blocks pass. A few words come back: `layout::Counters`,
//!   the minima and the exact-mode candidates (`layout::Candidate`), read by spinning on the
//!   map for a short while before the thread parks.
//! - **Then** the shared `finish::finish` refines the exact candidates and assembles the result,
//!   so both backends report through one code path.
//!
//! The link that won each minimum is kept for the next query's seed pass (the previous frame's
//! winners: on a stream of clouds from one sensor, the same pixels are near the arm again).
//!
//! Agreement with the CPU: the same posed links, trees, blocks, box tests, thresholds and
//! recording rules; only the rounding of the square root may differ (a few ulps, far below 1 µm
//! at robot scale).
//!
//! The files, in that order: `options` and `error`; `engine`, the engine's state, made by
//! `setup` (with `bindings`, the buffers and layout entries every part makes alike); `buffers`,
//! those that grow with the cloud; `run`, a query's host steps ([`HOST_STEPS`]), as the CPU's
//! `run`; `passes`, its dispatches; `transfer`, what crosses to and from the device;
//! `unproject`, a depth image's first pass; `cell`, the unseen space's cells judged in the same
//! submission (`shaders/cell.wgsl`).

mod bindings;
mod buffers;
mod cell;
mod engine;
mod error;
mod options;
mod passes;
mod run;
mod setup;
mod transfer;
mod unproject;

pub use engine::{GpuEngine, HOST_STEPS};
pub use error::GpuError;
pub use options::{GpuOptions, NO_INT64_ENV, NO_SUBGROUPS_ENV, PACKETS_ENV};
