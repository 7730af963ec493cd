//! Making the GPU engine, once per robot: the device (with 64-bit atomics and subgroup
//! operations where the adapter has them and the options allow), the shader module (compiled
//! without runtime bounds checks once every tree's child indices are checked), the bind group
//! layouts and one pipeline per entry point, and the trees uploaded as they are.

use std::borrow::Cow;

use super::bindings::{layout_entry, storage};
use super::cell::CellPass;
use super::engine::{GpuEngine, Pipelines, HOST_STEPS};
use super::error::GpuError;
use super::options::GpuOptions;
use super::passes::{MAX_STEPS, STAMP_BYTES};
use super::unproject::Unproject;
use crate::ist::IstNode;
use crate::packing::InnerSphere;
use crate::query::descent;
use crate::query::layout::{
    self, Candidate, Counters, Minima, QueryParams, Reduce, FRONTIER, GPU_CANDIDATES, GPU_STACK,
};
use crate::query::link::QueryLink;

/// Checks that every child index of `link`'s tree lies inside its arrays, after its parent, and
/// that no node has more than BRANCHING children (the packets' votes and keys hold that many):
/// the shader reads them without bounds checks (`descent::bad_node`).
fn check_tree(link: &QueryLink) -> Result<(), GpuError> {
    match descent::bad_node(&link.nodes, link.spheres.len()) {
        Some(node) => Err(GpuError::BadTree {
            link: link.name.clone(),
            node,
        }),
        None => Ok(()),
    }
}

/// Every link's tree: walkable without bounds checks ([`check_tree`]) and within the shader's
/// stack.
fn check_trees(links: &[QueryLink]) -> Result<(), GpuError> {
    for link in links {
        check_tree(link)?;
        if descent::tree_depth(&link.nodes) > layout::max_tree_depth(GPU_STACK, FRONTIER) {
            return Err(GpuError::TooDeep {
                link: link.name.clone(),
            });
        }
    }
    Ok(())
}

/// A device opened on the adapter, with the paths its features allow.
struct Opened {
    adapter: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    features: wgpu::Features,
    minima: Minima,
    reduce: Reduce,
    device: wgpu::Device,
    queue: wgpu::Queue,
}

/// Opens the device on the adapter `WGPU_ADAPTER_NAME` names, else the default one, asking for
/// 64-bit atomics and subgroup operations where the adapter has them and `options` allow, and
/// for timestamps where it has them.
fn open(options: GpuOptions) -> Result<Opened, GpuError> {
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
    let int64 = wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
    let minima = if options.int64_atomics && adapter.features().contains(int64) {
        Minima::Packed64
    } else {
        Minima::Split32
    };
    let reduce = if options.subgroups && adapter.features().contains(wgpu::Features::SUBGROUP) {
        Reduce::Subgroups
    } else {
        Reduce::Shared
    };
    let mut features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
    if minima == Minima::Packed64 {
        features |= int64;
    }
    if reduce == Reduce::Subgroups {
        features |= wgpu::Features::SUBGROUP;
    }
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("ist_monitor"),
        required_features: features,
        required_limits: limits.clone(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    }))
    .map_err(|e| GpuError::Device(e.to_string()))?;
    device.on_uncaptured_error(Box::new(|e| log::error!("GPU: {e}")));
    Ok(Opened {
        adapter: adapter.get_info(),
        limits,
        features,
        minima,
        reduce,
        device,
        queue,
    })
}

/// The traversal's shader module, for the way `minima` are kept and workgroups `reduce`.
fn shader_module(device: &wgpu::Device, minima: Minima, reduce: Reduce) -> wgpu::ShaderModule {
    // SAFETY: the shader indexes its arrays only with indices in range — the trees' child
    // indices and counts (checked before the engine is made, `check_tree`; children after their
    // parent, so every descent ends), the stack
    // (bounded by GPU_STACK at each push, and swapped only below its size), the points
    // (below `n_points`, the buffer's size), the kept blocks (below the block count, the
    // buffer's capacity), the items and candidates (below their capacities, checked at each
    // append), the links (below `n_links`), the packets' workgroup arrays (by lane / SUB) —
    // and every loop ends: descents pop what they push, and the passes stride over bounded
    // counts.
    unsafe {
        device.create_shader_module_trusted(
            wgpu::ShaderModuleDescriptor {
                label: Some("traverse.wgsl"),
                source: wgpu::ShaderSource::Wgsl(Cow::Owned(layout::shader_source(minima, reduce))),
            },
            wgpu::ShaderRuntimeChecks::unchecked(),
        )
    }
}

/// The bind group layouts: the traversal's buffers in their binding order (the shader's), and
/// the dispatch buffer that `plan` writes.
fn bind_group_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let entry = layout_entry;
    let read = wgpu::BufferBindingType::Storage { read_only: true };
    let write = wgpu::BufferBindingType::Storage { read_only: false };
    let uniform = wgpu::BufferBindingType::Uniform;
    let kinds = [
        read, read, read, read, uniform, write, write, write, write, write, read, write, read, read,
    ];
    let entries: Vec<_> = (0u32..).zip(kinds).map(|(b, t)| entry(b, t)).collect();
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("traverse"),
        entries: &entries,
    });
    let dispatch_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("dispatch"),
        entries: &[entry(0, write)],
    });
    (layout, dispatch_layout)
}

