//! The GPU engine's state, made once per robot (`setup.rs`): the device and its queue, the
//! pipelines, the trees' buffers, the buffers that grow with the cloud (`buffers.rs`), the
//! readback and the timings of the last query's passes and host steps ([`HOST_STEPS`]).

use std::sync::atomic::AtomicU8;
use std::sync::Arc;

use super::cell::CellPass;
use super::unproject::Unproject;
use crate::query::layout::{Minima, Reduce};

/// A device with a robot's trees uploaded.
pub struct GpuEngine {
    pub(super) device: wgpu::Device,
    pub(super) queue: wgpu::Queue,
    pub(super) pipelines: Pipelines,
    pub(super) unproject: Unproject,
    /// The unseen space's cells, judged after `unproject` when a request is pending.
    pub(super) cells: CellPass,
    /// The adapter, as wgpu describes it.
    pub adapter: wgpu::AdapterInfo,
    /// How the minima are kept on this adapter.
    pub minima: Minima,
    /// How a workgroup reduces on this adapter.
    pub reduce: Reduce,
    /// Whether the measure pass descends packets (`GpuOptions::packets`).
    pub packets: bool,
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) nodes: wgpu::Buffer,
    pub(super) spheres: wgpu::Buffer,
    pub(super) links: wgpu::Buffer,
    pub(super) params: wgpu::Buffer,
    pub(super) state: wgpu::Buffer,
    pub(super) minima_buffer: wgpu::Buffer,
    pub(super) candidates: wgpu::Buffer,
    pub(super) winners: wgpu::Buffer,
    pub(super) dispatch: wgpu::Buffer,
    pub(super) dispatch_group: wgpu::BindGroup,
    pub(super) readback: wgpu::Buffer,
    pub(super) sized: Option<Sized>,
    pub(super) max_binding: u64,
    /// Timestamps around the query's passes, where the adapter has them.
    pub(super) timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    /// GPU time of the last query's passes, s (with timestamp queries).
    pub last_kernel_s: Option<f64>,
    /// Each dispatch in a pass of its own with its own timestamps ([`GpuEngine::set_profile`]).
    pub(super) profile: bool,
    /// With `profile`: the last query's dispatches and their GPU time, s.
    pub last_passes: Vec<(&'static str, f64)>,
    /// The last query's host side, s, one after the other: the small inputs (sizes, poses,
    /// counters), the points' (or the image's) copy into the staging memory, encoding the
    /// passes, the submission (and its error scopes), waiting for the readback to be mapped,
    /// and reading it back into the result ([`HOST_STEPS`] names them).
    pub last_host_s: [f64; HOST_STEPS.len()],
    /// Each link's arg-min point of the last query (`u32::MAX`: none): the next one's seeds.
    pub(super) last_winners: Vec<u32>,
    /// The self-filter's grids (headers, packed cells) and the padding they were built for.
    pub(super) grids: (wgpu::Buffer, wgpu::Buffer, Option<f32>),
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
}

/// The buffers that grow with the cloud, and the bind group over them.
pub(super) struct Sized {
    pub(super) points: wgpu::Buffer,
    /// The points' (or the depth image's) staging memory, mapped for writing between queries,
    /// and its state (`UNMAPPED`, `MAPPING`, `MAPPED`).
    pub(super) staging: wgpu::Buffer,
    pub(super) staging_state: Arc<AtomicU8>,
    /// The kept blocks, the work items and the boxed blocks, which only the shader reads and
    /// writes.
    pub(super) scratch: [wgpu::Buffer; 3],
    /// A depth image's bytes, for the unprojection, and the group that binds it with the
    /// points.
    pub(super) image: wgpu::Buffer,
    pub(super) image_group: wgpu::BindGroup,
    pub(super) points_capacity: usize,
    pub(super) blocks_capacity: usize,
    pub(super) items_capacity: usize,
    /// Bytes of the image buffer (and at least of the staging buffer).
    pub(super) image_capacity: u64,
    /// Over every buffer; `None` once one of them changed.
    pub(super) group: Option<wgpu::BindGroup>,
}

/// The compute pipelines, one per entry point.
pub(super) struct Pipelines {
    pub(super) seed_scan: wgpu::ComputePipeline,
    /// Only without 64-bit atomics.
    pub(super) seed_pick: Option<wgpu::ComputePipeline>,
    pub(super) seed: wgpu::ComputePipeline,
    pub(super) cull: wgpu::ComputePipeline,
    pub(super) blocks: wgpu::ComputePipeline,
    pub(super) plan: wgpu::ComputePipeline,
    pub(super) measure: wgpu::ComputePipeline,
    pub(super) tally: wgpu::ComputePipeline,
    /// Only without 64-bit atomics.
    pub(super) argmin: Option<wgpu::ComputePipeline>,
}
