//! Pose envelopes: bounds for the poses games make (crossfades, additive layers, IK, scripted
//! joints), not only for clips played alone. The conservative-bounds paper (section 8) names
//! IK and blending as open; a crossfade turns each joint along the arc between two clips'
//! rotations, which neither clip visits, so the union of clip bounds does not hold for it.
//!
//! An envelope is, per node, a range of motion: every local rotation within `angle` of a
//! centre rotation (a cap), and a box for the translation and one for the scale; plus a range
//! per morph weight. Bounds computed for it ([`envelope_bounds`]) hold for every pose inside
//! it, whatever produced the pose: the cap acts on boxes exactly ([`super::motion::cap_extent`])
//! and everything downstream is the clip bounds' machinery ([`super::vertex`], the corner
//! argument for cones). Blends stay inside: boxes and ranges are convex, and a cap of angle
//! below 90° holds two rotations less than 90° apart, whose representatives on the quaternion
//! sphere are then less than 45° apart, so shortest-path slerp and nlerp run along the arc
//! between them, inside the cap. [`PoseGuard`] is the run-time guard that checks a pose.
//!
//! [`Envelope::from_clips`] makes the smallest such envelope around every clip, between keys
//! too (the exact largest angle from the centre over each LINEAR arc, a bound over each
//! CUBICSPLINE piece; [`super::motion::RotationMotion::min_abs_dot`]), widened by a margin
//! for additive layers and IK.

use super::Aabb;
use super::motion::{Motion, RotationMotion, node_motion};
use super::refine::Ctx;
use super::sphere_cone::{MeshletBounds, key_intervals, piece_extent, rest_bounds, round_up};
use super::vertex::{IntervalMotions, clip_weight_ranges};
use crate::clip::Clip;
use crate::meshlet::Meshlets;
use crate::model::{Skeleton, Skin, SkinnedMesh, Trs};
use crate::{Error, Result};
use glam::{DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

pub use skinlet_runtime::pose_guard::{BOX_SLACK, GUARD_SLACK, NodeRange, PoseGuard, widened};

/// A pose envelope: ranges of motion of the nodes that move the skin's joints, and of the
/// morph weights. Nodes not listed keep their rest transform (glTF `matrix` nodes keep their
/// matrix).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Envelope {
    pub nodes: Vec<NodeRange>,
    /// Per morph weight of the mesh (`Morphs::weights`), its range (min, max).
    pub weights: Vec<(f32, f32)>,
}

fn down(x: f64) -> f32 {
    -round_up(-x)
}

impl Envelope {
    /// The envelope of `clips` (and the rest pose) for the joints of `skin` and the morph
    /// weights of `mesh`: per node that is a joint or a joint's ancestor and not a `matrix`
    /// node, the box of its translations and scales and the narrowest cap found around its
    /// rotations, between keys included, widened by `margin` radians (rotations only) and by
    /// [`GUARD_SLACK`]; per morph weight its range over the clips and its default.
    pub fn from_clips(
        skeleton: &Skeleton,
        skin: &Skin,
        mesh: &SkinnedMesh,
        clips: &[&Clip],
        margin: f64,
    ) -> Result<Envelope> {
        if !(0.0..=PI).contains(&margin) {
            return Err(Error::invalid("pose envelope", format!("margin {margin} rad (need 0 to π)")));
        }
        let mut wanted = vec![false; skeleton.nodes.len()];
        for &j in &skin.joints {
            for n in skeleton.ancestry(j) {
                wanted[n as usize] = true;
            }
        }
        let intervals: Vec<(&Clip, f32, f32)> =
            clips.iter().flat_map(|c| key_intervals(c).into_iter().map(move |(a, b)| (*c, a, b))).collect();
        let nodes = (0..skeleton.nodes.len() as u32)
            .filter(|&n| wanted[n as usize] && skeleton.nodes[n as usize].matrix.is_none())
            .collect::<Vec<_>>()
            .par_iter()
            .map(|&n| {
                let node = &skeleton.nodes[n as usize];
                let mut motions = vec![node_motion(node, n, None, 0.0, 0.0)?];
                for &(c, a, b) in &intervals {
                    if c.animates(n) {
                        motions.push(node_motion(node, n, Some(c), a, b)?);
                    }
                }
                Ok(node_range(n, &motions, margin))
            })
            .collect::<Result<Vec<_>>>()?;
        let weights = clip_weight_ranges(&mesh.morphs, clips)?
            .into_iter()
            .zip(&mesh.morphs.weights)
            .map(|((lo, hi), w)| (down(lo.min(w.default as f64)), round_up(hi.max(w.default as f64))))
            .collect();
        Ok(Envelope { nodes, weights })
    }

