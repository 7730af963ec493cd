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
//! - `layout`: the `#[repr(C)]` Pod structs (posed links, robot box, dispatch parameters,
//!   counters, candidates) that the CPU walks and the GPU uploads as they are, and the named
//!   constants and codes that the WGSL shader receives generated from them;
//! - `pose` (step 1, both backends): links and robot box composed in f64, rounded once;
//! - `bounds`: the shared minima, global bounds and exact candidates of one query;
//! - `cpu` and `descent` (steps 2 and 3 on the CPU): seeds, blocks, frontiers, the descent;
//!   `self_grid`, the CPU self-filter's per-link grid;
//! - `gpu` (steps 2 and 3 on the GPU): the wgpu host of `shaders/traverse.wgsl`;
//! - `exact` and `result` (steps 4 and 5, both backends): exact refinement and the result;
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
//!    hysteresis) and for the nearest link; a link farther away is pruned with the global
//!    bound and reported as farther than the final threshold (`bounds::threshold`), with the
//!    certified lower bound that follows. Switching per-link minima off leaves one shared
//!    bound;
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
pub mod exact;
pub mod gpu;
pub mod layout;
#[cfg(feature = "fixtures")]
pub mod peers;
mod pose;
mod result;
pub use result::{LinkDistance, Nearest, Outcome, QueryResult, StageCounts};
mod self_grid;
mod work;

pub use work::WorkCounts;

pub use descent::valid as is_valid_point;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::cloud::depth::DepthView;
use crate::ist::{IstNode, LinkTree};
use crate::packing::{InnerSphere, Solid};
use crate::robot::{LinkGeometry, RobotModel};

/// Most links with collision geometry one engine handles (a bit mask per point).
pub const MAX_LINKS: usize = 128;

/// Default crossover of `Backend::Auto` for a cloud, in points: where `ist_monitor bench gpu`
/// puts it on an H100 beside 16 CPU cores (docs/gpu.md). There a cloud of 307,200 points is
/// level on the two backends (CPU / GPU 0.93–1.18), one of 1 M to 2 M is faster on the CPU (the
/// cloud's upload is then twice the kernel; CPU / GPU 0.65–0.83), and one of 5 M is faster on the
/// GPU (0.95–1.19, 1.13 in the sweep). On quiet H200s the two were level from 307,200 to 2 M
/// points and the GPU ahead at 5 M; on one whose CPU was busy the GPU was 1.2–2.1× ahead from
/// 100,000 points on. Run the bench on the machine and set `gpu_min_points` from its figure.
pub const DEFAULT_GPU_MIN_POINTS: usize = 5_000_000;

/// Default crossover of `Backend::Auto` for a depth image that the GPU unprojects itself, in
/// pixels: only the image's bytes cross to the device (a sixth of its points'), and the CPU must
/// also make the points. On the H100 and every H200 measured the GPU wins from the sweep's 99,840
/// pixels on (156 rows of 640; 1.4–2.1× the CPU there, 2.6–4.7× at 640 × 480) and the CPU at 9,600
/// (`ist_monitor bench gpu --depth`).
pub const DEFAULT_GPU_MIN_DEPTH_PIXELS: usize = 99_840;

/// What the query computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Distance to the inner spheres: an upper bound.
    Fast,
    /// Upper bound and certified lower bound `max(0, d − h)`.
    Certified,
    /// Exact distance to the collision meshes.
    Exact,
}

impl Mode {
    /// The mode's code in the shared layout (`layout::MODE_*`, the shader's `params.mode`).
    pub fn code(self) -> u32 {
        match self {
            Mode::Fast => layout::MODE_FAST,
            Mode::Certified => layout::MODE_CERTIFIED,
            Mode::Exact => layout::MODE_EXACT,
        }
    }
}

/// Options of one query.
#[derive(Debug, Clone, PartialEq)]
pub struct QueryOptions {
    pub mode: Mode,
    /// Points farther than this from the robot's bounding box are dropped; a result beyond it is
    /// reported as "nothing within max_distance". Infinity keeps everything.
    pub max_distance_m: f32,
    /// Points within this inner-sphere distance of the robot are the robot itself; `None`
    /// switches the self-filter off.
    pub self_filter_padding_m: Option<f32>,
    /// Per-link minima (one bound per link); off leaves one shared bound, which prunes more.
    pub per_link: bool,
    /// With per-link minima: a link's minimum is measured up to this distance (and always for
    /// the nearest link); a link farther away is reported as farther than a certified bound
    /// ([`LinkDistance::farther_than_m`]), which costs far less. Infinity measures every link.
    pub per_link_range_m: f32,
    pub backend: Backend,
    /// `Backend::Auto` uses the GPU for a cloud from this many points on.
    pub gpu_min_points: usize,
    /// `Backend::Auto` uses the GPU for a depth image it can unproject itself (no working frame)
    /// from this many pixels on.
    pub gpu_min_depth_pixels: usize,
}

