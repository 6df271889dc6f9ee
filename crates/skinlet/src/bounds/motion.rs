//! How far one node's local transform `T·R·S` can move during a time interval that lies
//! inside one key segment of each of its channels, and how that motion acts on boxes
//! (paper section 3.1 steps b/c.iii, section 3.2).
//!
//! - LINEAR translation and scale are linear in time: their range is spanned by the values at
//!   the interval's ends. A LINEAR rotation is a slerp, `R(s) = R_n(sθ)·q0`, a rotation about
//!   one fixed axis `n`: each box corner is swept along that arc and the arc's exact extent
//!   per axis (Rodrigues' formula and its extrema) is taken, which gives the exact AABB of
//!   the rotated box (the AABB of a rotated box is that of its rotated corners).
//! - STEP holds the first key and jumps to the second at the segment's end: both values.
//! - CUBICSPLINE translation and scale are cubic polynomials: exact ranges from the roots of
//!   their derivative. A CUBICSPLINE rotation is `normalize(p(s))` with `p` a cubic in each
//!   quaternion component, not a fixed-axis path: the interval is cut into
//!   [`CUBIC_PIECES`] pieces; on each, the components' exact ranges give an interval
//!   rotation matrix (entries intersected with [-1, 1]), applied by interval arithmetic.
//!   Conservative by construction; tighter with more pieces.
//!
//! Inverse motions (for walking down the hierarchy, eq. 2) undo translation, rotation and
//! scale in reverse order; a scale interval containing zero makes the box unbounded. Every
//! step grows the box by [`SAMPLING_ROUNDING`] to cover f32 sampling of the reference pose.

use super::Aabb;
use crate::clip::{Channel, Clip, Interpolation, Keyable, Segment};
use crate::model::{Node, Trs};
use crate::{Error, Result};
use glam::{DMat3, DMat4, DQuat, DVec3, DVec4, Quat, Vec3};
use std::f64::consts::{PI, TAU};

/// Relative growth of every box after each motion step: the reference samples local
/// transforms in f32 (interpolated values round to ~6e-8 relative, and a rounded quaternion
/// turns by ~1e-7 rad), so its path wanders off the exact one by that much per level.
pub const SAMPLING_ROUNDING: f64 = 1e-6;

/// Pieces a CUBICSPLINE rotation interval is cut into.
pub const CUBIC_PIECES: usize = 16;

/// An interval matrix: entry-wise lower and upper bounds.
pub type IntervalMat3 = (DMat3, DMat3);

/// The set of rotations a node can take during the interval.
#[derive(Clone, Debug, PartialEq)]
pub enum RotationMotion {
    Fixed(DQuat),
    /// `R_axis(φ) · start` for φ between 0 and `angle` (either sign).
    Arc {
        start: DQuat,
        axis: DVec3,
        angle: f64,
    },
    /// One of these rotations (STEP keys).
    Set(Vec<DQuat>),
    /// `normalize(q)` for `q` in one of these boxes of quaternion components (x, y, z, w),
    /// whose rotation matrices lie in the matching interval matrices (CUBICSPLINE pieces).
    Intervals {
        quats: Vec<[(f64, f64); 4]>,
        matrices: Vec<IntervalMat3>,
    },
    /// Every rotation within `angle` (radians, at most π) of `centre`: `R_δ · centre` with
    /// `R_δ` any rotation by at most `angle` (a pose envelope's range of motion).
    Cap {
        centre: DQuat,
        angle: f64,
    },
}

/// The local transforms a node can take during the interval.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// A constant matrix (glTF `matrix` nodes, which cannot be animated).
    Matrix(DMat4),
    Trs {
        translation: Aabb,
        rotation: RotationMotion,
        scale: Aabb,
    },
}

/// Motion of `node` over `[t1, t2]`; errors when the interval spans a key of the node.
pub fn node_motion(node: &Node, index: u32, clip: Option<&Clip>, t1: f32, t2: f32) -> Result<Motion> {
    let animated = clip.is_some_and(|c| c.animates(index));
    if let (Some(m), false) = (node.matrix, animated) {
        return Ok(Motion::Matrix(m.as_dmat4()));
    }
    let rest: Trs = node.rest;
    let find = |chs: &'_ [Channel<Vec3>]| chs.iter().find(|c| c.node == index).cloned();
    let (t, r, s) = match clip {
        Some(c) => (find(&c.translations), c.rotations.iter().find(|ch| ch.node == index).cloned(), find(&c.scales)),
        None => (None, None, None),
    };
    let translation = match t {
        Some(ch) => vec3_range(&segment(&ch, t1, t2, index)?, t1, t2),
        None => Aabb::point(rest.translation.as_dvec3()),
    };
    let scale = match s {
        Some(ch) => vec3_range(&segment(&ch, t1, t2, index)?, t1, t2),
        None => Aabb::point(rest.scale.as_dvec3()),
    };
    let rotation = match r {
        Some(ch) => rotation_motion(&segment(&ch, t1, t2, index)?, t1, t2),
        None => RotationMotion::Fixed(rest.rotation.as_dquat().normalize()),
    };
    Ok(Motion::Trs { translation, rotation, scale })
}

