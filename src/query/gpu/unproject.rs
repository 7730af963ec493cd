//! Depth images unprojected on the GPU (`shaders/unproject.wgsl`): the image's bytes go through
//! the points' staging memory into an image buffer, and the first pass of the query writes its
//! points into the point buffer the other passes read, with the constants the CPU uses
//! (`cloud::depth::DepthView`), so that they are the CPU's points bit for bit. The host then
//! unprojects only the few points the result names (`Input::point`).

use super::bindings::one_pass;
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
        // A short pass, which indexes the image by the row step it is given.
        let (pipeline, layout, params) = one_pass(
            device,
            "unproject",
            layout::unproject_source(),
            "unproject",
            std::mem::size_of::<DepthParams>(),
        );
        Self {
            pipeline,
            layout,
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
