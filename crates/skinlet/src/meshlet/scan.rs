//! Scan builder: packs triangles into meshlets strictly in index-buffer order, starting a
//! new meshlet when the next triangle would exceed a limit (thesis listing 4.1 / A.1).
//! Fast and simple; its quality depends entirely on the input order, which is why meshes
//! are vertex-cache ordered first ([`super::prepare()`]).

use super::{MeshletLimits, Meshlets, Packer};

pub fn build(triangles: &[[u32; 3]], vertex_count: usize, limits: MeshletLimits) -> Meshlets {
    let mut out = Meshlets::default();
    let mut packer = Packer::new(vertex_count, limits);
    for &t in triangles {
        packer.add(t, &mut out);
    }
    packer.flush(&mut out);
    out
}