/// Range of one morph weight over `[t1, t2]` (inside one key segment of its channel; no
/// channel: the default weight): LINEAR the ends, STEP the held key and the next one at the
/// segment's end, CUBICSPLINE the cubic's extrema, widened by f32 interpolation rounding
/// like translations.
pub fn weight_range(channel: Option<&Channel<f32>>, default: f32, node: u32, t1: f32, t2: f32) -> Result<(f64, f64)> {
    let Some(ch) = channel else { return Ok((default as f64, default as f64)) };
    let s = segment(ch, t1, t2, node)?;
    let splat = |x: f32| Vec3::new(x, 0.0, 0.0);
    let seg = Segment {
        t0: s.t0,
        t1: s.t1,
        interpolation: s.interpolation,
        v0: splat(s.v0),
        v1: splat(s.v1),
        out_tangent0: splat(s.out_tangent0),
        in_tangent1: splat(s.in_tangent1),
    };
    let b = vec3_range(&seg, t1, t2);
    Ok((b.min.x, b.max.x))
}

fn segment<T: Keyable>(ch: &Channel<T>, t1: f32, t2: f32, node: u32) -> Result<Segment<T>> {
    let seg = ch.segment(t1);
    if t2 > seg.t1 {
        return Err(Error::invalid(
            format!("node {node}"),
            format!("bounds interval [{t1}, {t2}] spans the key at {} s; split it at every key", seg.t1),
        ));
    }
    Ok(seg)
}

/// Interpolation parameter of `t` in a segment, computed as the sampler does.
fn param<T>(seg: &Segment<T>, t: f32) -> f64 {
    if t <= seg.t0 || seg.t1 <= seg.t0 {
        0.0
    } else if t >= seg.t1 {
        1.0
    } else {
        ((t - seg.t0) / (seg.t1 - seg.t0)) as f64
    }
}

/// Coefficients of the cubic Hermite polynomial in `s` for one component.
fn hermite_coeffs(v0: f64, b0: f64, v1: f64, a1: f64, dt: f64) -> [f64; 4] {
    let (m0, m1) = (dt * b0, dt * a1);
    [v0, m0, -3.0 * v0 - 2.0 * m0 + 3.0 * v1 - m1, 2.0 * v0 + m0 - 2.0 * v1 + m1]
}

/// Exact range of a cubic `c0 + c1 s + c2 s² + c3 s³` over `[s1, s2]`.
fn cubic_range(c: [f64; 4], s1: f64, s2: f64) -> (f64, f64) {
    let f = |s: f64| c[0] + s * (c[1] + s * (c[2] + s * c[3]));
    let (mut lo, mut hi) = (f(s1).min(f(s2)), f(s1).max(f(s2)));
    // Derivative c1 + 2 c2 s + 3 c3 s².
    let (a, b, cc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut roots = [f64::NAN; 2];
    if a.abs() > 1e-300 {
        let disc = b * b - 4.0 * a * cc;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            roots = [q / a, if q != 0.0 { cc / q } else { f64::NAN }];
        }
    } else if b.abs() > 1e-300 {
        roots[0] = -cc / b;
    }
    for r in roots {
        if r > s1 && r < s2 {
            lo = lo.min(f(r));
            hi = hi.max(f(r));
        }
    }
    (lo, hi)
}

/// Range of a translation or scale channel over `[t1, t2]`, widened by the absolute error of
/// the reference's f32 interpolation (a few ulps of the key and tangent magnitudes), which
/// matters when the value passes near zero and is inverted on the way down the hierarchy.
fn vec3_range(seg: &Segment<Vec3>, t1: f32, t2: f32) -> Aabb {
    let dt = (seg.t1 - seg.t0).abs();
    let dt = if dt.is_finite() { dt } else { 0.0 };
    let magnitude = [seg.v0, seg.v1, seg.out_tangent0 * dt, seg.in_tangent1 * dt]
        .iter()
        .map(|v| v.abs().max_element())
        .fold(0f32, f32::max) as f64;
    let r = exact_vec3_range(seg, t1, t2);
    let e = DVec3::splat(4.0 * f32::EPSILON as f64 * magnitude);
    Aabb { min: r.min - e, max: r.max + e }
}