/// Where a query runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    Cpu,
    Gpu,
    /// The GPU for clouds of at least `gpu_min_points` and depth images of at least
    /// `gpu_min_depth_pixels` on a hardware GPU, else the CPU.
    Auto,
}

impl QueryOptions {
    /// Whether a cloud of `points` points asks for the GPU: always with `gpu`, from
    /// `gpu_min_points` on with `auto` (which still stays on the CPU on a software adapter).
    pub fn wants_gpu(&self, points: usize) -> bool {
        self.wants_gpu_from(points, self.gpu_min_points)
    }

    /// Whether a depth image of `pixels` pixels asks for the GPU: as [`Self::wants_gpu`], from
    /// `gpu_min_depth_pixels` on with `auto`.
    pub fn wants_gpu_for_depth(&self, pixels: usize) -> bool {
        self.wants_gpu_from(pixels, self.gpu_min_depth_pixels)
    }

    fn wants_gpu_from(&self, n: usize, crossover: usize) -> bool {
        match self.backend {
            Backend::Cpu => false,
            Backend::Gpu => true,
            Backend::Auto => n >= crossover,
        }
    }

    /// Refuses a NaN or negative `max_distance_m` and a negative or non-finite padding.
    pub fn validate(&self) -> Result<(), QueryError> {
        if self.max_distance_m.is_nan() || self.max_distance_m < 0.0 {
            return Err(QueryError::BadOption(
                "max_distance_m must be ≥ 0 (infinity allowed)",
            ));
        }
        if self.per_link_range_m.is_nan() || self.per_link_range_m < 0.0 {
            return Err(QueryError::BadOption(
                "per_link_range_m must be ≥ 0 (infinity allowed)",
            ));
        }
        if self
            .self_filter_padding_m
            .is_some_and(|p| !(p.is_finite() && p >= 0.0))
        {
            return Err(QueryError::BadOption(
                "self_filter_padding_m must be finite and ≥ 0",
            ));
        }
        Ok(())
    }
}

/// The defaults of the node parameters of the same names (`config::PARAMETERS`; a test there
/// checks that the two agree).
impl Default for QueryOptions {
    fn default() -> Self {
        Self {
            mode: Mode::Certified,
            max_distance_m: 2.0,
            self_filter_padding_m: Some(0.01),
            per_link: true,
            // The node's warn_distance + hysteresis (0.3 + 0.02 m).
            per_link_range_m: 0.32,
            backend: Backend::Auto,
            gpu_min_points: DEFAULT_GPU_MIN_POINTS,
            gpu_min_depth_pixels: DEFAULT_GPU_MIN_DEPTH_PIXELS,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    #[error(
        "link {0} named in the link selection has no collision geometry (links with geometry: {1})"
    )]
    UnknownLink(String, String),
    #[error("link {0} has an inner sphere tree but is not in the robot's kinematics")]
    NotInKinematics(String),
    #[error("{0} links selected; the engine handles at most {MAX_LINKS}")]
    TooManyLinks(usize),
    #[error("link {link}: tree depth {depth} exceeds the traversal stack (at most {max})")]
    TreeTooDeep {
        link: String,
        depth: usize,
        max: usize,
    },
    #[error("link {0}: a tree no descent can walk (empty, a node with more children than the tree's branching, or a child outside its arrays or before its parent)")]
    BadTree(String),
    #[error("no link selected")]
    NoLinks,
    #[error("the sensor pose is not finite")]
    NonFiniteSensorPose,
    #[error("option {0}")]
    BadOption(&'static str),
    #[error("{0} points: point indices are 32-bit")]
    TooManyPoints(usize),
    #[error("{got} link poses given, the robot has {expected} links")]
    LinkPoses { got: usize, expected: usize },
    #[error(
        "the cloud's f32 coordinates are {spacing_m} m apart where the robot is ({offset_m:.0} m \
         from the origin of the cloud's frame), coarser than the {limit_m} m the query certifies: \
         publish the cloud in a frame near the robot"
    )]
    CoarseCloud {
        spacing_m: f32,
        offset_m: f64,
        limit_m: f32,
    },
}

