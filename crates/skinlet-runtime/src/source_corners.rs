//! Each meshlet corner's source vertex: what a renderer needs to draw a bake's meshlets with
//! the glTF primitives' own vertex attributes (UVs, normals, tangents, colours), which the
//! baker's welding merged away. The bake's `SRCT` section names each meshlet triangle's source
//! triangle and corner rotation (`docs/FORMAT.md`); with each part's source index buffer (the
//! engine's own mesh of that glTF primitive) this gives, per corner id `3·i + k` (corner `k` of
//! the triangle at MLET triangle byte `3·i`, as `skinlet_gpu`'s triangle lists name corners),
//! the bake vertex its position is skinned from and the source vertex its attributes come from.
//!
//! Guarantee: every corner's source vertex exists in its part's primitive, and where the
//! caller gives the primitive's positions, they are bit-identical to the bake vertex's (else
//! the bake is not of this file: an error that names the part).

use crate::bake_view::BakeView;
use crate::{Error, Result};

/// One part's source primitive, as the engine loaded it: its triangle-list indices (`None`:
/// not indexed, triangle `t` is vertices `3t..3t + 3`), its vertex count, and optionally its
/// positions (checked against the bake's).
#[derive(Clone, Copy, Debug)]
pub struct PartSource<'a> {
    pub indices: Option<&'a [u32]>,
    pub vertices: u32,
    pub positions: Option<&'a [[f32; 3]]>,
}

/// A corner: the bake vertex its position is skinned from, the vertex of its part's source
/// primitive its attributes come from, and the part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Corner {
    pub vertex: u32,
    pub source: u32,
    pub part: u32,
}

/// Per corner id (`3·i + k` up to MLET's triangle bytes; bytes no meshlet uses stay
/// `u32::MAX` throughout), its [`Corner`]. `sources[p]` is part `p`'s source primitive, in the
/// bake's part order. Errors when the bake has no `SRCT` section, the part count differs, a
/// source triangle or vertex is past its primitive, or a given position differs from the
/// bake's.
pub fn source_corners(view: &BakeView, sources: &[PartSource]) -> Result<Vec<Corner>> {
    let location = "source corners";
    let codes = view
        .sources()
        .ok_or_else(|| Error::invalid(location, "the bake has no SRCT section (bake it again with this skinlet)"))?;
    let parts = view.parts();
    if sources.len() != parts.len() {
        return Err(Error::invalid(location, format!("{} source primitives for {} parts", sources.len(), parts.len())));
    }
    let meshlets = view.meshlets();
    let positions = view.vertices().positions;
    let mut out = vec![Corner { vertex: u32::MAX, source: u32::MAX, part: u32::MAX }; 3 * codes.len()];
    for (p, (part, src)) in parts.iter().zip(sources).enumerate() {
        let name = || format!("part {p} (node {}, mesh {}, primitive {})", part.node, part.mesh, part.primitive);
        let triangles = src.indices.map_or(src.vertices as usize, <[u32]>::len) / 3;
        if src.positions.is_some_and(|x| x.len() != src.vertices as usize) {
            return Err(Error::invalid(name(), format!("positions for other than its {} vertices", src.vertices)));
        }
        for m in part.meshlets[0] as usize..part.meshlets[1] as usize {
            let (first, count) = (meshlets.headers[m][1] as usize, meshlets.counts(m).1);
            let local = meshlets.vertices_of(m);
            for t in 0..count {
                let i = first / 3 + t;
                let (index, rotation) = ((codes[i] & ((1 << 30) - 1)) as usize, (codes[i] >> 30) as usize);
                if index >= triangles {
                    return Err(Error::invalid(
                        name(),
                        format!("meshlet triangle {i} comes from triangle {index} of a primitive of {triangles}"),
                    ));
                }
                for k in 0..3 {
                    let vertex = local[meshlets.triangles[first + 3 * t + k] as usize];
                    let c = 3 * index + (k + rotation) % 3;
                    let source = src.indices.map_or(c as u32, |x| x[c]);
                    if source >= src.vertices {
                        return Err(Error::invalid(name(), format!("index {c} is {source}, past {}", src.vertices)));
                    }
                    if let Some(x) = src.positions
                        && x[source as usize].map(f32::to_bits)
                            != positions[vertex as usize].to_array().map(f32::to_bits)
                    {
                        return Err(Error::invalid(
                            name(),
                            format!(
                                "vertex {source} is at {:?}, the bake's corner at {}: the bake is not of this file",
                                x[source as usize], positions[vertex as usize]
                            ),
                        ));
                    }
                    out[3 * i + k] = Corner { vertex, source, part: p as u32 };
                }
            }
        }
    }
    Ok(out)
}
