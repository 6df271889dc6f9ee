//! Preparation before meshlet building (thesis section 3.2): weld vertices equal in
//! position and skin data ([`crate::weld`]; the thesis' welding cut 854 meshlets to 563),
//! drop triangles that repeat a vertex (they draw nothing), and order triangles for the
//! post-transform vertex cache with meshoptimizer (Forsyth-style `optimizeVertexCache`).
//! Each vertex's influences are first sorted by joint ([`crate::model::Influences::sort_by_joint`]):
//! vertices that differ only in slot order then weld, and the slim vertices of
//! common-influences meshlets (weights in the meshlet's joint order) sum like full ones.

use crate::model::SkinnedMesh;
use crate::weld::{WeldReport, weld};

#[derive(Clone, Debug)]
pub struct PreparedMesh {
    pub mesh: SkinnedMesh,
    /// Map from input vertex to prepared vertex.
    pub remap: Vec<u32>,
    pub weld: WeldReport,
    /// Input triangles dropped because they repeat a vertex.
    pub dropped_triangles: usize,
}

pub fn prepare(mesh: &SkinnedMesh) -> PreparedMesh {
    let mut sorted = mesh.clone();
    if let Some(inf) = &mut sorted.influences {
        inf.sort_by_joint();
    }
    let (mut welded, remap, weld) = weld(&sorted);
    let before = welded.triangles.len();
    welded.triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    let dropped_triangles = before - welded.triangles.len();
    let flat: Vec<u32> = welded.triangles.iter().flatten().copied().collect();
    let ordered = meshopt::optimize_vertex_cache(&flat, welded.positions.len());
    welded.triangles = ordered.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    PreparedMesh { mesh: welded, remap, weld, dropped_triangles }
}