/// One link as the query sees it: its tree, its surface gap and, for exact mode, its solids.
pub struct QueryLink {
    pub name: String,
    /// Index into the kinematics' link poses.
    pub pose_index: usize,
    pub nodes: Vec<IstNode>,
    pub spheres: Vec<InnerSphere>,
    /// Certified surface gap h, m.
    pub gap_m: f32,
    /// One solid per collision element (elements may overlap, so they are kept apart).
    pub solids: Vec<Solid>,
    /// Packed as its convex hull: its inner-sphere distance is no upper bound of the link's,
    /// so the result gives its certified lower bound as its distance.
    pub convex_hull: bool,
    /// Structure-of-arrays copies of the node and sphere arrays for the CPU descent (four
    /// children tested at once); derived from `nodes` and `spheres` by [`QueryLink::new`].
    pub(crate) node_soa: SphereSoa,
    pub(crate) sphere_soa: SphereSoa,
}

/// Sphere centres and radii as four arrays, padded with four far spheres so that four
/// consecutive entries can always be loaded.
#[derive(Debug, Clone, Default)]
pub(crate) struct SphereSoa {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
    pub r: Vec<f32>,
}

impl SphereSoa {
    fn new(spheres: impl Iterator<Item = ([f32; 3], f32)>) -> Self {
        let mut soa = Self::default();
        for (c, r) in spheres.chain(std::iter::repeat_n(([1e30; 3], 0.0), 4)) {
            soa.x.push(c[0]);
            soa.y.push(c[1]);
            soa.z.push(c[2]);
            soa.r.push(r);
        }
        soa
    }
}

impl QueryLink {
    /// A link from its tree and, for exact mode, its collision geometry.
    pub fn from_tree(tree: &LinkTree, geometry: Option<&LinkGeometry>, pose_index: usize) -> Self {
        let solids = geometry
            .map(|g| g.elements.iter().map(|e| Solid::new(&e.mesh)).collect())
            .unwrap_or_default();
        let mut link = Self::new(
            tree.link.clone(),
            pose_index,
            tree.nodes.clone(),
            tree.spheres.clone(),
            tree.quality.gap_m as f32,
            solids,
        );
        link.convex_hull = geometry.is_some_and(|g| g.hull_of_volume_m3.is_some());
        link
    }

    /// A link from its tree, surface gap, solids and index into the link poses.
    pub fn new(
        name: String,
        pose_index: usize,
        nodes: Vec<IstNode>,
        spheres: Vec<InnerSphere>,
        gap_m: f32,
        solids: Vec<Solid>,
    ) -> Self {
        let node_soa = SphereSoa::new(nodes.iter().map(|n| (n.center, n.radius)));
        let sphere_soa = SphereSoa::new(spheres.iter().map(|s| (s.center, s.radius)));
        Self {
            name,
            pose_index,
            nodes,
            spheres,
            gap_m,
            solids,
            convex_hull: false,
            node_soa,
            sphere_soa,
        }
    }
}

pub use crate::robot::LinkSelection;

impl LinkSelection {
    /// Checks the selection against `model` before anything is built: every name it gives is a
    /// link with collision geometry, and the links it selects are at least one and at most
    /// [`MAX_LINKS`].
    pub fn check(&self, model: &RobotModel) -> Result<(), QueryError> {
        // Links the selection left out when the robot was loaded are known by name.
        let names = || {
            model
                .links
                .iter()
                .map(|l| l.name.as_str())
                .chain(model.unloaded_links.iter().map(String::as_str))
        };
        let hulls = self.convex_hull.iter().filter(|n| n.as_str() != "*");
        for name in self.include.iter().chain(&self.exclude).chain(hulls) {
            if !names().any(|n| n == name) {
                return Err(QueryError::UnknownLink(
                    name.clone(),
                    names().collect::<Vec<_>>().join(", "),
                ));
            }
        }
        match model.links.iter().filter(|l| self.selects(&l.name)).count() {
            0 => Err(QueryError::NoLinks),
            n if n > MAX_LINKS => Err(QueryError::TooManyLinks(n)),
            _ => Ok(()),
        }
    }
}

