//! Common-influences builder (thesis section 3.1.1, listing 4.2 and A.2): triangles whose
//! three vertices have the same set of influencing joints are grouped per joint set; each
//! group large enough is packed on its own, in index order, so its meshlets carry the joint
//! IDs once and their vertices can drop them ("slim" vertices). Triangles of mixed sets and
//! groups too small to fill half a meshlet go to a remainder packed the same way.

use super::{MeshletLimits, Meshlets, Packer, joint_set};
use crate::model::SkinnedMesh;
use std::collections::BTreeMap;

pub fn build(mesh: &SkinnedMesh, limits: MeshletLimits) -> Meshlets {
    let Some(inf) = &mesh.influences else {
        return super::scan::build(&mesh.triangles, mesh.positions.len(), limits);
    };
    // Triangle numbers grouped by joint set, in a deterministic order; `None` is the remainder.
    let mut groups: BTreeMap<Option<Vec<u16>>, Vec<usize>> = BTreeMap::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        let s = joint_set(inf, t[0] as usize);
        let same = t[1..].iter().all(|&v| joint_set(inf, v as usize) == s);
        groups.entry(same.then_some(s)).or_default().push(i);
    }
    // The thesis' minimum group size: smaller groups would make tiny meshlets.
    let min = limits.max_triangles / 2;
    let mut remainder = groups.remove(&None).unwrap_or_default();
    let mut out = Meshlets::default();
    let mut packer = Packer::new(mesh.positions.len(), limits);
    for tris in groups.into_values() {
        if tris.len() < min {
            remainder.extend(tris);
            continue;
        }
        tris.iter().for_each(|&t| packer.add(mesh.triangles[t], &mut out));
        packer.flush(&mut out);
    }
    // The remainder keeps the (vertex-cache optimized) order of the mesh.
    remainder.sort_unstable();
    remainder.iter().for_each(|&t| packer.add(mesh.triangles[t], &mut out));
    packer.flush(&mut out);
    out
}
