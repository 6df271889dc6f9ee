//! The edge structure of contour extraction (Tsiapkolis & Bénard 2024, "Patch Decomposition
//! for Efficient Mesh Contours Extraction", section 4.1): every unique edge of a triangle mesh
//! with what the contour test needs, and that test.
//!
//! A mesh contour edge joins a front-facing face to one that is not (section 1): with the
//! viewer at `e`, face `(a, b, c)` is front-facing when `((b − a) × (c − a)) · (e − a) > 0`
//! (orthographic views: `−dir` instead of `e − a`). Every extractor (brute force here, the
//! patches of [`crate::contour_patches`], the baker's baselines) runs this one test, in f64
//! on the f32 positions, so their results can be compared edge for edge.
//!
//! - *Quads* `(a, b, c, d)`: interior edges with exactly two faces of consistent winding,
//!   `(a, b, c)` and `(b, a, d)`. Contour when one face is front-facing and the other not
//!   (see [`quad_is_contour`]); the quads are what patches, hierarchies and meshlets cull.
//! - *Irregular* edges: more than two faces, or two faces that wind the edge the same way.
//!   Contour when their faces do not all face the same way; always tested (never culled).
//! - *Boundary* edges (one face): the border of an open surface, always part of the result.
//!
//! Edge identifiers, used by every extractor's output: quads `0..Q`, irregular edges
//! `Q..Q+I`, boundary edges `Q+I..Q+I+B`. Triangles that repeat a vertex index have no
//! meaningful edges and are skipped (counted); zero-area triangles with distinct indices are
//! kept (their edges are tested but never culled: a zero normal has no direction).
//!
//! The optional concave filter ([`Edges::drop_concave`]) removes quads whose dihedral angle,
//! seen from outside, exceeds π: their contours are always hidden by the adjacent faces, so
//! line drawings and shadow volumes do not need them (the paper applies it to all models).

use crate::camera::Projection;
use crate::{Error, Result};
use glam::{DVec3, Vec3};

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Edges {
    pub quads: Vec<[u32; 4]>,
    /// The two triangles (indices into the input) of each quad: `(a, b, c)` then `(b, a, d)`.
    pub quad_faces: Vec<[u32; 2]>,
    pub irregular: Vec<Irregular>,
    pub boundary: Vec<[u32; 2]>,
    /// Input triangles skipped because they repeat a vertex index.
    pub skipped_triangles: usize,
    /// Quads removed by [`Edges::drop_concave`].
    pub dropped_concave: usize,
}

/// An edge with more than two faces or inconsistently wound faces.
#[derive(Clone, Debug, PartialEq)]
pub struct Irregular {
    pub edge: [u32; 2],
    /// The edge's faces as triangles with their own winding.
    pub faces: Vec<[u32; 3]>,
}