fn exact_vec3_range(seg: &Segment<Vec3>, t1: f32, t2: f32) -> Aabb {
    let (s1, s2) = (param(seg, t1), param(seg, t2));
    match seg.interpolation {
        Interpolation::Step => {
            let mut b = Aabb::point(seg.v0.as_dvec3());
            if t2 >= seg.t1 {
                b.extend(seg.v1.as_dvec3());
            }
            b
        }
        Interpolation::Linear => {
            let mut b = Aabb::point(seg.eval(t1).as_dvec3());
            b.extend(seg.eval(t2).as_dvec3());
            b
        }
        Interpolation::CubicSpline => {
            let dt = (seg.t1 - seg.t0) as f64;
            let (v0, b0, v1, a1) =
                (seg.v0.as_dvec3(), seg.out_tangent0.as_dvec3(), seg.v1.as_dvec3(), seg.in_tangent1.as_dvec3());
            let mut lo = DVec3::ZERO;
            let mut hi = DVec3::ZERO;
            for k in 0..3 {
                let (l, h) = cubic_range(hermite_coeffs(v0[k], b0[k], v1[k], a1[k], dt), s1, s2);
                lo[k] = l;
                hi[k] = h;
            }
            Aabb { min: lo, max: hi }
        }
    }
}

fn rotation_motion(seg: &Segment<Quat>, t1: f32, t2: f32) -> RotationMotion {
    let (s1, s2) = (param(seg, t1), param(seg, t2));
    match seg.interpolation {
        Interpolation::Step => {
            let mut set = vec![seg.v0.as_dquat().normalize()];
            if t2 >= seg.t1 {
                set.push(seg.v1.as_dquat().normalize());
            }
            RotationMotion::Set(set)
        }
        Interpolation::Linear => {
            let q0 = seg.v0.as_dquat().normalize();
            let mut q1 = seg.v1.as_dquat().normalize();
            if q0.dot(q1) < 0.0 {
                q1 = -q1;
            }
            // slerp(q0, q1, s) = Δ^s · q0 with Δ = q1 · q0⁻¹ (its w is q0·q1 ≥ 0), a rotation
            // by s·θ about one axis.
            let mut delta = (q1 * q0.conjugate()).normalize();
            if delta.w < 0.0 {
                delta = -delta;
            }
            let v = DVec3::new(delta.x, delta.y, delta.z);
            let theta = 2.0 * v.length().atan2(delta.w);
            if theta < 1e-12 {
                return RotationMotion::Fixed(q0);
            }
            let axis = v.normalize();
            if delta.w < 1e-7 {
                // A half turn between the keys: rounding decides the direction; sweep both.
                return RotationMotion::Arc { start: q0, axis, angle: TAU };
            }
            let start = DQuat::from_axis_angle(axis, s1 * theta) * q0;
            RotationMotion::Arc { start, axis, angle: (s2 - s1) * theta }
        }
        Interpolation::CubicSpline => {
            let dt = (seg.t1 - seg.t0) as f64;
            let comps: [[f64; 4]; 4] = std::array::from_fn(|k| {
                let g = |q: Quat| DVec4::from(q.as_dquat())[k];
                hermite_coeffs(g(seg.v0), g(seg.out_tangent0), g(seg.v1), g(seg.in_tangent1), dt)
            });
            let quats: Vec<[(f64, f64); 4]> = (0..CUBIC_PIECES)
                .map(|i| {
                    let a = s1 + (s2 - s1) * i as f64 / CUBIC_PIECES as f64;
                    let b = s1 + (s2 - s1) * (i + 1) as f64 / CUBIC_PIECES as f64;
                    std::array::from_fn(|k| cubic_range(comps[k], a, b))
                })
                .collect();
            let matrices = quats.iter().map(|r| quat_interval_matrix(*r)).collect();
            RotationMotion::Intervals { quats, matrices }
        }
    }
}

type Iv = (f64, f64);

fn iv_mul(a: Iv, b: Iv) -> Iv {
    let p = [a.0 * b.0, a.0 * b.1, a.1 * b.0, a.1 * b.1];
    (p.iter().copied().fold(f64::INFINITY, f64::min), p.iter().copied().fold(f64::NEG_INFINITY, f64::max))
}

fn iv_sq(a: Iv) -> Iv {
    let (l, h) = (a.0.abs().min(a.1.abs()), a.0.abs().max(a.1.abs()));
    if a.0 <= 0.0 && a.1 >= 0.0 { (0.0, h * h) } else { (l * l, h * h) }
}

