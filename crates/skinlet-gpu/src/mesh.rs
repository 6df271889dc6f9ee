//! A skinned mesh on the GPU: bind-pose vertices, influences, morph target deltas, triangles,
//! and the buffers the compute path writes skinned vertices to; a [`Pose`] is what one draw
//! moves it by. The input is a mesh as a bake stores it ([`MeshData`]: from a bake file's
//! [`skinlet_runtime::bake_view::BakeView::mesh_data`], or the baker's in-memory mesh).

use crate::{Gpu, GpuError, Result};
use glam::{Affine3A, Vec3};
use skinlet_runtime::bake_view::{MeshData, MeshletView, VertexView};

/// Most vertices and triangles per meshlet the mesh shader emits (its output arrays).
pub const MAX_MESHLET_VERTICES: usize = 128;
pub const MAX_MESHLET_TRIANGLES: usize = 256;
/// Most joints a slim meshlet's mesh shader holds in workgroup memory.
pub const MAX_SLIM_JOINTS: usize = 16;

/// A mesh's meshlets on the GPU, for mesh-shader drawing.
pub struct GpuMeshlets {
    pub count: u32,
    /// Meshlets drawn with slim vertices by `Skinning::MeshSlim`: their vertices all have
    /// the meshlet's joint set, in joint order, and it has at most [`MAX_SLIM_JOINTS`].
    pub slim: u32,
    /// Vertices of slim meshlets (counted once per meshlet) and of the others.
    pub slim_vertices: u32,
    pub fat_vertices: u32,
    /// Per meshlet: vertex offset and count, triangle offset and count, joint offset and
    /// count (0: not slim), padding (`Meshlet` in WGSL).
    pub meshlets: wgpu::Buffer,
    /// The slim meshlets' joint lists.
    pub joint_lists: wgpu::Buffer,
    pub vertices: wgpu::Buffer,
    /// One u32 per triangle: its three local vertex indices in the low three bytes.
    pub triangles: wgpu::Buffer,
    /// Per meshlet: index count and first index in the mesh's index buffer (for indirect draws).
    pub draws: wgpu::Buffer,
}

/// What one draw poses a mesh with: a skinning matrix per joint and, for a mesh with morph
/// targets, the frame's value of each of its morph weights (`skinlet::model::Morphs::weights_at`).
#[derive(Clone, Copy, Debug)]
pub struct Pose<'a> {
    pub matrices: &'a [Affine3A],
    pub morph_weights: &'a [f32],
}

impl<'a> From<&'a [Affine3A]> for Pose<'a> {
    /// Skinning matrices alone (a mesh without morph targets).
    fn from(matrices: &'a [Affine3A]) -> Self {
        Pose { matrices, morph_weights: &[] }
    }
}

impl<'a> From<&'a Vec<Affine3A>> for Pose<'a> {
    fn from(matrices: &'a Vec<Affine3A>) -> Self {
        Pose { matrices, morph_weights: &[] }
    }
}

pub struct GpuMesh {
    pub vertices: u32,
    pub has_normals: bool,
    /// One more than the largest joint index used: the skinning matrices a draw needs.
    pub joint_count: usize,
    /// Morph weights a pose must give (0: the mesh has no morph deltas).
    pub morph_weights: usize,
    /// Vertex count, influences per vertex, normals present (0/1), morph deltas present
    /// (0/1), where the morph weights start in the pose buffer (in vec4s), where the deltas
    /// start in the morph buffer, padding: `Params` in WGSL.
    pub params: wgpu::Buffer,
    pub positions: wgpu::Buffer,
    pub normals: wgpu::Buffer,
    pub joints: wgpu::Buffer,
    pub weights: wgpu::Buffer,
    /// Per vertex its first morph delta (one more entry than vertices; one 0 without
    /// morphs), then eight words per delta: position delta, weight index, normal delta, 0.
    pub morphs: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub index_count: u32,
    /// Skinned positions and unit normals written by compute skinning (3 f32 per vertex).
    pub out_positions: wgpu::Buffer,
    pub out_normals: wgpu::Buffer,
    /// Present when uploaded with meshlets; the index buffer then lists the meshlets'
    /// triangles in meshlet order, so every pipeline draws the same triangles in the same order.
    pub meshlets: Option<GpuMeshlets>,
}

