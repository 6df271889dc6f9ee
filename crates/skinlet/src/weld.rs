//! Vertex welding: merges vertices whose position and skin data (joints and weights) are
//! bit-identical, so that UV or normal seams no longer split the surface. The welded
//! vertex keeps the attributes of the first vertex of its group; vertices are numbered by
//! first occurrence, so the output is deterministic and triangle windings are unchanged.

use crate::model::{Influences, SkinnedMesh};

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
    let n = mesh.positions.len();
    let stride = mesh.influences.as_ref().map_or(0, |i| i.stride);
    let width = 3 + 2 * stride;
    let mut keys = Vec::with_capacity(n * width);
    for v in 0..n {
        keys.extend(mesh.positions[v].to_array().map(f32::to_bits));
        if let Some(inf) = &mesh.influences {
            keys.extend(inf.joints[v * stride..(v + 1) * stride].iter().map(|&j| j as u32));
            keys.extend(inf.weights[v * stride..(v + 1) * stride].iter().map(|w| w.to_bits()));
        }
    }
    let key = |v: usize| &keys[v * width..(v + 1) * width];
    let mut order: Vec<u32> = (0..n as u32).collect();
    order.sort_by(|&a, &b| key(a as usize).cmp(key(b as usize)).then(a.cmp(&b)));
    // Representative (smallest index) of each vertex's group.
    let mut rep = vec![0u32; n];
    let mut g = 0;
    while g < n {
        let first = order[g];
        let mut e = g;
        while e < n && key(order[e] as usize) == key(first as usize) {
            rep[order[e] as usize] = first;
            e += 1;
        }
        g = e;
    }
    let mut remap = vec![u32::MAX; n];
    let mut kept = Vec::new();
    for v in 0..n {
        let r = rep[v] as usize;
        if remap[r] == u32::MAX {
            remap[r] = kept.len() as u32;
            kept.push(r);
        }
        remap[v] = remap[r];
    }
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
    };
    let report = WeldReport { input_vertices: n, output_vertices: kept.len() };
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
        };
        let (w, remap, r) = weld(&mesh);
        assert_eq!(remap, vec![0, 0, 1]);
        assert_eq!(r.merged(), 1);
        assert_eq!(w.positions.len(), 2);
        assert_eq!(w.normals, vec![Vec3::X, Vec3::Z]);
        assert_eq!(w.triangles, vec![[0, 0, 1]]);
        assert_eq!(w.influences.unwrap().joints[4], 1);
    }
}