/// The query engine: the selected links and the scratch memory reused from query to query.
pub struct Engine {
    links: Vec<QueryLink>,
    pose_count: usize,
    bounds: bounds::Bounds,
    gpu: GpuSlot,
    /// The points in the working frame, for clouds far from their frame's origin (kept to
    /// avoid an allocation per query).
    work: Vec<[f32; 3]>,
    /// The self-filter's grids of the links (CPU), for the padding they were built for.
    self_grids: Option<(f32, Vec<self_grid::SelfGrid>)>,
}

/// The GPU backend, created on first use.
enum GpuSlot {
    Untried,
    Unavailable,
    Ready(Box<gpu::GpuEngine>),
}

impl Engine {
    /// An engine over `trees` (from `ist::build_robot`), posed by `model`'s kinematics, with the
    /// meshes of `model` for exact mode.
    pub fn new(
        model: &RobotModel,
        trees: &[LinkTree],
        selection: &LinkSelection,
    ) -> Result<Self, QueryError> {
        selection.check(model)?;
        let mut links = Vec::new();
        for tree in trees {
            if !selection.selects(&tree.link) {
                continue;
            }
            let pose_index = model
                .kinematics
                .link_index(&tree.link)
                .ok_or_else(|| QueryError::NotInKinematics(tree.link.clone()))?;
            let geometry = model.links.iter().find(|l| l.name == tree.link);
            links.push(QueryLink::from_tree(tree, geometry, pose_index));
        }
        Self::from_links(links, model.kinematics.link_names().len())
    }

    /// An engine over links made by hand (tests, benchmarks); `pose_count` is the length of the
    /// link pose array the queries will pass.
    pub fn from_links(links: Vec<QueryLink>, pose_count: usize) -> Result<Self, QueryError> {
        if links.is_empty() {
            return Err(QueryError::NoLinks);
        }
        if links.len() > MAX_LINKS {
            return Err(QueryError::TooManyLinks(links.len()));
        }
        let max = layout::max_tree_depth(layout::STACK, layout::FRONTIER);
        for link in &links {
            if descent::bad_node(&link.nodes, link.spheres.len()).is_some() {
                return Err(QueryError::BadTree(link.name.clone()));
            }
            let depth = descent::tree_depth(&link.nodes);
            if depth > max {
                return Err(QueryError::TreeTooDeep {
                    link: link.name.clone(),
                    depth,
                    max,
                });
            }
        }
        let bounds = bounds::Bounds::new(&links);
        Ok(Self {
            links,
            pose_count,
            bounds,
            gpu: GpuSlot::Untried,
            work: Vec::new(),
            self_grids: None,
        })
    }

    /// The work counts of the last query, on whichever backend it ran.
    pub fn last_work(&self) -> WorkCounts {
        WorkCounts::from(&self.bounds.work)
    }

    pub fn links(&self) -> &[QueryLink] {
        &self.links
    }