fn iv_add(a: Iv, b: Iv) -> Iv {
    (a.0 + b.0, a.1 + b.1)
}

fn iv_sub(a: Iv, b: Iv) -> Iv {
    (a.0 - b.1, a.1 - b.0)
}

/// Interval rotation matrix of `normalize(q)` for q with components in the given ranges
/// (x, y, z, w); entries clamped to [-1, 1], which every rotation matrix entry satisfies.
fn quat_interval_matrix(r: [Iv; 4]) -> IntervalMat3 {
    let [x, y, z, w] = r;
    let (xx, yy, zz, ww) = (iv_sq(x), iv_sq(y), iv_sq(z), iv_sq(w));
    let n = iv_add(iv_add(xx, yy), iv_add(zz, ww));
    let two = |a: Iv| (2.0 * a.0, 2.0 * a.1);
    let (xy, xz, yz, wx, wy, wz) = (iv_mul(x, y), iv_mul(x, z), iv_mul(y, z), iv_mul(w, x), iv_mul(w, y), iv_mul(w, z));
    // Row-major numerators of the (unnormalized) rotation matrix.
    let num = [
        [iv_sub(iv_add(ww, xx), iv_add(yy, zz)), two(iv_sub(xy, wz)), two(iv_add(xz, wy))],
        [two(iv_add(xy, wz)), iv_sub(iv_add(ww, yy), iv_add(xx, zz)), two(iv_sub(yz, wx))],
        [two(iv_sub(xz, wy)), two(iv_add(yz, wx)), iv_sub(iv_add(ww, zz), iv_add(xx, yy))],
    ];
    let mut lo = [[-1.0; 3]; 3];
    let mut hi = [[1.0; 3]; 3];
    if n.0 > 0.0 {
        let inv = (1.0 / n.1, 1.0 / n.0);
        for i in 0..3 {
            for j in 0..3 {
                let e = iv_mul(num[i][j], inv);
                lo[i][j] = e.0.max(-1.0);
                hi[i][j] = e.1.min(1.0);
            }
        }
    }
    // DMat3 is column-major: column j holds row entries (0..3, j).
    let to_mat = |m: [[f64; 3]; 3]| {
        DMat3::from_cols_array_2d(&[
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ])
    };
    (to_mat(lo), to_mat(hi))
}

/// Exact AABB of the arc `R_axis(φ)·x`, φ from 0 to `angle`.
pub fn arc_extent(x: DVec3, axis: DVec3, angle: f64) -> Aabb {
    let (pa, pb) = if angle >= 0.0 { (0.0, angle) } else { (angle, 0.0) };
    let a = axis * axis.dot(x);
    let b = x - a;
    let c = axis.cross(x);
    let at = |phi: f64| a + b * phi.cos() + c * phi.sin();
    let mut bx = Aabb::point(at(pa));
    bx.extend(at(pb));
    for k in 0..3 {
        let r = (b[k] * b[k] + c[k] * c[k]).sqrt();
        let psi = c[k].atan2(b[k]);
        // Maximum a + r at φ = ψ (mod 2π), minimum a - r at φ = ψ + π (mod 2π).
        for (offset, value) in [(0.0, a[k] + r), (PI, a[k] - r)] {
            let d = (psi + offset - pa).rem_euclid(TAU);
            if d <= pb - pa {
                bx.min[k] = bx.min[k].min(value);
                bx.max[k] = bx.max[k].max(value);
            }
        }
    }
    bx
}

/// Exact AABB of `{R·x : R a rotation by at most angle θ}`: the directions within θ of `x`'s
/// on the sphere of radius `|x|` (a rotation by ω moves a direction by at most ω, and the
/// turn about `x × v` reaches any `v` within θ). Per axis `k`, with `φ` the angle between
/// `x` and `e_k`: from `|x|·cos(min(π, φ + θ))` to `|x|·cos(max(0, φ − θ))`, widened by
/// a few ulps of `|x|` for the rounding of `acos` and `cos`.
pub fn cap_extent(x: DVec3, angle: f64) -> Aabb {
    let r = x.length();
    if r == 0.0 {
        return Aabb::point(x);
    }
    let u = x / r;
    let e = 8.0 * f64::EPSILON * r;
    let mut b = Aabb::point(DVec3::ZERO);
    for k in 0..3 {
        let phi = u[k].clamp(-1.0, 1.0).acos();
        b.min[k] = (r * (phi + angle).min(PI).cos()).min(x[k]) - e;
        b.max[k] = (r * (phi - angle).max(0.0).cos()).max(x[k]) + e;
    }
    b
}

