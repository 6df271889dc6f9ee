//! The run-time pose guard (issue "poses games make"): whether a pose lies inside a pose
//! envelope, so that bounds the baker computed for that envelope hold for it. An envelope
//! lists, per node that moves the skin's joints, a range of motion ([`NodeRange`]: a cap of
//! rotations within an angle of a centre, translation and scale boxes) and a range per morph
//! weight. For caps below 90° the cap is geodesically convex, so slerp or nlerp blends of
//! poses inside stay inside. The baker makes envelopes (`skinlet::bounds::envelope`) and
//! their bounds; this module checks poses against them, per node one quaternion product and
//! two box tests in f32, no allocation.

use crate::{Error, Result};
use glam::{Mat4, Quat, Vec3};

/// How much wider than the guard admits a rotation cap is taken for the bounds (radians):
/// the guard's f32 arithmetic then never admits a rotation the bounds do not cover.
pub const GUARD_SLACK: f64 = 1e-5;

/// Relative slack of boxes and ranges: the guard admits values this share of the range's
/// magnitude outside it (an f32 blend of equal values can round by an ulp), and the bounds
/// cover twice that.
pub const BOX_SLACK: f64 = 1e-6;

/// `[lo, hi]` widened by `k` × [`BOX_SLACK`] of the larger magnitude.
pub fn widened(lo: f64, hi: f64, k: f64) -> (f64, f64) {
    let s = k * BOX_SLACK * lo.abs().max(hi.abs());
    (lo - s, hi + s)
}

/// A node's local transform: translation, rotation, scale (glTF's TRS, applied `T · R · S`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Trs {
    pub const IDENTITY: Trs = Trs { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE };

    pub fn to_mat4(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// `T * R * S` in double precision (used by the reference pose).
    pub fn to_dmat4(&self) -> glam::DMat4 {
        glam::DMat4::from_scale_rotation_translation(
            self.scale.as_dvec3(),
            self.rotation.as_dquat().normalize(),
            self.translation.as_dvec3(),
        )
    }
}

impl Default for Trs {
    fn default() -> Self {
        Trs::IDENTITY
    }
}

/// One node's range of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeRange {
    /// The node (index into the skeleton's nodes).
    pub node: u32,
    /// Unit centre rotation.
    pub centre: Quat,
    /// Largest rotation angle from the centre that the bounds cover (radians, from
    /// 2 × [`GUARD_SLACK`] to π: the guard admits rotations up to `GUARD_SLACK` less, so a
    /// narrower cap could admit none; envelopes made by the baker add `2 × GUARD_SLACK`).
    pub angle: f32,
    /// Translation and scale boxes (min, max).
    pub translation: (Vec3, Vec3),
    pub scale: (Vec3, Vec3),
}

/// Checks an envelope's ranges from outside (a file): nodes listed once (and below
/// `node_count` when given), unit finite centres, angles in [2 × [`GUARD_SLACK`], π],
/// ordered finite boxes, `weight_count` morph weight ranges, ordered and finite.
pub fn check_ranges(
    nodes: &[NodeRange],
    weights: &[(f32, f32)],
    node_count: Option<usize>,
    weight_count: usize,
) -> Result<()> {
    let bad = |what: String| Err(Error::invalid("pose envelope", what));
    let mut ids: Vec<u32> = nodes.iter().map(|r| r.node).collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return bad(format!("node {} listed twice", w[0]));
    }
    for r in nodes {
        if let Some(n) = node_count.filter(|&n| r.node as usize >= n) {
            return bad(format!("node {} of {n}", r.node));
        }
        let ordered = |(lo, hi): (Vec3, Vec3)| lo.is_finite() && hi.is_finite() && lo.cmple(hi).all();
        let unit = r.centre.is_finite() && (r.centre.length() - 1.0).abs() < 1e-4;
        if !(unit && (0.0..=std::f32::consts::PI).contains(&r.angle) && ordered(r.translation) && ordered(r.scale)) {
            return bad(format!("node {}: {r:?} (need a unit centre, an angle in [0, π], ordered boxes)", r.node));
        }
        if r.angle < (2.0 * GUARD_SLACK) as f32 {
            return bad(format!(
                "node {}: cap angle {:e} rad is below twice the guard's slack ({:e} rad): the guard could admit no \
                 rotation",
                r.node, r.angle, GUARD_SLACK
            ));
        }
    }
    if weights.len() != weight_count {
        return bad(format!("{} morph weight ranges for {weight_count} morph weights", weights.len()));
    }
    if let Some((k, w)) = weights.iter().enumerate().find(|(_, w)| !(w.0.is_finite() && w.1.is_finite() && w.0 <= w.1))
    {
        return bad(format!("morph weight {k}: range {w:?}"));
    }
    Ok(())
}

