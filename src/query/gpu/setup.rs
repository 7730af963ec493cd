//! Making the GPU engine, once per robot: the device (with 64-bit atomics and subgroup
//! operations where the adapter has them and the options allow), the shader module (compiled without runtime bounds checks once
//! every tree's child indices are checked), the bind group layouts and one pipeline per entry
//! point, and the trees uploaded as they are.

use std::borrow::Cow;

use wgpu::util::DeviceExt;

use super::passes::{MAX_STEPS, STAMP_BYTES};
use super::{GpuEngine, GpuError, GpuOptions, Pipelines};
use crate::ist::IstNode;
use crate::packing::InnerSphere;
use crate::query::descent;
use crate::query::layout::{
    self, Candidate, Counters, Minima, QueryParams, Reduce, FRONTIER, GPU_CANDIDATES, GPU_STACK,
};
use crate::query::QueryLink;

pub(super) fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
    })
}

/// A compute shader's buffer binding `binding` of type `ty`.
pub(super) fn layout_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

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

impl GpuEngine {
    /// Creates the device (the adapter `WGPU_ADAPTER_NAME` names, else the default one) and
    /// uploads the trees of `links`.
    pub fn new(links: &[QueryLink], options: GpuOptions) -> Result<Self, GpuError> {
        for link in links {
            check_tree(link)?;
            if descent::tree_depth(&link.nodes) > layout::max_tree_depth(GPU_STACK, FRONTIER) {
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
        // SAFETY: the shader indexes its arrays only with indices in range — the trees' child
        // indices and counts (checked above, `check_tree`; children after their parent, so
        // every descent ends), the stack
        // (bounded by GPU_STACK at each push, and swapped only below its size), the points
        // (below `n_points`, the buffer's size), the kept blocks (below the block count, the
        // buffer's capacity), the items and candidates (below their capacities, checked at each
        // append), the links (below `n_links`), the packets' workgroup arrays (by lane / SUB) —
        // and every loop ends: descents pop what they push, and the passes stride over bounded
        // counts.
        let module = unsafe {
            device.create_shader_module_trusted(
                wgpu::ShaderModuleDescriptor {
                    label: Some("traverse.wgsl"),
                    source: wgpu::ShaderSource::Wgsl(Cow::Owned(layout::shader_source(
                        minima, reduce,
                    ))),
                },
                wgpu::ShaderRuntimeChecks::unchecked(),
            )
        };
        let entry = layout_entry;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        let kinds = [
            read, read, read, read, uniform, write, write, write, write, write, read, write, read,
            read,
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
        let pipeline_layout = |groups: &[&wgpu::BindGroupLayout]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: None,
                bind_group_layouts: groups,
                push_constant_ranges: &[],
            })
        };
        let common = pipeline_layout(&[&layout]);
        let with_dispatch = pipeline_layout(&[&layout, &dispatch_layout]);
        // The shader's overridable constants: whether the measure pass descends packets.
        let constants = [("DESCEND_PACKETS", if options.packets { 1.0 } else { 0.0 })];
        let pipeline_with = |name: &str, layout: &wgpu::PipelineLayout, constants: &[_]| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: Some(layout),
                module: &module,
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
        let pipelines = Pipelines {
            seed_scan: pipeline("seed_scan", &common),
            seed_pick: (minima == Minima::Split32).then(|| pipeline("seed_pick", &common)),
            seed: pipeline("seed", &common),
            cull: pipeline("cull", &common),
            blocks: pipeline("blocks", &common),
            plan: pipeline("plan", &with_dispatch),
            measure: pipeline_with("measure", &common, &constants),
            tally: pipeline("tally", &common),
            argmin: (minima == Minima::Split32).then(|| pipeline("argmin", &common)),
        };
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
        let timestamps = features.contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
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
        });
        // No grid yet: one empty header per link (every point outside it), until a query with
        // the self-filter on brings the grids.
        let grids = (
            storage(&device, "grid headers", &vec![0u8; 32 * n]),
            storage(&device, "grid cells", &[0u8; 4]),
            None,
        );
        let dispatch = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dispatch"),
            size: 24,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
            mapped_at_creation: false,
        });
        let dispatch_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dispatch"),
            layout: &dispatch_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: dispatch.as_entire_binding(),
            }],
        });
        Ok(Self {
            timestamps,
            last_kernel_s: None,
            profile: false,
            last_passes: Vec::new(),
            last_host_s: [0.0; super::HOST_STEPS.len()],
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
            adapter: adapter.get_info(),
            minima,
            reduce,
            packets: options.packets,
            layout,
            pipelines,
            unproject: super::unproject::Unproject::new(&device),
            device,
            queue,
            sized: None,
            max_binding,
            last_winners: vec![u32::MAX; n],
            grids,
        })
    }
}