impl GpuMesh {
    /// Uploads `mesh`, with its meshlets if it has them (for mesh-shader drawing and
    /// meshlet culling). Errors when it has no skin weights, its lengths disagree, an index
    /// is out of range, its morph targets or meshlets are malformed, or a meshlet is larger
    /// than the mesh shader's outputs.
    pub fn new(gpu: &Gpu, mesh: &MeshData) -> Result<GpuMesh> {
        let invalid = |message: String| GpuError::Invalid { location: "GPU mesh", message };
        let v = &mesh.vertices;
        let (positions, normals, stride) = (v.positions, v.normals, v.stride);
        if stride == 0 {
            return Err(invalid("the mesh has no skin weights".into()));
        }
        let n = positions.len();
        if v.joints.len() != n * stride
            || v.weights.len() != n * stride
            || !(normals.is_empty() || normals.len() == n)
            || n > u32::MAX as usize / 3
        {
            return Err(invalid(format!(
                "{n} positions, {} normals, {} joints and {} weights at {stride} influences per vertex",
                normals.len(),
                v.joints.len(),
                v.weights.len()
            )));
        }
        if let Some((t, tri)) = mesh.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&i| i as usize >= n)) {
            return Err(invalid(format!("triangle {t} {tri:?} indexes past {n} vertices")));
        }
        let joints: Vec<u32> = v.joints.iter().map(|&j| j as u32).collect();
        let (indices, draws) = match &mesh.meshlets {
            Some(m) => meshlet_index_buffer(m, n)?,
            None => (mesh.triangles.iter().flatten().copied().collect(), Vec::new()),
        };
        let meshlets = mesh.meshlets.as_ref().map(|m| upload_meshlets(gpu, m, v, &draws)).transpose()?;
        if let Some(m) = &mesh.morphs {
            m.check(n).map_err(|e| invalid(e.to_string()))?;
        }
        // One u32 buffer: per vertex its first delta (one more offset than vertices), then
        // eight words per delta: position delta, weight index, normal delta, 0.
        let mut morph_data: Vec<u32> = mesh.morphs.map_or(vec![0], |m| m.offsets.to_vec());
        let delta_base = morph_data.len() as u32;
        for d in mesh.morphs.iter().flat_map(|m| m.deltas) {
            let [px, py, pz] = d.position.to_array().map(f32::to_bits);
            let [nx, ny, nz] = d.normal.to_array().map(f32::to_bits);
            morph_data.extend([px, py, pz, d.weight, nx, ny, nz, 0]);
        }
        let joint_count = v.joints.iter().map(|&j| j as usize + 1).max().unwrap_or(0);
        let morph_weights = mesh.morphs.map_or(0, |m| m.weights.len());
        let params: [u32; 8] = [
            n as u32,
            stride as u32,
            !normals.is_empty() as u32,
            mesh.morphs.is_some() as u32,
            4 * joint_count as u32,
            delta_base,
            0,
            0,
        ];
        let out = wgpu::BufferUsages::COPY_SRC;
        gpu.checked("GPU mesh upload", || GpuMesh {
            vertices: n as u32,
            has_normals: !normals.is_empty(),
            joint_count,
            morph_weights,
            params: gpu.buffer("mesh params", &params, wgpu::BufferUsages::UNIFORM),
            positions: vec3_buffer(gpu, "positions", positions),
            normals: vec3_buffer(gpu, "normals", normals),
            joints: gpu.buffer("joints", &joints, wgpu::BufferUsages::STORAGE),
            weights: gpu.buffer("weights", v.weights, wgpu::BufferUsages::STORAGE),
            morphs: gpu.buffer("morph deltas", &morph_data, wgpu::BufferUsages::STORAGE),
            indices: gpu.buffer("indices", &indices, wgpu::BufferUsages::INDEX),
            index_count: indices.len() as u32,
            out_positions: gpu.buffer("skinned positions", &vec![0f32; 3 * n], wgpu::BufferUsages::STORAGE | out),
            out_normals: gpu.buffer(
                "skinned normals",
                &vec![0f32; 3 * normals.len()],
                wgpu::BufferUsages::STORAGE | out,
            ),
            meshlets,
        })
    }

    /// A pose as the shaders read it: per joint the four columns of glam's `Affine3A` (x, y,
    /// z axes, translation), each a vec4, for the joints the mesh uses, then its morph
    /// weights, four per vec4. Errors when a joint has no matrix or the weights are not the
    /// mesh's.
    pub fn pose_buffer(&self, gpu: &Gpu, pose: Pose) -> Result<wgpu::Buffer> {
        let invalid = |message: String| GpuError::Invalid { location: "skinning", message };
        if pose.matrices.len() < self.joint_count {
            return Err(invalid(format!(
                "joint {} used but only {} skinning matrices",
                self.joint_count - 1,
                pose.matrices.len()
            )));
        }
        if pose.morph_weights.len() != self.morph_weights {
            return Err(invalid(format!(
                "{} morph weight values for a mesh with {} morph weights",
                pose.morph_weights.len(),
                self.morph_weights
            )));
        }
        let mut columns: Vec<[f32; 4]> = pose.matrices[..self.joint_count]
            .iter()
            .flat_map(|m| [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis, m.translation])
            .map(|c| c.extend(0.0).to_array())
            .collect();
        columns.extend(pose.morph_weights.chunks(4).map(|w| std::array::from_fn(|k| w.get(k).copied().unwrap_or(0.0))));
        columns.resize(columns.len().max(1), [0.0; 4]);
        Ok(gpu.buffer("pose", &columns, wgpu::BufferUsages::STORAGE))
    }
}

