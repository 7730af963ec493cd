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
//! - **Then** the shared `result::finish` refines the exact candidates and assembles the result,
//!   so both backends report through one code path.
//!
//! The link that won each minimum is kept for the next query's seed pass (the previous frame's
//! winners: on a stream of clouds from one sensor, the same pixels are near the arm again).
//!
//! Agreement with the CPU: the same posed links, trees, blocks, box tests, thresholds and
//! recording rules; only the rounding of the square root may differ (a few ulps, far below 1 µm
//! at robot scale).

mod passes;
mod setup;
mod transfer;
mod unproject;

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

use bytemuck::Zeroable;

use super::bounds::{pack_minimum, threshold, Bounds, EMPTY};
use super::cpu::blocks::Tiling;
use super::layout::{
    self, BoxedBlock, Candidate, Counters, GridHeader, KeptBlock, Minima, QueryParams, Reduce,
    RobotBox, Stage, GPU_CANDIDATES, GPU_STACK, SEED_STRIDE,
};
use super::self_grid::SelfGrid;
use super::{result, Backend, Input, Mode, QueryLink, QueryResult, StageCounts};
use passes::{encode, groups, steps, Step, STAMP_BYTES};
use setup::storage;
use transfer::MAPPED;

/// Setting this variable (to anything but `0`) keeps the GPU from using 64-bit atomics even
/// where the adapter has them: the portable path ([`Minima::Split32`]), as on adapters without.
pub const NO_INT64_ENV: &str = "IST_MONITOR_GPU_NO_INT64";

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("GPU device: {0}")]
    Device(String),
    #[error("link {link}: tree depth needs more than the shader's stack of {GPU_STACK}")]
    TooDeep { link: String },
    #[error("link {link}: node {node} of a tree no descent can walk (empty, more children than the tree's branching, or a child outside its arrays or before its parent)")]
    BadTree { link: String, node: usize },
    #[error("{0} bytes exceed the device's storage buffer limit")]
    TooLarge(u64),
    #[error("reading back: {0}")]
    Readback(String),
}

/// Setting this variable (to anything but `0`) keeps the GPU from using subgroup operations
/// even where the adapter has them: the workgroup-memory reductions ([`Reduce::Shared`]), as on
/// adapters without.
pub const NO_SUBGROUPS_ENV: &str = "IST_MONITOR_GPU_NO_SUBGROUPS";

/// Setting this variable (to anything but `0`) makes the measure pass descend each sub-block's
/// points as a packet (the shader's `DESCEND_PACKETS`: one stack for the eight points, as the CPU's
/// `descent::nearest_packet`) instead of each point on its own. Off by default: packets made the
/// kernel slower on an H100, 0.217 → 0.252 ms at 307,200 points (docs/gpu.md; the measure pass
/// 92 → 127 µs on an H200), as `bench gpu --packets` measures.
pub const PACKETS_ENV: &str = "IST_MONITOR_GPU_PACKETS";

/// How the GPU engine is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuOptions {
    /// Use 64-bit atomics where the adapter has them ([`Minima::Packed64`]).
    pub int64_atomics: bool,
    /// Use subgroup operations where the adapter has them ([`Reduce::Subgroups`]).
    pub subgroups: bool,
    /// Descend each sub-block's points as a packet in the measure pass ([`PACKETS_ENV`]).
    pub packets: bool,
}

impl Default for GpuOptions {
    /// 64-bit atomics and subgroup operations where the adapter has them, unless
    /// [`NO_INT64_ENV`] or [`NO_SUBGROUPS_ENV`] is set; packets where [`PACKETS_ENV`] is set.
    fn default() -> Self {
        let set = |var| std::env::var(var).is_ok_and(|v| v != "0");
        Self {
            int64_atomics: !set(NO_INT64_ENV),
            subgroups: !set(NO_SUBGROUPS_ENV),
            packets: set(PACKETS_ENV),
        }
    }
}

