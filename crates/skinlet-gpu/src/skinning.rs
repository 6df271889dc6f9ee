//! Compute-shader skinning (thesis chapter 3, "compute shader skinning": skinned vertices
//! written to a buffer that a plain vertex shader then draws).
//!
//! `shaders/skin.wgsl` performs skinlet's reference linear blend skinning
//! ([`skinlet::skinning`]) with the same operations in the same order, one invocation per
//! vertex, so the only differences are the GPU's own rounding (fused multiply-adds, the
//! reciprocal square root of the normalization): tests/skinning.rs checks every vertex of
//! every shared asset against the CPU to 1e-5 of the model's size.

use crate::{Gpu, GpuError, Result};
use glam::{Affine3A, Vec3};
use skinlet::model::Influences;
use wgpu::util::DeviceExt;

/// The compute pipeline (create once per device).
pub struct ComputeSkinning {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// One mesh's vertex data on the GPU and the buffers its skinned vertices go to.
pub struct SkinnedBuffers {
    pub vertices: u32,
    has_normals: bool,
    joint_count: usize,
    params: wgpu::Buffer,
    positions: wgpu::Buffer,
    normals: wgpu::Buffer,
    joints: wgpu::Buffer,
    weights: wgpu::Buffer,
    /// Skinned positions (3 f32 per vertex), usable as a vertex buffer.
    pub out_positions: wgpu::Buffer,
    /// Skinned unit normals (3 f32 per vertex; absent normals: a placeholder).
    pub out_normals: wgpu::Buffer,
}

impl ComputeSkinning {
    pub fn new(gpu: &Gpu) -> Result<ComputeSkinning> {
        gpu.checked("compute skinning pipeline", || {
            let module = gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("skin.wgsl"),
                source: wgpu::ShaderSource::Wgsl(include_str!("shaders/skin.wgsl").into()),
            });
            let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            };
            let mut entries = vec![wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }];
            entries.extend((1..=5).map(|b| storage(b, true)));
            entries.extend((6..=7).map(|b| storage(b, false)));
            let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("skinning"),
                entries: &entries,
            });
            let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("skinning"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("skinning"),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some("skin"),
                compilation_options: Default::default(),
                cache: None,
            });
            ComputeSkinning { pipeline, layout }
        })
    }

    /// Uploads a mesh: bind-pose `positions`, `normals` (empty or one per vertex) and its
    /// influences. Errors when the lengths disagree.
    pub fn upload(
        &self,
        gpu: &Gpu,
        influences: &Influences,
        positions: &[Vec3],
        normals: &[Vec3],
    ) -> Result<SkinnedBuffers> {
        let n = influences.vertex_count();
        if positions.len() != n || !(normals.is_empty() || normals.len() == n) || n > u32::MAX as usize / 3 {
            return Err(GpuError::Invalid {
                location: "compute skinning",
                message: format!("{n} influence sets but {} positions and {} normals", positions.len(), normals.len()),
            });
        }
        let flat = |v: &[Vec3]| v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>();
        let joints: Vec<u32> = influences.joints.iter().map(|&j| j as u32).collect();
        let joint_count = influences.joints.iter().map(|&j| j as usize + 1).max().unwrap_or(0);
        let out = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_SRC;
        gpu.checked("compute skinning upload", || {
            let params: [u32; 4] = [n as u32, influences.stride as u32, !normals.is_empty() as u32, 0];
            SkinnedBuffers {
                vertices: n as u32,
                has_normals: !normals.is_empty(),
                joint_count,
                params: gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("skinning params"),
                    contents: bytemuck::cast_slice(&params),
                    usage: wgpu::BufferUsages::UNIFORM,
                }),
                positions: gpu.storage("positions", &flat(positions), wgpu::BufferUsages::empty()),
                normals: gpu.storage("normals", &flat(normals), wgpu::BufferUsages::empty()),
                joints: gpu.storage("joints", &joints, wgpu::BufferUsages::empty()),
                weights: gpu.storage("weights", &influences.weights, wgpu::BufferUsages::empty()),
                out_positions: gpu.storage("skinned positions", &vec![0f32; 3 * n], out),
                out_normals: gpu.storage("skinned normals", &vec![0f32; 3 * normals.len()], out),
            }
        })
    }

    /// Skins `mesh` with `matrices` (one skinning matrix per joint) on the GPU (submitted,
    /// not waited for). Errors when a joint has no matrix.
    pub fn skin(&self, gpu: &Gpu, mesh: &SkinnedBuffers, matrices: &[Affine3A]) -> Result<()> {
        if matrices.len() < mesh.joint_count {
            return Err(GpuError::Invalid {
                location: "compute skinning",
                message: format!("joint {} used but only {} skinning matrices", mesh.joint_count - 1, matrices.len()),
            });
        }
        let columns: Vec<[f32; 4]> = matrices
            .iter()
            .flat_map(|m| [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis, m.translation])
            .map(|c| c.extend(0.0).to_array())
            .collect();
        gpu.checked("compute skinning", || {
            let matrices = gpu.storage("skinning matrices", &columns, wgpu::BufferUsages::empty());
            let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("skinning"),
                layout: &self.layout,
                entries: &[
                    entry(0, &mesh.params),
                    entry(1, &mesh.positions),
                    entry(2, &mesh.normals),
                    entry(3, &mesh.joints),
                    entry(4, &mesh.weights),
                    entry(5, &matrices),
                    entry(6, &mesh.out_positions),
                    entry(7, &mesh.out_normals),
                ],
            });
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups(mesh.vertices.div_ceil(64), 1, 1);
            }
            gpu.queue.submit([encoder.finish()]);
        })
    }

    /// Reads the skinned positions and normals back (normals empty when the mesh has none).
    pub fn read(&self, gpu: &Gpu, mesh: &SkinnedBuffers) -> Result<(Vec<Vec3>, Vec<Vec3>)> {
        let size = 12 * mesh.vertices as u64;
        let to_vec3 = |bytes: Vec<u8>| -> Vec<Vec3> {
            bytemuck::pod_collect_to_vec::<u8, f32>(&bytes).chunks_exact(3).map(Vec3::from_slice).collect()
        };
        let positions = to_vec3(gpu.read(&mesh.out_positions, size.max(4))?);
        let normals = if mesh.has_normals { to_vec3(gpu.read(&mesh.out_normals, size.max(4))?) } else { Vec::new() };
        Ok((positions, normals))
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}