    /// This envelope with some nodes' ranges replaced by a joint-limits file (JSON):
    ///
    /// ```json
    /// { "joints": { "LeftForeArm": { "angle_deg": 70, "centre": [0, 0, 0, 1],
    ///                                "translation": [[0, 0.2, 0], [0, 0.3, 0]],
    ///                                "scale": [[1, 1, 1], [1, 1, 1]] } } }
    /// ```
    ///
    /// Each key names a node this envelope lists (a joint or a joint's ancestor); `angle_deg`
    /// (0 to 180) is required, `centre` (a unit quaternion x, y, z, w) defaults to the node's
    /// rest rotation, `translation` and `scale` (min and max corners) keep this envelope's
    /// boxes when absent. The bounds cover the angle plus [`GUARD_SLACK`] twice, like clip
    /// envelopes. Errors say which joint and field is wrong.
    pub fn with_limits(mut self, skeleton: &Skeleton, json: &str) -> Result<Envelope> {
        let bad = |what: String| Error::invalid("joint limits", what);
        let doc: serde_json::Value = serde_json::from_str(json).map_err(|e| bad(e.to_string()))?;
        let joints = doc.get("joints").and_then(|j| j.as_object()).ok_or_else(|| bad("no \"joints\" object".into()))?;
        let floats = |v: &serde_json::Value, n: usize, what: &str| -> Result<Vec<f32>> {
            let a =
                v.as_array().filter(|a| a.len() == n).ok_or_else(|| bad(format!("{what}: expected {n} numbers")))?;
            a.iter()
                .map(|x| x.as_f64().filter(|x| x.is_finite()).map(|x| x as f32))
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| bad(format!("{what}: expected {n} finite numbers")))
        };
        let corners = |v: &serde_json::Value, what: &str| -> Result<(Vec3, Vec3)> {
            let a = v.as_array().filter(|a| a.len() == 2).ok_or_else(|| bad(format!("{what}: expected [min, max]")))?;
            let (lo, hi) = (Vec3::from_slice(&floats(&a[0], 3, what)?), Vec3::from_slice(&floats(&a[1], 3, what)?));
            if !lo.cmple(hi).all() {
                return Err(bad(format!("{what}: min {lo} above max {hi}")));
            }
            Ok((lo, hi))
        };
        for (name, limits) in joints {
            let node = skeleton
                .nodes
                .iter()
                .position(|n| &n.name == name)
                .ok_or_else(|| bad(format!("no node named {name:?}")))?;
            let range = self.nodes.iter_mut().find(|r| r.node as usize == node).ok_or_else(|| {
                bad(format!("{name:?} does not move the skin (not a joint or a joint's ancestor), or is a matrix node"))
            })?;
            let field = |f: &str| format!("{name:?}.{f}");
            let angle = limits
                .get("angle_deg")
                .and_then(|a| a.as_f64())
                .filter(|a| (0.0..=180.0).contains(a))
                .ok_or_else(|| bad(format!("{}: expected a number from 0 to 180", field("angle_deg"))))?;
            range.angle = round_up((angle.to_radians() + 2.0 * GUARD_SLACK).min(PI));
            range.centre = match limits.get("centre") {
                Some(c) => {
                    let q = Quat::from_slice(&floats(c, 4, &field("centre"))?);
                    if (q.length() - 1.0).abs() > 1e-3 {
                        return Err(bad(format!("{}: not a unit quaternion", field("centre"))));
                    }
                    q.normalize()
                }
                None => skeleton.nodes[node].rest.rotation.normalize(),
            };
            if let Some(t) = limits.get("translation") {
                range.translation = corners(t, &field("translation"))?;
            }
            if let Some(sc) = limits.get("scale") {
                range.scale = corners(sc, &field("scale"))?;
            }
        }
        Ok(self)
    }

    /// Checks an envelope from outside (a file): nodes below `nodes` and listed once, unit
    /// finite centres, angles in [0, π], ordered finite boxes, `weights` ranges, ordered.
    pub fn check(&self, nodes: usize, weights: usize) -> Result<()> {
        Ok(skinlet_runtime::pose_guard::check_ranges(&self.nodes, &self.weights, Some(nodes), weights)?)
    }

    /// The motions the envelope allows, as one "interval" for the vertex boxes: listed nodes
    /// within their cap and boxes, the others at rest (or their matrix); nodes the skeleton
    /// does not have are ignored ([`Envelope::check`] refuses them).
    pub fn motions(&self, skeleton: &Skeleton) -> IntervalMotions {
        let mut motions: Vec<Motion> = (skeleton.nodes.iter().enumerate())
            .map(|(i, n)| node_motion(n, i as u32, None, 0.0, 0.0).expect("no clip: no key to span"))
            .collect();
        for r in &self.nodes {
            let b = |(lo, hi): (Vec3, Vec3)| {
                let w: [(f64, f64); 3] = std::array::from_fn(|k| widened(lo[k] as f64, hi[k] as f64, 2.0));
                Aabb { min: DVec3::new(w[0].0, w[1].0, w[2].0), max: DVec3::new(w[0].1, w[1].1, w[2].1) }
            };
            let Some(m) = motions.get_mut(r.node as usize) else { continue };
            *m = Motion::Trs {
                translation: b(r.translation),
                rotation: RotationMotion::Cap { centre: r.centre.as_dquat().normalize(), angle: r.angle as f64 },
                scale: b(r.scale),
            };
        }
        IntervalMotions::from_motions(skeleton, motions, self.weight_ranges())
    }

    /// The morph weight ranges bounds must cover: each range widened by twice
    /// [`BOX_SLACK`], like the boxes.
    pub fn weight_ranges(&self) -> Vec<(f64, f64)> {
        self.weights.iter().map(|&(lo, hi)| widened(lo as f64, hi as f64, 2.0)).collect()
    }

    /// `count` poses inside the envelope, deterministic for `seed`, for checking bounds: every
    /// node's local transform (listed nodes within their cap, less the guard's slack, and
    /// boxes; the others at rest) and the morph weights. Every other pose lies on the
    /// envelope's boundary (the full angle, box corners, range ends), where bounds are
    /// tightest; the rest anywhere inside.
    pub fn sample_poses(&self, skeleton: &Skeleton, count: usize, seed: u64) -> Vec<(Vec<Trs>, Vec<f32>)> {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut u = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..count)
            .map(|k| {
                let edge = k % 2 == 0;
                let t = |u: &mut dyn FnMut() -> f32| if edge { (u() < 0.5) as u8 as f32 } else { u() };
                let mut locals: Vec<Trs> = skeleton.nodes.iter().map(|n| n.rest).collect();
                for r in &self.nodes {
                    let axis = loop {
                        let v = Vec3::new(u() * 2.0 - 1.0, u() * 2.0 - 1.0, u() * 2.0 - 1.0);
                        if v.length() > 0.1 && v.length() <= 1.0 {
                            break v.normalize();
                        }
                    };
                    let angle = (r.angle - 2.0 * GUARD_SLACK as f32).max(0.0) * if edge { 1.0 } else { u() };
                    let mut within =
                        |(lo, hi): (Vec3, Vec3)| lo + (hi - lo) * Vec3::new(t(&mut u), t(&mut u), t(&mut u));
                    let (translation, scale) = (within(r.translation), within(r.scale));
                    if let Some(l) = locals.get_mut(r.node as usize) {
                        *l = Trs {
                            rotation: (Quat::from_axis_angle(axis, angle) * r.centre).normalize(),
                            translation,
                            scale,
                        };
                    }
                }
                let weights = self.weights.iter().map(|&(lo, hi)| lo + (hi - lo) * t(&mut u)).collect();
                (locals, weights)
            })
            .collect()
    }

    /// The run-time guard for this envelope ([`PoseGuard`]). Errors where
    /// [`skinlet_runtime::pose_guard::check_ranges`] refuses the ranges.
    pub fn guard(&self) -> Result<PoseGuard> {
        Ok(PoseGuard::new(&self.nodes, &self.weights)?)
    }
}

