//! The CPU backend's traversal, steps 2 and 3 of [`super::Engine::query`] (step 1, posing, is
//! `pose.rs`; steps 4 and 5, exact refinement and the result, are `exact.rs` and `finish.rs`,
//! shared with the GPU). Each stage sits under the name of the GPU pass that does its job
//! (`shaders/traverse.wgsl`):
//!
//! 2. **Seeds** (`seed.rs`; the GPU's `seed`): tight bounds before any block is culled, from
//!    the sample points nearest to each link.
//! 3. **Main pass** (`pass.rs`; the GPU's `blocks`, then `measure`), parallel over groups of blocks
//!    (rayon), the one sweep over the whole cloud. The cloud's hierarchy (`blocks.rs`: the
//!    tiling and the blocks' SIMD bounds), bottom up: points; **sub-blocks** of `SUB` = 8
//!    points; **blocks** of `BLOCK` = 32 points, runs of consecutive points or, for an
//!    organized cloud, tiles of 8 × 4 pixels (`layout::Tiling`; a tile's sphere is about a third of a
//!    row run's); groups of 16 blocks, a rayon task. Each block gets its valid count and the
//!    bounding box of its valid points (eight lanes at a time, SIMD). A group, then a block, is
//!    dropped whole when its box lies outside the region of interest or farther from the
//!    robot's box than every link's bound (squared distances between the boxes, eight blocks at
//!    a time); a block, also when its box is beyond every link's root sphere by the link's
//!    bound (eight links at a time). No square root for the blocks dropped here, nearly all of
//!    them (on the Kinect scene, global: about 250 of 9600 blocks go further). Otherwise a block
//!    is taken (`measure.rs`), as the sphere around its box, in two phases: **the robot** (the
//!    self-filter, through each link's grid) and **the obstacles** (each link's tree cut at the
//!    block, the frontier; sub-blocks tested against it; points descending from it in packets
//!    of up to eight).
//!
//!    A point equal to the one before it (within a group, across blocks too) takes its result
//!    with no work. Minima go into the shared atomics with `fetch_min`, so every thread prunes
//!    with the best bound found by any.
//!
//! The pruning rule ([`Pass::threshold`]) and the recording rule ([`Pass::record`]) are the
//! ones the GPU shader implements; the frontiers, sub-blocks, packets and SIMD are the CPU's
//! own. Both count their work alike (`query::work`: blocks, culled, items, descents, nodes).
//! Nothing is allocated per query once the scratch memory has grown (thread-local frontier
//! buffers, the exact candidates' vector), but the seed lists (a few hundred bytes per rayon
//! split).

//!
//! `run.rs` runs the steps in order for one query.

mod blocks;
mod measure;
mod pass;
mod run;
mod seed;

pub(super) use run::run;
