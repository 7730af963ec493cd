//! The query's data layout, shared by the CPU traversal and the GPU shader: `#[repr(C)]` Pod
//! structs that the CPU walks and the GPU uploads as they are, and the named constants and codes
//! that both sides use.
//!
//! | host (here, or `ist`/`packing`) | WGSL (`shaders/traverse.wgsl`) | role |
//! |---|---|---|
//! | [`IstNode`] | `Node` | a bounding sphere of the tree and its children |
//! | [`InnerSphere`] | `Sphere` | an inner sphere (tree leaf) |
//! | [`PosedLink`] | `Link` | a link posed for one query, in the sensor frame |
//! | [`RobotBox`] | `RobotBox` | the robot's box in its root frame, for the region of interest |
//! | [`QueryParams`] | `Params` | one dispatch's options (a uniform) |
//! | [`Counters`] | `State` | the shared bounds and the stage counts of the GPU |
//! | [`Candidate`] | `Candidate` | an exact-mode (point, link) pair |
//! | [`BoxedBlock`] | `Boxed` | a block the GPU's cull pass kept, with its box |
//! | [`GridHeader`] | `Grid` | one link's self-filter grid |
//! | [`KeptBlock`] | `Kept` | a block the GPU's block pass kept, with its points to measure |
//!
//! The WGSL side never writes a constant of its own: [`wgsl_constants`] generates the constants
//! and codes below and [`shader_source`] puts them in front of the shader files (the traversal
//! and the way the minima are kept, [`Minima`]). A CPU-only test
//! (`tests/shaders.rs`) checks every mirrored struct member's name and offset with naga against
//! [`MIRRORS`].
//!
//! Both backends also cut a cloud into the same blocks ([`Tiling`]) and read a self-filter
//! grid's cells with the same codes ([`Cell`]).

use bytemuck::{Pod, Zeroable};
use std::mem::{offset_of, size_of};

use crate::ist::IstNode;
use crate::packing::InnerSphere;

/// Most links with collision geometry one engine handles (a bit mask per point).
pub const MAX_LINKS: usize = 128;

/// Points per block of either backend's block pass (one GPU workgroup).
pub const BLOCK: usize = 32;
/// Points per sub-block (a row of a tile of an organized cloud: tiles are `SUB` × `BLOCK / SUB`
/// pixels).
pub const SUB: usize = 8;
/// Rows of a tile of an organized cloud.
pub const TILE_ROWS: usize = BLOCK / SUB;
/// Stride of the sample that seeds the links' bounds (prime, so that it does not alias with
/// the rows of an organized cloud); both backends seed from the same points.
pub const SEED_STRIDE: u32 = 61;
/// The CPU seeds' coarse scan takes every `SEED_COARSE`-th sample, so that the full scan
/// starts from short lists (the GPU scans the whole sample at once).
pub const SEED_COARSE: u32 = 16;
/// Most frontier nodes per block and link (CPU).
pub const FRONTIER: usize = 32;
/// The CPU's depth-first stack; it starts with up to `FRONTIER` entries (a block's frontier).
pub const STACK: usize = 192;
/// The GPU's depth-first stack (per invocation, in private memory); it starts with the root or
/// with up to `FRONTIER` entries (an item's frontier).
pub const GPU_STACK: usize = 96;

/// The deepest tree (root = 1) a depth-first stack of `capacity` entries takes when it starts
/// with `starts` entries: each level pops one entry and pushes at most `BRANCHING`, so
/// `starts + depth·(BRANCHING − 1) ≤ capacity` holds every descent (one level of margin). The
/// one rule both backends check: `STACK` and `GPU_STACK` with `FRONTIER` starts.
pub const fn max_tree_depth(capacity: usize, starts: usize) -> usize {
    (capacity - starts) / (crate::ist::build::BRANCHING - 1)
}
/// Invocations per GPU workgroup.
pub const WORKGROUP: u32 = 256;
/// Exact-mode candidates the GPU keeps; more sends the query to the CPU.
pub const GPU_CANDIDATES: u32 = 1 << 16;

/// How the points are grouped into blocks of `BLOCK`: runs of consecutive points, or, for an
/// organized cloud (a depth image, `width` > 0), tiles of `SUB` × `BLOCK / SUB` pixels, whose
/// rows are the sub-blocks. A tile's points lie closer together than a run of a row's (its
/// bounding sphere is about a third as large), so that blocks are culled, and their frontiers
/// cut, more tightly.
#[derive(Clone, Copy)]
pub(in crate::query) struct Tiling {
    points: usize,
    /// Width and height of an organized cloud.
    image: Option<(usize, usize)>,
}

