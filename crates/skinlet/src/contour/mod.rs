//! Mesh contour extraction (Tsiapkolis & Bénard 2024, "Patch Decomposition for Efficient Mesh
//! Contours Extraction"), for static meshes and skinned characters.
//!
//! A mesh contour edge joins a front-facing face to one that is not (section 1): with the
//! viewer at `e`, face `(a, b, c)` is front-facing when `((b − a) × (c − a)) · (e − a) > 0`
//! (orthographic views: `−dir` instead of `e − a`). Modules:
//! - [`edges`]: the edge structure (quads `a, b, c, d`, boundary and irregular edges, the
//!   concave filter).
//! - [`bound`]: spatialized normal cones — Mean and Reduced Sphere (section 3.1), the cone
//!   test `|n·s| ≤ sin(α + β)` (eq. 1) — and the acceptance metric and cost (section 3.2).
//! - [`patches`]: greedy patch fusion with the k-best cache and space partition (3.3).
//! - [`snch`], [`meshlet_patches`]: the baselines (Johnson & Cohen 2001's hierarchy; meshoptimizer
//!   meshlets used as patches, with a correct cone).
//! - [`skinned`]: skinned characters — the paper's rigid parts, and patches bounded over the
//!   clips with the conservative animated bounds of [`crate::bounds`], per time window.
//! - [`evaluate`]: the paper's protocol (42 directions × 6 distances, and frames of clips).
//!
//! Guarantee, for every extractor: the extracted edge set equals [`brute_force`]'s. All of
//! them run the same per-edge test ([`quad_is_contour`], in f64 on the f32 positions), and
//! every culling test keeps a margin ([`bound::MARGIN`]) far above the rounding of that test,
//! so a culled edge is one whose computed test is certainly negative. Edges whose faces are
//! too thin for their normal to have a reliable direction are never culled.

pub mod bound;
pub mod edges;
pub mod evaluate;
pub mod meshlet_patches;
pub mod patches;
pub mod skinned;
pub mod snch;

pub use crate::cull::Projection;
pub use edges::{Edges, Irregular};

use edges::quad_normals;
use glam::{DVec3, Vec3};

/// What an extraction did: edges tested and bounding volumes (patches, nodes) tested.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tested {
    pub edges: usize,
    pub bounds: usize,
}

/// The viewer as the edge test uses it (f64).
#[derive(Clone, Copy, Debug)]
pub struct Viewer {
    /// The eye, or for orthographic views the unit vector toward the viewer.
    v: DVec3,
    ortho: bool,
}

impl Viewer {
    pub fn new(projection: Projection) -> Viewer {
        match projection {
            Projection::Perspective { eye } => Viewer { v: eye.as_dvec3(), ortho: false },
            Projection::Orthographic { dir } => Viewer { v: -dir.as_dvec3(), ortho: true },
        }
    }

    /// A vector from point `a` toward the viewer.
    #[inline(always)]
    pub fn toward(&self, a: DVec3) -> DVec3 {
        if self.ortho { self.v } else { self.v - a }
    }
}

/// The contour test of a quad `(a, b, c, d)`: faces `(a, b, c)` and `(b, a, d)` differ in facing.
#[inline(always)]
pub fn quad_is_contour(p: &[Vec3], q: [u32; 4], viewer: &Viewer) -> bool {
    let [a, b, c, d] = q.map(|i| p[i as usize].as_dvec3());
    let (n1, n2) = quad_normals(a, b, c, d);
    let v = viewer.toward(a);
    (n1.dot(v) > 0.0) != (n2.dot(v) > 0.0)
}

/// The contour test of an irregular edge: its faces do not all face the same way (each face
/// with its own winding, measured at the edge's first vertex, which lies on every face).
pub fn irregular_is_contour(p: &[Vec3], e: &Irregular, viewer: &Viewer) -> bool {
    let v = viewer.toward(p[e.edge[0] as usize].as_dvec3());
    let facing = |f: &[u32; 3]| {
        let [x, y, z] = f.map(|i| p[i as usize].as_dvec3());
        (y - x).cross(z - x).dot(v) > 0.0
    };
    let first = e.faces.first().map(facing);
    e.faces.iter().any(|f| Some(facing(f)) != first)
}

/// Appends the contours of irregular edges and every boundary edge (no extractor culls them).
pub(crate) fn extract_uncullable(p: &[Vec3], edges: &Edges, viewer: &Viewer, out: &mut Vec<u32>) -> usize {
    let q = edges.quads.len() as u32;
    for (i, e) in edges.irregular.iter().enumerate() {
        if irregular_is_contour(p, e, viewer) {
            out.push(q + i as u32);
        }
    }
    let first_boundary = q + edges.irregular.len() as u32;
    out.extend(first_boundary..first_boundary + edges.boundary.len() as u32);
    edges.irregular.len()
}

/// The reference: tests every edge. `out` receives the contour edge identifiers, ascending.
pub fn brute_force(positions: &[Vec3], edges: &Edges, projection: Projection, out: &mut Vec<u32>) -> Tested {
    let viewer = Viewer::new(projection);
    out.clear();
    for (i, q) in edges.quads.iter().enumerate() {
        if quad_is_contour(positions, *q, &viewer) {
            out.push(i as u32);
        }
    }
    let irregular = extract_uncullable(positions, edges, &viewer, out);
    Tested { edges: edges.quads.len() + irregular, bounds: 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_contour_is_the_equator_band() {
        // A UV sphere seen from far along +z (and orthographically): contour edges lie
        // near z = 0, and seen from the pole a closed mesh has a closed, non-empty contour.
        let (p, t) = crate::contour::evaluate::uv_sphere(24, 48);
        let edges = Edges::build(&p, &t).unwrap();
        let mut out = Vec::new();
        for proj in
            [Projection::Perspective { eye: Vec3::new(0.0, 0.0, 1e4) }, Projection::Orthographic { dir: Vec3::NEG_Z }]
        {
            let tested = brute_force(&p, &edges, proj, &mut out);
            assert_eq!(tested.edges, edges.quads.len());
            assert!(!out.is_empty());
            for &id in &out {
                let [a, b] = edges.endpoints(id);
                assert!(p[a as usize].z.abs() < 0.14 && p[b as usize].z.abs() < 0.14);
            }
            // Every vertex of a closed contour curve is used by an even number of its edges.
            let mut degree = vec![0; p.len()];
            for &id in &out {
                for v in edges.endpoints(id) {
                    degree[v as usize] += 1;
                }
            }
            assert!(degree.iter().all(|d| d % 2 == 0));
        }
    }
}
