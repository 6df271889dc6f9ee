//! Comparison metrics of a meshlet build: counts and fill, vertex re-use, how rigidly the
//! meshlets are skinned (one shared joint set; one dominant joint carrying ≥ 0.9 of the
//! weight), memory with fat and slim vertices (thesis fig. 4.4), and meshoptimizer's static
//! cone-culling rate over six axis views in the rest pose.

use super::{Meshlets, flat};
use crate::model::SkinnedMesh;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshletStats {
    pub meshlets: usize,
    pub avg_vertices: f64,
    pub avg_triangles: f64,
    /// Meshlet vertex references ÷ unique vertices (1.0: no vertex is in two meshlets).
    pub vertex_refs_ratio: f64,
    pub single_joint_set_pct: f64,
    /// Meshlets whose principal joint carries ≥ 0.9 of their vertices' total weight.
    pub dominant_joint_pct: f64,
    /// Meshlet data plus every vertex in the fat format.
    pub bytes_fat: usize,
    /// Meshlet data plus vertices in the slim format where only single-joint-set meshlets use them.
    pub bytes: usize,
    /// Share of (meshlet, view) pairs backface-culled by meshoptimizer's cone from 6 axis views.
    pub cone_cull_pct: f64,
}

/// Fat vertex: position, normal (f32×3 each), joints (u16) and weights (f32) per slot.
pub fn fat_vertex_bytes(stride: usize) -> usize {
    24 + 6 * stride
}

/// Slim vertex: no joint IDs (the meshlet holds them).
pub fn slim_vertex_bytes(stride: usize) -> usize {
    24 + 4 * stride
}

/// Principal joint of a set of vertices (largest summed weight) and its share of the weight.
pub fn principal_joint(mesh: &SkinnedMesh, vertices: &[u32]) -> Option<(u16, f32)> {
    let inf = mesh.influences.as_ref()?;
    let mut acc: Vec<(u16, f32)> = Vec::new();
    for &v in vertices {
        for (j, w) in inf.of(v as usize) {
            match acc.iter_mut().find(|a| a.0 == j) {
                Some(a) => a.1 += w,
                None => acc.push((j, w)),
            }
        }
    }
    let total: f32 = acc.iter().map(|a| a.1).sum();
    acc.into_iter()
        .fold(None, |b: Option<(u16, f32)>, (j, w)| match b {
            Some((bj, bw)) if bw > w || (bw == w && bj < j) => Some((bj, bw)),
            _ => Some((j, w)),
        })
        .map(|(j, w)| (j, w / total))
}

pub fn compute(mesh: &SkinnedMesh, m: &Meshlets) -> MeshletStats {
    let n = m.len().max(1) as f64;
    let vertex_refs = m.vertices.len();
    let mut used = vec![0u8; mesh.positions.len()]; // bit 0: in a mixed meshlet, bit 1: used
    for h in &m.meshlets {
        for &v in m.vertices_of(h) {
            used[v as usize] |= 2 | (!h.single_joint_set()) as u8;
        }
    }
    let unique = used.iter().filter(|&&u| u & 2 != 0).count();
    let stride = mesh.influences.as_ref().map_or(0, |i| i.stride);
    let slim = used.iter().filter(|&&u| u == 2).count();
    let meshlet_bytes = flat::byte_len(m);
    let dominant = m
        .meshlets
        .iter()
        .filter(|h| principal_joint(mesh, m.vertices_of(h)).is_some_and(|(_, share)| share >= 0.9))
        .count();
    MeshletStats {
        meshlets: m.len(),
        avg_vertices: vertex_refs as f64 / n,
        avg_triangles: m.triangles.len() as f64 / 3.0 / n,
        vertex_refs_ratio: vertex_refs as f64 / unique.max(1) as f64,
        single_joint_set_pct: 100.0 * m.meshlets.iter().filter(|h| h.single_joint_set()).count() as f64 / n,
        dominant_joint_pct: 100.0 * dominant as f64 / n,
        bytes_fat: meshlet_bytes + unique * fat_vertex_bytes(stride),
        bytes: meshlet_bytes + (unique - slim) * fat_vertex_bytes(stride) + slim * slim_vertex_bytes(stride),
        cone_cull_pct: cone_cull_pct(&mesh.positions, m),
    }
}

/// meshoptimizer's estimate: per meshlet `meshopt_computeMeshletBounds`, culled from an
/// orthographic view along `d` when `dot(d, cone_axis) >= cone_cutoff`; six axis views.
pub fn cone_cull_pct(positions: &[Vec3], m: &Meshlets) -> f64 {
    if m.is_empty() {
        return 0.0;
    }
    let bytes = meshopt::typed_to_bytes(positions);
    let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).expect("Vec3 positions form a valid vertex stream");
    let views = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];
    let mut culled = 0;
    for h in &m.meshlets {
        let b = meshopt::compute_meshlet_bounds(
            meshopt::Meshlet { vertices: m.vertices_of(h), triangles: m.triangles_of(h) },
            &adapter,
        );
        let axis = Vec3::from(b.cone_axis);
        culled += views.iter().filter(|d| d.dot(axis) >= b.cone_cutoff).count();
    }
    100.0 * culled as f64 / (6 * m.len()) as f64
}

/// Sampled preview of how tight animated bounds can be (not conservative; the bounds module
/// computes the real ones): per meshlet, the largest distance of its skinned vertices from
/// the rest-pose center, measured in the principal joint's bind space, over the given poses
/// (skinning matrices per pose), divided by the rest radius. Returns the mean over meshlets
/// (1.0: every meshlet moves rigidly with its principal joint).
pub fn animated_radius_ratio(mesh: &SkinnedMesh, m: &Meshlets, poses: &[Vec<glam::Affine3A>]) -> f64 {
    let Some(inf) = &mesh.influences else { return 1.0 };
    if m.is_empty() || poses.is_empty() {
        return 1.0;
    }
    let inverses: Vec<Vec<glam::Affine3A>> = poses.iter().map(|p| p.iter().map(|a| a.inverse()).collect()).collect();
    let mut sum = 0.0;
    for h in &m.meshlets {
        let verts = m.vertices_of(h);
        let Some((j, _)) = principal_joint(mesh, verts) else { continue };
        let (lo, hi) = verts.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, u), &v| {
            (l.min(mesh.positions[v as usize]), u.max(mesh.positions[v as usize]))
        });
        let c = (lo + hi) / 2.0;
        let rest = verts.iter().map(|&v| mesh.positions[v as usize].distance(c)).fold(0f32, f32::max).max(1e-12);
        let mut swept = rest;
        for (pose, inv) in poses.iter().zip(&inverses) {
            for &v in verts {
                let blended = crate::skinning::blend_matrix(inf, v as usize, pose);
                let q = inv[j as usize].transform_point3(blended.transform_point3(mesh.positions[v as usize]));
                swept = swept.max(q.distance(c));
            }
        }
        sum += (swept / rest) as f64;
    }
    sum / m.len() as f64
}
