//! Baseline: meshoptimizer meshlets used as contour patches (Tsiapkolis & Bénard 2024,
//! section 4.3 compare against them with 16-face meshlets). Each quad joins the meshlet of
//! its first face.
//!
//! The cone must bound the normals of *every* face adjacent to the patch's edges, including
//! faces in neighbouring meshlets, and meshoptimizer's `cone_cutoff` is the sine of the
//! normal cone's half-angle (α = asin(cutoff)), not its cosine: a published baseline got
//! both wrong and culled real contours. Here the axis is meshoptimizer's, the half-angle the
//! larger of asin(cutoff) and the widest adjacent face, the sphere meshoptimizer's (it holds
//! every vertex of the meshlet, so every point of its edges).
//! Guarantee (see [`super`]): the same edge set as brute force.

use glam::{DVec3, Vec3};
use skinlet::contour::Edges;
use skinlet::contour::bound::{cone_angle, edge_geometry};
use skinlet::contour::patches::{BuiltPatch, Patches, assemble, size_of};
use skinlet::meshlet::{MeshletLimits, canonical, greedy};
use std::collections::HashMap;

/// meshoptimizer meshlets of at most `max_triangles` faces as patches.
pub fn build(positions: &[Vec3], triangles: &[[u32; 3]], edges: &Edges, max_triangles: usize) -> Patches {
    let limits = MeshletLimits { max_vertices: 64, max_triangles };
    let m = greedy::build(triangles, positions, limits, greedy::CONE_WEIGHT);
    let mut of_face: HashMap<[u32; 3], usize> = HashMap::new();
    for (k, h) in m.meshlets.iter().enumerate() {
        for t in m.mesh_triangles(h) {
            of_face.entry(canonical(t)).or_insert(k);
        }
    }
    // Per meshlet, its quads and their two face normals.
    let mut members: Vec<Vec<(u32, [DVec3; 2])>> = vec![Vec::new(); m.len()];
    let mut always = Vec::new();
    for (i, (q, f)) in edges.quads.iter().zip(&edges.quad_faces).enumerate() {
        match (edge_geometry(positions, *q), of_face.get(&canonical(triangles[f[0] as usize]))) {
            (Some(g), Some(&k)) => members[k].push((i as u32, [g.n1, g.n2])),
            _ => always.push(i as u32),
        }
    }
    let bytes = meshopt::typed_to_bytes(positions);
    let adapter = meshopt::VertexDataAdapter::new(bytes, std::mem::size_of::<Vec3>(), 0)
        .expect("Vec3 positions form a valid vertex stream");
    let mut built = Vec::new();
    for (h, quads) in m.meshlets.iter().zip(members) {
        if quads.is_empty() {
            continue;
        }
        let b = meshopt::compute_meshlet_bounds(
            meshopt::Meshlet { vertices: m.vertices_of(h), triangles: m.triangles_of(h) },
            &adapter,
        );
        let axis = Vec3::from(b.cone_axis).as_dvec3().normalize();
        let normals = quads.iter().flat_map(|(_, n)| *n);
        let angle = cone_angle(axis, normals).max((b.cone_cutoff as f64).clamp(-1.0, 1.0).asin());
        built.push(BuiltPatch {
            edges: quads.iter().map(|(q, _)| *q).collect(),
            center: Vec3::from(b.center).as_dvec3(),
            radius: b.radius as f64,
            axis,
            angle,
        });
    }
    assemble(edges, built, always, size_of(positions, edges))
}
