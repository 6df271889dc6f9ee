//! The headless device skinlet's tools and tests draw on: the first Vulkan adapter (a real
//! GPU, or Mesa's lavapipe on CPU-only machines) with the optional features it offers, waited
//! on with `pollster`. A game brings its own device (`skinlet_gpu::Gpu::from_device`).

use skinlet_gpu::{Gpu, GpuError, Result};

/// How to pick the adapter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Only a software adapter (lavapipe), even where a GPU exists.
    pub software: bool,
    /// Do not ask for mesh shaders even where the adapter has them (tests the fallback).
    pub no_mesh_shaders: bool,
    /// Do not ask for subgroup operations (tests the atomics-only compaction).
    pub no_subgroups: bool,
}

/// The first Vulkan adapter, with mesh shaders, timestamp queries, subgroup operations,
/// 64-bit floats in shaders, indirect first instance and indirect draw counts enabled where the
/// adapter has them.
pub fn gpu(options: GpuOptions) -> Result<Gpu> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        force_fallback_adapter: options.software,
        ..Default::default()
    }))
    .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
    let mut wanted = wgpu::Features::TIMESTAMP_QUERY
        | wgpu::Features::SHADER_F64
        | wgpu::Features::INDIRECT_FIRST_INSTANCE
        | wgpu::Features::MULTI_DRAW_INDIRECT_COUNT;
    if !options.no_subgroups {
        wanted |= wgpu::Features::SUBGROUP;
    }
    if !options.no_mesh_shaders {
        wanted |= wgpu::Features::EXPERIMENTAL_MESH_SHADER;
    }
    let features = adapter.features() & wanted;
    let mesh = features.contains(wgpu::Features::EXPERIMENTAL_MESH_SHADER);
    // Large storage bindings where the adapter has them (up to 1 GiB): the triangle pass's
    // lists of a dense crowd's survivors hold millions of triangles.
    let offered = adapter.limits();
    let large = |limits: wgpu::Limits| wgpu::Limits {
        max_storage_buffer_binding_size: (offered.max_storage_buffer_binding_size.min(1 << 30))
            .max(limits.max_storage_buffer_binding_size),
        max_buffer_size: offered.max_buffer_size.min(1 << 30).max(limits.max_buffer_size),
        ..limits
    };
    let desc = wgpu::DeviceDescriptor {
        label: Some("skinlet"),
        required_features: features,
        required_limits: large(if mesh {
            // Task-culled slim mesh shading binds 10 storage buffers to the mesh stage, and
            // one draw launches a task workgroup per meshlet group (more than the 256 per
            // dimension wgpu's portable minimum allows): what the adapter offers.
            let limits = wgpu::Limits::defaults().using_recommended_minimum_mesh_shader_values();
            let storage = offered.max_storage_buffers_per_shader_stage.min(16);
            wgpu::Limits {
                max_storage_buffers_per_shader_stage: limits.max_storage_buffers_per_shader_stage.max(storage),
                max_task_mesh_workgroup_total_count: (limits.max_task_mesh_workgroup_total_count)
                    .max(offered.max_task_mesh_workgroup_total_count),
                max_task_mesh_workgroups_per_dimension: (limits.max_task_mesh_workgroups_per_dimension)
                    .max(offered.max_task_mesh_workgroups_per_dimension),
                ..limits
            }
        } else {
            wgpu::Limits::defaults()
        }),
        // SAFETY: mesh shaders are an experimental wgpu feature; we opt in only when the
        // adapter reports them, and every mesh pipeline is checked against the CPU path.
        experimental_features: if mesh {
            unsafe { wgpu::ExperimentalFeatures::enabled() }
        } else {
            wgpu::ExperimentalFeatures::disabled()
        },
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    };
    let (device, queue) =
        pollster::block_on(adapter.request_device(&desc)).map_err(|e| GpuError::Device(e.to_string()))?;
    let mut gpu = Gpu::from_device(device, queue, adapter.get_info());
    gpu.subpixel_bits = skinlet_gpu::crowd_culling::subpixel_bits(&adapter);
    Ok(gpu)
}