impl Tiling {
    /// Tiles for a `width`-wide image of `points` points (runs when the width does not divide
    /// the point count, or the cloud is one row).
    pub(in crate::query) fn new(points: usize, width: Option<usize>) -> Self {
        let image = width
            .filter(|&w| w > 0 && w < points && points.is_multiple_of(w))
            .map(|w| (w, points / w));
        Self { points, image }
    }

    /// An organized cloud's width and height (blocks are tiles); `None`: runs.
    pub(in crate::query) fn image(&self) -> Option<(usize, usize)> {
        self.image
    }

    pub(in crate::query) fn blocks(&self) -> usize {
        match self.image {
            None => self.points.div_ceil(BLOCK),
            Some((w, h)) => w.div_ceil(SUB) * h.div_ceil(TILE_ROWS),
        }
    }

    /// The sub-blocks of block `b`: (first point, length), at most `TILE_ROWS`, the rest
    /// (0, 0).
    #[inline]
    pub(in crate::query) fn subs(&self, b: usize) -> [(usize, usize); TILE_ROWS] {
        let mut out = [(0, 0); TILE_ROWS];
        match self.image {
            None => {
                for (k, o) in out.iter_mut().enumerate() {
                    let start = b * BLOCK + k * SUB;
                    if start < self.points {
                        *o = (start, SUB.min(self.points - start));
                    }
                }
            }
            Some((w, h)) => {
                let per_row = w.div_ceil(SUB);
                let (row, col) = ((b / per_row) * TILE_ROWS, (b % per_row) * SUB);
                for (k, o) in out.iter_mut().enumerate() {
                    if row + k < h {
                        *o = ((row + k) * w + col, SUB.min(w - col));
                    }
                }
            }
        }
        out
    }

    /// The block that holds point `i`.
    pub(in crate::query) fn block_of(&self, i: usize) -> usize {
        match self.image {
            None => i / BLOCK,
            Some((w, _)) => (i / w / TILE_ROWS) * w.div_ceil(SUB) + (i % w) / SUB,
        }
    }
}

/// What a cell says about the points in it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Cell {
    /// No point of the cell is within the padding.
    Clear = 0,
    /// The cell straddles the padding: the point's own descent decides.
    Shell = 1,
    /// Every point of the cell is within the padding.
    SelfPoint = 2,
}

/// The mode as both backends read it ([`super::Mode`]'s code).
pub const MODE_FAST: u32 = 0;
pub const MODE_CERTIFIED: u32 = 1;
pub const MODE_EXACT: u32 = 2;

/// Where a point ended, as the index of its count in [`Counters::counts`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Stage {
    Invalid = 0,
    OutsideRoi = 1,
    SelfFiltered = 2,
    Pruned = 3,
    Evaluated = 4,
    /// Evaluated and inside an inner sphere (counted in addition to `Evaluated`).
    Inside = 5,
}
/// Stage counts kept by the GPU (one per [`Stage`]).
pub const STAGES: usize = 6;

/// A link posed for one query, in the sensor frame (f32, rounded once from the f64 poses).
/// WGSL `Link`.
#[repr(C)]
#[derive(Clone, Copy, Default, Pod, Zeroable, Debug)]
pub struct PosedLink {
    /// `link_from_sensor` as three rows: xyz the rotation, w the translation.
    pub rows: [[f32; 4]; 3],
    /// The root sphere of the link's tree, in the sensor frame.
    pub center: [f32; 3],
    pub radius: f32,
    /// The link's certified surface gap h, m.
    pub gap: f32,
    /// Where the link's nodes and spheres start in the concatenated arrays (GPU).
    pub node_base: u32,
    pub sphere_base: u32,
    /// With per-link minima, the distance up to which this link's own minimum is measured
    /// (`QueryOptions::link_range`).
    pub range: f32,
}
const _: () = assert!(size_of::<PosedLink>() == 80);

impl PosedLink {
    /// A sensor-frame point in the link frame.
    #[inline(always)]
    pub fn in_link(&self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rows;
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + r[0][3],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + r[1][3],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + r[2][3],
        ]
    }
}

