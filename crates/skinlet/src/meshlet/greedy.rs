//! meshoptimizer's meshlet builders (meshoptimizer 1.3 via the `meshopt` crate): the greedy
//! `meshopt_buildMeshlets`, which grows spatially compact meshlets and, with a cone weight,
//! favours triangles whose normals agree (better backface cone culling); its flexible-size
//! variant `meshopt_buildMeshletsFlex` (meshlets between a minimum and the limit, split where
//! their bounds grow large); and the SAH-driven `meshopt_buildMeshletsSpatial` (made for ray
//! tracing clusters). Each meshlet is then reordered for locality with
//! `meshopt_optimizeMeshlet`.

use super::{MeshletLimits, Meshlets};
use glam::Vec3;

/// meshoptimizer's recommended cone weight when cone culling is used.
pub const CONE_WEIGHT: f32 = 0.25;

/// Which of meshoptimizer's builders, with its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    Greedy {
        cone_weight: f32,
    },
    /// Meshlets of at least half the triangle limit unless split by `split_factor`.
    Flex {
        cone_weight: f32,
        split_factor: f32,
    },
    Spatial {
        fill_weight: f32,
    },
}

/// `meshopt_buildMeshletsFlex` as meshoptimizer suggests it for cone culling.
pub const FLEX: Method = Method::Flex { cone_weight: CONE_WEIGHT, split_factor: 2.0 };
/// `meshopt_buildMeshletsSpatial` with meshoptimizer's "safe default" fill weight.
pub const SPATIAL: Method = Method::Spatial { fill_weight: 0.5 };

/// The greedy builder with `cone_weight`.
pub fn build(triangles: &[[u32; 3]], positions: &[Vec3], limits: MeshletLimits, cone_weight: f32) -> Meshlets {
    build_with(triangles, positions, limits, Method::Greedy { cone_weight })
}

/// meshoptimizer needs a triangle limit that is a multiple of 4: limits in between are
/// rounded down (126 → 124), and below 4 triangles the scan builder is used.
pub fn build_with(triangles: &[[u32; 3]], positions: &[Vec3], limits: MeshletLimits, method: Method) -> Meshlets {
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
    let v = limits.max_vertices;
    let min_triangles = (max_triangles / 2 / 4 * 4).max(4);
    let built = match method {
        Method::Greedy { cone_weight } => meshopt::build_meshlets(&indices, &adapter, v, max_triangles, cone_weight),
        Method::Flex { cone_weight, split_factor } => {
            meshopt::build_meshlets_flex(&indices, &adapter, v, min_triangles, max_triangles, cone_weight, split_factor)
        }
        Method::Spatial { fill_weight } => {
            meshopt::build_meshlets_spatial(&indices, &adapter, v, min_triangles, max_triangles, fill_weight)
        }
    };
    for m in built.iter() {
        let mut verts = m.vertices.to_vec();
        let mut tris = m.triangles.to_vec();
        meshopt::optimize_meshlet_level(&mut verts, &mut tris, 0);
        out.push(&verts, &tris);
    }
    out
}