fn rotate_box(q: DQuat, b: &Aabb) -> Aabb {
    b.corners().iter().fold(Aabb::EMPTY, |mut acc, &c| {
        acc.extend(q * c);
        acc
    })
}

fn interval_mat_box(m: &IntervalMat3, b: &Aabb) -> Aabb {
    let mut out = Aabb::point(DVec3::ZERO);
    for i in 0..3 {
        let mut acc = (0.0, 0.0);
        for j in 0..3 {
            let e = (m.0.col(j)[i], m.1.col(j)[i]);
            acc = iv_add(acc, iv_mul(e, (b.min[j], b.max[j])));
        }
        out.min[i] = acc.0;
        out.max[i] = acc.1;
    }
    out
}

impl RotationMotion {
    fn apply(&self, b: &Aabb) -> Aabb {
        match self {
            RotationMotion::Fixed(q) => rotate_box(*q, b),
            RotationMotion::Arc { start, axis, angle } => {
                let axis = *axis;
                b.corners().iter().fold(Aabb::EMPTY, |acc, &c| acc.union(&arc_extent(*start * c, axis, *angle)))
            }
            RotationMotion::Set(qs) => qs.iter().fold(Aabb::EMPTY, |acc, q| acc.union(&rotate_box(*q, b))),
            RotationMotion::Intervals { matrices, .. } => {
                matrices.iter().fold(Aabb::EMPTY, |acc, m| acc.union(&interval_mat_box(m, b)))
            }
            // The AABB of R_δ·centre·B is that of its corners' images, so the union over R_δ is
            // that of the corners' caps.
            RotationMotion::Cap { centre, angle } => {
                b.corners().iter().fold(Aabb::EMPTY, |acc, &c| acc.union(&cap_extent(*centre * c, *angle)))
            }
        }
    }

    fn apply_inverse(&self, b: &Aabb) -> Aabb {
        match self {
            RotationMotion::Fixed(q) => rotate_box(q.conjugate(), b),
            // (R_n(φ)·start)⁻¹ x = R_{start⁻¹ n}(-φ) (start⁻¹ x).
            RotationMotion::Arc { start, axis, angle } => {
                let inv = start.conjugate();
                let axis = inv * *axis;
                b.corners().iter().fold(Aabb::EMPTY, |acc, &c| acc.union(&arc_extent(inv * c, axis, -*angle)))
            }
            RotationMotion::Set(qs) => qs.iter().fold(Aabb::EMPTY, |acc, q| acc.union(&rotate_box(q.conjugate(), b))),
            RotationMotion::Intervals { matrices, .. } => matrices
                .iter()
                .fold(Aabb::EMPTY, |acc, m| acc.union(&interval_mat_box(&(m.0.transpose(), m.1.transpose()), b))),
            // (R_δ·C)⁻¹ = (C⁻¹·R_δ⁻¹·C)·C⁻¹, and the conjugate of a rotation by ω is one by ω.
            RotationMotion::Cap { centre, angle } => {
                let inv = centre.conjugate();
                b.corners().iter().fold(Aabb::EMPTY, |acc, &c| acc.union(&cap_extent(inv * c, *angle)))
            }
        }
    }

    /// A lower bound of `|q·c|` over the unit quaternions `q` of these rotations: the cosine
    /// of half the largest rotation angle between one of them and `c` (exact for fixed,
    /// STEP and LINEAR motions). An arc `R_axis(φ)·start` has quaternions
    /// `cos(φ/2)·start + sin(φ/2)·(axis ⊗ start)`, whose dot with `c` is a sinusoid in `φ/2`:
    /// its smallest magnitude is at an end of the range unless it crosses zero. A CUBICSPLINE
    /// piece's `normalize(q)` has `|q·c| ≥ min|q·c| / max|q|` over its box.
    pub fn min_abs_dot(&self, c: DQuat) -> f64 {
        match self {
            RotationMotion::Fixed(q) => q.dot(c).abs(),
            RotationMotion::Set(qs) => qs.iter().map(|q| q.dot(c).abs()).fold(1.0, f64::min),
            RotationMotion::Arc { start, axis, angle } => {
                let turned = DQuat::from_xyzw(axis.x, axis.y, axis.z, 0.0) * *start;
                let (a, b) = (start.dot(c), turned.dot(c));
                // a·cos ψ + b·sin ψ = ρ·cos(ψ − ψ0) for ψ between 0 and angle/2.
                let (lo, hi) = if *angle >= 0.0 { (0.0, angle / 2.0) } else { (angle / 2.0, 0.0) };
                let (rho, psi0) = (a.hypot(b), b.atan2(a));
                // A zero at ψ0 + π/2 + kπ inside the range?
                let first = ((lo - psi0 - PI / 2.0) / PI).ceil();
                if psi0 + PI / 2.0 + first * PI <= hi {
                    return 0.0;
                }
                (rho * (lo - psi0).cos()).abs().min((rho * (hi - psi0).cos()).abs())
            }
            RotationMotion::Intervals { quats, .. } => quats
                .iter()
                .map(|r| {
                    let c = [c.x, c.y, c.z, c.w];
                    let (mut lo, mut hi, mut len2) = (0.0, 0.0, 0.0);
                    for k in 0..4 {
                        let (p, q) = (r[k].0 * c[k], r[k].1 * c[k]);
                        lo += p.min(q);
                        hi += p.max(q);
                        len2 += (r[k].0 * r[k].0).max(r[k].1 * r[k].1);
                    }
                    let dot = if lo > 0.0 {
                        lo
                    } else if hi < 0.0 {
                        -hi
                    } else {
                        0.0
                    };
                    if len2 > 0.0 { (dot / len2.sqrt()).min(1.0) } else { 0.0 }
                })
                .fold(1.0, f64::min),
            RotationMotion::Cap { centre, angle } => {
                // Within angle/2 of centre on the quaternion sphere.
                let d = centre.dot(c).abs().min(1.0).acos();
                (d + angle / 2.0).min(PI / 2.0).cos().max(0.0)
            }
        }
    }
}

