//! A crowd's skinning on the GPU as one WGSL function of (instance, vertex), for the triangle
//! pass ([`crate::triangle_culling`]) and the caller's draw alike: morph target deltas by the
//! instance's weights, then linear blend skinning by the instance's palette (the world-space
//! skinning matrices crowd culling reads). The mesh is one storage buffer of words
//! ([`CrowdMesh::pack`]); the bindings are `@group(1)` (uniform, palette, mesh words, morph
//! weights: [`layout_entries`]).
//!
//! The guarantee the triangle pass keeps rests on the draw skinning with these same functions:
//! compiled into another pipeline they round differently only by a few ulps of their terms,
//! which [`CrowdMesh::margins`] bounds.

use crate::{GpuError, Result};
use skinlet_runtime::bake_view::MeshData;

/// `skinned_position(i, v)`, `skin_matrix(i, v)` and `morphed_position(i, v)` over the
/// bindings of [`layout_entries`] in `@group(1)`.
pub const CROWD_SKIN_WGSL: &str = include_str!("shaders/crowd_skin.wgsl");

/// A mesh packed for [`CROWD_SKIN_WGSL`]: the words of its storage buffer (positions,
/// influences, per-vertex morph offsets, morph deltas) and the uniform (`Skin`: joints,
/// influence stride, morph weights per instance, where each array starts).
#[derive(Clone, Debug, PartialEq)]
pub struct CrowdMesh {
    pub words: Vec<u32>,
    pub uniform: [u32; 8],
    /// The largest bind-pose coordinate magnitude.
    pub size: f32,
}

impl CrowdMesh {
    /// Packs a bake's mesh (`BakeView::mesh_data`, or the baker's) for palettes of `joints`
    /// matrices per instance (the bake's drivers). Errors when it has no skin weights, a
    /// weight names a joint past `joints`, or it has more words than 32-bit indices reach.
    pub fn pack(mesh: &MeshData, joints: u32) -> Result<CrowdMesh> {
        let invalid = |message: String| GpuError::Invalid { location: "crowd skinning", message };
        let v = &mesh.vertices;
        if v.stride == 0 {
            return Err(invalid("the mesh has no skin weights".into()));
        }
        let n = v.positions.len();
        let mut words: Vec<u32> = v.positions.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect();
        let influences = words.len();
        words.extend(v.joints.iter().zip(v.weights).flat_map(|(&j, w)| [j as u32, w.to_bits()]));
        let morph_offsets = words.len();
        let (weights, offsets, deltas) =
            mesh.morphs.map_or((0, &[][..], &[][..]), |m| (m.weights.len(), m.offsets, m.deltas));
        words.extend(offsets);
        words.resize(morph_offsets + n + 1, offsets.last().copied().unwrap_or(0));
        let morph_deltas = words.len();
        words.extend(
            deltas.iter().flat_map(|d| {
                [d.position.x, d.position.y, d.position.z].map(f32::to_bits).into_iter().chain([d.weight])
            }),
        );
        if words.len() > u32::MAX as usize / 2 {
            return Err(invalid(format!("{} words", words.len())));
        }
        if let Some(&j) = v.joints.iter().find(|&&j| j as u32 >= joints) {
            return Err(invalid(format!("an influence names joint {j} of {joints}")));
        }
        let uniform = [
            joints,
            v.stride as u32,
            weights as u32,
            influences as u32,
            morph_offsets as u32,
            morph_deltas as u32,
            0,
            0,
        ];
        let size = v.positions.iter().fold(0f32, |m, p| m.max(p.abs().max_element()));
        Ok(CrowdMesh { words, uniform, size })
    }

    /// The triangle pass's rounding margins (`TriangleSkinning::margin` and `relative`):
    /// 2^-16 of the mesh's size and of the position (in the bake's units: a skin that scales
    /// the mesh down to world units, as Xbot's does from centimeters, only widens them).
    pub fn margins(&self) -> (f32, f32) {
        (self.size / 65536.0, 1.0 / 65536.0)
    }
}

/// The four `@group(1)` layout entries of [`CROWD_SKIN_WGSL`], seen by `stages`: the uniform,
/// the palette, the mesh words, the morph weights (at least one word: a storage binding is
/// never empty).
pub fn layout_entries(stages: wgpu::ShaderStages) -> [wgpu::BindGroupLayoutEntry; 4] {
    use crate::skinning::buffer_entry;
    use wgpu::BufferBindingType::{Storage, Uniform};
    let storage = Storage { read_only: true };
    [
        buffer_entry(0, stages, Uniform),
        buffer_entry(1, stages, storage),
        buffer_entry(2, stages, storage),
        buffer_entry(3, stages, storage),
    ]
}
