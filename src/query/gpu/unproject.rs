//! Depth images unprojected on the GPU (`shaders/unproject.wgsl`): the image's bytes go through
//! the points' staging memory into an image buffer, and the first pass of the query writes its
//! points into the point buffer the other passes read, with the constants the CPU uses
//! (`cloud::depth::DepthView`), so that they are the CPU's points bit for bit. The host then
//! unprojects only the few points the result names (`Input::point`).

use std::borrow::Cow;

use super::bindings::layout_entry;
use super::error::GpuError;
use crate::cloud::depth::{DepthEncoding, DepthView};
use crate::query::layout::{self, DepthParams, DEPTH_M32, DEPTH_MM16};

/// The unprojection's pipeline, its bind group layout and its uniform.
pub(super) struct Unproject {
    pub(super) pipeline: wgpu::ComputePipeline,
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) params: wgpu::Buffer,
}

impl Unproject {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        // Compiled with wgpu's runtime checks: a short pass, which indexes the image by the
        // row step it is given.
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("unproject.wgsl"),
            source: wgpu::ShaderSource::Wgsl(Cow::Owned(layout::unproject_source())),
        });
        let entry = layout_entry;
        let group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("unproject"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(1, wgpu::BufferBindingType::Storage { read_only: false }),
                entry(2, wgpu::BufferBindingType::Uniform),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("unproject"),
            bind_group_layouts: &[&group_layout],
            push_constant_ranges: &[],
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("unproject"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("unproject"),
            compilation_options: Default::default(),
            cache: None,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("depth params"),
            size: std::mem::size_of::<DepthParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            pipeline,
            layout: group_layout,
            params,
        }
    }

    /// The bind group over `image` and `points`.
    pub(super) fn bind(
        &self,
        device: &wgpu::Device,
        image: &wgpu::Buffer,
        points: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("unproject"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: image.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: points.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.params.as_entire_binding(),
                },
            ],
        })
    }
}

/// The uniform of `depth`; an error where its sizes do not fit the shader's 32-bit indices.
pub(super) fn params(depth: &DepthView) -> Result<DepthParams, GpuError> {
    let bytes = depth.data().len() as u64;
    if bytes > u64::from(u32::MAX) {
        return Err(GpuError::TooLarge(bytes));
    }
    let (min2, max2) = depth.range.map_or((0.0, f32::INFINITY), |r| r.squared());
    Ok(DepthParams {
        width: depth.width() as u32,
        height: depth.height() as u32,
        step: depth.step() as u32,
        encoding: match depth.encoding() {
            DepthEncoding::Millimetres16 => DEPTH_MM16,
            DepthEncoding::Metres32 => DEPTH_M32,
        },
        big_endian: depth.big_endian() as u32,
        limited: depth.range.is_some() as u32,
        min2,
        max2,
        cx: depth.cx,
        cy: depth.cy,
        kx: depth.kx,
        ky: depth.ky,
        unit: depth.unit,
        pad0: 0,
        pad1: 0,
        pad2: 0,
    })
}
