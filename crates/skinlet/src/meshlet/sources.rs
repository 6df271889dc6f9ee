//! Where each meshlet triangle came from: its triangle in the glTF primitive of its part, and
//! which of that triangle's corners is its first. Welding ([`crate::weld`]) merges vertices
//! that differ only in attributes the bounds do not read (UVs, normals, tangents, colours),
//! and the meshlet builders reorder triangles and may rotate their corners; a renderer that
//! draws the meshlets with the source's attributes (its UV seams and hard edges intact) looks
//! each corner up here: corner `k` of the triangle at meshlet triangle byte `3·i` is corner
//! `(k + rotation) % 3` of the part's source triangle `index`, where
//! `sources[i] = index | rotation << 30`.
//!
//! Guarantee (checked here, and by the tests on every builder): each meshlet triangle is
//! matched to a distinct source triangle of its own part whose welded corners are its own, in
//! its winding.

use crate::character::Character;
use crate::meshlet::{Meshlets, PreparedMesh};
use crate::{Error, Result};
use std::collections::HashMap;

/// Bits 0–29 of a source code: the triangle's index in its part's primitive.
pub const SOURCE_INDEX_MASK: u32 = (1 << 30) - 1;

/// The rotation that brings a triangle's smallest vertex first, and the rotated triangle
/// (the same triangle with the same winding reads the same).
fn canonical(t: [u32; 3]) -> (u32, [u32; 3]) {
    let r = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
    (r as u32, [t[r], t[(r + 1) % 3], t[(r + 2) % 3]])
}

/// One source code per triangle byte triple of `meshlets` (entries of bytes no meshlet uses
/// stay `u32::MAX`): `character` is what `prepared` was prepared from
/// ([`crate::bake::prepare_character`]), `part_meshlets[p]` part `p`'s meshlets. Errors (an
/// internal inconsistency, never the input's fault) when a meshlet triangle has no unused
/// source triangle left.
pub fn source_triangles(
    character: &Character,
    prepared: &PreparedMesh,
    meshlets: &Meshlets,
    part_meshlets: &[std::ops::Range<u32>],
) -> Result<Vec<u32>> {
    let mut out = vec![u32::MAX; meshlets.triangles.len() / 3];
    for (p, (part, range)) in character.parts.iter().zip(part_meshlets).enumerate() {
        let first = part.triangles.start as usize;
        let own = &character.mesh.triangles[first..part.triangles.end as usize];
        if own.len() > SOURCE_INDEX_MASK as usize {
            return Err(Error::invalid(format!("part {p}"), format!("{} triangles (at most 2^30)", own.len())));
        }
        // Canonical welded triangle → its source triangles (index, rotation), last first.
        let mut by_welded: HashMap<[u32; 3], Vec<(u32, u32)>> = HashMap::new();
        for (i, t) in own.iter().enumerate().rev() {
            let (r, key) = canonical(t.map(|v| prepared.remap[v as usize]));
            by_welded.entry(key).or_default().push((i as u32, r));
        }
        for m in &meshlets.meshlets[range.start as usize..range.end as usize] {
            for (t, tri) in meshlets.mesh_triangles(m).enumerate() {
                let (r, key) = canonical(tri);
                let (index, rs) = by_welded.get_mut(&key).and_then(Vec::pop).ok_or_else(|| {
                    Error::invalid(format!("part {p}"), format!("meshlet triangle {tri:?} matches no source triangle"))
                })?;
                out[m.triangle_offset as usize / 3 + t] = index | ((rs + 3 - r) % 3) << 30;
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_keeps_winding() {
        assert_eq!(canonical([5, 2, 9]), (1, [2, 9, 5]));
        assert_eq!(canonical([2, 9, 5]), (0, [2, 9, 5]));
        assert_ne!(canonical([2, 5, 9]).1, canonical([2, 9, 5]).1);
    }
}
