//! The flat, GPU-uploadable form of [`Meshlets`]: one little-endian byte buffer that can be
//! bound as a storage buffer as is, and its inverse [`from_bytes`].
//!
//! Layout (all offsets in bytes from the start, every section 4-byte aligned):
//!
//! | offset | size | content |
//! |---|---|---|
//! | 0 | 4 | `M`, meshlet count (u32) |
//! | 4 | 4 | `V`, vertex index count (u32) |
//! | 8 | 4 | `T`, triangle byte count (u32, 3 per triangle) |
//! | 12 | 4 | `J`, joint count (u32) |
//! | 16 | 16·M | meshlet headers, 4 u32 each: `vertex_offset`, `triangle_offset` (in bytes of the triangle section), `joint_offset`, `packed` |
//! | 16 + 16·M | 4·V | vertex indices (u32) into the mesh's vertex buffer |
//! | … | T, padded to 4 | local triangle indices (u8 triples) |
//! | … | 2·J, padded to 4 | joint numbers (u16) of single-joint-set meshlets |
//!
//! `packed` = `vertex_count` (bits 0–8) | `triangle_count` << 9 (bits 9–18) |
//! `joint_count` << 19 (bits 19–22) | bit 31 set when all vertices share one joint set (the
//! thesis' "optimal meshlet" flag, which selects the slim vertex format in the shader).

use super::{Meshlet, Meshlets};
use crate::Result;
use skinlet_runtime::bake_view::MeshletView;

const HEADER: usize = 16;

fn pad4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

pub fn to_bytes(m: &Meshlets) -> Vec<u8> {
    let mut out = Vec::with_capacity(byte_len(m));
    for n in [m.meshlets.len(), m.vertices.len(), m.triangles.len(), m.joints.len()] {
        out.extend_from_slice(&(n as u32).to_le_bytes());
    }
    for x in m.headers().iter().flatten() {
        out.extend_from_slice(&x.to_le_bytes());
    }
    m.vertices.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
    out.extend_from_slice(&m.triangles);
    out.resize(pad4(out.len()), 0);
    m.joints.iter().for_each(|j| out.extend_from_slice(&j.to_le_bytes()));
    out.resize(pad4(out.len()), 0);
    out
}

impl Meshlets {
    /// The meshlet headers as the layout stores them: `vertex_offset`, `triangle_offset`,
    /// `joint_offset`, `packed`.
    pub fn headers(&self) -> Vec<[u32; 4]> {
        (self.meshlets.iter())
            .map(|h| {
                let packed = h.vertex_count as u32
                    | (h.triangle_count as u32) << 9
                    | (h.joint_count as u32) << 19
                    | (h.single_joint_set() as u32) << 31;
                [h.vertex_offset, h.triangle_offset, h.joint_offset, packed]
            })
            .collect()
    }

    /// The meshlets as the runtime's view of a bake's `MLET` holds them, over `headers`
    /// ([`Self::headers`]): what a GPU upload reads.
    pub fn view<'a>(&'a self, headers: &'a [[u32; 4]]) -> MeshletView<'a> {
        let (vertices, triangles, joints) = (&self.vertices[..], &self.triangles[..], &self.joints[..]);
        MeshletView { headers, vertices, triangles, joints }
    }
}

/// Size in bytes of [`to_bytes`]'s output.
pub fn byte_len(m: &Meshlets) -> usize {
    HEADER + 16 * m.meshlets.len() + 4 * m.vertices.len() + pad4(m.triangles.len()) + pad4(2 * m.joints.len())
}

/// Parses the layout through the runtime's view of it ([`MeshletView::new`] and
/// [`MeshletView::check`] against the largest limits and any vertex count).
pub fn from_bytes(b: &[u8]) -> Result<Meshlets> {
    let words = crate::bake::aligned_words(b);
    let view = MeshletView::new(&bytemuck::cast_slice::<u32, u8>(&words)[..b.len()])?;
    view.check(usize::MAX, [256, 512])?;
    Ok(Meshlets::from_view(&view))
}

impl Meshlets {
    /// The meshlets of a checked view ([`MeshletView::check`]), copied.
    pub fn from_view(v: &MeshletView) -> Meshlets {
        let meshlets = (v.headers.iter())
            .map(|h| Meshlet {
                vertex_offset: h[0],
                triangle_offset: h[1],
                joint_offset: h[2],
                vertex_count: (h[3] & 0x1ff) as u16,
                triangle_count: (h[3] >> 9 & 0x3ff) as u16,
                joint_count: (h[3] >> 19 & 0xf) as u16,
            })
            .collect();
        Meshlets { meshlets, vertices: v.vertices.to_vec(), triangles: v.triangles.to_vec(), joints: v.joints.to_vec() }
    }
}