impl Edges {
    /// Unique edges of `triangles` over `positions` (weld seams first: edges are found by
    /// vertex index). Errors name the triangle with an out-of-range index or the vertex with
    /// a non-finite position.
    pub fn build(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Edges> {
        if let Some(v) = positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid(format!("vertex {v}"), format!("position {} is not finite", positions[v])));
        }
        let n = positions.len() as u32;
        let mut half = Vec::with_capacity(triangles.len() * 3);
        let mut skipped = 0;
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i >= n) {
                return Err(Error::invalid(
                    format!("triangle {t}"),
                    format!("vertex index {i} is out of range ({n} vertices)"),
                ));
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                skipped += 1;
                continue;
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                // Key: the unordered edge; the rest says which way this face winds it.
                half.push((a.min(b), a.max(b), t as u32, k as u8));
            }
        }
        half.sort_unstable();
        let mut e = Edges { skipped_triangles: skipped, ..Edges::default() };
        for group in half.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let (lo, hi) = (group[0].0, group[0].1);
            let faces: Vec<(u32, [u32; 3], bool)> = group
                .iter()
                .map(|&(_, _, t, k)| {
                    let tri = triangles[t as usize];
                    (t, tri, tri[k as usize] == lo) // true: the face winds the edge lo → hi
                })
                .collect();
            match faces.as_slice() {
                [(_, _, fwd)] => e.boundary.push(if *fwd { [lo, hi] } else { [hi, lo] }),
                [(t1, f1, fwd1), (t2, f2, fwd2)] if fwd1 != fwd2 => {
                    // Put the face winding a → b first.
                    let ((ta, fa), (tb, fb)) = if *fwd1 { ((t1, f1), (t2, f2)) } else { ((t2, f2), (t1, f1)) };
                    let third = |f: &[u32; 3]| f.iter().copied().find(|&v| v != lo && v != hi).unwrap_or(lo);
                    e.quads.push([lo, hi, third(fa), third(fb)]);
                    e.quad_faces.push([*ta, *tb]);
                }
                _ => e.irregular.push(Irregular { edge: [lo, hi], faces: faces.iter().map(|f| f.1).collect() }),
            }
        }
        Ok(e)
    }

    /// Total number of edges (the identifier range).
    pub fn len(&self) -> usize {
        self.quads.len() + self.irregular.len() + self.boundary.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The two vertices of edge `id`.
    pub fn endpoints(&self, id: u32) -> [u32; 2] {
        let (q, i) = (self.quads.len(), self.irregular.len());
        let id = id as usize;
        if id < q {
            [self.quads[id][0], self.quads[id][1]]
        } else if id < q + i {
            self.irregular[id - q].edge
        } else {
            self.boundary[id - q - i]
        }
    }

    /// Removes the concave quads for which `eligible` holds (e.g. only rigid ones on an
    /// animated mesh, whose concavity cannot change); a quad is concave when `d` lies strictly
    /// in front of face `(a, b, c)`.
    pub fn drop_concave(&mut self, positions: &[Vec3], eligible: impl Fn(&[u32; 4]) -> bool) {
        let keep: Vec<bool> = self.quads.iter().map(|q| !(eligible(q) && concave(positions, q))).collect();
        let before = self.quads.len();
        let (mut i, mut j) = (0, 0);
        self.quads.retain(|_| (keep[i], i += 1).0);
        self.quad_faces.retain(|_| (keep[j], j += 1).0);
        self.dropped_concave += before - self.quads.len();
    }
}

/// Whether the quad's edge is concave (false, so the quad is kept, for a vertex past `p`).
fn concave(p: &[Vec3], q: &[u32; 4]) -> bool {
    vertices(p, *q).is_some_and(|[a, b, c, d]| (b - a).cross(c - a).dot(d - a) > 0.0)
}