fn mul_box(b: &Aabb, s: &Aabb) -> Aabb {
    let mut out = Aabb::point(DVec3::ZERO);
    for k in 0..3 {
        let p = iv_mul((b.min[k], b.max[k]), (s.min[k], s.max[k]));
        out.min[k] = p.0;
        out.max[k] = p.1;
    }
    out
}

/// An upper bound of a matrix's largest singular value: the square root of the largest
/// absolute row sum of `AᵀA` (Gershgorin; exact for a scaled rotation).
pub(crate) fn spectral_bound(a: &DMat3) -> f64 {
    let g = a.transpose() * *a;
    let rows = (0..3).map(|i| (0..3).map(|j| g.col(j)[i].abs()).sum::<f64>());
    rows.fold(0.0, f64::max).sqrt() * (1.0 + SAMPLING_ROUNDING)
}

fn matrix_box(m: &DMat4, b: &Aabb) -> Aabb {
    b.corners().iter().fold(Aabb::EMPTY, |mut acc, &c| {
        acc.extend(m.transform_point3(c));
        acc
    })
}

impl Motion {
    /// Upper bounds of how far the linear part of `L(t)` and of `L(t)⁻¹` get from their
    /// values for the local transform `at` (the interval's start, sampled) over the interval,
    /// in operator norm: `‖RS − R₁S₁‖ ≤ ‖R − R₁‖·‖S‖ + ‖S − S₁‖` with `‖R − R₁‖ = 2 sin(θ/2)`,
    /// θ the largest angle between the rotations; the inverse likewise.
    pub fn deviation(&self, at: &Trs) -> (f64, f64) {
        let Motion::Trs { rotation, scale, .. } = self else { return (0.0, 0.0) };
        let m = rotation.min_abs_dot(at.rotation.as_dquat().normalize()).min(1.0);
        let turn = 2.0 * (1.0 - m * m).max(0.0).sqrt();
        let s1 = at.scale.as_dvec3();
        let largest = scale.min.abs().max(scale.max.abs()).max_element();
        let forward = turn * largest + (scale.min - s1).abs().max((scale.max - s1).abs()).max_element();
        let straddles = (0..3).any(|k| scale.min[k] <= 0.0 && scale.max[k] >= 0.0 || s1[k] == 0.0);
        let inverse = if straddles {
            f64::INFINITY
        } else {
            let gap =
                (DVec3::ONE / scale.min - DVec3::ONE / s1).abs().max((DVec3::ONE / scale.max - DVec3::ONE / s1).abs());
            gap.max_element() + turn / s1.abs().min_element()
        };
        let grow = |d: f64| d * (1.0 + SAMPLING_ROUNDING) + SAMPLING_ROUNDING;
        (grow(forward), grow(inverse))
    }

