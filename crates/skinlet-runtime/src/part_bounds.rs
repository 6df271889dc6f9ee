//! One box per part of a baked character (a glTF node drawing one mesh primitive: what an
//! engine culls as one entity), every frame, morph targets included.
//!
//! Three bounds, each conservative for the poses it is valid for; [`PartBounds::part_box`]
//! intersects those that hold:
//! - **Any pose** (always): per-joint boxes, the method of Bevy's per-joint skinned bounds
//!   (`per-joint-skinned-bounds-bevy-pr.txt`), in each driver's bind space, grown by each
//!   morph weight's delta box. A skinned vertex `Σ wⱼ Gⱼ Bⱼ (p + Σₖ μₖ dₖ)` (skin weights ≥ 0
//!   summing to 1, `Bⱼ` the inverse bind matrix, `Gⱼ` the joint's global matrix) is a convex
//!   combination of points `Gⱼ xⱼ` with `xⱼ ∈ boxⱼ + Σₖ μₖ·deltasⱼₖ`, where `boxⱼ` holds
//!   `Bⱼ p` and `deltasⱼₖ` holds the linear part of `Bⱼ` applied to every delta of weight `k`
//!   (and zero), over the vertices `j` influences: so it lies in the union of the moved boxes,
//!   whatever the joint matrices and morph weights.
//! - **The baked clips** ([`PoseBounds::Clips`]): the part's meshlet spheres (`BNDS`, in each
//!   meshlet's principal joint's bind space), which hold over every time of the baked clips
//!   (conservative-bounds paper, section 5), their morph weights included; each sphere moved
//!   exactly (the box of the ellipsoid it becomes).
//! - **The pose envelope** ([`PoseBounds::Envelope`]): the same for `ENVL`'s bounds, which hold
//!   for every pose the pose guard admits.
//!
//! Boxes are moved with Arvo's method; the f32 rounding of every move is covered by a relative
//! margin of 1e-5 of the magnitudes involved (far above the few ulps it can be). A matrix that
//! is not finite gives the infinite box.

use crate::bake_view::{BakeView, BakedBounds, BakedPartRecord};
use crate::joint_boxes::Box3;
use crate::{Error, Result};
use glam::{Affine3A, DVec3, Mat4, Vec3, Vec3A};

/// Which stored bounds hold for this frame's pose, besides the any-pose boxes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseBounds {
    /// Only the any-pose boxes (procedural poses, ragdolls, blends the guard refused).
    Any,
    /// The pose is one of the baked clips' (one baked clip playing alone).
    Clips,
    /// The pose guard admitted the pose (`pose_guard::PoseGuard::admits`).
    Envelope,
}

/// A box in one driver's bind space (center, half extents), with a range of morph boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct JointBox {
    driver: u32,
    center: Vec3A,
    half: Vec3A,
    /// Its morph boxes, `morphs[start..end]`.
    morphs: [u32; 2],
}

/// The delta box of one morph weight for one joint box.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MorphBox {
    weight: u32,
    center: Vec3A,
    half: Vec3A,
}

/// The meshlet spheres of one part on one principal joint (a range of `sphere_list`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct SphereGroup {
    driver: u32,
    spheres: [u32; 2],
}

/// A meshlet sphere in its principal joint's bind space (radius grown for the f32 store).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sphere {
    center: Vec3A,
    radius: f32,
}

/// Ranges of one part's any-pose boxes and its clip and envelope sphere groups, `[start,
/// end)` each.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PartRanges {
    any: [u32; 2],
    clips: [u32; 2],
    envelope: [u32; 2],
}

/// Every part's boxes, built once from a bake; [`PartBounds::part_box`] every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PartBounds {
    parts: Vec<BakedPartRecord>,
    ranges: Vec<PartRanges>,
    boxes: Vec<JointBox>,
    morphs: Vec<MorphBox>,
    spheres: Vec<SphereGroup>,
    sphere_list: Vec<Sphere>,
    drivers: usize,
    weights: usize,
}

/// Grows an f64 box outward and stores it in f32 (center, half extents): by 2e-6 of its
/// largest coordinate magnitude (at least 1e-30), far above the f32 rounding of the store.
fn stored(lo: DVec3, hi: DVec3) -> (Vec3A, Vec3A) {
    let grow = 2e-6 * lo.abs().max(hi.abs()).max_element().max(1e-30);
    let (lo, hi) = (lo - grow, hi + grow);
    (((lo + hi) / 2.0).as_vec3a(), ((hi - lo) / 2.0 * (1.0 + 1e-6)).as_vec3a())
}