/// The two face normals of a quad, as every extractor computes them (f64, unnormalized):
/// `(b − a) × (c − a)` and `(d − a) × (b − a)`.
#[inline(always)]
pub fn quad_normals(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> (DVec3, DVec3) {
    let ab = b - a;
    (ab.cross(c - a), (d - a).cross(ab))
}

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

/// The contour test of a quad `(a, b, c, d)`: faces `(a, b, c)` and `(b, a, d)` differ in facing
/// (true when a vertex is past `p`: a pose of another mesh says nothing, so nothing is left
/// out).
#[inline(always)]
pub fn quad_is_contour(p: &[Vec3], q: [u32; 4], viewer: &Viewer) -> bool {
    // A vertex past the positions (another mesh's): nothing is known, so a contour.
    let Some([a, b, c, d]) = vertices(p, q) else { return true };
    let (n1, n2) = quad_normals(a, b, c, d);
    let v = viewer.toward(a);
    (n1.dot(v) > 0.0) != (n2.dot(v) > 0.0)
}

/// The contour test of an irregular edge: its faces do not all face the same way (each face
/// with its own winding, measured at the edge's first vertex, which lies on every face).
pub fn irregular_is_contour(p: &[Vec3], e: &Irregular, viewer: &Viewer) -> bool {
    let Some([start]) = vertices(p, [e.edge[0]]) else { return true };
    let v = viewer.toward(start);
    // A face with a vertex past the positions faces neither way: the edge is a contour.
    let facing = |f: &[u32; 3]| vertices(p, *f).map(|[x, y, z]| (y - x).cross(z - x).dot(v) > 0.0);
    let first = e.faces.first().map(facing);
    e.faces.iter().any(|f| facing(f).is_none() || Some(facing(f)) != first)
}

/// The positions of vertices `ids` in f64, or `None` when one is past `p`.
#[inline(always)]
fn vertices<const N: usize>(p: &[Vec3], ids: [u32; N]) -> Option<[DVec3; N]> {
    let mut out = [DVec3::ZERO; N];
    for (o, i) in out.iter_mut().zip(ids) {
        *o = p.get(i as usize)?.as_dvec3();
    }
    Some(out)
}

/// Appends the contours of irregular edges and every boundary edge (no extractor culls them);
/// returns the irregular edges tested.
pub fn extract_uncullable(p: &[Vec3], edges: &Edges, viewer: &Viewer, out: &mut Vec<u32>) -> usize {
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
/// `positions` must be the ones `edges` was built over (or a pose of them).
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

    fn tetra() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        (p, vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    }

    #[test]
    fn closed_tetrahedron_has_six_quads() {
        let (p, t) = tetra();
        let e = Edges::build(&p, &t).unwrap();
        assert_eq!((e.quads.len(), e.irregular.len(), e.boundary.len()), (6, 0, 0));
        for (q, f) in e.quads.iter().zip(&e.quad_faces) {
            // Face 1 winds a → b and contains c; face 2 winds b → a and contains d.
            let (f1, f2) = (t[f[0] as usize], t[f[1] as usize]);
            assert!((0..3).any(|k| [f1[k], f1[(k + 1) % 3], f1[(k + 2) % 3]] == [q[0], q[1], q[2]]));
            assert!((0..3).any(|k| [f2[k], f2[(k + 1) % 3], f2[(k + 2) % 3]] == [q[1], q[0], q[3]]));
            // A convex solid has no concave edge and outward normals.
            assert!(!concave(&p, q));
        }
    }

    #[test]
    fn positions_of_another_mesh_give_every_edge_not_a_panic() {
        // A tetrahedron with one face left open and an edge given a third face (irregular),
        // extracted over too few positions: every edge whose vertices are missing is a contour.
        let (p, t) = tetra();
        let e = Edges::build(&p, &[t[0], t[1], t[2], [0, 1, 2]]).unwrap();
        assert!(!e.quads.is_empty() && !e.irregular.is_empty() && !e.boundary.is_empty());
        let viewer = Viewer::new(Projection::Perspective { eye: Vec3::new(3.0, 2.0, 1.0) });
        let mut out = Vec::new();
        let (q, i) = (e.quads.len() as u32, e.irregular.len() as u32);
        let want: Vec<u32> = (0..q + i + e.boundary.len() as u32).collect();
        for quad in &e.quads {
            assert!(quad_is_contour(&p[..1], *quad, &viewer));
        }
        extract_uncullable(&p[..1], &e, &viewer, &mut out);
        assert_eq!(out, want[q as usize..]);
        assert_eq!(brute_force(&[], &e, Projection::Perspective { eye: Vec3::X }, &mut out).edges, (q + i) as usize);
        assert_eq!(out, want);
    }

    #[test]
    fn boundary_irregular_and_bad_input() {
        let (p, t) = tetra();
        let open = Edges::build(&p, &t[..3]).unwrap();
        assert_eq!((open.quads.len(), open.boundary.len()), (3, 3));
        // A fin: a third face on edge 0–1, and a face wound the same way as its neighbour.
        let mut fin = t.clone();
        fin.push([1, 0, 2]);
        let e = Edges::build(&p, &fin).unwrap();
        assert_eq!(e.irregular.len(), 3, "{e:?}");
        assert!(e.irregular.iter().any(|i| i.edge == [0, 1] && i.faces.len() == 3));
        assert_eq!(e.len(), 6);
        let e = Edges::build(&p, &[[0, 1, 1], [0, 1, 2]]).unwrap();
        assert_eq!((e.skipped_triangles, e.boundary.len()), (1, 3));
        let err = Edges::build(&p, &[[0, 1, 9]]).unwrap_err().to_string();
        assert!(err.contains("triangle 0") && err.contains("index 9"), "{err}");
        let err = Edges::build(&[Vec3::NAN], &[]).unwrap_err().to_string();
        assert!(err.contains("vertex 0"), "{err}");
    }

    #[test]
    fn concave_filter() {
        // Two triangles folded up along x: a valley seen from +z.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1.0, 1.0), Vec3::new(0.5, -1.0, 1.0)];
        let mut e = Edges::build(&p, &[[0, 1, 2], [1, 0, 3]]).unwrap();
        assert_eq!(e.quads.len(), 1);
        let mut ridge = e.clone();
        e.drop_concave(&p, |_| true);
        assert_eq!((e.quads.len(), e.dropped_concave), (0, 1));
        // Mirrored in z it is a ridge and stays.
        let q: Vec<Vec3> = p.iter().map(|v| Vec3::new(v.x, v.y, -v.z)).collect();
        ridge.drop_concave(&q, |_| true);
        assert_eq!(ridge.quads.len(), 1);
    }
}
