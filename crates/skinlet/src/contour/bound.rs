//! Spatialized normal cones (Johnson & Cohen 2001) as Tsiapkolis & Bénard 2024 build and
//! test them (sections 3.1, 3.2), plus the margins that keep culling exact.
//!
//! - Normal cone: axis = mean of the unit normals of every face adjacent to the edges,
//!   half-angle α = largest angle from the axis to one of them.
//! - Mean Sphere: center = mean of the edges' distinct vertices, radius to the farthest one.
//! - Reduced Sphere: center = mean of the edge midpoints, radius = largest perpendicular
//!   distance from the center to an edge's *line*. The contour test of an edge gives the same
//!   answer from any point of its line (the line lies in both face planes), so the view cone
//!   only has to reach each line once.
//! - Test (eq. 1): with `s` the unit vector from the eye to the center and `sin β = r / d`,
//!   a patch may hold a contour only if `|n·s| ≤ sin(α + β)`; always when `d ≤ r`.
//! - Acceptance ratio `H = sin(α + asin(r / d_cam))` over viewers at distance `d_cam` (eq. 3)
//!   and expected cost `E = t_P + H·t_e·ξ` (eq. 4), in units of `t_e`.
//!
//! Exactness: cones and spheres are built in f64 from the same f64 face normals the edge test
//! computes, stored rounded outward, and the f32 run-time test accepts `MARGIN` beyond eq. 1.
//! The edge test's rounding moves its normal by < 1e-8 rad for the faces allowed in a cone
//! ([`edge_geometry`] refuses thinner ones), so a culled edge's test is certainly negative.

use super::edges::quad_normals;
use glam::{DVec3, Vec3};
use std::f64::consts::FRAC_PI_2;

/// The bounds as stored and tested at run time live in the runtime crate.
pub use skinlet_runtime::contour_patches::{MARGIN, PatchBounds, ViewF, viewers};

/// A face whose normal is shorter than this times the product of its two edge lengths (its
/// angle's sine) is too thin to bound; its edges are never culled.
const THIN: f64 = 1e-7;

/// What patch building needs of one quad (f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeGeometry {
    pub a: DVec3,
    pub b: DVec3,
    /// Unit normals of the two faces.
    pub n1: DVec3,
    pub n2: DVec3,
}

impl EdgeGeometry {
    pub fn midpoint(&self) -> DVec3 {
        (self.a + self.b) * 0.5
    }
}

/// The geometry of a quad, or `None` when a face is too thin (or degenerate) to bound.
pub fn edge_geometry(p: &[Vec3], q: [u32; 4]) -> Option<EdgeGeometry> {
    let [a, b, c, d] = q.map(|i| p[i as usize].as_dvec3());
    quad_geometry(a, b, c, d)
}