/// The robot's bounding box in its root frame (over the links' root spheres), where it is
/// tight for an arm standing on its base, with `root_from_sensor` in f32, and the two limits
/// that come with it. WGSL `RobotBox`.
#[repr(C)]
#[derive(Clone, Copy, Default, Pod, Zeroable, Debug)]
pub struct RobotBox {
    /// `root_from_sensor` rows: xyz the rotation, w the translation.
    pub rows: [[f32; 4]; 3],
    pub lo: [f32; 3],
    /// Points farther than this from the box are outside the region of interest, m.
    pub max_distance: f32,
    pub hi: [f32; 3],
    /// Self-filter padding, m; negative when the self-filter is off.
    pub padding: f32,
}
const _: () = assert!(size_of::<RobotBox>() == 80);

impl RobotBox {
    /// Whether a sensor-frame point lies within `distance` of the box (tested in squared
    /// distances: no square root).
    #[inline(always)]
    pub fn within(&self, p: [f32; 3], distance: f32) -> bool {
        let mut s = 0.0;
        for (k, r) in self.rows.iter().enumerate() {
            let q = r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
            let e = (self.lo[k] - q).max(q - self.hi[k]).max(0.0);
            s += e * e;
        }
        distance >= 0.0 && s <= distance * distance
    }

    /// The squared distances from the box to the nearest and to the farthest point of a
    /// sensor-frame box `lo..hi` (a block of points), without a square root: the block's box is
    /// taken to the root frame as a box around it (its centre moved, its half-extents through
    /// `|R|`), widened for f32 rounding, so that the first is never too large and the second
    /// never too small.
    #[inline(always)]
    pub fn box_distances2(&self, lo: [f32; 3], hi: [f32; 3]) -> (f32, f32) {
        let c = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let e = [0, 1, 2].map(|k| 0.5 * (hi[k] - lo[k]));
        let slack = 1e-6 * (1.0 + c[0].abs() + c[1].abs() + c[2].abs());
        let (mut near, mut far) = (0.0, 0.0);
        for (k, r) in self.rows.iter().enumerate() {
            let q = r[0] * c[0] + r[1] * c[1] + r[2] * c[2] + r[3];
            let w =
                (r[0].abs() * e[0] + r[1].abs() * e[1] + r[2].abs() * e[2]) * (1.0 + 1e-6) + slack;
            let n = (self.lo[k] - (q + w)).max((q - w) - self.hi[k]).max(0.0);
            let f = (self.lo[k] - (q - w)).max((q + w) - self.hi[k]).max(0.0);
            near += n * n;
            far += f * f;
        }
        (near, far)
    }
}

/// One GPU query's options, read by every pass. WGSL `Params` (a uniform).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct QueryParams {
    pub robot_box: RobotBox,
    pub n_points: u32,
    pub n_links: u32,
    /// `MODE_*`.
    pub mode: u32,
    pub per_link: u32,
    /// The seed pass: sample point k is k · stride for k < n_sample, then the `n_winners`
    /// points of the winners' buffer.
    pub stride: u32,
    pub n_sample: u32,
    pub n_winners: u32,
    pub pad0: u32,
    /// Room for exact-mode candidates.
    pub capacity: u32,
    pub pad3: u32,
    /// An organized cloud's width and height (blocks are tiles); width 0: runs.
    pub width: u32,
    pub height: u32,
    pub n_blocks: u32,
    /// Room for work items (kept block, link).
    pub item_capacity: u32,
    pub pad1: u32,
    pub pad2: u32,
}
const _: () = assert!(size_of::<QueryParams>() == 144);

/// The GPU's shared bounds and counts. WGSL `State` (every member but the padding is atomic).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct Counters {
    /// The smallest inner-sphere distance of any link (f32 bits).
    pub global: u32,
    /// The smallest certified lower bound (f32 bits; certified mode).
    pub global_lower: u32,
    pub candidate_count: u32,
    /// Blocks the block pass kept ([`KeptBlock`]).
    pub kept_count: u32,
    /// Work items (kept block, link) appended; more than the room sends the query to the CPU.
    pub item_count: u32,
    /// Blocks the cull pass kept ([`BoxedBlock`]).
    pub boxed_count: u32,
    /// Points per [`Stage`].
    pub counts: [u32; STAGES],
    /// Per [`Work`].
    pub work: [u32; WORK_COUNTERS],
    /// Self-filtered points per link (the first link within the padding).
    pub self_filtered: [u32; MAX_LINKS],
    /// Per link, the seeds' scan: the nearest sample's squared distance to the link's root
    /// centre (f32 bits) and that sample.
    pub seed_key: [u32; MAX_LINKS],
    pub seed_point: [u32; MAX_LINKS],
}
const _: () = assert!(size_of::<Counters>() == 68 + 12 * MAX_LINKS);