    /// Upper bounds of the operator norm of the linear part of `L(t)` and of `L(t)⁻¹` over
    /// the interval (rotations keep lengths; a scale range through zero gives ∞ for the
    /// inverse).
    pub fn stretch(&self) -> (f64, f64) {
        match self {
            Motion::Matrix(m) => {
                let lin = DMat3::from_mat4(*m);
                (spectral_bound(&lin), spectral_bound(&lin.inverse()))
            }
            Motion::Trs { scale, .. } => {
                let largest = scale.min.abs().max(scale.max.abs()).max_element();
                let straddles = (0..3).any(|k| scale.min[k] <= 0.0 && scale.max[k] >= 0.0);
                let smallest = scale.min.abs().min(scale.max.abs()).min_element();
                let inverse = if straddles { f64::INFINITY } else { 1.0 / smallest };
                (largest * (1.0 + SAMPLING_ROUNDING), inverse * (1.0 + SAMPLING_ROUNDING))
            }
        }
    }

    /// All points `L(t)·x`, x in `b`, t in the interval.
    pub fn apply(&self, b: &Aabb) -> Aabb {
        if !b.is_finite() {
            return Aabb::EVERYWHERE;
        }
        let out = match self {
            Motion::Matrix(m) => matrix_box(m, b),
            Motion::Trs { translation, rotation, scale } => {
                let r = rotation.apply(&mul_box(b, scale));
                Aabb { min: r.min + translation.min, max: r.max + translation.max }
            }
        };
        out.inflated(SAMPLING_ROUNDING)
    }