/// The range of one node over its motions: boxes united, the cap's centre found by moving a
/// sign-aligned mean of sample rotations towards the farthest sample, its angle the exact
/// (or bounded) largest angle from the centre over every motion.
fn node_range(node: u32, motions: &[Motion], margin: f64) -> NodeRange {
    let (mut t, mut s) = (Aabb::EMPTY, Aabb::EMPTY);
    let mut rotations = Vec::new();
    let mut samples: Vec<DQuat> = Vec::new();
    for m in motions {
        let Motion::Trs { translation, rotation, scale } = m else { continue };
        t = t.union(translation);
        s = s.union(scale);
        match rotation {
            RotationMotion::Fixed(q) => samples.push(*q),
            RotationMotion::Set(qs) => samples.extend(qs),
            RotationMotion::Arc { start, axis, angle } => {
                samples.extend([0.0, 0.5, 1.0].map(|f| DQuat::from_axis_angle(*axis, f * angle) * *start))
            }
            RotationMotion::Intervals { quats, .. } => samples.extend(quats.iter().filter_map(|r| {
                let q = DQuat::from_xyzw(
                    (r[0].0 + r[0].1) / 2.0,
                    (r[1].0 + r[1].1) / 2.0,
                    (r[2].0 + r[2].1) / 2.0,
                    (r[3].0 + r[3].1) / 2.0,
                );
                (q.length() > 0.0).then(|| q.normalize())
            })),
            RotationMotion::Cap { centre, .. } => samples.push(*centre),
        }
        rotations.push(rotation);
    }
    let align = |q: DQuat, c: DQuat| if q.dot(c) < 0.0 { -q } else { q };
    let first = samples.first().copied().unwrap_or(DQuat::IDENTITY);
    let sum = samples.iter().fold(DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), |acc, &q| acc + align(q, first));
    let mut centre = if sum.length() > 1e-12 { sum.normalize() } else { first };
    for i in 0..32 {
        let far = samples.iter().copied().min_by(|a, b| a.dot(centre).abs().total_cmp(&b.dot(centre).abs()));
        let Some(far) = far else { break };
        centre = (centre + (align(far, centre) - centre) * (1.0 / (i as f64 + 3.0))).normalize();
    }
    let centre32 = centre.as_quat().normalize();
    let c = centre32.as_dquat().normalize();
    let min_dot = rotations.iter().map(|r| r.min_abs_dot(c)).fold(1.0, f64::min);
    let angle = (2.0 * min_dot.clamp(0.0, 1.0).acos() + margin + 2.0 * GUARD_SLACK).min(PI);
    let f32_box = |b: Aabb| (b.min.to_array().map(down).into(), b.max.to_array().map(round_up).into());
    NodeRange {
        node,
        centre: centre32,
        angle: round_up(angle).min(std::f32::consts::PI),
        translation: f32_box(t),
        scale: f32_box(s),
    }
}