/// A storage buffer of vectors, 3 f32 each (as the shaders read positions and normals).
pub(crate) fn vec3_buffer(gpu: &Gpu, label: &str, v: &[Vec3]) -> wgpu::Buffer {
    let flat: Vec<f32> = v.iter().flat_map(|p| p.to_array()).collect();
    gpu.buffer(label, &flat, wgpu::BufferUsages::STORAGE)
}

/// A bind group entry for a whole buffer.
pub fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

/// An index buffer listing `m`'s triangles meshlet by meshlet (mesh vertex indices), and per
/// meshlet its index count and first index in it: the `draws` of
/// [`crate::crowd_culling::GpuCharacter::new`]. Errors when a meshlet exceeds the mesh
/// shader's outputs or points past its arrays or the mesh's `vertices`.
pub fn meshlet_index_buffer(m: &MeshletView, vertices: usize) -> Result<(Vec<u32>, Vec<[u32; 2]>)> {
    let invalid = |message: String| GpuError::Invalid { location: "GPU meshlets", message };
    // The mesh shader's outputs are the limits.
    m.check(vertices, [MAX_MESHLET_VERTICES, MAX_MESHLET_TRIANGLES]).map_err(|e| invalid(e.to_string()))?;
    Ok(m.index_buffer())
}

fn upload_meshlets(gpu: &Gpu, m: &MeshletView, v: &VertexView, draws: &[[u32; 2]]) -> Result<GpuMeshlets> {
    let mut joint_lists: Vec<u32> = Vec::new();
    let (mut slim, mut slim_vertices, mut fat_vertices) = (0, 0, 0);
    // A vertex's joints: its influence slots up to the first zero weight.
    let vertex_joints = |x: u32| {
        let slots = x as usize * v.stride..(x as usize + 1) * v.stride;
        v.joints[slots.clone()].iter().zip(&v.weights[slots]).take_while(|(_, w)| **w != 0.0).map(|(j, _)| *j)
    };
    let records: Vec<[u32; 8]> = (0..m.len())
        .map(|i| {
            let (h, (vc, tc)) = (m.headers[i], m.counts(i));
            // Slim when every vertex has exactly the meshlet's joints, in that order (skinlet's
            // `prepare` sorts influences by joint, so a shared joint set is a shared order).
            let joints = m.joints_of(i).unwrap_or(&[]);
            let verts = &m.vertices[h[0] as usize..][..vc];
            let shared = (1..=MAX_SLIM_JOINTS).contains(&joints.len())
                && verts.iter().all(|&x| vertex_joints(x).eq(joints.iter().copied()));
            let (offset, count) = if shared { (joint_lists.len() as u32, joints.len() as u32) } else { (0, 0) };
            if shared {
                joint_lists.extend(joints.iter().map(|&j| j as u32));
                slim += 1;
                slim_vertices += vc as u32;
            } else {
                fat_vertices += vc as u32;
            }
            [h[0], vc as u32, h[1] / 3, tc as u32, offset, count, 0, 0]
        })
        .collect();
    let packed: Vec<u32> =
        m.triangles.chunks_exact(3).map(|t| t[0] as u32 | (t[1] as u32) << 8 | (t[2] as u32) << 16).collect();
    let storage = wgpu::BufferUsages::STORAGE;
    gpu.checked("GPU meshlets upload", || GpuMeshlets {
        count: m.len() as u32,
        slim,
        slim_vertices,
        fat_vertices,
        joint_lists: gpu.buffer("meshlet joints", &joint_lists, storage),
        meshlets: gpu.buffer("meshlets", &records, storage),
        vertices: gpu.buffer("meshlet vertices", m.vertices, storage),
        triangles: gpu.buffer("meshlet triangles", &packed, storage),
        draws: gpu.buffer("meshlet draws", draws, storage),
    })
}