/// The work counters both backends keep (`query::WorkCounts`), as indices of
/// [`Counters::work`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Work {
    /// Blocks of `BLOCK` points.
    Blocks = 0,
    /// Blocks dropped whole by their box: no valid point, outside the region of interest, or
    /// beyond every link's reach.
    Culled = 1,
    /// (Block, link) pairs whose points were measured against the link.
    Items = 2,
    /// Tree descents begun (a point against a link's tree; self-filter ones too).
    Descents = 3,
    /// Tree nodes expanded, per point.
    Nodes = 4,
}
/// Work counters kept (one per [`Work`]).
pub const WORK_COUNTERS: usize = 5;

/// A block the GPU's cull pass kept: its box (sensor frame) and whether the box straddles the
/// region of interest's edge (1) or lies inside it (0). WGSL `Boxed`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct BoxedBlock {
    pub lo: [f32; 3],
    pub block: u32,
    pub hi: [f32; 3],
    pub partial: u32,
}
const _: () = assert!(size_of::<BoxedBlock>() == 32);

/// A block the GPU's block pass kept: the sphere around its box (sensor frame, the item's
/// frontier is cut at it), its points still to be measured (bit k: point k of the block), and
/// those the measure pass found a distance for and found inside an inner sphere. WGSL `Kept`
/// (the last two members atomic).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct KeptBlock {
    pub center: [f32; 3],
    pub radius: f32,
    pub block: u32,
    pub todo: u32,
    pub measured: u32,
    pub inside: u32,
}
const _: () = assert!(size_of::<KeptBlock>() == 32);

/// One link's self-filter grid on the GPU (`query::self_grid::SelfGrid`, the CPU's): its
/// origin and inverse cell width in the link frame, its cells per axis, and where its cells
/// start in the packed cell words (2 bits a cell, 16 to a word, x fastest). WGSL `Grid`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct GridHeader {
    pub origin: [f32; 3],
    pub inv_cell: f32,
    pub dims: [u32; 3],
    pub base: u32,
}
const _: () = assert!(size_of::<GridHeader>() == 32);

/// How the GPU keeps each link's minimum: both ways give the CPU's answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Minima {
    /// Distance and point packed in one 64-bit atomic (`shaders/minima_u64.wgsl`), as on the
    /// CPU: needs `SHADER_INT64` and `SHADER_INT64_ATOMIC_MIN_MAX`.
    Packed64,
    /// The distance in a 32-bit atomic, its point found by an arg-min pass once the minima are
    /// final (`shaders/minima_u32.wgsl`).
    Split32,
}

/// How the GPU reduces within a workgroup: both ways give the same values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reduce {
    /// Each subgroup first, then one workgroup atomic per subgroup
    /// (`shaders/reduce_subgroups.wgsl`): needs wgpu's `SUBGROUP`.
    Subgroups,
    /// One workgroup atomic per invocation (`shaders/reduce_shared.wgsl`).
    Shared,
}

/// An exact-mode candidate: a (point, link) pair whose lower bound may beat the best upper
/// bound. WGSL `Candidate`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, Default)]
pub struct Candidate {
    /// Its lower bound `max(0, d − h)`, m.
    pub lower: f32,
    pub link: u32,
    pub point: u32,
    pub pad: u32,
}
const _: () = assert!(size_of::<Candidate>() == 16);

/// `DepthParams::encoding` of a 16UC1 image (millimetres).
pub const DEPTH_MM16: u32 = 1;
/// `DepthParams::encoding` of a 32FC1 image (metres).
pub const DEPTH_M32: u32 = 2;

/// A depth image to unproject on the GPU (`shaders/unproject.wgsl`): its layout and the
/// constants of `cloud::depth::DepthView`, as the CPU uses them. WGSL `DepthParams` (a
/// uniform).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug)]
pub struct DepthParams {
    pub width: u32,
    pub height: u32,
    /// Bytes from one row to the next.
    pub step: u32,
    /// `DEPTH_MM16` or `DEPTH_M32`.
    pub encoding: u32,
    pub big_endian: u32,
    /// 1 where the source has range limits (`min2`, `max2`: squared, as `RangeLimits`).
    pub limited: u32,
    pub min2: f32,
    pub max2: f32,
    pub cx: f32,
    pub cy: f32,
    pub kx: f32,
    pub ky: f32,
    pub unit: f32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}
