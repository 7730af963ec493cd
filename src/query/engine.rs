//! The query engine: the selected links, the shared bounds and the scratch memory kept from
//! query to query, and the backend a query runs on. A query is checked (poses, options, size,
//! the cloud's spacing where the robot is), moved to a working frame where its cloud's frame is
//! far from the robot, posed (step 1), then run on the GPU where it is asked for and usable, else
//! on the CPU (steps 2 and 3); both end in the same refinement and result (steps 4 and 5).

use std::sync::Arc;

use nalgebra::Isometry3;

use super::bounds::Bounds;
use super::error::QueryError;
use super::gpu;
use super::input::Input;
use super::layout::{self, RobotBox, MAX_LINKS};
use super::link::QueryLink;
use super::options::{Backend, QueryOptions};
use super::result::QueryResult;
use super::self_grid::SelfGrids;
use super::work::WorkCounts;
use super::{cpu, descent, pose};
use crate::cloud::depth::DepthView;
use crate::ist::LinkTree;
use crate::robot::{LinkSelection, RobotModel};

/// The query engine: the selected links and the scratch memory reused from query to query.
pub struct Engine {
    /// Shared, so that a caller may read the links while it queries (the unseen space's search).
    links: Arc<[QueryLink]>,
    pose_count: usize,
    bounds: Bounds,
    gpu: GpuSlot,
    /// The points in the working frame, for clouds far from their frame's origin (kept to
    /// avoid an allocation per query).
    work: Vec<[f32; 3]>,
    /// The self-filter's grids of the links, for the padding they were built for.
    self_grids: SelfGrids,
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
        let bounds = Bounds::new(&links);
        Ok(Self {
            links: links.into(),
            pose_count,
            bounds,
            gpu: GpuSlot::Untried,
            work: Vec::new(),
            self_grids: SelfGrids::default(),
        })
    }

    /// The work counts of the last query, on whichever backend it ran.
    pub fn last_work(&self) -> WorkCounts {
        WorkCounts::from(&self.bounds.work)
    }

    pub fn links(&self) -> &[QueryLink] {
        &self.links
    }

    /// The links, shared (one pointer's clone).
    pub fn shared_links(&self) -> Arc<[QueryLink]> {
        Arc::clone(&self.links)
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
        let input = Input {
            points,
            depth: None,
            width,
            root_from_sensor,
            link_poses,
            options,
        };
        let (origin, spacing) = self.check(&input)?;
        let Some(o) = origin else {
            let mut result = self.run(input);
            result.point_spacing_m = spacing;
            return Ok(result);
        };
        let mut work = std::mem::take(&mut self.work);
        pose::to_work(points, o, &mut work);
        let root_from_work = pose::root_from_work(root_from_sensor, o);
        let mut result = self.run(Input {
            points: &work,
            root_from_sensor: &root_from_work,
            ..input
        });
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
            let input = Input {
                points: &[],
                depth: Some(depth),
                width,
                root_from_sensor,
                link_poses,
                options,
            };
            let (origin, spacing) = self.check(&input)?;
            if origin.is_none() {
                let robot_box = self.pose(&input);
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

    /// Checks a query: the poses, the options, the size; where the robot is from the sensor
    /// (`pose::working_origin`), within the spacing the query certifies.
    fn check(&self, input: &Input) -> Result<(Option<[f32; 3]>, f32), QueryError> {
        let Input {
            root_from_sensor,
            link_poses,
            options,
            ..
        } = *input;
        let n = input.len();
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

    /// Step 1, for either backend: posed links and robot box in f64, rounded once, into
    /// `bounds`.
    fn pose(&mut self, input: &Input) -> RobotBox {
        self.bounds.prepare(
            &self.links,
            input.root_from_sensor,
            input.link_poses,
            input.options,
        )
    }

    /// Steps 1 to 5 of a checked query, in the frame the points are given in.
    fn run(&mut self, input: Input) -> QueryResult {
        let robot_box = self.pose(&input);
        if input.options.wants_gpu(input.points.len()) {
            if let Some(result) = self.run_gpu(input, &robot_box) {
                return result;
            }
        }
        let grids = self.self_grids.for_query(&self.links, input.options);
        cpu::run(&self.links, grids, &mut self.bounds, input, robot_box)
    }

    /// Steps 2 to 5 on the GPU, `bounds` prepared for `input`; `None` where there is no usable
    /// GPU (or only a software one, unless the GPU is asked for), or it gave up. A GPU that
    /// gives up leaves `bounds` as prepared (it writes them only on success), so the CPU starts
    /// from the same state.
    fn run_gpu(&mut self, input: Input, robot_box: &RobotBox) -> Option<QueryResult> {
        self.gpu();
        // Both backends' self-filter looks points up in the links' grids (built once a padding).
        let grids = self.self_grids.for_query(&self.links, input.options);
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

    /// Asks the next depth query that runs on the GPU to judge the unseen space's cells in the
    /// same submission (`gpu::GpuEngine::request_cells`); `None` takes the request back.
    pub fn request_cells(&mut self, request: Option<layout::CellParams>) {
        if let GpuSlot::Ready(g) = &mut self.gpu {
            g.request_cells(request);
        }
    }

    /// The cells' verdicts of the last depth query, where it ran them on the GPU.
    pub fn take_cells(&mut self) -> Option<Vec<u32>> {
        match &mut self.gpu {
            GpuSlot::Ready(g) => g.take_cells(),
            _ => None,
        }
    }

    /// Builds the self-filter's grids for the padding of `options` now, so that the first
    /// query does not (the node does this before it takes its first cloud).
    pub fn prepare_self_filter(&mut self, options: &QueryOptions) {
        self.self_grids.prepare(&self.links, options);
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