/// The buffers that grow with the cloud, and the bind group over them.
struct Sized {
    points: wgpu::Buffer,
    /// The points' (or the depth image's) staging memory, mapped for writing between queries,
    /// and its state (`UNMAPPED`, `MAPPING`, `MAPPED`).
    staging: wgpu::Buffer,
    staging_state: Arc<AtomicU8>,
    /// The kept blocks, the work items and the boxed blocks, which only the shader reads and
    /// writes.
    scratch: [wgpu::Buffer; 3],
    /// A depth image's bytes, for the unprojection, and the group that binds it with the
    /// points.
    image: wgpu::Buffer,
    image_group: wgpu::BindGroup,
    points_capacity: usize,
    blocks_capacity: usize,
    items_capacity: usize,
    /// Bytes of the image buffer (and at least of the staging buffer).
    image_capacity: u64,
    /// Over every buffer; `None` once one of them changed.
    group: Option<wgpu::BindGroup>,
}

/// The compute pipelines, one per entry point.
struct Pipelines {
    seed_scan: wgpu::ComputePipeline,
    /// Only without 64-bit atomics.
    seed_pick: Option<wgpu::ComputePipeline>,
    seed: wgpu::ComputePipeline,
    cull: wgpu::ComputePipeline,
    blocks: wgpu::ComputePipeline,
    plan: wgpu::ComputePipeline,
    measure: wgpu::ComputePipeline,
    tally: wgpu::ComputePipeline,
    /// Only without 64-bit atomics.
    argmin: Option<wgpu::ComputePipeline>,
}

/// A device with a robot's trees uploaded.
pub struct GpuEngine {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipelines: Pipelines,
    unproject: unproject::Unproject,
    /// The adapter, as wgpu describes it.
    pub adapter: wgpu::AdapterInfo,
    /// How the minima are kept on this adapter.
    pub minima: Minima,
    /// How a workgroup reduces on this adapter.
    pub reduce: Reduce,
    /// Whether the measure pass descends packets ([`GpuOptions::packets`]).
    pub packets: bool,
    layout: wgpu::BindGroupLayout,
    nodes: wgpu::Buffer,
    spheres: wgpu::Buffer,
    links: wgpu::Buffer,
    params: wgpu::Buffer,
    state: wgpu::Buffer,
    minima_buffer: wgpu::Buffer,
    candidates: wgpu::Buffer,
    winners: wgpu::Buffer,
    dispatch: wgpu::Buffer,
    dispatch_group: wgpu::BindGroup,
    readback: wgpu::Buffer,
    sized: Option<Sized>,
    max_binding: u64,
    /// Timestamps around the query's passes, where the adapter has them.
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    /// GPU time of the last query's passes, s (with timestamp queries).
    pub last_kernel_s: Option<f64>,
    /// Each dispatch in a pass of its own with its own timestamps ([`GpuEngine::set_profile`]).
    profile: bool,
    /// With `profile`: the last query's dispatches and their GPU time, s.
    pub last_passes: Vec<(&'static str, f64)>,
    /// The last query's host side, s, one after the other: the small inputs (sizes, poses,
    /// counters), the points' (or the image's) copy into the staging memory, encoding the
    /// passes, the submission (and its error scopes), waiting for the readback to be mapped,
    /// and reading it back into the result ([`HOST_STEPS`] names them).
    pub last_host_s: [f64; HOST_STEPS.len()],
    /// Each link's arg-min point of the last query (`u32::MAX`: none): the next one's seeds.
    last_winners: Vec<u32>,
    /// The self-filter's grids (headers, packed cells) and the padding they were built for.
    grids: (wgpu::Buffer, wgpu::Buffer, Option<f32>),
}

/// The names of [`GpuEngine::last_host_s`]'s steps, in its order.
pub const HOST_STEPS: [&str; 6] = [
    "host: inputs",
    "host: upload",
    "host: encode",
    "host: submit",
    "host: to mapped",
    "host: result",
];

impl GpuEngine {
    /// Times each dispatch on its own (`last_passes`; each then in a compute pass of its own,
    /// which costs a little): the profile `bench gpu --passes` prints.
    pub fn set_profile(&mut self, on: bool) {
        self.profile = on;
    }

