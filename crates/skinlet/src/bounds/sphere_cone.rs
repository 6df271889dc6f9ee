//! Per-meshlet bounds that hold over whole clips: a sphere (paper section 5, fig. 9) and a
//! normal cone (section 4), both in the space of the meshlet's principal joint, plus the
//! run-time transform of both and the conservative culling tests that use them.
//!
//! - Principal joint: largest summed weight over the meshlet's vertices (section 3).
//! - Sphere: the rest-pose bounding sphere of the vertices in the joint's bind space,
//!   its radius extended to contain every vertex box ([`super::vertex`]) of every key
//!   interval of every clip.
//! - Cone: axis = the mean rest normal or the axis of the smallest cap around the rest
//!   normals, whichever is narrower ([`super::cone`], joint space); angle = the largest angle
//!   between the axis and the normal of any triangle built from corners of its three vertex
//!   boxes (the paper's 8³ combinations), over all intervals. This is conservative, not just
//!   a heuristic: the face normal `(p2−p1)×(p3−p1)` is affine in each vertex separately, so
//!   every normal reachable with vertices inside their boxes is a convex combination of the
//!   corner normals, and a cone of half-angle below 90° is convex. When a corner normal is 90°
//!   or more away, the meshlet gets no useful cone (angle π: never backface-culled).
//!
//! At run time the bounds stay in the joint's bind space: the culler (`skinlet_runtime::meshlet_cull`)
//! moves the frustum planes and the eye there instead, which is exact for any joint matrix
//! (shear, non-uniform and negative scale included); [`super::verify`] checks them there too.

use super::cone::reference_axis;
use super::refine::{Ctx, Refinement, refine};
use super::vertex::{IntervalMotions, vertex_box};
use super::{Aabb, INFLATE};
use crate::Result;
use crate::clip::Clip;
use crate::meshlet::{Meshlet, Meshlets, stats::principal_joint};
use crate::model::{Skeleton, Skin, SkinnedMesh};
use glam::{DMat3, DVec3};
pub use skinlet_runtime::meshlet_bounds::{Class, MeshletBounds};
use std::f64::consts::PI;

/// The key intervals of a clip: consecutive distinct key times (one degenerate interval for a
/// single key). Outside them every channel is constant, so they cover all times.
pub fn key_intervals(clip: &Clip) -> Vec<(f32, f32)> {
    let keys = clip.key_times();
    match keys.len() {
        0 => vec![(0.0, 0.0)],
        1 => vec![(keys[0], keys[0])],
        _ => keys.windows(2).map(|w| (w[0], w[1])).collect(),
    }
}

/// Bounds for every meshlet, conservative over every key interval of every clip in `clips`
/// (no clip: the rest pose only); [`super::refine`] tightens them further.
pub fn meshlet_bounds(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
) -> Result<Vec<MeshletBounds>> {
    Ok(refine(skeleton, skin, clips, mesh, meshlets, &Refinement::NONE)?.bounds)
}

/// A meshlet's radius and smallest corner-normal cosine around its axis over one interval,
/// starting from its rest bounds. The cosine is the true minimum (also below 0, so that
/// refinement sees progress past 90°), skipped only when the rest cone is already ≥ 90°.
pub(crate) fn piece_extent(
    ctx: &Ctx,
    m: &Meshlet,
    rest: &MeshletBounds,
    mo: &IntervalMotions,
    boxes: &mut Vec<Aabb>,
) -> (f64, f64) {
    let verts = ctx.meshlets.vertices_of(m);
    let (c, axis) = (rest.center.as_dvec3(), rest.cone_axis.as_dvec3());
    let mut r = rest.radius as f64;
    let mut min_cos = (rest.rest_cone_angle as f64).cos();
    boxes.clear();
    boxes.extend(verts.iter().map(|&v| vertex_box(ctx.skeleton, ctx.skin, mo, ctx.mesh, v as usize, rest.joint)));
    for bx in boxes.iter() {
        r = r.max(bx.inflated(INFLATE).max_distance(c));
    }
    if rest.rest_cone_angle < std::f32::consts::FRAC_PI_2 {
        for t in ctx.meshlets.triangles_of(m).chunks_exact(3) {
            let (b1, b2, b3) = (&boxes[t[0] as usize], &boxes[t[1] as usize], &boxes[t[2] as usize]);
            // Most triangles stay well inside the cone: a cheap bound shows it, and the 8³
            // corner combinations are only enumerated for the others.
            if cos_lower_bound(b1, b2, b3, axis) < min_cos + 1e-12 {
                min_cos = min_cos.min(corner_normals_min_cos(b1, b2, b3, axis));
            }
        }
    }
    (r, min_cos)
}

