//! The device skinlet's GPU objects live on (the caller's: skinlet-gpu creates none; the
//! headless device of skinlet's own tools is `skinlet_lab::headless`), with the buffer,
//! pipeline and error-scope helpers the modules share.

use crate::{GpuError, Result};
use wgpu::util::DeviceExt;

/// A device and its queue, with what the adapter is and can do.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Features enabled on the device (what skinlet may use: mesh shaders, timestamps,
    /// subgroups, f64, indirect first instance).
    pub features: wgpu::Features,
    /// The rasterizer's sub-pixel precision the culling tests assume
    /// ([`crate::crowd_culling::MIN_SUBPIXEL_BITS`] unless set from
    /// [`crate::crowd_culling::subpixel_bits`]).
    pub subpixel_bits: u32,
}

impl Gpu {
    /// skinlet's GPU objects on the caller's own device and queue (handles of the same
    /// device, as wgpu's `clone` gives), with the caller's adapter's `info`. What skinlet may
    /// use is what the device was created with (`device.features()`): mesh-shader paths need
    /// `EXPERIMENTAL_MESH_SHADER`, crowd culling `INDIRECT_FIRST_INSTANCE`.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue, info: wgpu::AdapterInfo) -> Gpu {
        let features = device.features();
        Gpu { device, queue, info, features, subpixel_bits: crate::crowd_culling::MIN_SUBPIXEL_BITS }
    }

    /// Whether GPU timestamps can be written (frame times in `Drawn::gpu_ms`).
    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Whether subgroup operations are enabled (task-shader compaction uses them).
    pub fn has_subgroups(&self) -> bool {
        self.features.contains(wgpu::Features::SUBGROUP)
    }

    /// Whether indirect draws may take their count from a buffer
    /// (`multi_draw_indexed_indirect_count`: `CrowdCulling::draw_indexed`).
    pub fn has_indirect_count(&self) -> bool {
        self.features.contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT)
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
        let view = staging.slice(..).get_mapped_range();
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
    compute_pipeline_layouts(device, label, source, entry, &[Some(layout)])
}

/// A compute pipeline of `source`'s `entry` over bind groups of `layouts`, in order.
pub(crate) fn compute_pipeline_layouts(
    device: &wgpu::Device,
    label: &str,
    source: String,
    entry: &str,
    layouts: &[Option<&wgpu::BindGroupLayout>],
) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: layouts,
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
    let errors = [ready(validation.pop()), ready(memory.pop())];
    match errors.into_iter().flatten().next() {
        Some(message) => Err(GpuError::Gpu { location, message }),
        None => Ok(out),
    }
}

/// The outcome of an error scope, which native wgpu resolves when the scope is popped: polled
/// once, so that this crate needs no executor. A scope still pending (a backend that answers
/// later) reads as an error rather than as success.
fn ready(scope: impl std::future::Future<Output = Option<wgpu::Error>>) -> Option<String> {
    let mut scope = std::pin::pin!(scope);
    match scope.as_mut().poll(&mut std::task::Context::from_waker(std::task::Waker::noop())) {
        std::task::Poll::Ready(error) => error.map(|e| e.to_string()),
        std::task::Poll::Pending => Some("the error scope did not resolve when popped".into()),
    }
}