    /// All points `L(t)⁻¹·x`, x in `b`, t in the interval.
    pub fn apply_inverse(&self, b: &Aabb) -> Aabb {
        if !b.is_finite() {
            return Aabb::EVERYWHERE;
        }
        match self {
            Motion::Matrix(m) => matrix_box(&m.inverse(), b).inflated(SAMPLING_ROUNDING),
            Motion::Trs { translation, rotation, scale } => {
                let moved = Aabb { min: b.min - translation.max, max: b.max - translation.min };
                let r = rotation.apply_inverse(&moved);
                let straddles = (0..3).any(|k| scale.min[k] <= 0.0 && scale.max[k] >= 0.0);
                if straddles {
                    return Aabb::EVERYWHERE;
                }
                let inv = Aabb { min: DVec3::ONE / scale.max, max: DVec3::ONE / scale.min };
                mul_box(&r, &inv).inflated(SAMPLING_ROUNDING)
            }
        }
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

    fn rotation(axis: [f64; 3], angle: f64) -> DQuat {
        DQuat::from_axis_angle(unit(axis), angle)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        /// Every rotation by at most θ inside the centre's cap moves every point of a box into
        /// the cap motion's box, and back again with the inverse.
        #[test]
        fn caps_hold_every_rotation_within_them(
            centre in (prop::array::uniform3(-1.0f64..1.0), -3.2f64..3.2),
            angle in 0.0f64..3.2, turn in (prop::array::uniform3(-1.0f64..1.0), 0.0f64..1.0),
            lo in prop::array::uniform3(-2.0f64..2.0), size in prop::array::uniform3(0.0f64..1.0),
            pick in prop::array::uniform3(0.0f64..1.0),
        ) {
            let angle = angle.min(PI);
            let c = rotation(centre.0, centre.1);
            let r = rotation(turn.0, turn.1 * angle) * c;
            let b = Aabb { min: DVec3::from(lo), max: DVec3::from(lo) + DVec3::from(size) };
            let x = b.min + DVec3::from(pick) * DVec3::from(size);
            let cap = RotationMotion::Cap { centre: c, angle };
            let (fwd, back) = (cap.apply(&b), cap.apply_inverse(&b));
            prop_assert!(fwd.inflated(1e-12).contains(r * x), "{fwd:?} misses {}", r * x);
            prop_assert!(back.inflated(1e-12).contains(r.conjugate() * x), "{back:?} misses {}", r.conjugate() * x);
            // |q·c| of a rotation inside is at least the bound of the cap around c itself.
            prop_assert!(r.dot(c).abs() >= cap.min_abs_dot(c) - 1e-12);
        }

        /// `min_abs_dot` is a lower bound over a LINEAR arc and a CUBICSPLINE box, and exact for
        /// the arc (dense samples come within 1e-4 of it).
        #[test]
        fn arc_and_box_dots_are_lower_bounds(
            start in (prop::array::uniform3(-1.0f64..1.0), -3.2f64..3.2),
            axis in prop::array::uniform3(-1.0f64..1.0), angle in -6.3f64..6.3,
            c in (prop::array::uniform3(-1.0f64..1.0), -3.2f64..3.2),
            lo in prop::array::uniform4(-1.0f64..1.0), size in prop::array::uniform4(0.0f64..0.5),
            picks in prop::collection::vec(prop::array::uniform4(0.0f64..1.0), 16),
        ) {
            let (start, axis, c) = (rotation(start.0, start.1), unit(axis), rotation(c.0, c.1));
            let arc = RotationMotion::Arc { start, axis, angle };
            let bound = arc.min_abs_dot(c);
            let sampled = (0..=20_000)
                .map(|i| (DQuat::from_axis_angle(axis, angle * i as f64 / 20_000.0) * start).dot(c).abs())
                .fold(1.0, f64::min);
            prop_assert!(bound <= sampled + 1e-12 && sampled <= bound + 2e-4, "bound {bound}, sampled {sampled}");
            let r: [(f64, f64); 4] = std::array::from_fn(|k| (lo[k], lo[k] + size[k]));
            let boxed = RotationMotion::Intervals { quats: vec![r], matrices: vec![quat_interval_matrix(r)] };
            let bound = boxed.min_abs_dot(c);
            for p in picks {
                let q = DVec4::from_array(std::array::from_fn(|k| r[k].0 + p[k] * size[k]));
                if q.length() > 1e-9 {
                    let q = q / q.length();
                    let dot = q.dot(DVec4::new(c.x, c.y, c.z, c.w)).abs();
                    prop_assert!(bound <= dot + 1e-12, "bound {bound} above {dot}");
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

        /// Along an arc with a scale range, `‖L(t)‖`, `‖L(t)⁻¹‖` stay within `stretch` and
        /// `‖L(t) − L(start)‖`, `‖L(t)⁻¹ − L(start)⁻¹‖` within `deviation` (operator norms
        /// estimated from below by many unit vectors).
        #[test]
        fn stretch_and_deviation_bound_sampled_linear_parts(
            start in (prop::array::uniform3(-1.0f64..1.0), -3.2f64..3.2),
            axis in prop::array::uniform3(-1.0f64..1.0), angle in -1.5f64..1.5,
            s0 in prop::array::uniform3(0.3f64..2.0), s1 in prop::array::uniform3(0.3f64..2.0),
            picks in prop::collection::vec(0.0f64..1.0, 12),
        ) {
            let (start, axis) = (rotation(start.0, start.1), unit(axis));
            let (s0, s1) = (DVec3::from(s0), DVec3::from(s1));
            let motion = Motion::Trs {
                translation: Aabb::point(DVec3::ZERO),
                rotation: RotationMotion::Arc { start, axis, angle },
                scale: Aabb { min: s0.min(s1), max: s0.max(s1) },
            };
            let at = Trs { translation: Vec3::ZERO, rotation: start.as_quat(), scale: s0.as_vec3() };
            let ((d, d_inv), (n, n_inv)) = (motion.deviation(&at), motion.stretch());
            let linear = |q: DQuat, s: DVec3| DMat3::from_quat(q) * DMat3::from_diagonal(s);
            let l0 = linear(at.rotation.as_dquat(), at.scale.as_dvec3());
            let dirs: Vec<DVec3> = (0..200).map(|i| {
                let (a, b) = (i as f64 * 2.399_963, (i as f64 + 0.5) / 200.0);
                let z = 1.0 - 2.0 * b;
                let r = (1.0 - z * z).sqrt();
                DVec3::new(r * a.cos(), r * a.sin(), z)
            }).collect();
            let norm = |m: DMat3| dirs.iter().map(|&v| (m * v).length()).fold(0.0, f64::max);
            for &f in &picks {
                let l = linear(DQuat::from_axis_angle(axis, angle * f) * start, s0 + (s1 - s0) * f);
                prop_assert!(norm(l) <= n + 1e-9 && norm(l.inverse()) <= n_inv + 1e-9);
                prop_assert!(norm(l - l0) <= d + 1e-9, "{} above {d}", norm(l - l0));
                prop_assert!(norm(l.inverse() - l0.inverse()) <= d_inv + 1e-9);
            }
        }
    }

    #[test]
    fn cap_extent_is_exact_on_the_axes() {
        // A quarter turn reaches the other axes exactly, half a turn everything.
        let b = cap_extent(DVec3::X, FRAC_PI_2_F64);
        assert!(
            (b.min - DVec3::new(0.0, -1.0, -1.0)).length() < 1e-12 && (b.max - DVec3::ONE).length() < 1e-12,
            "{b:?}"
        );
        let b = cap_extent(DVec3::X * 2.0, PI);
        assert!((b.min + DVec3::splat(2.0)).length() < 1e-12 && (b.max - DVec3::splat(2.0)).length() < 1e-12, "{b:?}");
        let b = cap_extent(DVec3::Y, 0.0);
        assert!(b.contains(DVec3::Y) && (b.max - b.min).max_element() < 1e-14, "{b:?}");
    }

    const FRAC_PI_2_F64: f64 = std::f64::consts::FRAC_PI_2;
}