/// A lower bound of the cosine between `axis` and the normal of any triangle with vertices
/// in the three boxes, by interval arithmetic: edges `e1 ∈ B2 − B1`, `e2 ∈ B3 − B1` taken
/// independently (a superset), `n = e1 × e2` per component, then `min(n·axis) / max|n|`
/// when `min(n·axis) > 0`; −∞ otherwise (NaN for unbounded boxes, which never passes `≥`).
fn cos_lower_bound(b1: &Aabb, b2: &Aabb, b3: &Aabb, axis: DVec3) -> f64 {
    let (e1lo, e1hi) = (b2.min - b1.max, b2.max - b1.min);
    let (e2lo, e2hi) = (b3.min - b1.max, b3.max - b1.min);
    let mul = |alo: f64, ahi: f64, blo: f64, bhi: f64| {
        let p = [alo * blo, alo * bhi, ahi * blo, ahi * bhi];
        (p.iter().copied().fold(f64::INFINITY, f64::min), p.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    };
    let cross = |i: usize, j: usize| {
        let (alo, ahi) = mul(e1lo[i], e1hi[i], e2lo[j], e2hi[j]);
        let (blo, bhi) = mul(e1lo[j], e1hi[j], e2lo[i], e2hi[i]);
        (alo - bhi, ahi - blo)
    };
    let n = [cross(1, 2), cross(2, 0), cross(0, 1)];
    let mut dot_lo = 0.0;
    let mut len2_hi = 0.0;
    for (k, (lo, hi)) in n.into_iter().enumerate() {
        dot_lo += if axis[k] >= 0.0 { axis[k] * lo } else { axis[k] * hi };
        len2_hi += (lo * lo).max(hi * hi);
    }
    if dot_lo > 0.0 { dot_lo / len2_hi.sqrt() } else { f64::NEG_INFINITY }
}

/// The corners of a box, or its one point when it has no extent (rigid vertices stay cheap).
fn corners(b: &Aabb) -> ([DVec3; 8], usize) {
    if b.min == b.max { ([b.min; 8], 1) } else { (b.corners(), 8) }
}

/// Smallest cosine between `axis` and the normal of any triangle with corners of the three
/// boxes as vertices (zero normals skipped: a zero vector lies in every cone); -1 (no cone)
/// when a box is unbounded.
fn corner_normals_min_cos(b1: &Aabb, b2: &Aabb, b3: &Aabb, axis: DVec3) -> f64 {
    if !(b1.is_finite() && b2.is_finite() && b3.is_finite()) {
        return -1.0;
    }
    let ((c1, n1), (c2, n2), (c3, n3)) = (corners(b1), corners(b2), corners(b3));
    let mut min_cos: f64 = 1.0;
    for p1 in &c1[..n1] {
        for p2 in &c2[..n2] {
            let e1 = *p2 - *p1;
            for p3 in &c3[..n3] {
                let n = e1.cross(*p3 - *p1);
                let len = n.length();
                if !len.is_finite() {
                    return -1.0;
                }
                if len > 0.0 {
                    min_cos = min_cos.min(n.dot(axis) / len);
                }
            }
        }
    }
    min_cos
}

pub(crate) use skinlet_runtime::meshlet_bounds::round_up;

/// Rest-pose bounds: principal joint, bounding sphere of the vertices in the joint's bind
/// space (center of their box, radius to the farthest vertex), rest normal cone. The rest
/// shape has the default morph weights applied.
pub fn rest_bounds(skin: &Skin, mesh: &SkinnedMesh, meshlets: &Meshlets) -> Vec<MeshletBounds> {
    let mut defaults = Vec::new();
    mesh.morphs.weights_at(None, 0.0, &mut defaults);
    let (rest, _) = mesh.morphed(&defaults);
    meshlets
        .meshlets
        .iter()
        .map(|m| {
            let verts = meshlets.vertices_of(m);
            let joint = principal_joint(mesh, verts).map_or(0, |(j, _)| j);
            let ibm = skin.inverse_bind[joint as usize].as_dmat4();
            let bind: Vec<DVec3> = verts.iter().map(|&v| ibm.transform_point3(rest[v as usize].as_dvec3())).collect();
            let (lo, hi) = bind.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
            let center = (lo + hi) / 2.0;
            let r = bind.iter().map(|p| p.distance(center)).fold(0.0, f64::max);
            let normals: Vec<DVec3> = meshlets
                .triangles_of(m)
                .chunks_exact(3)
                .map(|t| (bind[t[1] as usize] - bind[t[0] as usize]).cross(bind[t[2] as usize] - bind[t[0] as usize]))
                .collect();
            let (axis, min_cos) = reference_axis(&normals);
            let angle = if min_cos > 0.0 { round_up(min_cos.acos()) } else { PI as f32 };
            MeshletBounds {
                joint,
                center: center.as_vec3(),
                radius: round_up(r),
                rest_radius: r as f32,
                cone_axis: axis.as_vec3(),
                cone_angle: angle,
                rest_cone_angle: angle,
            }
        })
        .collect()
}

/// The cofactor matrix `det(A)·A⁻ᵀ`, columns `b×c, c×a, a×b`: maps the cross product of two
/// vectors to the cross product of their images, so face normals move by it.
pub fn cofactor(a: &DMat3) -> DMat3 {
    DMat3::from_cols(a.y_axis.cross(a.z_axis), a.z_axis.cross(a.x_axis), a.x_axis.cross(a.y_axis))
}

/// Classifies with constant thresholds: the radius may grow at most `s_r` times the rest
/// radius, and the normals may turn at most `alpha_t` radians beyond the rest cone (the
/// paper's "normal deviation threshold": its table 2 has 82–88% of meshlets within 10°,
/// which only a deviation, not a whole cone angle, allows), the cone staying below 90°.
pub fn classify(b: &MeshletBounds, s_r: f32, alpha_t: f32) -> Class {
    if b.radius > s_r * b.rest_radius.max(f32::MIN_POSITIVE) {
        Class::None
    } else if b.cone_angle < std::f32::consts::FRAC_PI_2 && b.cone_angle - b.rest_cone_angle <= alpha_t {
        Class::Both
    } else {
        Class::FrustumOnly
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit(v: [f64; 3]) -> DVec3 {
        let v = DVec3::from(v);
        if v.length() < 1e-3 { DVec3::X } else { v.normalize() }
    }

    proptest! {
        /// The interval bound never exceeds the cosine of a normal built from points of the
        /// boxes, and the corner enumeration never exceeds it either (both are lower bounds).
        #[test]
        fn cone_cosine_bounds_are_lower_bounds(
            base in prop::array::uniform3(prop::array::uniform3(-1.0f64..1.0)),
            size in prop::array::uniform3(prop::array::uniform3(0.0f64..0.2)),
            a in any::<[f64; 3]>().prop_map(|v| v.map(|x| x % 1.0)),
            picks in prop::collection::vec(prop::array::uniform3(prop::array::uniform3(0.0f64..1.0)), 16),
        ) {
            let boxes: Vec<Aabb> = (0..3)
                .map(|i| { let lo = DVec3::from(base[i]); Aabb { min: lo, max: lo + DVec3::from(size[i]) } })
                .collect();
            let axis = unit(a);
            let lower = cos_lower_bound(&boxes[0], &boxes[1], &boxes[2], axis);
            let corners = corner_normals_min_cos(&boxes[0], &boxes[1], &boxes[2], axis);
            for pick in picks {
                let p: Vec<DVec3> = (0..3).map(|i| boxes[i].min + DVec3::from(pick[i]) * DVec3::from(size[i])).collect();
                let n = (p[1] - p[0]).cross(p[2] - p[0]);
                if n.length() > 1e-9 {
                    let cos = n.dot(axis) / n.length();
                    prop_assert!(lower <= cos + 1e-9, "interval bound {lower} above {cos}");
                    if corners > 0.0 {
                        prop_assert!(corners <= cos + 1e-9, "corner bound {corners} above {cos}");
                    }
                }
            }
        }
    }
}
