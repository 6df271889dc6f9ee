//! Conservative box of a skinned vertex over a time interval, in the space of a target
//! joint (paper section 3.1 and 3.3). For influence `i` the vertex's bind position in joint
//! `i`'s frame, `IBMᵢ·v`, is carried step by step up the hierarchy with each node's local
//! motion (child to parent) to the lowest common ancestor, then down to the target with
//! inverse motions (eq. 2); never through decomposed global matrices, whose intermediate
//! extremes would be missed. The per-influence boxes are combined by the weighted Minkowski
//! sum (fig. 7): `Σ wᵢ·Bᵢ`, since the skinned point in target space is `Σ wᵢ·qᵢ(t)`.
//!
//! Morph targets (glTF: applied before skinning) turn the rest point into a box: each morph
//! weight's exact range over the interval ([`super::motion::weight_range`]) times each of
//! the vertex's deltas, summed per axis (`p + Σ [lo, hi]·d`). Every influence's box is then
//! carried from that box; choosing the morphed point independently per influence and apart
//! from the joints' motion only adds points, so the result stays a superset.

use super::Aabb;
use super::motion::{Motion, SAMPLING_ROUNDING, node_motion, spectral_bound, weight_range};
use crate::Result;
use crate::clip::Clip;
use crate::model::{Morphs, Skeleton, Skin, SkinnedMesh, Trs};
use glam::DVec3;

/// Motions of every node during one interval `[t1, t2]` of a clip.
pub struct IntervalMotions {
    pub t1: f32,
    pub t2: f32,
    motions: Vec<Motion>,
    /// Parent links from each node to its root.
    depth: Vec<u32>,
    /// Range of each morph weight of the mesh ([`Morphs::weights`]) over the interval.
    weights: Vec<(f64, f64)>,
}

