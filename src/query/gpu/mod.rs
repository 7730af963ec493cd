//! GPU backend of the query (wgpu, `shaders/traverse.wgsl`): the seed's parallel traversal, one
//! invocation per cloud point, with the shared bounds in storage atomics.
//!
//! - **Once per robot**: the device is created and every link's `IstNode` and `InnerSphere`
//!   arrays are uploaded as they are, concatenated in link order (the CPU walks the same
//!   arrays; each posed link carries its offsets into them).
//! - **Per query**: the links are posed by the code the CPU uses (`Bounds::prepare`: f64,
//!   rounded once) and the posed links (`layout::PosedLink`, 80 B each) are written as they
//!   are, with three `layout::QueryParams` uniforms and the points. Three dispatches follow in
//!   one submission: seed (every `SEED_STRIDE`-th point), main (every point), arg-min (ties
//!   resolved to the smallest index). A few words come back: `layout::Counters`, the minima and
//!   the exact-mode candidates (`layout::Candidate`).
//! - **Then** the shared `result::finish` refines the exact candidates and assembles the result,
//!   so both backends report through one code path.
//!
//! The shader source is `layout::shader_source()`: the constants generated from the layout,
//! then the file. What the shader does and does not do like the CPU is in its header.
//!
//! Agreement with the CPU: the same posed links, trees, thresholds and recording rules; only
//! the rounding of `length` may differ (a few ulps, far below 1 µm at robot scale).

use std::borrow::Cow;

use bytemuck::Zeroable;
use wgpu::util::DeviceExt;

use super::bounds::{pack_minimum, Bounds, EMPTY};
use super::layout::{
    self, Candidate, Counters, PassKind, QueryParams, RobotBox, Stage, GPU_CANDIDATES, GPU_STACK,
    SEED_STRIDE, WORKGROUP,
};
use super::{descent, result, Backend, Input, Mode, QueryLink, QueryResult, StageCounts};
use crate::ist::IstNode;
use crate::packing::InnerSphere;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("GPU device: {0}")]
    Device(String),
    #[error("link {link}: tree depth needs more than the shader's stack of {GPU_STACK}")]
    TooDeep { link: String },
    #[error("{points} points exceed one dispatch ({max})")]
    TooManyPoints { points: usize, max: usize },
    #[error("{0} bytes exceed the device's storage buffer limit")]
    TooLarge(u64),
    #[error("reading back: {0}")]
    Readback(String),
}

/// The buffers that grow with the cloud.
struct PointBuffers {
    points: wgpu::Buffer,
    capacity_points: usize,
    bind_groups: [wgpu::BindGroup; 3],
}

/// A device with a robot's trees uploaded.
pub struct GpuEngine {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The adapter, as wgpu describes it.
    pub adapter: wgpu::AdapterInfo,
    nodes: wgpu::Buffer,
    spheres: wgpu::Buffer,
    links: wgpu::Buffer,
    params: [wgpu::Buffer; 3],
    state: wgpu::Buffer,
    minima: wgpu::Buffer,
    candidates: wgpu::Buffer,
    readback: wgpu::Buffer,
    point_buffers: Option<PointBuffers>,
    max_binding: u64,
    /// Timestamps around the three dispatches, where the adapter has them.
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    /// GPU time of the last query's three dispatches, s (with timestamp queries).
    pub last_kernel_s: Option<f64>,
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}

