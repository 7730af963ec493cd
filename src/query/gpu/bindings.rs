//! The wgpu objects every part of the GPU engine makes alike: a storage buffer filled from
//! bytes, a compute shader's buffer binding in a bind group layout, and a one-pass shader that
//! reads a buffer and writes another under a uniform of its own (`unproject`, `cell`).

use std::borrow::Cow;

use wgpu::util::DeviceExt;

/// A storage buffer holding `bytes`, which queries may also write and copy out of.
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

/// A compute pass over three bindings (0: read-only storage, 1: storage it writes, 2: its
/// uniform): the pipeline of `entry_point` in the WGSL `source`, its bind group layout, and the
/// uniform's buffer of `params_size` bytes. Compiled with wgpu's runtime checks: such a pass
/// indexes its buffers by sizes it is given.
pub(super) fn one_pass(
    device: &wgpu::Device,
    label: &str,
    source: String,
    entry_point: &str,
    params_size: usize,
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout, wgpu::Buffer) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(Cow::Owned(source)),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[
            layout_entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
            layout_entry(1, wgpu::BufferBindingType::Storage { read_only: false }),
            layout_entry(2, wgpu::BufferBindingType::Uniform),
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[&layout],
        push_constant_ranges: &[],
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry_point),
        compilation_options: Default::default(),
        cache: None,
    });
    let params = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: params_size as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    (pipeline, layout, params)
}
