//! Compute-shader skinning (thesis chapter 3: skinned vertices written to a buffer that a
//! plain vertex shader then draws).
//!
//! `shaders/common.wgsl` performs skinlet's reference linear blend skinning with morph
//! targets first (`skinlet::skinning::skin_mesh`) with the same operations in the same order, one invocation per
//! vertex, so the only differences are the GPU's own rounding (fused multiply-adds, the
//! normalization): tests/skinning.rs checks every vertex of every shared asset against the
//! CPU to 1e-5 of the model's size (on lavapipe they agree bit for bit).

use crate::mesh::{GpuMesh, Pose, entry};
use crate::{Gpu, Result};
use glam::Vec3;

/// The skinning arithmetic every skinning shader shares (the mesh's bindings 0–5 and 8, see
/// [`mesh_entries`], and `skin_vertex`): prepend it to your own vertex or compute shader.
pub const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");

/// The compute pipeline (create once per device).
pub struct ComputeSkinning {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// A bind group layout entry: a buffer of `ty` seen by `stages`.
pub fn buffer_entry(
    binding: u32,
    stages: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

/// Bindings 0–5 and 8 of `common.wgsl` (mesh parameters, bind-pose vertices, influences,
/// the pose, morph deltas).
pub fn mesh_entries(stages: wgpu::ShaderStages) -> Vec<wgpu::BindGroupLayoutEntry> {
    let mut entries = vec![buffer_entry(0, stages, wgpu::BufferBindingType::Uniform)];
    entries.extend(
        [1, 2, 3, 4, 5, 8].map(|b| buffer_entry(b, stages, wgpu::BufferBindingType::Storage { read_only: true })),
    );
    entries
}

/// Entries for bindings 0–5 and 8 of `common.wgsl`; `pose` from `GpuMesh::pose_buffer`.
pub fn mesh_bindings<'a>(mesh: &'a GpuMesh, pose: &'a wgpu::Buffer) -> Vec<wgpu::BindGroupEntry<'a>> {
    vec![
        entry(0, &mesh.params),
        entry(1, &mesh.positions),
        entry(2, &mesh.normals),
        entry(3, &mesh.joints),
        entry(4, &mesh.weights),
        entry(5, pose),
        entry(8, &mesh.morphs),
    ]
}

impl ComputeSkinning {
    pub fn new(gpu: &Gpu) -> Result<ComputeSkinning> {
        gpu.checked("compute skinning pipeline", || {
            let stage = wgpu::ShaderStages::COMPUTE;
            let mut entries = mesh_entries(stage);
            entries
                .extend((6..=7).map(|b| buffer_entry(b, stage, wgpu::BufferBindingType::Storage { read_only: false })));
            let source = [COMMON_WGSL, include_str!("shaders/skin.wgsl")].concat();
            let (pipeline, layout) = gpu.compute_pipeline("skinning", source, "skin", &entries);
            ComputeSkinning { pipeline, layout }
        })
    }

    /// Records the skinning of `mesh` by the matrices in `matrices` (from
    /// `GpuMesh::matrix_buffer`) into `positions` and `normals` (3 f32 per vertex).
    pub fn encode_into(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        mesh: &GpuMesh,
        matrices: &wgpu::Buffer,
        positions: &wgpu::Buffer,
        normals: &wgpu::Buffer,
    ) {
        let mut entries = mesh_bindings(mesh, matrices);
        entries.extend([entry(6, positions), entry(7, normals)]);
        let bind = gpu.bind_group("skinning", &self.layout, &entries);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(mesh.vertices.div_ceil(64), 1, 1);
    }

    /// Skins `mesh` in `pose` (one skinning matrix per joint, morph weights for a mesh with
    /// morph targets) into its output buffers (submitted, not waited for). Errors when a
    /// joint has no matrix or the morph weights are not the mesh's.
    pub fn skin<'a>(&self, gpu: &Gpu, mesh: &GpuMesh, pose: impl Into<Pose<'a>>) -> Result<()> {
        let matrices = mesh.pose_buffer(gpu, pose.into())?;
        gpu.checked("compute skinning", || {
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            self.encode_into(gpu, &mut encoder, mesh, &matrices, &mesh.out_positions, &mesh.out_normals);
            gpu.queue.submit([encoder.finish()]);
        })
    }

    /// Reads the skinned positions and normals back (normals empty when the mesh has none).
    pub fn read(&self, gpu: &Gpu, mesh: &GpuMesh) -> Result<(Vec<Vec3>, Vec<Vec3>)> {
        let size = (12 * mesh.vertices as u64).max(4);
        let to_vec3 = |bytes: Vec<u8>| -> Vec<Vec3> {
            bytemuck::pod_collect_to_vec::<u8, f32>(&bytes).chunks_exact(3).map(Vec3::from_slice).collect()
        };
        let positions = to_vec3(gpu.read(&mesh.out_positions, size)?);
        let normals = if mesh.has_normals { to_vec3(gpu.read(&mesh.out_normals, size)?) } else { Vec::new() };
        Ok((positions, normals))
    }
}