/// The run-time guard: whether a pose lies inside a pose envelope, so that bounds computed
/// for it hold. Per listed node one quaternion product and two box tests, in f32, no
/// allocation. A rotation `q` is compared by the vector part of `centre⁻¹·q` (accurate for
/// small angles too, where a cosine is flat): `|v|² ≤ tan²(θ/2)·w²` for an angle
/// [`GUARD_SLACK`] smaller than the bounds cover (a cap of π covers, and admits, every
/// rotation); boxes and ranges are widened by [`BOX_SLACK`], half what the bounds cover.
/// Built once per envelope ([`PoseGuard::new`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PoseGuard {
    nodes: Vec<u32>,
    centres: Vec<Quat>,
    tan2: Vec<f32>,
    translation: Vec<(Vec3, Vec3)>,
    scale: Vec<(Vec3, Vec3)>,
    weights: Vec<(f32, f32)>,
}

impl PoseGuard {
    /// The guard of an envelope: its node ranges and morph weight ranges. Errors where
    /// [`check_ranges`] does.
    pub fn new(nodes: &[NodeRange], weights: &[(f32, f32)]) -> Result<PoseGuard> {
        check_ranges(nodes, weights, None, weights.len())?;
        let widen = |(lo, hi): (Vec3, Vec3)| {
            let w: [(f64, f64); 3] = std::array::from_fn(|k| widened(lo[k] as f64, hi[k] as f64, 1.0));
            (
                Vec3::new(w[0].0 as f32, w[1].0 as f32, w[2].0 as f32),
                Vec3::new(w[0].1 as f32, w[1].1 as f32, w[2].1 as f32),
            )
        };
        Ok(PoseGuard {
            nodes: nodes.iter().map(|r| r.node).collect(),
            centres: nodes.iter().map(|r| r.centre.conjugate()).collect(),
            tan2: (nodes.iter())
                .map(|r| {
                    // A cap of π holds every rotation: nothing to keep a slack from.
                    if r.angle >= std::f32::consts::PI {
                        return f32::INFINITY;
                    }
                    // `check_ranges` keeps the angle at least twice the slack.
                    ((r.angle as f64 - GUARD_SLACK) / 2.0).tan().powi(2) as f32
                })
                .collect(),
            translation: nodes.iter().map(|r| widen(r.translation)).collect(),
            scale: nodes.iter().map(|r| widen(r.scale)).collect(),
            weights: (weights.iter())
                .map(|&(lo, hi)| {
                    let (lo, hi) = widened(lo as f64, hi as f64, 1.0);
                    (lo as f32, hi as f32)
                })
                .collect(),
        })
    }

