//! The buffers that grow with the cloud (points, staging memory, depth image, kept blocks, work
//! items, boxed blocks), the self-filter's grids uploaded once per padding, and the bind group
//! over them all, made anew only when one of them changed. Sizes in points, blocks, items and
//! bytes.

use std::sync::atomic::AtomicU8;
use std::sync::Arc;

use super::bindings::storage;
use super::engine::{GpuEngine, Sized};
use super::error::GpuError;
use super::transfer::MAPPED;
use crate::query::layout::{BoxedBlock, GridHeader, KeptBlock};
use crate::query::self_grid::SelfGrid;

impl GpuEngine {
    /// Grows the cloud's buffers to hold `points` points in `blocks` blocks with `items` work
    /// items, and a depth image of `image_bytes` (a multiple of four).
    pub(super) fn ensure(
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
    pub(super) fn use_grids(&mut self, padding: f32, grids: &[SelfGrid]) -> Result<(), GpuError> {
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
    pub(super) fn bind(&mut self) {
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
}