/// [`edge_geometry`] of a quad given by its points.
pub fn quad_geometry(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> Option<EdgeGeometry> {
    let (n1, n2) = quad_normals(a, b, c, d);
    let ab = (b - a).length();
    let ok = |n: DVec3, other: DVec3| n.length() > THIN * ab * other.length() && n.is_finite();
    (ok(n1, c - a) && ok(n2, d - a)).then(|| EdgeGeometry { a, b, n1: n1.normalize(), n2: n2.normalize() })
}

/// Half-angle of the cone around unit `axis` containing unit `normals` (π when the axis is
/// not finite).
pub fn cone_angle(axis: DVec3, normals: impl Iterator<Item = DVec3>) -> f64 {
    if !axis.is_finite() {
        return std::f64::consts::PI;
    }
    normals.map(|n| n.dot(axis).clamp(-1.0, 1.0).acos()).fold(0.0, f64::max)
}

/// Mean axis of unit normals given as their sum: `None` when they cancel out.
pub fn mean_axis(sum: DVec3) -> Option<DVec3> {
    let len = sum.length();
    (len > 1e-9).then(|| sum / len)
}

/// Reduced Sphere of edges: (center, radius).
pub fn reduced_sphere(geo: &[EdgeGeometry]) -> (DVec3, f64) {
    let center = geo.iter().map(EdgeGeometry::midpoint).sum::<DVec3>() / geo.len().max(1) as f64;
    (center, geo.iter().map(|g| line_distance(center, g.a, g.b)).fold(0.0, f64::max))
}

/// Mean Sphere of edges: (center, radius) around the mean of their distinct vertices.
pub fn mean_sphere(points: &mut Vec<DVec3>) -> (DVec3, f64) {
    points.sort_unstable_by(|x, y| x.to_array().partial_cmp(&y.to_array()).unwrap_or(std::cmp::Ordering::Equal));
    points.dedup();
    let center = points.iter().sum::<DVec3>() / points.len().max(1) as f64;
    (center, points.iter().map(|p| p.distance(center)).fold(0.0, f64::max))
}

/// Perpendicular distance from `o` to the line through `a` and `b` (to `a` if they coincide).
pub fn line_distance(o: DVec3, a: DVec3, b: DVec3) -> f64 {
    let d = b - a;
    let len2 = d.length_squared();
    let v = o - a;
    if len2 > 0.0 { (v - d * (v.dot(d) / len2)).length() } else { v.length() }
}

/// The acceptance ratio `H` (eq. 3) of a cone of half-angle `alpha` and a sphere of radius
/// `r`, over viewers at distance `d_cam`.
#[inline]
pub fn acceptance(alpha: f64, r: f64, d_cam: f64) -> f64 {
    let s = alpha + (r / d_cam).min(1.0).asin();
    if s >= FRAC_PI_2 { 1.0 } else { s.sin() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_sphere_touches_every_line_and_is_smaller() {
        // Two parallel edges far apart along their own direction.
        let g = |a: DVec3, b: DVec3| EdgeGeometry { a, b, n1: DVec3::Z, n2: DVec3::Z };
        let geo = [g(DVec3::ZERO, DVec3::X), g(DVec3::new(10.0, 1.0, 0.0), DVec3::new(11.0, 1.0, 0.0))];
        let (c, r) = reduced_sphere(&geo);
        assert!((r - 0.5).abs() < 1e-12 && (c - DVec3::new(5.5, 0.5, 0.0)).length() < 1e-12);
        let mut pts = vec![geo[0].a, geo[0].b, geo[1].a, geo[1].b, geo[0].a];
        let (_, rm) = mean_sphere(&mut pts);
        assert_eq!(pts.len(), 4);
        assert!(rm > 5.0);
    }

    #[test]
    fn acceptance_and_test_agree_on_simple_cases() {
        assert_eq!(acceptance(0.0, 0.0, 10.0), 0.0);
        assert_eq!(acceptance(1.6, 0.0, 10.0), 1.0);
        assert!((acceptance(0.3, 1.0, 10.0) - (0.3 + 0.1f64.asin()).sin()).abs() < 1e-12);
        let b = PatchBounds::new(DVec3::ZERO, 1.0, DVec3::Z, 0.2);
        // Seen from above (|n·s| = 1): culled; from the side: accepted; from inside: accepted.
        assert!(!b.accepts(&ViewF::Eye(Vec3::new(0.0, 0.0, 100.0))));
        assert!(b.accepts(&ViewF::Eye(Vec3::new(100.0, 0.0, 0.0))));
        assert!(b.accepts(&ViewF::Eye(Vec3::new(0.0, 0.0, 0.5))));
        assert!(!b.accepts(&ViewF::Dir(Vec3::NEG_Z)));
        assert!(b.accepts(&ViewF::Dir(Vec3::X)));
        assert!(PatchBounds::ALWAYS.accepts(&ViewF::Eye(Vec3::splat(1e6))));
        assert!(PatchBounds::new(DVec3::X, 1.0, DVec3::Z, 2.0).accepts(&ViewF::Dir(Vec3::Z)));
        assert_eq!(PatchBounds::new(DVec3::NAN, 1.0, DVec3::Z, 0.1), PatchBounds::ALWAYS);
    }
}