const _: () = assert!(size_of::<DepthParams>() == 64);

/// One view's lattice cells to judge on the GPU (`shaders/cell.wgsl`, in the depth query's
/// submission): the image's camera and range limits, the range noise and the f32 rounding the
/// free distances lose, the pixel angle's cosine and sine, the base and sub-balls' radii, and
/// the lattice placed in the camera frame (its first centre and a step per index). Made by the
/// unseen space (`unseen::PlacedView`, `unseen::BallSize`) with the CPU's very values. WGSL
/// `CellParams` (a uniform).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, PartialEq)]
pub struct CellParams {
    pub width: u32,
    pub height: u32,
    pub n0: u32,
    pub n1: u32,
    pub n2: u32,
    pub cells: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub min_range: f32,
    pub max_range: f32,
    pub noise: f32,
    pub rounding: f32,
    pub cos_k: f32,
    pub sin_k: f32,
    pub ball: f32,
    pub sub_ball: f32,
    /// x y z and 0 (a WGSL `vec4<f32>`).
    pub origin: [f32; 4],
    pub step0: [f32; 4],
    pub step1: [f32; 4],
    pub step2: [f32; 4],
}
const _: () = assert!(size_of::<CellParams>() == 144);

/// A host struct mirrored in WGSL: its WGSL name, size, and members with their offsets.
pub struct Mirror {
    pub wgsl: &'static str,
    pub size: usize,
    pub members: &'static [(&'static str, usize)],
}

macro_rules! mirror {
    ($wgsl:literal, $ty:ty, [$($field:ident),* $(,)?]) => {
        Mirror {
            wgsl: $wgsl,
            size: size_of::<$ty>(),
            members: &[$((stringify!($field), offset_of!($ty, $field))),*],
        }
    };
}

/// Every mirrored struct, for the naga test of `tests/shaders.rs`.
pub const MIRRORS: &[Mirror] = &[
    mirror!(
        "Node",
        IstNode,
        [
            center,
            radius,
            first_child,
            child_count,
            children_are_spheres,
            pad
        ]
    ),
    mirror!("Sphere", InnerSphere, [center, radius]),
    mirror!(
        "Link",
        PosedLink,
        [rows, center, radius, gap, node_base, sphere_base, range]
    ),
    mirror!("RobotBox", RobotBox, [rows, lo, max_distance, hi, padding]),
    mirror!(
        "Params",
        QueryParams,
        [
            robot_box,
            n_points,
            n_links,
            mode,
            per_link,
            stride,
            n_sample,
            n_winners,
            pad0,
            capacity,
            pad3,
            width,
            height,
            n_blocks,
            item_capacity,
            pad1,
            pad2
        ]
    ),
    mirror!(
        "State",
        Counters,
        [
            global,
            global_lower,
            candidate_count,
            kept_count,
            item_count,
            boxed_count,
            counts,
            work,
            self_filtered,
            seed_key,
            seed_point
        ]
    ),
    mirror!("Candidate", Candidate, [lower, link, point, pad]),
    mirror!("Boxed", BoxedBlock, [lo, block, hi, partial]),
    mirror!("Grid", GridHeader, [origin, inv_cell, dims, base]),
    mirror!(
        "Kept",
        KeptBlock,
        [center, radius, block, todo, measured, inside]
    ),
];

/// The structs of `shaders/unproject.wgsl`, as [`MIRRORS`] for the traversal.
pub const UNPROJECT_MIRRORS: &[Mirror] = &[mirror!(
    "DepthParams",
    DepthParams,
    [
        width, height, step, encoding, big_endian, limited, min2, max2, cx, cy, kx, ky, unit, pad0,
        pad1, pad2
    ]
)];

/// The structs of `shaders/cell.wgsl`.
pub const CELL_MIRRORS: &[Mirror] = &[mirror!(
    "CellParams",
    CellParams,
    [
        width, height, n0, n1, n2, cells, pad0, pad1, fx, fy, cx, cy, min_range, max_range, noise,
        rounding, cos_k, sin_k, ball, sub_ball, origin, step0, step1, step2
    ]
)];