    /// The adapter and the paths taken on it: "name (type, backend; minima …, reductions …,
    /// descents per point | in packets)".
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?}; minima {:?}, reductions {:?}, descents {})",
            self.adapter.name,
            self.adapter.device_type,
            self.adapter.backend,
            self.minima,
            self.reduce,
            if self.packets {
                "in packets"
            } else {
                "per point"
            }
        )
    }

    /// Whether the adapter is a software rasterizer (lavapipe, WARP, SwiftShader): correct, but
    /// never faster than the CPU backend.
    pub fn is_software(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    /// Grows the cloud's buffers to hold `points` points in `blocks` blocks with `items` work
    /// items, and a depth image of `image_bytes` (a multiple of four).
    fn ensure(
        &mut self,
        points: usize,
        blocks: usize,
        items: usize,
        image_bytes: u64,
    ) -> Result<(), GpuError> {
        if self.sized.as_ref().is_some_and(|s| {
            s.points_capacity >= points
                && s.blocks_capacity >= blocks
                && s.items_capacity >= items
                && s.image_capacity >= image_bytes
        }) {
            return Ok(());
        }
        let grow = |n: usize| n.next_power_of_two().max(1024);
        // Items past the room send that query to the CPU (its result says so), where a buffer
        // the device cannot bind would fail every query.
        let most_items = (self.max_binding / 4) as usize;
        let (points, blocks, items) = (grow(points), grow(blocks), grow(items).min(most_items));
        let buffer = |label, bytes: u64| -> Result<wgpu::Buffer, GpuError> {
            if bytes > self.max_binding {
                return Err(GpuError::TooLarge(bytes));
            }
            Ok(self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }))
        };
        if 12 * points as u64 > self.max_binding {
            return Err(GpuError::TooLarge(12 * points as u64));
        }
        let point_buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("points"),
            size: 12 * points as u64,
            // Read back only by `read_points` (tests, benchmarks).
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let image_capacity = image_bytes.next_power_of_two().max(4096);
        let image = buffer("depth image", image_capacity)?;
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("points staging"),
            size: (12 * points as u64).max(image_capacity),
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: true,
        });
        let kept = buffer(
            "kept blocks",
            (std::mem::size_of::<KeptBlock>() * blocks) as u64,
        )?;
        let item_buffer = buffer("items", 4 * items as u64)?;
        let boxed = buffer(
            "boxed blocks",
            (std::mem::size_of::<BoxedBlock>() * blocks) as u64,
        )?;
        let image_group = self.unproject.bind(&self.device, &image, &point_buffer);
        self.sized = Some(Sized {
            points: point_buffer,
            staging,
            staging_state: Arc::new(AtomicU8::new(MAPPED)),
            scratch: [kept, item_buffer, boxed],
            image,
            image_group,
            points_capacity: points,
            blocks_capacity: blocks,
            items_capacity: items,
            image_capacity,
            group: None,
        });
        Ok(())
    }

    /// The self-filter's grids for `padding` on the GPU (built by the engine once per padding),
    /// uploaded when the padding changes.
    fn use_grids(&mut self, padding: f32, grids: &[SelfGrid]) -> Result<(), GpuError> {
        if self.grids.2 == Some(padding) || grids.is_empty() {
            return Ok(());
        }
        let mut words = Vec::new();
        let headers: Vec<GridHeader> = grids.iter().map(|g| g.pack(&mut words)).collect();
        words.push(0);
        let bytes = 4 * words.len() as u64;
        if bytes > self.max_binding {
            return Err(GpuError::TooLarge(bytes));
        }
        self.grids = (
            storage(&self.device, "grid headers", bytemuck::cast_slice(&headers)),
            storage(&self.device, "grid cells", bytemuck::cast_slice(&words)),
            Some(padding),
        );
        if let Some(sized) = &mut self.sized {
            sized.group = None;
        }
        Ok(())
    }

    /// The bind group over the current buffers, made anew when one of them changed.
    fn bind(&mut self) {
        let Some(sized) = &mut self.sized else {
            return;
        };
        if sized.group.is_some() {
            return;
        }
        let [kept, items, boxed] = &sized.scratch;
        let buffers = [
            &self.nodes,
            &self.spheres,
            &self.links,
            &sized.points,
            &self.params,
            &self.state,
            &self.minima_buffer,
            &self.candidates,
            kept,
            items,
            &self.winners,
            boxed,
            &self.grids.0,
            &self.grids.1,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = (0u32..)
            .zip(buffers)
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            })
            .collect();
        sized.group = Some(self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("traverse"),
            layout: &self.layout,
            entries: &entries,
        }));
    }

    /// The query on the GPU; `bounds` must hold the posed links (`Bounds::prepare`).
    /// Returns `Ok(None)` when the exact candidates or the work items overflowed, or an arg-min
    /// was not found again (the caller runs the CPU).
    /// `grids`: the self-filter's grids for the padding of `input`'s options (none when it is
    /// off).
    pub(super) fn query(
        &mut self,
        links: &[QueryLink],
        bounds: &mut Bounds,
        robot_box: &RobotBox,
        input: Input,
        grids: &[SelfGrid],
    ) -> Result<Option<QueryResult>, GpuError> {
        let Input {
            points,
            width,
            options,
            ..
        } = input;
        let n = input.len();
        let l = links.len();
        let started = std::time::Instant::now();
        // The CPU's blocks: runs, or tiles of an organized cloud (width 0: runs).
        let tiling = Tiling::new(n, width);
        let n_blocks = tiling.blocks();
        let (width, height) = tiling.image().unwrap_or((0, 0));
        // A depth image crosses as its bytes (whole words), its points made by the first pass.
        let depth = input
            .depth
            .map(|d| Ok::<_, GpuError>((unproject::params(d)?, d.data())))
            .transpose()?;
        let image_bytes = depth.map_or(0, |(_, data)| data.len().next_multiple_of(4) as u64);
        self.ensure(n, n_blocks, n_blocks * l, image_bytes)?;
        if let Some(padding) = options.self_filter_padding_m {
            self.use_grids(padding, grids)?;
        }
        self.bind();
        let Some(sized) = self.sized.as_ref() else {
            return Err(GpuError::Device("no point buffers".into()));
        };
        let Some(group) = sized.group.as_ref() else {
            return Err(GpuError::Device("no bind group".into()));
        };
        let winners: Vec<u32> = self
            .last_winners
            .iter()
            .copied()
            .filter(|&i| (i as usize) < n)
            .collect();
        let n_sample = (n as u32).div_ceil(SEED_STRIDE);
        let params = QueryParams {
            robot_box: *robot_box,
            n_points: n as u32,
            n_links: l as u32,
            mode: options.mode.code(),
            per_link: options.per_link as u32,
            stride: SEED_STRIDE,
            n_sample,
            n_winners: winners.len() as u32,
            capacity: GPU_CANDIDATES,
            per_link_range: options.per_link_range_m,
            width: width as u32,
            height: height as u32,
            n_blocks: n_blocks as u32,
            item_capacity: sized.items_capacity.min(u32::MAX as usize) as u32,
            ..QueryParams::zeroed()
        };
        let q = &self.queue;
        q.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        q.write_buffer(&self.links, 0, bytemuck::cast_slice(&bounds.posed));
        let state = Counters {
            global: f32::INFINITY.to_bits(),
            global_lower: f32::INFINITY.to_bits(),
            seed_key: [u32::MAX; super::MAX_LINKS],
            seed_point: [u32::MAX; super::MAX_LINKS],
            ..Counters::zeroed()
        };
        q.write_buffer(&self.state, 0, bytemuck::bytes_of(&state));
        match self.minima {
            // The minima, then the seeds' scan.
            Minima::Packed64 => q.write_buffer(
                &self.minima_buffer,
                0,
                bytemuck::cast_slice(&vec![EMPTY; 2 * l]),
            ),
            Minima::Split32 => {
                let mut minima = vec![f32::INFINITY.to_bits(); l];
                minima.extend(std::iter::repeat_n(u32::MAX, l));
                q.write_buffer(&self.minima_buffer, 0, bytemuck::cast_slice(&minima));
            }
        }
        if !winners.is_empty() {
            q.write_buffer(&self.winners, 0, bytemuck::cast_slice(&winners));
        }
        let uploading = std::time::Instant::now();
        let upload = match depth {
            Some((params, data)) => {
                q.write_buffer(&self.unproject.params, 0, bytemuck::bytes_of(&params));
                self.upload(data)?
            }
            None => self.upload(bytemuck::cast_slice(points))?,
        };
        let uploaded = std::time::Instant::now();
        // Validation errors of this query come back as an error (the caller then runs the
        // CPU), not as wgpu's default panic.
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let mut steps = steps(&self.pipelines, n, n_blocks, l, params.n_winners);
        if depth.is_some() && n > 0 {
            let unproject = Step {
                group: Some(&sized.image_group),
                ..Step::direct(
                    "unproject",
                    &self.unproject.pipeline,
                    groups(n.div_ceil(layout::WORKGROUP as usize)),
                )
            };
            steps.insert(0, unproject);
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        if upload > 0 {
            let target = if depth.is_some() {
                &sized.image
            } else {
                &sized.points
            };
            encoder.copy_buffer_to_buffer(&sized.staging, 0, target, 0, upload);
        }
        let last_stamp = encode(
            &mut encoder,
            &steps,
            group,
            &self.dispatch_group,
            &self.dispatch,
            self.timestamps.as_ref().map(|(set, _)| set),
            self.profile,
        );
        let state_size = std::mem::size_of::<Counters>() as u64;
        let minima_size = 8 * l as u64;
        encoder.copy_buffer_to_buffer(&self.state, 0, &self.readback, 0, state_size);
        encoder.copy_buffer_to_buffer(
            &self.minima_buffer,
            0,
            &self.readback,
            state_size,
            minima_size,
        );
        let stamps_at = state_size + minima_size;
        if let Some((set, resolve)) = &self.timestamps {
            encoder.resolve_query_set(set, 0..last_stamp + 1, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &self.readback, stamps_at, STAMP_BYTES);
        }
        if options.mode == Mode::Exact {
            encoder.copy_buffer_to_buffer(
                &self.candidates,
                0,
                &self.readback,
                stamps_at + STAMP_BYTES,
                (std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize) as u64,
            );
        }
        // The small writes (queue.write_buffer) go first in this submission, then the points'
        // copy, then the passes.
        let written = std::time::Instant::now();
        let submission = q.submit([encoder.finish()]);
        for scope in [self.device.pop_error_scope(), self.device.pop_error_scope()] {
            if let Some(e) = pollster::block_on(scope) {
                return Err(GpuError::Device(e.to_string()));
            }
        }
        let submitted = std::time::Instant::now();
        // The staging buffer's map for the next query's points, asked for now: it is done when
        // this submission is (the copy out of it is its first command), in the same poll that
        // maps the readback, so that the next upload finds it mapped instead of waiting on the
        // device once more.
        self.remap_staging();
        self.read_back(submission)?;
        let mapped = std::time::Instant::now();
        let slice = self.readback.slice(..);
        let (state, minima, candidates) = {
            let bytes = slice.get_mapped_range();
            let state: Counters = bytemuck::pod_read_unaligned(&bytes[..state_size as usize]);
            let minima: Vec<u64> = bytemuck::pod_collect_to_vec(
                &bytes[state_size as usize..(state_size + minima_size) as usize],
            );
            let stamps: Vec<u64> = bytemuck::pod_collect_to_vec(
                &bytes[stamps_at as usize..(stamps_at + STAMP_BYTES) as usize],
            );
            let period_s = f64::from(self.queue.get_timestamp_period()) * 1e-9;
            let span = |a: usize, b: usize| stamps[b].saturating_sub(stamps[a]) as f64 * period_s;
            self.last_kernel_s = self
                .timestamps
                .as_ref()
                .map(|_| span(0, last_stamp as usize));
            self.last_passes.clear();
            if self.profile && self.timestamps.is_some() {
                for (k, step) in steps.iter().enumerate() {
                    self.last_passes.push((step.name, span(2 * k, 2 * k + 1)));
                }
            }
            let count = (state.candidate_count.min(GPU_CANDIDATES)) as usize;
            let start = (stamps_at + STAMP_BYTES) as usize;
            let candidates: Vec<Candidate> = if options.mode == Mode::Exact {
                let end = start + std::mem::size_of::<Candidate>() * count;
                bytemuck::pod_collect_to_vec(&bytes[start..end])
            } else {
                Vec::new()
            };
            (state, minima, candidates)
        };
        self.readback.unmap();
        if state.candidate_count > GPU_CANDIDATES {
            return Ok(None);
        }
        if state.item_count > params.item_capacity {
            log::debug!(
                "GPU: {} work items, room for {}",
                state.item_count,
                params.item_capacity
            );
            return Ok(None);
        }
        // Each link's minimum, packed as the CPU packs it.
        let packed: Vec<u64> = match self.minima {
            Minima::Packed64 => minima,
            Minima::Split32 => match split_minima(&minima, &state, bounds, options) {
                Some(packed) => packed,
                None => return Ok(None),
            },
        };
        // Into the CPU's layout, and on through the CPU's refinement and assembly.
        for ((best, &v), winner) in bounds.best.iter().zip(&packed).zip(&mut self.last_winners) {
            best.store(v, Ordering::Relaxed);
            *winner = if v == EMPTY { u32::MAX } else { v as u32 };
        }
        bounds.global.store(state.global, Ordering::Relaxed);
        bounds
            .global_lower
            .store(state.global_lower, Ordering::Relaxed);
        bounds.candidates_mut().extend_from_slice(&candidates);
        for (n, &s) in bounds.self_filtered.iter().zip(&state.self_filtered) {
            n.store(u64::from(s), Ordering::Relaxed);
        }
        for (n, &w) in bounds.work.iter().zip(&state.work) {
            n.store(u64::from(w), Ordering::Relaxed);
        }
        let c = |stage: Stage| u64::from(state.counts[stage as usize]);
        let counts = StageCounts {
            total: n as u64,
            invalid: c(Stage::Invalid),
            outside_roi: c(Stage::OutsideRoi),
            self_filtered: c(Stage::SelfFiltered),
            pruned: c(Stage::Pruned),
            evaluated: c(Stage::Evaluated),
            inside: c(Stage::Inside),
            exact_refined: 0,
        };
        let result = result::finish(links, bounds, input, counts, Backend::Gpu);
        self.last_host_s = [
            (uploading - started).as_secs_f64(),
            (uploaded - uploading).as_secs_f64(),
            (written - uploaded).as_secs_f64(),
            (submitted - written).as_secs_f64(),
            (mapped - submitted).as_secs_f64(),
            mapped.elapsed().as_secs_f64(),
        ];
        Ok(Some(result))
    }
}

