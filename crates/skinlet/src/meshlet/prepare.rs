//! Preparation before meshlet building (thesis section 3.2): weld vertices equal in
//! position and skin data ([`crate::weld`]; the thesis' welding cut 854 meshlets to 563),
//! drop triangles that repeat a vertex (they draw nothing), and order triangles for the
//! post-transform vertex cache with meshoptimizer (Forsyth-style `optimizeVertexCache`).
//! Each vertex's influences are first sorted by joint ([`crate::model::Influences::sort_by_joint`]):
//! vertices that differ only in slot order then weld, and the slim vertices of
//! common-influences meshlets (weights in the meshlet's joint order) sum like full ones.
//!
//! A character's parts ([`crate::character`]) are prepared apart: no vertex is welded
//! across two parts and each part's triangles stay one contiguous run, so the meshlet
//! builders never mix two primitives.

use crate::model::SkinnedMesh;
use crate::weld::{WeldReport, weld_groups};
use crate::{Error, Result};
use std::ops::Range;

/// Where one part's vertices and triangles lie in a mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartRange {
    pub vertices: Range<u32>,
    pub triangles: Range<u32>,
}

#[derive(Clone, Debug)]
pub struct PreparedMesh {
    pub mesh: SkinnedMesh,
    /// Map from input vertex to prepared vertex.
    pub remap: Vec<u32>,
    pub weld: WeldReport,
    /// Input triangles dropped because they repeat a vertex.
    pub dropped_triangles: usize,
    /// The parts in the prepared mesh, in input order (one part for [`prepare`]).
    pub parts: Vec<PartRange>,
}

/// Prepares a mesh as one part; errors name a triangle that uses a vertex past the mesh.
pub fn prepare(mesh: &SkinnedMesh) -> Result<PreparedMesh> {
    let whole = PartRange { vertices: 0..mesh.positions.len() as u32, triangles: 0..mesh.triangles.len() as u32 };
    prepare_parts(mesh, &[whole])
}

/// Prepares a mesh whose parts are `parts`: consecutive vertex and triangle ranges that
/// cover the mesh, each part's triangles using only its own vertices.
pub fn prepare_parts(mesh: &SkinnedMesh, parts: &[PartRange]) -> Result<PreparedMesh> {
    check_parts(mesh, parts)?;
    let mut sorted = mesh.clone();
    if let Some(inf) = &mut sorted.influences {
        inf.sort_by_joint();
    }
    let mut group = vec![0u32; mesh.positions.len()];
    for (k, p) in parts.iter().enumerate() {
        group[p.vertices.start as usize..p.vertices.end as usize].fill(k as u32);
    }
    let (mut welded, remap, weld) = weld_groups(&sorted, &group);
    // Welded vertices keep their part's order: part k's vertices are one run.
    let mut out_parts = Vec::with_capacity(parts.len());
    let mut triangles = Vec::with_capacity(welded.triangles.len());
    let mut first_vertex = 0u32;
    let mut dropped_triangles = 0;
    for p in parts {
        let own = &remap[p.vertices.start as usize..p.vertices.end as usize];
        let end_vertex = own.iter().max().map_or(first_vertex, |&m| m + 1);
        let mut flat: Vec<u32> = Vec::with_capacity(3 * p.triangles.len());
        for t in &welded.triangles[p.triangles.start as usize..p.triangles.end as usize] {
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                flat.extend(t.iter().map(|i| i - first_vertex));
            } else {
                dropped_triangles += 1;
            }
        }
        let ordered = meshopt::optimize_vertex_cache(&flat, (end_vertex - first_vertex) as usize);
        let start = triangles.len() as u32;
        triangles.extend(ordered.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|i| i + first_vertex)));
        out_parts.push(PartRange { vertices: first_vertex..end_vertex, triangles: start..triangles.len() as u32 });
        first_vertex = end_vertex;
    }
    welded.triangles = triangles;
    Ok(PreparedMesh { mesh: welded, remap, weld, dropped_triangles, parts: out_parts })
}

fn check_parts(mesh: &SkinnedMesh, parts: &[PartRange]) -> Result<()> {
    let (mut v, mut t) = (0u32, 0u32);
    for (k, p) in parts.iter().enumerate() {
        if p.vertices.start != v || p.triangles.start != t || p.vertices.end < v || p.triangles.end < t {
            return Err(Error::invalid(format!("part {k}"), "parts must be consecutive vertex and triangle ranges"));
        }
        (v, t) = (p.vertices.end, p.triangles.end);
        let tris = mesh.triangles.get(p.triangles.start as usize..t as usize).unwrap_or(&[]);
        if tris.len() != p.triangles.len() {
            return Err(Error::invalid(format!("part {k}"), "triangle range past the mesh's triangles"));
        }
        if let Some(i) = tris.iter().flatten().find(|&&i| !p.vertices.contains(&i)) {
            return Err(Error::invalid(format!("part {k}"), format!("a triangle uses vertex {i}, outside the part")));
        }
    }
    if v as usize != mesh.positions.len() || t as usize != mesh.triangles.len() {
        return Err(Error::invalid("parts", "the parts do not cover the whole mesh"));
    }
    Ok(())
}
