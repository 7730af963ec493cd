//! The unseen space's cells judged on the GPU (`shaders/cell.wgsl`, issue 55), in the depth
//! query's submission: the image uploaded once serves both, as the query's `unproject` pass has
//! written its points into the point buffer that this pass reads (z per pixel). The caller asks
//! for it with `GpuEngine::request_cells` (a [`CellParams`]: the view's camera, the lattice
//! placed in its frame, the balls' radii) before a depth query; the pass is encoded after
//! `unproject` (`run.rs`), its verdicts (one word per cell: bit 0 the base ball ruled out, bit
//! `1 + k` sub-ball `k`) copied into a readback of their own and read after the query's, for
//! `GpuEngine::take_cells`. A query that does not run on the GPU leaves none: the CPU then
//! judges the cells (`unseen::cell`), by the same rule.

use super::bindings::one_pass;
use super::error::GpuError;
use crate::query::layout::{self, CellParams};

/// The cells' pipeline, its bind group layout, its uniform and its buffers.
pub(super) struct CellPass {
    pub(super) pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    /// The verdicts and their readback, and how many cells they hold.
    buffers: Option<(wgpu::Buffer, wgpu::Buffer, u64)>,
    /// The request of the next depth query.
    pub(super) request: Option<CellParams>,
    /// The verdicts of the last query that ran the pass.
    pub(super) last: Option<Vec<u32>>,
}

impl CellPass {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        // It indexes the points by the image's size.
        let (pipeline, layout, params) = one_pass(
            device,
            "cells",
            layout::cell_source(),
            "judge_cells",
            std::mem::size_of::<CellParams>(),
        );
        Self {
            pipeline,
            layout,
            params,
            buffers: None,
            request: None,
            last: None,
        }
    }

    /// The verdicts' buffers for `cells` cells (grown to a power of two), and the bind group
    /// over `points`, the request written into the uniform.
    pub(super) fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        points: &wgpu::Buffer,
        request: &CellParams,
    ) -> wgpu::BindGroup {
        let cells = u64::from(request.cells).max(1);
        if self.buffers.as_ref().is_none_or(|(_, _, n)| *n < cells) {
            let n = cells.next_power_of_two();
            let verdicts = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cell verdicts"),
                size: 4 * n,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let readback = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cell readback"),
                size: 4 * n,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.buffers = Some((verdicts, readback, n));
        }
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(request));
        let (verdicts, _, _) = self.buffers.as_ref().expect("just made");
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cells"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: points.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: verdicts.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.params.as_entire_binding(),
                },
            ],
        })
    }

    /// Records the copy of `cells` verdicts into their readback.
    pub(super) fn copy_out(&self, encoder: &mut wgpu::CommandEncoder, cells: u32) {
        if let Some((verdicts, readback, _)) = &self.buffers {
            encoder.copy_buffer_to_buffer(verdicts, 0, readback, 0, 4 * u64::from(cells));
        }
    }

    /// The `cells` verdicts of the submitted query, once the device has finished it.
    pub(super) fn read(&self, device: &wgpu::Device, cells: u32) -> Result<Vec<u32>, GpuError> {
        let Some((_, readback, _)) = &self.buffers else {
            return Err(GpuError::Device("no cell verdicts".into()));
        };
        let slice = readback.slice(0..4 * u64::from(cells));
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        device
            .poll(wgpu::PollType::Wait)
            .map_err(|e| GpuError::Device(format!("waiting for the cell verdicts: {e}")))?;
        receiver
            .recv()
            .map_err(|e| GpuError::Device(format!("the cell verdicts' mapping: {e}")))?
            .map_err(|e| GpuError::Device(format!("mapping the cell verdicts: {e}")))?;
        let words = bytemuck::pod_collect_to_vec(&slice.get_mapped_range());
        readback.unmap();
        Ok(words)
    }
}