    /// Whether a pose is inside: `locals` holds every node's local transform (skeleton
    /// order), `weights` the morph weights' values. A pose without a listed node is not.
    pub fn admits(&self, locals: &[Trs], weights: &[f32]) -> bool {
        let inside = |x: Vec3, (lo, hi): (Vec3, Vec3)| x.cmpge(lo).all() && x.cmple(hi).all();
        (0..self.nodes.len()).all(|i| {
            let Some(l) = locals.get(self.nodes[i] as usize) else { return false };
            let rel = self.centres[i] * l.rotation;
            let v2 = rel.x * rel.x + rel.y * rel.y + rel.z * rel.z;
            (v2 <= self.tan2[i] * rel.w * rel.w || (self.tan2[i] == f32::INFINITY && rel.is_finite()))
                && inside(l.translation, self.translation[i])
                && inside(l.scale, self.scale[i])
        }) && self.admits_weights(weights)
    }

    /// Whether the morph weights lie in the envelope's ranges: the any-pose boxes hold for
    /// any joints then.
    pub fn admits_weights(&self, weights: &[f32]) -> bool {
        weights.len() == self.weights.len() && weights.iter().zip(&self.weights).all(|(w, r)| (r.0..=r.1).contains(w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn range(centre: Quat, angle: f32) -> NodeRange {
        NodeRange { node: 0, centre, angle, translation: (Vec3::ZERO, Vec3::ZERO), scale: (Vec3::ONE, Vec3::ONE) }
    }

    #[test]
    fn a_cap_narrower_than_the_slack_is_refused_with_a_reason() {
        let err = PoseGuard::new(&[range(Quat::IDENTITY, 3e-6)], &[]).unwrap_err().to_string();
        assert!(err.contains("node 0") && err.contains("slack"), "{err}");
        assert!(PoseGuard::new(&[range(Quat::IDENTITY, (2.0 * GUARD_SLACK) as f32)], &[]).is_ok());
    }

    proptest! {
        /// The narrowest cap the guard takes still admits its centre and every rotation
        /// `2 × GUARD_SLACK` inside it, for any centre and axis (the f32 product's rounding
        /// stays within the slack); and refuses rotations past the cap.
        #[test]
        fn narrow_and_wide_caps_admit_what_they_cover(
            c in prop::array::uniform4(-1.0f32..1.0),
            a in prop::array::uniform3(-1.0f32..1.0),
            wide in 0.0f32..3.0,
            f in 0.0f32..1.0,
        ) {
            let centre = Quat::from_array(c);
            let axis = Vec3::from_array(a);
            prop_assume!(centre.length() > 0.1 && axis.length() > 0.1);
            let (centre, axis) = (centre.normalize(), axis.normalize());
            for angle in [(2.0 * GUARD_SLACK) as f32, wide + (2.0 * GUARD_SLACK) as f32] {
                let guard = PoseGuard::new(&[range(centre, angle)], &[]).unwrap();
                let pose = |turn: f32| {
                    [Trs { rotation: (Quat::from_axis_angle(axis, turn) * centre).normalize(), translation: Vec3::ZERO, scale: Vec3::ONE }]
                };
                let inside = (angle - (2.0 * GUARD_SLACK) as f32).max(0.0);
                prop_assert!(guard.admits(&pose(0.0), &[]), "centre of a cap of {angle}");
                for turn in [f * inside, inside] {
                    prop_assert!(guard.admits(&pose(turn), &[]), "{turn} inside a cap of {angle}");
                }
                if angle + 0.01 < std::f32::consts::PI {
                    prop_assert!(!guard.admits(&pose(angle + 0.01), &[]), "past a cap of {angle}");
                }
            }
            // A cap of π (envelopes clamp there) holds every rotation, half a turn included.
            let guard = PoseGuard::new(&[range(centre, std::f32::consts::PI)], &[]).unwrap();
            for turn in [f * std::f32::consts::PI, std::f32::consts::PI] {
                let rotation = (Quat::from_axis_angle(axis, turn) * centre).normalize();
                prop_assert!(guard.admits(&[Trs { rotation, ..Trs::IDENTITY }], &[]), "{turn} in a cap of π");
            }
            let nan = Trs { rotation: Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0), ..Trs::IDENTITY };
            prop_assert!(!guard.admits(&[nan], &[]));
        }
    }
}