impl IntervalMotions {
    /// The motions of every node and the ranges of the morph weights `morphs` (may be
    /// empty) over `[t1, t2]`; errors when the interval spans a key of some channel.
    pub fn new(skeleton: &Skeleton, morphs: &Morphs, clip: Option<&Clip>, t1: f32, t2: f32) -> Result<IntervalMotions> {
        let weights = weight_ranges(morphs, clip, t1, t2)?;
        let motions = skeleton
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| node_motion(n, i as u32, clip, t1, t2))
            .collect::<Result<Vec<_>>>()?;
        Ok(IntervalMotions { t1, t2, ..IntervalMotions::from_motions(skeleton, motions, weights) })
    }

    /// Motions given directly (one per skeleton node) with morph weight ranges, e.g. a pose
    /// envelope's ([`super::envelope::Envelope::motions`]); `t1` and `t2` are 0.
    pub(crate) fn from_motions(skeleton: &Skeleton, motions: Vec<Motion>, weights: Vec<(f64, f64)>) -> IntervalMotions {
        let mut depth = vec![0u32; skeleton.nodes.len()];
        for &i in &skeleton.order {
            if let Some(p) = skeleton.nodes[i as usize].parent {
                depth[i as usize] = depth[p as usize] + 1;
            }
        }
        IntervalMotions { t1: 0.0, t2: 0.0, motions, depth, weights }
    }

    /// Box of vertex `v` of `mesh` in mesh space over the interval: its position moved by
    /// every morph delta times the range of the delta's weight, grown by the f32 rounding of
    /// the reference's sum (4 ulps of the magnitudes summed). A point without deltas.
    pub fn rest_box(&self, mesh: &SkinnedMesh, v: usize) -> Aabb {
        morph_box(mesh, v, &self.weights)
    }

    /// All points `global(to)⁻¹ · global(from) · x`, x in `b`, over the interval.
    pub fn carry(&self, skeleton: &Skeleton, from: u32, to: u32, b: Aabb) -> Aabb {
        let parent = |n: u32| skeleton.nodes[n as usize].parent;
        // Climb to the lowest common ancestor: `from`'s side applies motions on the way up,
        // `to`'s side is remembered and undone top-down afterwards.
        let (mut a, mut t, mut b) = (Some(from), Some(to), b);
        let mut down = [0u32; 64];
        let mut down_spill = Vec::new();
        let mut n_down = 0;
        let depth = |n: Option<u32>| n.map_or(-1, |n| self.depth[n as usize] as i64);
        while a != t {
            if depth(a) >= depth(t) {
                let n = a.expect("deeper side is a node");
                b = self.motions[n as usize].apply(&b);
                a = parent(n);
            } else {
                let n = t.expect("deeper side is a node");
                if n_down < down.len() {
                    down[n_down] = n
                } else {
                    down_spill.push(n)
                }
                n_down += 1;
                t = parent(n);
            }
        }
        for n in down_spill.iter().rev().chain(down[..n_down.min(down.len())].iter().rev()) {
            b = self.motions[*n as usize].apply_inverse(&b);
        }
        // Unbounded (a scale through zero): keep it unbounded rather than NaN.
        if b.is_finite() { b } else { Aabb::EVERYWHERE }
    }

    /// A ball holding every point `global(to)⁻¹ · global(from) · x`, x in the ball (`centre`,
    /// `radius`), over the interval: [`Self::carry`] with balls, each rotation taken about the
    /// node's rotation in `at` (a rotation within angle θ of it moves a point `c` by at most
    /// `2 sin(θ/2)|c|`). Boxes grow at every rotation of a chain (a rotated box's box is
    /// larger); balls only by the motion, so over wide motions (a pose envelope's) this is the
    /// tighter one. Infinite radius where unbounded.
    pub fn carry_ball(&self, skeleton: &Skeleton, from: u32, to: u32, at: &[Trs], ball: (DVec3, f64)) -> (DVec3, f64) {
        let parent = |n: u32| skeleton.nodes[n as usize].parent;
        let depth = |n: Option<u32>| n.map_or(-1, |n| self.depth[n as usize] as i64);
        let (mut a, mut t, mut ball) = (Some(from), Some(to), ball);
        let mut down = Vec::new();
        while a != t {
            if depth(a) >= depth(t) {
                let n = a.expect("deeper side is a node");
                ball = ball_motion(&self.motions[n as usize], &at[n as usize], ball, false);
                a = parent(n);
            } else {
                let n = t.expect("deeper side is a node");
                down.push(n);
                t = parent(n);
            }
        }
        for &n in down.iter().rev() {
            ball = ball_motion(&self.motions[n as usize], &at[n as usize], ball, true);
        }
        if ball.0.is_finite() && !ball.1.is_nan() { ball } else { (DVec3::ZERO, f64::INFINITY) }
    }

    /// An upper bound of how far the linear part of `global(to)⁻¹ · global(from)` gets over
    /// the interval from its value for the local transforms `at` (every node's, sampled at
    /// the interval's start), in operator norm: for a product of factors `Xₙ` against `Yₙ`,
    /// `‖ΠX − ΠY‖ ≤ Σₙ ‖Xₙ − Yₙ‖ · Πⱼ≠ₙ max(‖Xⱼ‖, ‖Yⱼ‖)`.
    pub fn deviation(&self, skeleton: &Skeleton, from: u32, to: u32, at: &[Trs]) -> f64 {
        // Σ dₙ Πⱼ≠ₙ normⱼ, accumulated factor by factor: (sum, product of norms).
        let (mut sum, mut product) = (0.0f64, 1.0f64);
        self.factors(skeleton, from, Some(to), |n, motion, inverse| {
            let ((d, d_inv), (norm, norm_inv)) = (motion.deviation(&at[n as usize]), motion.stretch());
            let (d, norm) = if inverse { (d_inv, norm_inv) } else { (d, norm) };
            sum = sum * norm + d * product;
            product *= norm;
        });
        if sum.is_nan() { f64::INFINITY } else { sum }
    }

    /// An upper bound of the operator norm of the linear part of `global(to)⁻¹ · global(from)`
    /// over the interval (`to`: `None` for the scene): the product of the nodes' stretches
    /// on the way from `from` up to the common ancestor and of their inverses' down to `to`.
    pub fn stretch(&self, skeleton: &Skeleton, from: u32, to: Option<u32>) -> f64 {
        let mut s = 1.0f64;
        self.factors(skeleton, from, to, |_, motion, inverse| {
            let (norm, norm_inv) = motion.stretch();
            s *= if inverse { norm_inv } else { norm };
        });
        if s.is_nan() { f64::INFINITY } else { s }
    }

    /// Calls `f` with every factor of `global(to)⁻¹ · global(from)` (`to`: `None` for the
    /// scene): each node from `from` up to the common ancestor, then each from `to` up to it,
    /// inverted (`true`); in no particular order of products.
    fn factors(&self, skeleton: &Skeleton, from: u32, to: Option<u32>, mut f: impl FnMut(u32, &Motion, bool)) {
        let parent = |n: u32| skeleton.nodes[n as usize].parent;
        let depth = |n: Option<u32>| n.map_or(-1, |n| self.depth[n as usize] as i64);
        let (mut a, mut t) = (Some(from), to);
        while a != t {
            if depth(a) >= depth(t) {
                let n = a.expect("deeper side is a node");
                f(n, &self.motions[n as usize], false);
                a = parent(n);
            } else {
                let n = t.expect("deeper side is a node");
                f(n, &self.motions[n as usize], true);
                t = parent(n);
            }
        }
    }
}