    /// The minimum distance between the robot posed by `link_poses` (`root_from_link`, indexed
    /// like the kinematics' links) and `points`, given in the frame whose pose is
    /// `root_from_sensor`.
    pub fn query(
        &mut self,
        points: &[[f32; 3]],
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> Result<QueryResult, QueryError> {
        self.query_image(points, None, root_from_sensor, link_poses, options)
    }

    /// [`Engine::query`] for an organized cloud (a depth image) of `width` points per row, row
    /// after row: the CPU then takes the points in tiles of 8 × 4 pixels, which lie closer
    /// together than runs of a row (the answer is the same; `None`, or a width that does not
    /// divide the point count, takes runs).
    pub fn query_image(
        &mut self,
        points: &[[f32; 3]],
        width: Option<usize>,
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> Result<QueryResult, QueryError> {
        let (origin, spacing) = self.check(points.len(), root_from_sensor, link_poses, options)?;
        let Some(o) = origin else {
            let mut result = self.run(points, width, root_from_sensor, link_poses, options);
            result.point_spacing_m = spacing;
            return Ok(result);
        };
        let mut work = std::mem::take(&mut self.work);
        pose::to_work(points, o, &mut work);
        let root_from_work = pose::root_from_work(root_from_sensor, o);
        let mut result = self.run(&work, width, &root_from_work, link_poses, options);
        self.work = work;
        result.point_spacing_m = spacing;
        // The one sensor-frame coordinate of the result: the point as the cloud gave it.
        if let Some(n) = &mut result.nearest {
            n.point_sensor = points[n.point_index as usize];
        }
        Ok(result)
    }

    /// The points of depth image `depth` measured as [`Engine::query_image`] measures them
    /// (`depth` made by `cloud::depth::DepthView::new`). Where the query runs on the GPU and
    /// the robot is within 16 m of the camera (no working frame), the GPU makes the points from
    /// the image (614 KB for 640 × 480 16UC1, against 3.7 MB of points) and `points` is left
    /// empty; otherwise they are made into `points` on the CPU (its allocation kept) and
    /// measured from there.
    pub fn query_depth(
        &mut self,
        depth: &DepthView,
        points: &mut Vec<[f32; 3]>,
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> Result<QueryResult, QueryError> {
        let width = (depth.height() > 1).then_some(depth.width());
        if options.wants_gpu_for_depth(depth.len()) {
            let (origin, spacing) =
                self.check(depth.len(), root_from_sensor, link_poses, options)?;
            if origin.is_none() {
                let input = Input {
                    points: &[],
                    depth: Some(depth),
                    width,
                    root_from_sensor,
                    link_poses,
                    options,
                };
                let robot_box =
                    self.bounds
                        .prepare(&self.links, root_from_sensor, link_poses, options);
                if let Some(mut result) = self.run_gpu(input, &robot_box) {
                    points.clear();
                    result.point_spacing_m = spacing;
                    return Ok(result);
                }
            }
        }
        depth.unproject_into(points);
        self.query_image(points, width, root_from_sensor, link_poses, options)
    }

    /// Checks a query of `n` points: the poses, the options, the size; where the robot is from
    /// the sensor (`pose::working_origin`), within the spacing the query certifies.
    fn check(
        &self,
        n: usize,
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> Result<(Option<[f32; 3]>, f32), QueryError> {
        if link_poses.len() != self.pose_count {
            return Err(QueryError::LinkPoses {
                got: link_poses.len(),
                expected: self.pose_count,
            });
        }
        let m = root_from_sensor.to_homogeneous();
        if m.iter().any(|v| !v.is_finite()) {
            return Err(QueryError::NonFiniteSensorPose);
        }
        options.validate()?;
        if n > u32::MAX as usize {
            return Err(QueryError::TooManyPoints(n));
        }
        let (origin, spacing) = pose::working_origin(&self.links, root_from_sensor, link_poses);
        if spacing > pose::MAX_POINT_SPACING_M {
            let o = origin.unwrap_or_default();
            return Err(QueryError::CoarseCloud {
                spacing_m: spacing,
                offset_m: o.iter().map(|v| (*v as f64).powi(2)).sum::<f64>().sqrt(),
                limit_m: pose::MAX_POINT_SPACING_M,
            });
        }
        Ok((origin, spacing))
    }

    /// Steps 1 to 5 of a checked query, in the frame the points are given in.
    fn run(
        &mut self,
        points: &[[f32; 3]],
        width: Option<usize>,
        root_from_sensor: &Isometry3<f64>,
        link_poses: &[Isometry3<f64>],
        options: &QueryOptions,
    ) -> QueryResult {
        let input = Input {
            points,
            depth: None,
            width,
            root_from_sensor,
            link_poses,
            options,
        };
        // Step 1, for either backend: posed links and robot box in f64, rounded once.
        let robot_box = self
            .bounds
            .prepare(&self.links, root_from_sensor, link_poses, options);
        if options.wants_gpu(points.len()) {
            if let Some(result) = self.run_gpu(input, &robot_box) {
                return result;
            }
        }
        // Both backends' self-filter looks points up in the links' grids (built once a padding).
        self.prepare_self_filter(options);
        let grids = match (&self.self_grids, options.self_filter_padding_m) {
            (Some((_, grids)), Some(_)) => grids.as_slice(),
            _ => &[],
        };
        cpu::run(&self.links, grids, &mut self.bounds, input, robot_box)
    }

    /// Steps 2 to 5 on the GPU, `bounds` prepared for `input`; `None` where there is no usable
    /// GPU (or only a software one, unless the GPU is asked for), or it gave up. A GPU that
    /// gives up leaves `bounds` as prepared (it writes them only on success), so the CPU starts
    /// from the same state.
    fn run_gpu(&mut self, input: Input, robot_box: &layout::RobotBox) -> Option<QueryResult> {
        self.gpu();
        self.prepare_self_filter(input.options);
        let grids = match (&self.self_grids, input.options.self_filter_padding_m) {
            (Some((_, grids)), Some(_)) => grids.as_slice(),
            _ => &[],
        };
        let GpuSlot::Ready(g) = &mut self.gpu else {
            return None;
        };
        if input.options.backend != Backend::Gpu && g.is_software() {
            return None;
        }
        match g.query(&self.links, &mut self.bounds, robot_box, input, grids) {
            Ok(Some(r)) => Some(r),
            Ok(None) => {
                log::debug!("GPU result incomplete (candidate list full, or an arg-min lost): CPU");
                None
            }
            Err(e) => {
                log::warn!("GPU query failed ({e}): this query runs on the CPU");
                None
            }
        }
    }

    /// The links' self-filter grids for `padding`, built on the first CPU query with it (once;
    /// 43 ms for the demo arm, 90 ms for the Panda on 2 cores; [`Engine::prepare_self_filter`]
    /// builds them ahead).
    fn self_grids(&mut self, padding: f32) {
        if self.self_grids.as_ref().is_none_or(|(p, _)| *p != padding) {
            let start = std::time::Instant::now();
            let grids: Vec<_> = self
                .links
                .iter()
                .map(|l| self_grid::SelfGrid::new(l, padding))
                .collect();
            let cells = grids
                .iter()
                .map(|g| g.census())
                .fold([0; 3], |a, c| [a[0] + c[0], a[1] + c[1], a[2] + c[2]]);
            log::debug!(
                "self-filter grids for padding {padding} m: {} cells ({} self, {} shell) in {:.0} ms",
                cells.iter().sum::<usize>(),
                cells[2],
                cells[1],
                start.elapsed().as_secs_f64() * 1e3
            );
            self.self_grids = Some((padding, grids));
        }
    }

    /// Builds the self-filter's grids for the padding of `options` now, so that the first
    /// query does not (the node does this before it takes its first cloud).
    pub fn prepare_self_filter(&mut self, options: &QueryOptions) {
        if let Some(padding) = options.self_filter_padding_m {
            self.self_grids(padding);
        }
    }

    /// The GPU backend, created on first use; `None` (said once) when there is no usable GPU.
    pub fn gpu(&mut self) -> Option<&mut gpu::GpuEngine> {
        if matches!(self.gpu, GpuSlot::Untried) {
            self.gpu_with(gpu::GpuOptions::default());
        }
        match &mut self.gpu {
            GpuSlot::Ready(g) => Some(g),
            _ => None,
        }
    }

    /// Makes the GPU backend anew with `options` (tests and benchmarks: the portable path on an
    /// adapter that has 64-bit atomics); `None` (said) when there is no usable GPU.
    pub fn gpu_with(&mut self, options: gpu::GpuOptions) -> Option<&mut gpu::GpuEngine> {
        self.gpu = match gpu::GpuEngine::new(&self.links, options) {
            Ok(g) => {
                log::info!("GPU: {}", g.describe());
                GpuSlot::Ready(Box::new(g))
            }
            Err(e) => {
                log::warn!("no usable GPU ({e}): queries run on the CPU");
                GpuSlot::Unavailable
            }
        };
        match &mut self.gpu {
            GpuSlot::Ready(g) => Some(g),
            _ => None,
        }
    }
}

/// `root_from_sensor` from two poses in a common (map) frame, composed in f64 so that large map
/// coordinates cancel before anything is rounded.
pub fn root_from_sensor_via_map(
    map_from_root: &Isometry3<f64>,
    map_from_sensor: &Isometry3<f64>,
) -> Isometry3<f64> {
    map_from_root.inverse() * map_from_sensor
}

/// What one query asks: the cloud, where its sensor is, how the robot is posed, the options.
#[derive(Clone, Copy)]
struct Input<'a> {
    /// The points the CPU sweeps; empty for a depth image unprojected on the GPU (`depth`).
    points: &'a [[f32; 3]],
    /// A depth image whose points the GPU makes; the host unprojects the few the result needs
    /// ([`Input::point`]), exactly as the GPU did.
    depth: Option<&'a DepthView<'a>>,
    /// Points per row of an organized cloud.
    width: Option<usize>,
    root_from_sensor: &'a Isometry3<f64>,
    link_poses: &'a [Isometry3<f64>],
    options: &'a QueryOptions,
}

impl Input<'_> {
    /// Points in the query.
    fn len(&self) -> usize {
        self.depth.map_or(self.points.len(), |d| d.len())
    }

    /// Point `i`.
    fn point(&self, i: u32) -> [f32; 3] {
        match self.depth {
            Some(d) => d.point(i as usize),
            None => self.points[i as usize],
        }
    }
}