impl GpuEngine {
    /// Creates the device (the adapter `WGPU_ADAPTER_NAME` names, else the default one) and
    /// uploads the trees of `links`.
    pub fn new(links: &[QueryLink]) -> Result<Self, GpuError> {
        for link in links {
            if descent::tree_depth(&link.nodes) > layout::max_tree_depth(GPU_STACK, 1) {
                return Err(GpuError::TooDeep {
                    link: link.name.clone(),
                });
            }
        }
        // Vulkan, Metal or DX12 unless WGPU_BACKEND says otherwise: compute needs no GL, and
        // probing it prints EGL noise on headless machines.
        let mut descriptor = wgpu::InstanceDescriptor::from_env_or_default();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            descriptor.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(&descriptor);
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        ))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let limits = adapter.limits();
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("ist_monitor"),
            required_features: features,
            required_limits: limits.clone(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        device.on_uncaptured_error(Box::new(|e| log::error!("GPU: {e}")));
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("traverse.wgsl"),
            source: wgpu::ShaderSource::Wgsl(Cow::Owned(layout::shader_source())),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("traverse"),
            layout: None,
            module: &module,
            entry_point: Some("traverse"),
            compilation_options: Default::default(),
            cache: None,
        });
        // In link order: the offsets `Bounds::new` gives the posed links.
        let nodes: Vec<IstNode> = links.iter().flat_map(|l| l.nodes.iter().copied()).collect();
        let spheres: Vec<InnerSphere> = links
            .iter()
            .flat_map(|l| l.spheres.iter().copied())
            .collect();
        let max_binding = u64::from(limits.max_storage_buffer_binding_size);
        let bytes = std::mem::size_of_val(nodes.as_slice())
            .max(std::mem::size_of_val(spheres.as_slice())) as u64;
        if bytes > max_binding {
            return Err(GpuError::TooLarge(bytes));
        }
        let uniform = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: std::mem::size_of::<QueryParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let n = links.len();
        let readback_size = (std::mem::size_of::<Counters>()
            + 8 * n
            + 16
            + std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize)
            as u64;
        let timestamps = features.contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            (
                device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("kernel time"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                }),
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamps"),
                    size: 16,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
            )
        });
        Ok(Self {
            timestamps,
            last_kernel_s: None,
            nodes: storage(&device, "nodes", bytemuck::cast_slice(&nodes)),
            spheres: storage(&device, "spheres", bytemuck::cast_slice(&spheres)),
            links: storage(
                &device,
                "links",
                &vec![0u8; std::mem::size_of::<layout::PosedLink>() * n],
            ),
            params: [uniform("seed"), uniform("main"), uniform("argmin")],
            state: storage(&device, "state", &[0u8; std::mem::size_of::<Counters>()]),
            minima: storage(&device, "minima", &vec![0u8; 8 * n]),
            candidates: storage(
                &device,
                "candidates",
                &vec![0u8; std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize],
            ),
            readback: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: readback_size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            adapter: adapter.get_info(),
            device,
            queue,
            pipeline,
            point_buffers: None,
            max_binding,
        })
    }

    /// Whether the adapter is a software rasterizer (lavapipe, WARP, SwiftShader): correct, but
    /// never faster than the CPU backend.
    pub fn is_software(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    fn ensure_points(&mut self, n: usize) -> Result<(), GpuError> {
        if self
            .point_buffers
            .as_ref()
            .is_some_and(|s| s.capacity_points >= n)
        {
            return Ok(());
        }
        let capacity = n.next_power_of_two().max(1024);
        let bytes = (capacity * 12) as u64;
        if bytes > self.max_binding {
            return Err(GpuError::TooLarge(bytes));
        }
        let points = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("points"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = self.pipeline.get_bind_group_layout(0);
        let group = |params: &wgpu::Buffer| {
            let buffers = [
                &self.nodes,
                &self.spheres,
                &self.links,
                &points,
                params,
                &self.state,
                &self.minima,
                &self.candidates,
            ];
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("traverse"),
                layout: &layout,
                entries: &entries,
            })
        };
        let bind_groups = [
            group(&self.params[0]),
            group(&self.params[1]),
            group(&self.params[2]),
        ];
        self.point_buffers = Some(PointBuffers {
            points,
            capacity_points: capacity,
            bind_groups,
        });
        Ok(())
    }

    /// The query on the GPU; `bounds` must hold the posed links (`Bounds::prepare`).
    /// Returns `Ok(None)` when the exact candidates overflowed, or an arg-min was not found again
    /// (the caller runs the CPU).
    pub(super) fn query(
        &mut self,
        links: &[QueryLink],
        bounds: &mut Bounds,
        robot_box: &RobotBox,
        input: Input,
    ) -> Result<Option<QueryResult>, GpuError> {
        let Input {
            points, options, ..
        } = input;
        let n = points.len();
        let max = 65_535 * WORKGROUP as usize;
        if n > max {
            return Err(GpuError::TooManyPoints { points: n, max });
        }
        self.ensure_points(n)?;
        let l = links.len();
        let base = QueryParams {
            robot_box: *robot_box,
            n_points: n as u32,
            n_links: l as u32,
            mode: options.mode.code(),
            per_link: options.per_link as u32,
            stride: 1,
            offset: 0,
            n_work: n as u32,
            pass_kind: PassKind::Main as u32,
            capacity: GPU_CANDIDATES,
            per_link_range: options.per_link_range_m,
            ..QueryParams::zeroed()
        };
        let seed = QueryParams {
            stride: SEED_STRIDE,
            n_work: (n as u32).div_ceil(SEED_STRIDE),
            pass_kind: PassKind::Seed as u32,
            ..base
        };
        let argmin = QueryParams {
            pass_kind: PassKind::ArgMin as u32,
            ..base
        };
        let q = &self.queue;
        q.write_buffer(&self.links, 0, bytemuck::cast_slice(&bounds.posed));
        for (buffer, params) in self.params.iter().zip([seed, base, argmin]) {
            q.write_buffer(buffer, 0, bytemuck::bytes_of(&params));
        }
        let state = Counters {
            global: f32::INFINITY.to_bits(),
            global_lower: f32::INFINITY.to_bits(),
            ..Counters::zeroed()
        };
        q.write_buffer(&self.state, 0, bytemuck::bytes_of(&state));
        let mut minima = vec![f32::INFINITY.to_bits(); l];
        minima.extend(std::iter::repeat_n(u32::MAX, l));
        q.write_buffer(&self.minima, 0, bytemuck::cast_slice(&minima));
        let Some(sized) = self.point_buffers.as_ref() else {
            return Err(GpuError::Device("no point buffers".into()));
        };
        if n > 0 {
            q.write_buffer(&sized.points, 0, bytemuck::cast_slice(points));
        }
        // Validation errors of this query come back as an error (the caller then runs the
        // CPU), not as wgpu's default panic.
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        for (k, params) in [seed, base, argmin].iter().enumerate() {
            let timestamp_writes = self.timestamps.as_ref().filter(|_| k != 1).map(|(set, _)| {
                wgpu::ComputePassTimestampWrites {
                    query_set: set,
                    beginning_of_pass_write_index: (k == 0).then_some(0),
                    end_of_pass_write_index: (k == 2).then_some(1),
                }
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("traverse"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &sized.bind_groups[k], &[]);
            pass.dispatch_workgroups(params.n_work.div_ceil(WORKGROUP).max(1), 1, 1);
        }
        let state_size = std::mem::size_of::<Counters>() as u64;
        let minima_size = 8 * l as u64;
        encoder.copy_buffer_to_buffer(&self.state, 0, &self.readback, 0, state_size);
        encoder.copy_buffer_to_buffer(&self.minima, 0, &self.readback, state_size, minima_size);
        let stamps_at = state_size + minima_size;
        if let Some((set, resolve)) = &self.timestamps {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &self.readback, stamps_at, 16);
        }
        if options.mode == Mode::Exact {
            encoder.copy_buffer_to_buffer(
                &self.candidates,
                0,
                &self.readback,
                stamps_at + 16,
                (std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize) as u64,
            );
        }
        q.submit([encoder.finish()]);
        for scope in [self.device.pop_error_scope(), self.device.pop_error_scope()] {
            if let Some(e) = pollster::block_on(scope) {
                return Err(GpuError::Device(e.to_string()));
            }
        }
        let slice = self.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.device
            .poll(wgpu::PollType::Wait)
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let (state, minima, candidates) = {
            let bytes = slice.get_mapped_range();
            let state: Counters = bytemuck::pod_read_unaligned(&bytes[..state_size as usize]);
            let minima: Vec<u32> = bytemuck::pod_collect_to_vec(
                &bytes[state_size as usize..(state_size + minima_size) as usize],
            );
            let stamps: [u64; 2] =
                bytemuck::pod_read_unaligned(&bytes[stamps_at as usize..stamps_at as usize + 16]);
            self.last_kernel_s = self.timestamps.as_ref().map(|_| {
                stamps[1].saturating_sub(stamps[0]) as f64
                    * f64::from(self.queue.get_timestamp_period())
                    * 1e-9
            });
            let count = (state.candidate_count.min(GPU_CANDIDATES)) as usize;
            let start = (stamps_at + 16) as usize;
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
        // A minimum whose point the arg-min pass did not find again bit for bit (a compiler
        // that rounds the two descents differently) is not trusted: the CPU answers.
        if (0..l).any(|k| minima[k] != f32::INFINITY.to_bits() && minima[l + k] == u32::MAX) {
            return Ok(None);
        }
        // Into the CPU's layout, and on through the CPU's refinement and assembly.
        for (k, best) in bounds.best.iter().enumerate() {
            let (d, p) = (minima[k], minima[l + k]);
            let v = if d == f32::INFINITY.to_bits() || p == u32::MAX {
                EMPTY
            } else {
                pack_minimum(f32::from_bits(d), p)
            };
            best.store(v, std::sync::atomic::Ordering::Relaxed);
        }
        bounds
            .global
            .store(state.global, std::sync::atomic::Ordering::Relaxed);
        bounds
            .global_lower
            .store(state.global_lower, std::sync::atomic::Ordering::Relaxed);
        bounds.candidates_mut().extend_from_slice(&candidates);
        for (n, &s) in bounds.self_filtered.iter().zip(&state.self_filtered) {
            n.store(u64::from(s), std::sync::atomic::Ordering::Relaxed);
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
        Ok(Some(result::finish(
            links,
            bounds,
            input,
            counts,
            Backend::Gpu,
        )))
    }
}