/// Range of each morph weight of `morphs` over `[t1, t2]` of `clip` (`None`: the defaults);
/// errors when the interval spans a key of a weight channel.
pub fn weight_ranges(morphs: &Morphs, clip: Option<&Clip>, t1: f32, t2: f32) -> Result<Vec<(f64, f64)>> {
    (morphs.weights.iter())
        .map(|w| {
            let ch = clip.and_then(|c| c.weights.iter().find(|c| c.channel.node == w.node && c.target == w.target));
            weight_range(ch.map(|c| &c.channel), w.default, w.node, t1, t2)
        })
        .collect()
}

/// Range of each morph weight over every key interval of every clip in `clips` (no clip:
/// the defaults): what a bound valid for whole clips must cover.
pub fn clip_weight_ranges(morphs: &Morphs, clips: &[&Clip]) -> Result<Vec<(f64, f64)>> {
    let mut out = weight_ranges(morphs, None, 0.0, 0.0)?;
    if clips.is_empty() {
        return Ok(out);
    }
    out.fill((f64::INFINITY, f64::NEG_INFINITY));
    for c in clips {
        for (a, b) in super::sphere_cone::key_intervals(c) {
            for (o, r) in out.iter_mut().zip(weight_ranges(morphs, Some(c), a, b)?) {
                *o = (o.0.min(r.0), o.1.max(r.1));
            }
        }
    }
    Ok(out)
}

/// Box of vertex `v` of `mesh` in mesh space while each morph weight `k` stays in
/// `ranges[k]`: its position plus every delta times its weight's range, per axis, grown by
/// the f32 rounding of the reference's sum (4 ulps of the magnitudes summed). A point for a
/// vertex without deltas.
pub fn morph_box(mesh: &SkinnedMesh, v: usize, ranges: &[(f64, f64)]) -> Aabb {
    let p = mesh.positions[v].as_dvec3();
    let deltas = mesh.morphs.of(v);
    if deltas.is_empty() {
        return Aabb::point(p);
    }
    let (mut lo, mut hi, mut magnitude) = (p, p, p.abs());
    for d in deltas {
        let (wlo, whi) = ranges[d.weight as usize];
        let d = d.position.as_dvec3();
        let (a, b) = (d * wlo, d * whi);
        lo += a.min(b);
        hi += a.max(b);
        magnitude += a.abs().max(b.abs());
    }
    let e = magnitude * (4.0 * f32::EPSILON as f64);
    Aabb { min: lo - e, max: hi + e }
}