/// The portable path's minima (`[0, l)` f32 bits, `[l, 2 l)` their points, read back as `l`
/// words of 8 bytes) packed as the CPU packs them; `None` when a minimum within its link's
/// final threshold has no point (the CPU answers).
fn split_minima(
    minima: &[u64],
    state: &Counters,
    bounds: &Bounds,
    options: &super::QueryOptions,
) -> Option<Vec<u64>> {
    let l = minima.len();
    let words: &[u32] = bytemuck::cast_slice(minima);
    let (global, global_lower) = (
        f32::from_bits(state.global),
        f32::from_bits(state.global_lower),
    );
    let mut packed = Vec::with_capacity(l);
    for k in 0..l {
        let (d, p) = (words[k], words[l + k]);
        if d == f32::INFINITY.to_bits() {
            packed.push(EMPTY);
        } else if p != u32::MAX {
            packed.push(pack_minimum(f32::from_bits(d), p));
        } else {
            // No point attains the minimum bit for bit: a seed's upper bound that
            // no exact descent went below, which is only so for a link farther
            // than its final threshold (reported as farther than it, as the CPU
            // reports a link it never measured). Within its threshold, the two
            // descents rounded differently: the CPU answers.
            let t = threshold(
                options.mode,
                options.per_link,
                options.per_link_range_m,
                global,
                global_lower,
                f32::from_bits(d),
                bounds.posed[k].gap,
            );
            if f32::from_bits(d) <= t {
                return None;
            }
            packed.push(EMPTY);
        }
    }
    Some(packed)
}