/// A part's meshlet spheres grouped by principal joint; returns the range of groups.
fn sphere_groups(records: &[BakedBounds], part: &BakedPartRecord, out: &mut PartBounds) -> [u32; 2] {
    let start = out.spheres.len() as u32;
    let mut records: Vec<&BakedBounds> = records[part.meshlets[0] as usize..part.meshlets[1] as usize].iter().collect();
    records.sort_by_key(|b| b.joint);
    for run in records.chunk_by(|a, b| a.joint == b.joint) {
        let first = out.sphere_list.len() as u32;
        out.sphere_list.extend(run.iter().map(|b| {
            let c = Vec3::from(b.center);
            // Stored centers are exact; the radius grows by 2e-6 of the sphere's magnitude.
            Sphere { center: c.into(), radius: b.radius + 2e-6 * (c.abs().max_element() + b.radius) }
        }));
        out.spheres.push(SphereGroup { driver: run[0].joint, spheres: [first, out.sphere_list.len() as u32] });
    }
    [start, out.spheres.len() as u32]
}

impl PartBounds {
    /// The boxes of every part of `view` (the any-pose boxes from its vertices, skin weights
    /// and morph deltas; the clip boxes from `BNDS`; the envelope boxes from `ENVL` when the
    /// bake has one). Allocates: run it once, at load. Errors on a bake the view refuses.
    pub fn new(view: &BakeView) -> Result<PartBounds> {
        let parts = view.parts()?.to_vec();
        let vertices = view.vertices()?;
        let inverse_bind: Vec<Mat4> = view.inverse_bind()?.iter().map(Mat4::from_cols_array).collect();
        let nodes = view.joint_nodes()?;
        let morphs = view.morphs()?;
        let weights = morphs.map_or(0, |m| m.weights.len());
        let bounds = view.meshlet_bounds()?;
        let envelope = view.envelope(weights)?;
        let (drivers, stride) = (inverse_bind.len(), vertices.stride);
        let mut out = PartBounds {
            parts: Vec::new(),
            ranges: Vec::new(),
            boxes: Vec::new(),
            morphs: Vec::new(),
            spheres: Vec::new(),
            sphere_list: Vec::new(),
            drivers,
            weights,
        };
        for (i, part) in parts.iter().enumerate() {
            let err = |what: String| Error::invalid("bake section PART", format!("part {i}: {what}"));
            // A rigid part (or a bake without skin weights) is weight 1 on its node's driver.
            let rigid = (stride == 0 || part.skin == u32::MAX)
                .then(|| {
                    nodes
                        .iter()
                        .position(|&n| n == part.node)
                        .ok_or_else(|| err(format!("no driver for node {}", part.node)))
                })
                .transpose()?;
            // Per driver: the box of bind-space positions and, per morph weight, of deltas.
            let mut joint: Vec<Option<(DVec3, DVec3)>> = vec![None; drivers];
            let mut delta: Vec<Vec<(u32, DVec3, DVec3)>> = vec![Vec::new(); drivers];
            for v in part.vertices[0] as usize..part.vertices[1] as usize {
                let p = vertices.positions[v].as_dvec3();
                let influences: Vec<usize> = match rigid {
                    Some(d) => vec![d],
                    None => (0..stride)
                        .filter(|&k| vertices.weights[v * stride + k] > 0.0)
                        .map(|k| vertices.joints[v * stride + k] as usize)
                        .collect(),
                };
                for d in influences {
                    let m =
                        inverse_bind.get(d).ok_or_else(|| err(format!("vertex {v} uses driver {d} of {drivers}")))?;
                    let m = m.as_dmat4();
                    let x = m.transform_point3(p);
                    let b = joint[d].get_or_insert((x, x));
                    *b = (b.0.min(x), b.1.max(x));
                    for md in morphs.map_or(&[][..], |m| m.of(v)) {
                        let y = m.transform_vector3(md.position.as_dvec3());
                        match delta[d].iter_mut().find(|(w, _, _)| *w == md.weight) {
                            Some((_, lo, hi)) => (*lo, *hi) = (lo.min(y), hi.max(y)),
                            // Vertices without a delta of this weight add zero.
                            None => delta[d].push((md.weight, y.min(DVec3::ZERO), y.max(DVec3::ZERO))),
                        }
                    }
                }
            }
            let any_start = out.boxes.len() as u32;
            for (d, b) in joint.iter().enumerate() {
                let Some((lo, hi)) = *b else { continue };
                let (center, half) = stored(lo, hi);
                let start = out.morphs.len() as u32;
                delta[d].sort_by_key(|(w, _, _)| *w);
                for &(weight, lo, hi) in &delta[d] {
                    let (center, half) = stored(lo, hi);
                    out.morphs.push(MorphBox { weight, center, half });
                }
                out.boxes.push(JointBox { driver: d as u32, center, half, morphs: [start, out.morphs.len() as u32] });
            }
            let any = [any_start, out.boxes.len() as u32];
            let clips = sphere_groups(bounds, part, &mut out);
            let envelope = match &envelope {
                Some(e) => sphere_groups(e.bounds, part, &mut out),
                None => [0, 0],
            };
            out.ranges.push(PartRanges { any, clips, envelope });
        }
        out.parts = parts;
        Ok(out)
    }

