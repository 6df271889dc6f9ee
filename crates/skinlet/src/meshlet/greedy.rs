//! meshoptimizer's greedy meshlet builder (`meshopt_buildMeshlets`, meshoptimizer 1.3 via
//! the `meshopt` crate), which grows spatially compact meshlets and, with a cone weight,
//! favours triangles whose normals agree (better backface cone culling); each meshlet is
//! then reordered for locality with `meshopt_optimizeMeshlet`.

use super::{MeshletLimits, Meshlets};
use glam::Vec3;

/// meshoptimizer's recommended cone weight when cone culling is used.
pub const CONE_WEIGHT: f32 = 0.25;

/// meshoptimizer needs a triangle limit that is a multiple of 4: limits in between are
/// rounded down (126 → 124), and below 4 triangles the scan builder is used.
pub fn build(triangles: &[[u32; 3]], positions: &[Vec3], limits: MeshletLimits, cone_weight: f32) -> Meshlets {
    let mut out = Meshlets::default();
    if triangles.is_empty() {
        return out;
    }
    let max_triangles = limits.max_triangles / 4 * 4;
    if max_triangles == 0 {
        return super::scan::build(triangles, positions.len(), limits);
    }
    let indices: Vec<u32> = triangles.iter().flatten().copied().collect();
    let bytes = meshopt::typed_to_bytes(positions);
    let adapter = meshopt::VertexDataAdapter::new(bytes, std::mem::size_of::<Vec3>(), 0)
        .expect("Vec3 positions form a valid vertex stream");
    let built = meshopt::build_meshlets(&indices, &adapter, limits.max_vertices, max_triangles, cone_weight);
    for m in built.iter() {
        let mut verts = m.vertices.to_vec();
        let mut tris = m.triangles.to_vec();
        meshopt::optimize_meshlet_level(&mut verts, &mut tris, 0);
        out.push(&verts, &tris);
    }
    out
}
