//! The device: a headless Vulkan adapter (a real GPU, or Mesa's lavapipe on CPU-only
//! machines) with the optional features the adapter offers.

use crate::{GpuError, Result};
use wgpu::util::DeviceExt;

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

/// A device and its queue, with what the adapter is and can do.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Features enabled on the device (a subset of mesh shaders, timestamps, subgroups, f64).
    pub features: wgpu::Features,
}

impl Gpu {
    /// The first Vulkan adapter, with mesh shaders, timestamp queries, subgroup operations and
    /// 64-bit floats in shaders enabled where the adapter has them.
    pub fn new(options: GpuOptions) -> Result<Gpu> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            force_fallback_adapter: options.software,
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let mut wanted =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::SHADER_F64 | wgpu::Features::INDIRECT_FIRST_INSTANCE;
        if !options.no_subgroups {
            wanted |= wgpu::Features::SUBGROUP;
        }
        if !options.no_mesh_shaders {
            wanted |= wgpu::Features::EXPERIMENTAL_MESH_SHADER;
        }
        let features = adapter.features() & wanted;
        let mesh = features.contains(wgpu::Features::EXPERIMENTAL_MESH_SHADER);
        let desc = wgpu::DeviceDescriptor {
            label: Some("skinlet"),
            required_features: features,
            required_limits: if mesh {
                // Task-culled slim mesh shading binds 10 storage buffers to the mesh stage.
                let limits = wgpu::Limits::defaults().using_recommended_minimum_mesh_shader_values();
                let storage = adapter.limits().max_storage_buffers_per_shader_stage.min(16);
                wgpu::Limits {
                    max_storage_buffers_per_shader_stage: limits.max_storage_buffers_per_shader_stage.max(storage),
                    ..limits
                }
            } else {
                wgpu::Limits::defaults()
            },
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
        Ok(Gpu { device, queue, info: adapter.get_info(), features })
    }

    /// skinlet's GPU objects on the caller's own device and queue (handles of the same
    /// device, as wgpu's `clone` gives), with the caller's adapter's `info`. What skinlet may
    /// use is what the device was created with (`device.features()`): mesh-shader paths need
    /// `EXPERIMENTAL_MESH_SHADER`, crowd culling `INDIRECT_FIRST_INSTANCE`.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue, info: wgpu::AdapterInfo) -> Gpu {
        let features = device.features();
        Gpu { device, queue, info, features }
    }

    /// Whether GPU timestamps can be written (frame times in `Drawn::gpu_ms`).
    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Whether subgroup operations are enabled (task-shader compaction uses them).
    pub fn has_subgroups(&self) -> bool {
        self.features.contains(wgpu::Features::SUBGROUP)
    }

    /// Whether mesh (and task) shaders are enabled.
    pub fn has_mesh_shaders(&self) -> bool {
        self.features.contains(wgpu::Features::EXPERIMENTAL_MESH_SHADER)
    }

    /// A buffer holding `data` (at least 16 bytes: empty bindings are not allowed).
    pub fn buffer<T: bytemuck::Pod>(&self, label: &str, data: &[T], usage: wgpu::BufferUsages) -> wgpu::Buffer {
        buffer(&self.device, label, data, usage)
    }

    /// A compute pipeline from WGSL `source` with entry point `entry` and one bind group of
    /// `entries`; returns the pipeline and that group's layout.
    pub fn compute_pipeline(
        &self,
        label: &str,
        source: String,
        entry: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
    ) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
        let layout =
            self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
        (self.compute_pipeline_with(label, source, entry, &layout), layout)
    }

    /// A compute pipeline from WGSL `source` with entry point `entry` and one bind group of
    /// an existing `layout`.
    pub fn compute_pipeline_with(
        &self,
        label: &str,
        source: String,
        entry: &str,
        layout: &wgpu::BindGroupLayout,
    ) -> wgpu::ComputePipeline {
        compute_pipeline_with(&self.device, label, source, entry, layout)
    }

    /// A bind group of `entries` for `layout`.
    pub fn bind_group(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        entries: &[wgpu::BindGroupEntry],
    ) -> wgpu::BindGroup {
        self.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries })
    }

    /// Runs `work` inside a validation error scope and waits for the queue: a validation or
    /// out-of-memory error becomes a [`GpuError`] named after `location`.
    pub fn checked<T>(&self, location: &'static str, work: impl FnOnce() -> T) -> Result<T> {
        checked(&self.device, location, work)
    }

    /// Copies `size` bytes of `buffer` (which needs COPY_SRC) back to the CPU.
    pub fn read(&self, buffer: &wgpu::Buffer, size: u64) -> Result<Vec<u8>> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
        let index = self.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        let gpu_err = |message: String| GpuError::Gpu { location: "readback", message };
        self.device
            .poll(wgpu::PollType::Wait { submission_index: Some(index), timeout: None })
            .map_err(|e| gpu_err(e.to_string()))?;
        rx.recv().map_err(|e| gpu_err(e.to_string()))?.map_err(|e| gpu_err(e.to_string()))?;
        let view = staging.slice(..).get_mapped_range().map_err(|e| gpu_err(e.to_string()))?;
        let out = view.to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// A buffer holding `data` (at least 16 bytes: empty bindings are not allowed).
pub(crate) fn buffer<T: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    data: &[T],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let mut bytes = bytemuck::cast_slice::<T, u8>(data).to_vec();
    bytes.resize(bytes.len().max(16).next_multiple_of(4), 0);
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: &bytes, usage })
}

/// A compute pipeline from WGSL `source` with entry point `entry` and one bind group of an
/// existing `layout`.
pub(crate) fn compute_pipeline_with(
    device: &wgpu::Device,
    label: &str,
    source: String,
    entry: &str,
    layout: &wgpu::BindGroupLayout,
) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Runs `work` inside a validation and an out-of-memory error scope on `device`: an error
/// becomes a [`GpuError`] named after `location`.
pub(crate) fn checked<T>(device: &wgpu::Device, location: &'static str, work: impl FnOnce() -> T) -> Result<T> {
    let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = work();
    let errors = [pollster::block_on(validation.pop()), pollster::block_on(memory.pop())];
    match errors.into_iter().flatten().next() {
        Some(e) => Err(GpuError::Gpu { location, message: e.to_string() }),
        None => Ok(out),
    }
}