    /// The parts, in the bake's order (node, mesh and primitive of each: how an engine finds
    /// the entity that draws it).
    pub fn parts(&self) -> &[BakedPartRecord] {
        &self.parts
    }

    /// Whether the bake has envelope bounds ([`PoseBounds::Envelope`] narrows anything).
    pub fn has_envelope(&self) -> bool {
        self.ranges.iter().any(|r| r.envelope[0] < r.envelope[1])
    }

    /// Part `part`'s box in a target space (an entity's, or the world's) for one frame.
    /// `to_target` maps world space into the target space; `joint_globals[j]` is driver `j`'s
    /// world matrix (its node's global transform: the skinning matrix times the inverse of
    /// the inverse bind matrix), for every driver of the bake; `morph_weights` are the bake's
    /// morph weights (`MRPH`'s order) this frame; `pose` says which stored bounds hold besides
    /// the any-pose boxes. Never panics: a part index out of range, too few matrices or
    /// weights, or a matrix that is not finite gives the infinite box (never culled).
    pub fn part_box(
        &self,
        part: usize,
        to_target: &Affine3A,
        joint_globals: &[Affine3A],
        morph_weights: &[f32],
        pose: PoseBounds,
    ) -> Box3 {
        const ALL: Box3 = Box3 { min: Vec3::NEG_INFINITY, max: Vec3::INFINITY };
        let Some(r) = self.ranges.get(part) else { return ALL };
        if joint_globals.len() < self.drivers || morph_weights.len() < self.weights {
            return ALL;
        }
        // The any-pose boxes, morphed and moved by Arvo's method.
        let boxes = |range: [u32; 2]| {
            let (mut lo, mut hi, mut finite) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, true);
            for b in &self.boxes[range[0] as usize..range[1] as usize] {
                let (mut c, mut h) = (b.center, b.half);
                for m in &self.morphs[b.morphs[0] as usize..b.morphs[1] as usize] {
                    let w = morph_weights[m.weight as usize];
                    (c, h) = (c + m.center * w, h + m.half * w.abs());
                }
                // The sums' rounding, far inside the margin below.
                h += (c.abs() + h) * 1e-6;
                let g = *to_target * joint_globals[b.driver as usize];
                let a = &g.matrix3;
                let center = a.x_axis * c.x + a.y_axis * c.y + a.z_axis * c.z + g.translation;
                let (ax, ay, az) = (a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs());
                let half = ax * h.x + ay * h.y + az * h.z;
                let scale = ax * c.x.abs() + ay * c.y.abs() + az * c.z.abs() + half + g.translation.abs();
                let half = half + scale * 1e-5;
                finite &= center.is_finite() && half.is_finite();
                lo = lo.min(center - half);
                hi = hi.max(center + half);
            }
            if finite && lo.is_finite() && hi.is_finite() { Box3 { min: lo.into(), max: hi.into() } } else { ALL }
        };
        // Meshlet spheres, each moved exactly: the ellipsoid `A·(c + r·ball) + t` reaches
        // `r·|row i of A|` from its center along axis i.
        let spheres = |range: [u32; 2]| {
            let (mut lo, mut hi, mut finite) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, true);
            for group in &self.spheres[range[0] as usize..range[1] as usize] {
                let g = *to_target * joint_globals[group.driver as usize];
                let a = &g.matrix3;
                let rows = (a.x_axis * a.x_axis + a.y_axis * a.y_axis + a.z_axis * a.z_axis).sqrt();
                let (ax, ay, az) = (a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs());
                for s in &self.sphere_list[group.spheres[0] as usize..group.spheres[1] as usize] {
                    let c = s.center;
                    let center = a.x_axis * c.x + a.y_axis * c.y + a.z_axis * c.z + g.translation;
                    let half = rows * s.radius;
                    let scale = ax * c.x.abs() + ay * c.y.abs() + az * c.z.abs() + half + g.translation.abs();
                    let half = half + scale * 1e-5;
                    finite &= center.is_finite() && half.is_finite();
                    lo = lo.min(center - half);
                    hi = hi.max(center + half);
                }
            }
            if finite && lo.is_finite() && hi.is_finite() { Box3 { min: lo.into(), max: hi.into() } } else { ALL }
        };
        let mut out = boxes(r.any);
        let narrower = match pose {
            PoseBounds::Any => None,
            PoseBounds::Clips => Some(r.clips),
            PoseBounds::Envelope => Some(r.envelope).filter(|e| e[0] < e[1]),
        };
        if let Some(range) = narrower {
            let b = spheres(range);
            out = Box3 { min: out.min.max(b.min), max: out.max.min(b.max) };
        }
        out
    }
}