/// The WGSL declarations of the constants and codes above, generated so that the shader never
/// repeats a number of the host's.
pub fn wgsl_constants() -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    [
        "// Generated by src/query/layout.rs (wgsl_constants): the host's constants and codes.\n"
            .to_owned(),
        u("BLOCK", BLOCK as u32),
        u("SUB", SUB as u32),
        u("TILE_ROWS", (BLOCK / SUB) as u32),
        u("PACKETS", (BLOCK / SUB) as u32),
        u("BRANCHING", crate::ist::build::BRANCHING as u32),
        u("MASK_WORDS", (MAX_LINKS / 32) as u32),
        u("FRONTIER", FRONTIER as u32),
        u("GPU_STACK", GPU_STACK as u32),
        u("WORKGROUP", WORKGROUP),
        u("STAGES", STAGES as u32),
        u("WORK_COUNTERS", WORK_COUNTERS as u32),
        u("MAX_LINKS", MAX_LINKS as u32),
        u("MODE_FAST", MODE_FAST),
        u("MODE_CERTIFIED", MODE_CERTIFIED),
        u("MODE_EXACT", MODE_EXACT),
        u("STAGE_INVALID", Stage::Invalid as u32),
        u("STAGE_OUTSIDE_ROI", Stage::OutsideRoi as u32),
        u("STAGE_SELF_FILTERED", Stage::SelfFiltered as u32),
        u("STAGE_PRUNED", Stage::Pruned as u32),
        u("STAGE_EVALUATED", Stage::Evaluated as u32),
        u("STAGE_INSIDE", Stage::Inside as u32),
        u("CELL_CLEAR", Cell::Clear as u32),
        u("CELL_SHELL", Cell::Shell as u32),
        u("CELL_SELF", Cell::SelfPoint as u32),
        u("WORK_BLOCKS", Work::Blocks as u32),
        u("WORK_CULLED", Work::Culled as u32),
        u("WORK_ITEMS", Work::Items as u32),
        u("WORK_DESCENTS", Work::Descents as u32),
        u("WORK_NODES", Work::Nodes as u32),
        u("DEPTH_MM16", DEPTH_MM16),
        u("DEPTH_M32", DEPTH_M32),
    ]
    .concat()
}

/// The traversal shader file, embedded.
pub const TRAVERSE_WGSL: &str = include_str!("../../shaders/traverse.wgsl");
/// The workgroup reductions with subgroup operations ([`Reduce::Subgroups`]).
pub const REDUCE_SUBGROUPS_WGSL: &str = include_str!("../../shaders/reduce_subgroups.wgsl");
/// The workgroup reductions through workgroup memory ([`Reduce::Shared`]).
pub const REDUCE_SHARED_WGSL: &str = include_str!("../../shaders/reduce_shared.wgsl");
/// The depth images' unprojection, embedded.
pub const UNPROJECT_WGSL: &str = include_str!("../../shaders/unproject.wgsl");
/// The unseen space's cells, embedded.
pub const CELL_WGSL: &str = include_str!("../../shaders/cell.wgsl");
/// The minima in 64-bit atomics ([`Minima::Packed64`]).
pub const MINIMA_U64_WGSL: &str = include_str!("../../shaders/minima_u64.wgsl");
/// The minima in 32-bit atomics and the arg-min pass ([`Minima::Split32`]).
pub const MINIMA_U32_WGSL: &str = include_str!("../../shaders/minima_u32.wgsl");

/// The shader as compiled: the generated constants, the file of `minima`, the file of
/// `reduce`, then `shaders/traverse.wgsl`.
pub fn shader_source(minima: Minima, reduce: Reduce) -> String {
    let minima = match minima {
        Minima::Packed64 => MINIMA_U64_WGSL,
        Minima::Split32 => MINIMA_U32_WGSL,
    };
    let reduce = match reduce {
        Reduce::Subgroups => REDUCE_SUBGROUPS_WGSL,
        Reduce::Shared => REDUCE_SHARED_WGSL,
    };
    format!("{}\n{minima}\n{reduce}\n{TRAVERSE_WGSL}", wgsl_constants())
}

/// The unprojection shader as compiled: the generated constants, then `shaders/unproject.wgsl`.
pub fn unproject_source() -> String {
    format!("{}\n{UNPROJECT_WGSL}", wgsl_constants())
}

/// The cells' shader as compiled: the generated constants, then `shaders/cell.wgsl`.
pub fn cell_source() -> String {
    format!("{}\n{CELL_WGSL}", wgsl_constants())
}
