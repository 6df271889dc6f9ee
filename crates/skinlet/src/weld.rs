//! Vertex welding: merges vertices whose position, skin data (joints and weights) and morph
//! target deltas are bit-identical, so that UV or normal seams no longer split the surface. The remap is
//! meshoptimizer's (`meshopt_generateVertexRemapMulti`, vertices numbered by first
//! occurrence); the welded vertex keeps the attributes of the first vertex of its group, so
//! the output is deterministic and triangle windings are unchanged.

use crate::model::{Influences, SkinnedMesh};
use meshopt::VertexStream;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WeldReport {
    pub input_vertices: usize,
    pub output_vertices: usize,
}

impl WeldReport {
    pub fn merged(&self) -> usize {
        self.input_vertices - self.output_vertices
    }
}

/// Returns the welded mesh and the map from old to new vertex index.
pub fn weld(mesh: &SkinnedMesh) -> (SkinnedMesh, Vec<u32>, WeldReport) {
    weld_groups(mesh, &vec![0; mesh.positions.len()])
}

/// [`weld`], merging only vertices of the same group (`group[v]`, one per vertex): the
/// parts of a character stay apart. Groups that are contiguous runs of vertices stay
/// contiguous runs, in the same order (vertices are numbered by first occurrence).
pub(crate) fn weld_groups(mesh: &SkinnedMesh, group: &[u32]) -> (SkinnedMesh, Vec<u32>, WeldReport) {
    let n = mesh.positions.len();
    assert_eq!(group.len(), n, "one group per vertex");
    let stride = mesh.influences.as_ref().map_or(0, |i| i.stride);
    // Skin data padded to 8 slots, so one fixed-size stream each compares every slot.
    let (joints, weights): (Vec<[u16; 8]>, Vec<[f32; 8]>) = match &mesh.influences {
        Some(inf) => (0..n)
            .map(|v| {
                let (mut j, mut w) = ([0u16; 8], [0f32; 8]);
                j[..stride].copy_from_slice(&inf.joints[v * stride..(v + 1) * stride]);
                w[..stride].copy_from_slice(&inf.weights[v * stride..(v + 1) * stride]);
                (j, w)
            })
            .unzip(),
        None => (vec![[0; 8]; n], vec![[0.0; 8]; n]),
    };
    // Morph deltas differ in length per vertex: each distinct list gets a number.
    let mut lists: std::collections::HashMap<Vec<u32>, u32> = std::collections::HashMap::new();
    lists.insert(Vec::new(), 0);
    let morph_class: Vec<u32> = (0..n)
        .map(|v| {
            if mesh.morphs.of(v).is_empty() {
                return 0;
            }
            let key: Vec<u32> = (mesh.morphs.of(v).iter())
                .flat_map(|d| {
                    [d.weight]
                        .into_iter()
                        .chain(d.position.to_array().into_iter().chain(d.normal.to_array()).map(f32::to_bits))
                })
                .collect();
            let next = lists.len() as u32;
            *lists.entry(key).or_insert(next)
        })
        .collect();
    let streams = [
        VertexStream::new(mesh.positions.as_ptr()),
        VertexStream::new(joints.as_ptr()),
        VertexStream::new(weights.as_ptr()),
        VertexStream::new(group.as_ptr()),
        VertexStream::new(morph_class.as_ptr()),
    ];
    let (count, remap) = meshopt::generate_vertex_remap_multi(n, &streams, None);
    let mut first = vec![u32::MAX; count];
    for (v, &r) in remap.iter().enumerate() {
        if first[r as usize] == u32::MAX {
            first[r as usize] = v as u32;
        }
    }
    let kept: Vec<usize> = first.iter().map(|&v| v as usize).collect();
    let influences = mesh.influences.as_ref().map(|inf| Influences {
        stride,
        joints: kept.iter().flat_map(|&v| inf.joints[v * stride..(v + 1) * stride].iter().copied()).collect(),
        weights: kept.iter().flat_map(|&v| inf.weights[v * stride..(v + 1) * stride].iter().copied()).collect(),
    });
    let welded = SkinnedMesh {
        positions: kept.iter().map(|&v| mesh.positions[v]).collect(),
        normals: if mesh.normals.is_empty() { Vec::new() } else { kept.iter().map(|&v| mesh.normals[v]).collect() },
        triangles: mesh.triangles.iter().map(|t| t.map(|i| remap[i as usize])).collect(),
        influences,
        morphs: mesh.morphs.select(kept.iter().copied()),
    };
    let report = WeldReport { input_vertices: n, output_vertices: count };
    (welded, remap, report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn merges_only_equal_position_and_skin() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        let inf = Influences {
            stride: 4,
            joints: vec![0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0],
            weights: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        };
        let mesh = SkinnedMesh {
            positions: vec![p, p, p],
            normals: vec![Vec3::X, Vec3::Y, Vec3::Z],
            triangles: vec![[0, 1, 2]],
            influences: Some(inf),
            ..SkinnedMesh::default()
        };
        let (w, remap, r) = weld(&mesh);
        assert_eq!(remap, vec![0, 0, 1]);
        assert_eq!(r.merged(), 1);
        assert_eq!(w.positions.len(), 2);
        assert_eq!(w.normals, vec![Vec3::X, Vec3::Z]);
        assert_eq!(w.triangles, vec![[0, 0, 1]]);
        assert_eq!(w.influences.unwrap().joints[4], 1);
    }

    #[test]
    fn vertices_with_other_morph_deltas_stay_apart() {
        use crate::model::{MorphDelta, MorphWeight, Morphs};
        let p = Vec3::new(1.0, 2.0, 3.0);
        let inf = Influences { stride: 4, joints: vec![0; 16], weights: [1.0, 0.0, 0.0, 0.0].repeat(4) };
        let d = |x: f32| MorphDelta { weight: 0, position: Vec3::X * x, normal: Vec3::ZERO };
        // Vertices 0 and 1 move alike, 2 otherwise, 3 not at all.
        let morphs = Morphs {
            weights: vec![MorphWeight { node: 0, target: 0, default: 0.0 }],
            offsets: vec![0, 1, 2, 3, 3],
            deltas: vec![d(1.0), d(1.0), d(2.0)],
        };
        let mesh = SkinnedMesh {
            positions: vec![p; 4],
            triangles: vec![[0, 1, 2], [1, 2, 3]],
            influences: Some(inf),
            morphs,
            ..SkinnedMesh::default()
        };
        let (w, remap, _) = weld(&mesh);
        assert_eq!(remap, vec![0, 0, 1, 2]);
        assert_eq!(w.morphs.offsets, vec![0, 1, 2, 2]);
        assert_eq!(w.morphs.deltas, vec![d(1.0), d(2.0)]);
    }
}