/// One pipeline per entry point of `module` (`seed_pick` and `argmin` only without 64-bit
/// atomics), `plan` with the dispatch buffer's group; `packets` sets the measure pass's
/// `DESCEND_PACKETS`.
fn pipelines(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    (layout, dispatch_layout): (&wgpu::BindGroupLayout, &wgpu::BindGroupLayout),
    minima: Minima,
    packets: bool,
) -> Pipelines {
    let pipeline_layout = |groups: &[&wgpu::BindGroupLayout]| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: groups,
            push_constant_ranges: &[],
        })
    };
    let common = pipeline_layout(&[layout]);
    let with_dispatch = pipeline_layout(&[layout, dispatch_layout]);
    // The shader's overridable constants: whether the measure pass descends packets.
    let constants = [("DESCEND_PACKETS", if packets { 1.0 } else { 0.0 })];
    let pipeline_with = |name: &str, layout: &wgpu::PipelineLayout, constants: &[_]| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(layout),
            module,
            entry_point: Some(name),
            // Every workgroup variable is written before it is read.
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        })
    };
    let pipeline = |name: &str, layout: &wgpu::PipelineLayout| pipeline_with(name, layout, &[]);
    Pipelines {
        seed_scan: pipeline("seed_scan", &common),
        seed_pick: (minima == Minima::Split32).then(|| pipeline("seed_pick", &common)),
        seed: pipeline("seed", &common),
        cull: pipeline("cull", &common),
        blocks: pipeline("blocks", &common),
        plan: pipeline("plan", &with_dispatch),
        measure: pipeline_with("measure", &common, &constants),
        tally: pipeline("tally", &common),
        argmin: (minima == Minima::Split32).then(|| pipeline("argmin", &common)),
    }
}

/// The query set and resolve buffer of the passes' timestamps, where the device has them.
fn timestamps(
    device: &wgpu::Device,
    features: wgpu::Features,
) -> Option<(wgpu::QuerySet, wgpu::Buffer)> {
    features.contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
        (
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * MAX_STEPS as u32,
            }),
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: STAMP_BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
        )
    })
}

/// The indirect dispatch arguments `plan` writes, and the group that binds them.
fn dispatch(
    device: &wgpu::Device,
    dispatch_layout: &wgpu::BindGroupLayout,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let dispatch = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("dispatch"),
        size: 24,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("dispatch"),
        layout: dispatch_layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: dispatch.as_entire_binding(),
        }],
    });
    (dispatch, group)
}

impl GpuEngine {
    /// Creates the device (the adapter `WGPU_ADAPTER_NAME` names, else the default one) and
    /// uploads the trees of `links`.
    pub fn new(links: &[QueryLink], options: GpuOptions) -> Result<Self, GpuError> {
        check_trees(links)?;
        let Opened {
            adapter,
            limits,
            features,
            minima,
            reduce,
            device,
            queue,
        } = open(options)?;
        let module = shader_module(&device, minima, reduce);
        let (layout, dispatch_layout) = bind_group_layouts(&device);
        let pipelines = pipelines(
            &device,
            &module,
            (&layout, &dispatch_layout),
            minima,
            options.packets,
        );
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
        let n = links.len();
        let readback_size = std::mem::size_of::<Counters>() as u64
            + 8 * n as u64
            + STAMP_BYTES
            + (std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize) as u64;
        let timestamps = timestamps(&device, features);
        // No grid yet: one empty header per link (every point outside it), until a query with
        // the self-filter on brings the grids.
        let grids = (
            storage(&device, "grid headers", &vec![0u8; 32 * n]),
            storage(&device, "grid cells", &[0u8; 4]),
            None,
        );
        let (dispatch, dispatch_group) = dispatch(&device, &dispatch_layout);
        Ok(Self {
            timestamps,
            last_kernel_s: None,
            profile: false,
            last_passes: Vec::new(),
            last_host_s: [0.0; HOST_STEPS.len()],
            nodes: storage(&device, "nodes", bytemuck::cast_slice(&nodes)),
            spheres: storage(&device, "spheres", bytemuck::cast_slice(&spheres)),
            links: storage(
                &device,
                "links",
                &vec![0u8; std::mem::size_of::<layout::PosedLink>() * n],
            ),
            params: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("params"),
                size: std::mem::size_of::<QueryParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            state: storage(&device, "state", &[0u8; std::mem::size_of::<Counters>()]),
            minima_buffer: storage(&device, "minima", &vec![0u8; 16 * n]),
            candidates: storage(
                &device,
                "candidates",
                &vec![0u8; std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize],
            ),
            winners: storage(&device, "winners", &vec![0u8; 4 * n]),
            dispatch,
            dispatch_group,
            readback: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: readback_size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            adapter,
            minima,
            reduce,
            packets: options.packets,
            layout,
            pipelines,
            unproject: Unproject::new(&device),
            cells: CellPass::new(&device),
            device,
            queue,
            sized: None,
            max_binding,
            last_winners: vec![u32::MAX; n],
            grids,
        })
    }
}