/// Bounds of every meshlet for every pose inside `envelope`: the rest bounds (same joint,
/// center and axis) with the radius and cone grown over the envelope's motions, as clip
/// bounds grow over a key interval.
pub fn envelope_bounds(
    skeleton: &Skeleton,
    skin: &Skin,
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    envelope: &Envelope,
) -> Result<Vec<MeshletBounds>> {
    if mesh.influences.is_none() {
        return Err(Error::invalid("envelope bounds", "the mesh has no skin weights"));
    }
    mesh.morphs.check(mesh.positions.len())?;
    envelope.check(skeleton.nodes.len(), mesh.morphs.weights.len())?;
    let motions = envelope.motions(skeleton);
    let ctx = Ctx { skeleton, skin, mesh, meshlets };
    let mut bounds = rest_bounds(skin, mesh, meshlets);
    bounds.par_iter_mut().zip(&meshlets.meshlets).for_each(|(b, m)| {
        let (radius, min_cos) = piece_extent(&ctx, m, b, &motions, &mut Vec::new());
        let min_cos = min_cos.min((b.rest_cone_angle as f64).cos());
        b.radius = round_up(radius.max(b.radius as f64));
        b.cone_angle = if min_cos > 0.0 { round_up(min_cos.min(1.0).acos()) } else { PI as f32 };
    });
    Ok(bounds)
}