/// Box containing vertex `v` of `mesh` (morphs applied) at every time of the interval, in
/// the space of skin joint `target` (`global(joint node, t)⁻¹ · p(t)`), in exact arithmetic:
/// callers add [`super::INFLATE`] where f32 rounding of the reference must be covered. A
/// vertex without morphs bound to `target` alone gives a point. The mesh must have
/// influences.
pub fn vertex_box(
    skeleton: &Skeleton,
    skin: &Skin,
    motions: &IntervalMotions,
    mesh: &SkinnedMesh,
    v: usize,
    target: u16,
) -> Aabb {
    let to = skin.joints[target as usize];
    let rest = motions.rest_box(mesh, v);
    let Some(influences) = &mesh.influences else { return Aabb::EVERYWHERE };
    let mut sum = Aabb::point(DVec3::ZERO);
    for (j, w) in influences.of(v) {
        let bind = rest.transformed(&skin.inverse_bind[j as usize].as_dmat4());
        let b = motions.carry(skeleton, skin.joints[j as usize], to, bind);
        let w = w as f64;
        sum.min += w * b.min;
        sum.max += w * b.max;
    }
    sum
}

/// A ball holding `L·x` (or `L⁻¹·x` where `inverse`) for x in `ball` and every local
/// transform `L` of `motion`, rotations taken about `at`'s (see
/// [`IntervalMotions::carry_ball`]); grown by [`SAMPLING_ROUNDING`] as boxes are.
fn ball_motion(motion: &Motion, at: &Trs, (c, r): (DVec3, f64), inverse: bool) -> (DVec3, f64) {
    let (c, r) = match motion {
        Motion::Matrix(m) => {
            let m = if inverse { m.inverse() } else { *m };
            (m.transform_point3(c), r * spectral_bound(&glam::DMat3::from_mat4(m)))
        }
        Motion::Trs { translation, rotation, scale } => {
            let q = at.rotation.as_dquat().normalize();
            let m = rotation.min_abs_dot(q).min(1.0);
            let turn = 2.0 * (1.0 - m * m).max(0.0).sqrt();
            let (t_mid, t_half) =
                ((translation.min + translation.max) / 2.0, (translation.max - translation.min) / 2.0);
            // Per axis, the range of the scale (or of its reciprocal) as middle and half width,
            // and the largest magnitude.
            let range = |lo: DVec3, hi: DVec3| ((lo + hi) / 2.0, (hi - lo) / 2.0, lo.abs().max(hi.abs()).max_element());
            if inverse {
                let (c, r) = (c - t_mid, r + t_half.length());
                let (c, r) = (q.inverse() * c, r + turn * c.length());
                let straddles = (0..3).any(|k| scale.min[k] <= 0.0 && scale.max[k] >= 0.0);
                if straddles {
                    return (DVec3::ZERO, f64::INFINITY);
                }
                let (a, b) = (DVec3::ONE / scale.min, DVec3::ONE / scale.max);
                let (mid, half, largest) = range(a.min(b), a.max(b));
                (mid * c, (half * c).length() + r * largest)
            } else {
                let (mid, half, largest) = range(scale.min, scale.max);
                let (c, r) = (mid * c, (half * c).length() + r * largest);
                let (c, r) = (q * c, r + turn * c.length());
                (c + t_mid, r + t_half.length())
            }
        }
    };
    // The box's growth (`Aabb::inflated`) on every axis of the ball's box.
    (c, r + SAMPLING_ROUNDING * (c.abs().max_element() + r).max(1.0) * 3f64.sqrt())
}
