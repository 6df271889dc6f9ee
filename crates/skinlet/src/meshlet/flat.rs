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
use crate::{Error, Result};

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
    pub fn view<'a>(&'a self, headers: &'a [[u32; 4]]) -> skinlet_runtime::bake_view::MeshletView<'a> {
        let (vertices, triangles, joints) = (&self.vertices[..], &self.triangles[..], &self.joints[..]);
        skinlet_runtime::bake_view::MeshletView { headers, vertices, triangles, joints }
    }
}

/// Size in bytes of [`to_bytes`]'s output.
pub fn byte_len(m: &Meshlets) -> usize {
    HEADER + 16 * m.meshlets.len() + 4 * m.vertices.len() + pad4(m.triangles.len()) + pad4(2 * m.joints.len())
}

fn u32_at(b: &[u8], at: usize) -> Result<u32> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| Error::invalid("meshlet buffer", format!("truncated at byte {at}")))
}

pub fn from_bytes(b: &[u8]) -> Result<Meshlets> {
    let [nm, nv, nt, nj] = [0, 4, 8, 12].map(|o| u32_at(b, o).map(|x| x as usize));
    let (nm, nv, nt, nj) = (nm?, nv?, nt?, nj?);
    let expected = HEADER
        .checked_add(nm.saturating_mul(16))
        .and_then(|x| x.checked_add(nv.saturating_mul(4)))
        .and_then(|x| x.checked_add(pad4(nt)))
        .and_then(|x| x.checked_add(pad4(nj.saturating_mul(2))));
    if expected != Some(b.len()) {
        return Err(Error::invalid(
            "meshlet buffer",
            format!("{} bytes do not match the counts in its header", b.len()),
        ));
    }
    let mut m = Meshlets::default();
    for i in 0..nm {
        let at = HEADER + 16 * i;
        let packed = u32_at(b, at + 12)?;
        let h = Meshlet {
            vertex_offset: u32_at(b, at)?,
            triangle_offset: u32_at(b, at + 4)?,
            joint_offset: u32_at(b, at + 8)?,
            vertex_count: (packed & 0x1ff) as u16,
            triangle_count: (packed >> 9 & 0x3ff) as u16,
            joint_count: (packed >> 19 & 0xf) as u16,
        };
        let ends = [
            (h.vertex_offset as usize + h.vertex_count as usize, nv),
            (h.triangle_offset as usize + 3 * h.triangle_count as usize, nt),
            (h.joint_offset as usize + h.joint_count as usize, nj),
        ];
        if ends.iter().any(|(end, n)| end > n)
            || !h.triangle_offset.is_multiple_of(3)
            || (packed >> 31 == 1) != h.single_joint_set()
        {
            return Err(Error::invalid(
                "meshlet buffer",
                format!("meshlet {i} has ranges outside the buffer or a triangle offset off a triangle"),
            ));
        }
        m.meshlets.push(h);
    }
    let vbase = HEADER + 16 * nm;
    m.vertices = (0..nv).map(|i| u32_at(b, vbase + 4 * i)).collect::<Result<_>>()?;
    let tbase = vbase + 4 * nv;
    m.triangles = b[tbase..tbase + nt].to_vec();
    let jbase = tbase + pad4(nt);
    m.joints = (0..nj).map(|i| u16::from_le_bytes([b[jbase + 2 * i], b[jbase + 2 * i + 1]])).collect();
    Ok(m)
}
