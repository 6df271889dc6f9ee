//! Per-triangle culling inside visible meshlets (Lindqvist 2019, section 5.1.3): the CPU
//! reference for what a mesh shader does after skinning a meshlet's vertices.
//!
//! The thesis' test is the sign of a 3×3 determinant. We take it in world space relative to
//! the eye, `det[p₀ − e, p₁ − e, p₂ − e] = (p₀ − e)·((p₁ − p₀) × (p₂ − p₀))`: positive means
//! the triangle turns its back to the eye, zero means edge-on or degenerate (no pixel);
//! both are culled. (In clip space the same determinant of rows `(x, y, w)` decides, but in
//! f32 it loses the sign of small distant triangles: the clip transform's rounding is as
//! large as their edges. Edge vectors taken from world positions are exact differences, so
//! the world-space form agrees with exact arithmetic up to a few ulps, which the crowd
//! scene's brute-force check confirms.) Orthographic cameras use `d·n` with the view
//! direction `d`.

use super::Projection;
use crate::meshlet::Meshlets;
use glam::Vec3;

/// Triangles of the visible meshlets, by fate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TriangleCounts {
    pub kept: usize,
    pub backfacing: usize,
    pub degenerate: usize,
}

impl TriangleCounts {
    pub fn add(&mut self, o: &TriangleCounts) {
        self.kept += o.kept;
        self.backfacing += o.backfacing;
        self.degenerate += o.degenerate;
    }
}

/// `> 0`: back-facing, `< 0`: front-facing, `0`: edge-on or degenerate.
#[inline]
pub fn facing(p0: Vec3, p1: Vec3, p2: Vec3, projection: Projection) -> f32 {
    let n = (p1 - p0).cross(p2 - p0);
    match projection {
        Projection::Perspective { eye } => (p0 - eye).dot(n),
        Projection::Orthographic { dir } => dir.dot(n),
    }
}

/// Culls the triangles of `visible` meshlets given world positions of the mesh's vertices;
/// appends the kept triangles (mesh vertex indices) to `kept` when given.
pub fn cull_triangles(
    meshlets: &Meshlets,
    visible: &[u32],
    world: &[Vec3],
    projection: Projection,
    mut kept: Option<&mut Vec<[u32; 3]>>,
) -> TriangleCounts {
    let mut counts = TriangleCounts::default();
    for &m in visible {
        for t in meshlets.mesh_triangles(&meshlets.meshlets[m as usize]) {
            let f = facing(world[t[0] as usize], world[t[1] as usize], world[t[2] as usize], projection);
            if f < 0.0 {
                counts.kept += 1;
                if let Some(k) = kept.as_deref_mut() {
                    k.push(t);
                }
            } else if f > 0.0 {
                counts.backfacing += 1;
            } else {
                counts.degenerate += 1;
            }
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_back_edge_on_and_degenerate() {
        let mut m = Meshlets::default();
        // Counter-clockwise seen from +z (front for an eye on +z), clockwise, edge-on, a point.
        m.push(&[0, 1, 2, 3, 4, 5], &[0, 1, 2, 0, 2, 1, 3, 4, 5, 0, 0, 0]);
        let world = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 1.0),
        ];
        // The point triangle repeats vertex 0.
        let eye = Projection::Perspective { eye: Vec3::new(0.2, 0.2, 5.0) };
        let mut kept = Vec::new();
        let c = cull_triangles(&m, &[0], &world, eye, Some(&mut kept));
        assert_eq!(c, TriangleCounts { kept: 1, backfacing: 1, degenerate: 2 });
        assert_eq!(kept, vec![[0, 1, 2]]);
        let below = Projection::Orthographic { dir: Vec3::Z };
        let c = cull_triangles(&m, &[0], &world, below, None);
        assert_eq!(c, TriangleCounts { kept: 1, backfacing: 1, degenerate: 2 });
    }
}
