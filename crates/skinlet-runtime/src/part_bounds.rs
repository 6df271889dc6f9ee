//! One box per part of a baked character (a glTF node drawing one mesh primitive: what an
//! engine culls as one entity), every frame, morph targets included.
//!
//! Four bounds, each conservative for the poses it is valid for; [`PartBounds::part_box`]
//! moves the clip window's box, or the clip or envelope bounds, when they hold, else the
//! any-pose boxes ([`PartBounds::pruned`] drops clip and envelope bounds that are no tighter
//! than the any-pose boxes at the bind pose).
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
//!   (conservative-bounds paper, section 5), their morph weights included. The spheres on one
//!   principal joint are merged at load into one box of their centers grown by a ball of
//!   their largest radius (a superset of each sphere), so a frame moves one shape per joint,
//!   not one per meshlet.
//! - **A clip at a known time** ([`PoseBounds::ClipAt`]): the part's box over the clip window
//!   holding the time (`PWIN`, built by `skinlet::bounds::part_windows` from the paper's
//!   conservative vertex boxes over every key interval touching the window), in the skinning
//!   space of one driver, the part's anchor: one box moved by one matrix, whatever the number
//!   of joints.
//! - **The pose envelope** ([`PoseBounds::Envelope`]): the same for `ENVL`'s bounds, which hold
//!   for every pose the pose guard admits.
//!
//! A box grown by a ball `{c + h∘u + r·b : |u|∞ ≤ 1, |b| ≤ 1}` moved by `x ↦ A·x + t` is
//! bounded exactly per axis `i` by `(A·c + t)ᵢ ± (Σⱼ |Aᵢⱼ| hⱼ + r·|row i of A|)` (Arvo's method
//! plus the ball's reach). The f32 rounding of every move is covered by a relative margin of
//! 1e-5 of the magnitudes involved (far above the few ulps it can be). A matrix that is not
//! finite gives the infinite box.

use crate::bake_view::{BakeView, BakedBounds, BakedPartRecord};
use crate::contour_patches::ClipWindows;
use crate::joint_boxes::Box3;
use crate::meshlet_bounds::round_up;
use crate::{Error, Result};
use glam::{Affine3A, DVec3, Mat4, Vec3, Vec3A};

/// Which stored bounds hold for this frame's pose, besides the any-pose boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseBounds {
    /// Only the any-pose boxes (procedural poses, ragdolls, blends the guard refused).
    Any,
    /// The pose is one of the baked clips' (one baked clip playing alone).
    Clips,
    /// The pose is baked clip `clip` (`INFO`'s order) at `time` seconds (played alone): the
    /// part's box over the window holding `time` (`PWIN`) when the bake has them, else as
    /// [`PoseBounds::Clips`] (also for a time that is not finite).
    ClipAt { clip: u32, time: f32 },
    /// The pose guard admitted the pose (`pose_guard::PoseGuard::admits`).
    Envelope,
}

/// A box grown by a ball in one driver's bind space (center, half extents, radius), with a
/// range of morph boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct JointBox {
    driver: u32,
    center: Vec3A,
    half: Vec3A,
    radius: f32,
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

/// Ranges of `boxes` for one part's any-pose, clip and envelope bounds, `[start, end)` each.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PartRanges {
    any: [u32; 2],
    clips: [u32; 2],
    envelope: [u32; 2],
}

/// A part's box over one clip window (`PWIN`), in its anchor's skinning space: center, half
/// extents, and `reach = |B|·(|center| + half) + |t_B|` (the magnitude of its points in the
/// anchor's node space, `B` the anchor's inverse bind matrix) that sizes the rounding margin.
#[derive(Clone, Copy, Debug, PartialEq)]
struct WindowBox {
    center: Vec3A,
    half: Vec3A,
    reach: Vec3A,
}

/// Every part's boxes, built once from a bake; [`PartBounds::part_box`] every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PartBounds {
    parts: Vec<BakedPartRecord>,
    ranges: Vec<PartRanges>,
    boxes: Vec<JointBox>,
    morphs: Vec<MorphBox>,
    drivers: usize,
    weights: usize,
    envelope: bool,
    /// Every driver's matrix at the bind pose (the inverse of its inverse bind matrix).
    bind: Vec<Affine3A>,
    /// `PWIN`: per clip its windows; per part its anchor driver and that driver's inverse
    /// bind matrix; per part and window a box (`windows[part * window_count + w]`).
    clip_windows: Vec<ClipWindows>,
    anchors: Vec<(u32, Affine3A)>,
    windows: Vec<WindowBox>,
    window_count: usize,
}

/// The relative margin that covers the f32 rounding of moving a box (a few ulps, ~1e-7).
const MOVE_MARGIN: f32 = 1e-5;

/// Grows an f64 box outward and stores it in f32 (center, half extents): by 2e-6 of its
/// largest coordinate magnitude (at least 1e-30), far above the f32 rounding of the store.
/// The half extents also carry `MOVE_MARGIN·|center|`, so a move that covers its own
/// rounding only adds `MOVE_MARGIN` of the half extents and translation it makes.
fn stored(lo: DVec3, hi: DVec3) -> (Vec3A, Vec3A) {
    let grow = 2e-6 * lo.abs().max(hi.abs()).max_element().max(1e-30);
    let (lo, hi) = (lo - grow, hi + grow);
    let center = ((lo + hi) / 2.0).as_vec3a();
    (center, ((hi - lo) / 2.0 * (1.0 + 1e-6)).as_vec3a() + center.abs() * MOVE_MARGIN)
}

/// `|m|·v + |t|`: the magnitude bound of `m·x` for `|x| ≤ v` (entrywise absolute values).
fn abs_move(m: &Affine3A, v: Vec3A) -> Vec3A {
    m.matrix3.x_axis.abs() * v.x + m.matrix3.y_axis.abs() * v.y + m.matrix3.z_axis.abs() * v.z + m.translation.abs()
}

/// A part's meshlet spheres, one box grown by a ball per principal joint; returns the range
/// of `out.boxes` they went to.
fn merged_spheres(records: &[BakedBounds], part: &BakedPartRecord, out: &mut PartBounds) -> [u32; 2] {
    let start = out.boxes.len() as u32;
    let mut records: Vec<&BakedBounds> = records[part.meshlets[0] as usize..part.meshlets[1] as usize].iter().collect();
    records.sort_by_key(|b| b.joint);
    for run in records.chunk_by(|a, b| a.joint == b.joint) {
        let (mut lo, mut hi, mut radius) = (DVec3::INFINITY, DVec3::NEG_INFINITY, 0.0f32);
        for b in run {
            let c = Vec3::from(b.center);
            (lo, hi) = (lo.min(c.as_dvec3()), hi.max(c.as_dvec3()));
            // Stored centers are exact; the radius grows by 2e-6 of the sphere's magnitude.
            radius = radius.max(b.radius + 2e-6 * (c.abs().max_element() + b.radius));
        }
        let (center, half) = stored(lo, hi);
        let morphs = [out.morphs.len() as u32; 2];
        out.boxes.push(JointBox { driver: run[0].joint, center, half, radius: radius * (1.0 + 1e-6), morphs });
    }
    [start, out.boxes.len() as u32]
}

impl PartBounds {
    /// The boxes of every part of `view` (the any-pose boxes from its vertices, skin weights
    /// and morph deltas; the clip boxes from `BNDS`; the envelope boxes from `ENVL` when the
    /// bake has one). Allocates: run it once, at load. Errors on a bake the view refuses.
    pub fn new(view: &BakeView) -> Result<PartBounds> {
        let parts = view.parts();
        let vertices = view.vertices();
        let inverse_bind: Vec<Mat4> = view.inverse_bind().iter().map(Mat4::from_cols_array).collect();
        let nodes = view.joint_nodes();
        let morphs = view.morphs();
        let weights = morphs.map_or(0, |m| m.weights.len());
        let bounds = view.meshlet_bounds();
        let envelope = view.envelope();
        let (drivers, stride) = (inverse_bind.len(), vertices.stride);
        let mut out = PartBounds {
            parts: Vec::new(),
            ranges: Vec::new(),
            boxes: Vec::new(),
            morphs: Vec::new(),
            drivers,
            weights,
            envelope: false,
            bind: Vec::new(),
            clip_windows: Vec::new(),
            anchors: Vec::new(),
            windows: Vec::new(),
            window_count: 0,
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
                out.boxes.push(JointBox {
                    driver: d as u32,
                    center,
                    half,
                    radius: 0.0,
                    morphs: [start, out.morphs.len() as u32],
                });
            }
            let any = [any_start, out.boxes.len() as u32];
            let clips = merged_spheres(bounds, part, &mut out);
            let envelope = match envelope {
                Some(e) => merged_spheres(e.bounds, part, &mut out),
                None => [0, 0],
            };
            out.ranges.push(PartRanges { any, clips, envelope });
        }
        if let Some(w) = view.part_windows() {
            out.anchors = w.anchors.iter().map(|&a| (a, Affine3A::from_mat4(inverse_bind[a as usize]))).collect();
            out.window_count = w.windows();
            for (i, b) in w.boxes.iter().enumerate() {
                let (lo, hi) = (b[0].as_dvec3(), b[1].as_dvec3());
                let c = (lo + hi) / 2.0;
                let h = (hi - c.as_vec3().as_dvec3()).max(c.as_vec3().as_dvec3() - lo);
                let (center, half) = (c.as_vec3a(), Vec3A::new(round_up(h.x), round_up(h.y), round_up(h.z)));
                let reach = abs_move(&out.anchors[i / out.window_count.max(1)].1, center.abs() + half) * (1.0 + 1e-6);
                out.windows.push(WindowBox { center, half, reach });
            }
            out.clip_windows = w.clips.clone();
        }
        out.parts = parts.to_vec();
        out.envelope = envelope.is_some();
        out.bind = inverse_bind.iter().map(|m| Affine3A::from_mat4(*m).inverse()).collect();
        Ok(out)
    }

    /// Drops each part's clip and envelope bounds whose box at the bind pose is no smaller
    /// than its any-pose boxes' (few, large meshlets, say): for those poses each frame then
    /// moves the any-pose boxes alone. Whichever is moved, the box is conservative; this keeps
    /// the tighter at the bind pose and skips the other's work.
    pub fn pruned(mut self) -> PartBounds {
        let rest = vec![0.0; self.weights];
        let volume = |range: [u32; 2]| {
            let b = self.moved(range, &Affine3A::IDENTITY, &self.bind, &rest);
            (b.max - b.min).element_product()
        };
        let keep: Vec<[bool; 2]> = (self.ranges.iter())
            .map(|r| {
                let any = volume(r.any);
                [r.clips, r.envelope].map(|n| n[0] < n[1] && volume(n) < any)
            })
            .collect();
        for (r, [clips, envelope]) in self.ranges.iter_mut().zip(keep) {
            r.clips = if clips { r.clips } else { [0, 0] };
            r.envelope = if envelope { r.envelope } else { [0, 0] };
        }
        self
    }

    /// The parts, in the bake's order (node, mesh and primitive of each: how an engine finds
    /// the entity that draws it).
    pub fn parts(&self) -> &[BakedPartRecord] {
        &self.parts
    }

    /// Whether the bake has boxes per clip window (`PWIN`, for [`PoseBounds::ClipAt`]).
    pub fn has_clip_windows(&self) -> bool {
        !self.anchors.is_empty()
    }

    /// Whether the bake has envelope bounds.
    pub fn has_envelope(&self) -> bool {
        self.envelope
    }

    /// Whether `pose` changes which boxes some part moves: false when no part keeps stored
    /// bounds for it (an engine then need not work out the pose at all).
    pub fn narrows(&self, pose: PoseBounds) -> bool {
        if let PoseBounds::ClipAt { clip, time } = pose
            && self.window(clip, time).is_some()
        {
            return !self.anchors.is_empty();
        }
        self.ranges.iter().any(|r| {
            let n = match pose {
                PoseBounds::Any => return false,
                PoseBounds::Clips | PoseBounds::ClipAt { .. } => r.clips,
                PoseBounds::Envelope => r.envelope,
            };
            n[0] < n[1]
        })
    }

    /// The window of `PWIN` holding `time` of clip `clip`, when the bake has them and the
    /// time is finite.
    fn window(&self, clip: u32, time: f32) -> Option<usize> {
        let w = self.clip_windows.get(clip as usize).filter(|_| time.is_finite())?;
        Some(w.at(time) as usize)
    }

    /// The drivers whose matrices [`PartBounds::part_box`] reads for `part` and `pose` (each
    /// once; none for a part out of range): an engine fetches only these joints' matrices.
    pub fn drivers_read(&self, part: usize, pose: PoseBounds) -> impl Iterator<Item = usize> + '_ {
        let anchor = match pose {
            PoseBounds::ClipAt { clip, time } if self.window(clip, time).is_some() => self.anchors.get(part),
            _ => None,
        };
        let range = match (anchor, self.ranges.get(part)) {
            (None, Some(r)) => self.range(r, pose),
            _ => [0, 0],
        };
        let boxes = self.boxes[range[0] as usize..range[1] as usize].iter().map(|b| b.driver as usize);
        anchor.map(|a| a.0 as usize).into_iter().chain(boxes)
    }

    /// The boxes `part_box` moves: the clip or envelope bounds when `pose` says they hold
    /// and the part has them, else the any-pose boxes.
    fn range(&self, r: &PartRanges, pose: PoseBounds) -> [u32; 2] {
        let range = match pose {
            PoseBounds::Any => r.any,
            PoseBounds::Clips | PoseBounds::ClipAt { .. } => r.clips,
            PoseBounds::Envelope => r.envelope,
        };
        if range[0] < range[1] { range } else { r.any }
    }

    /// Part `part`'s box in a target space (an entity's, or the world's) for one frame.
    /// `to_target` maps world space into the target space; `joint_globals[j]` is driver `j`'s
    /// world matrix (its node's global transform: the skinning matrix times the inverse of
    /// the inverse bind matrix), for every driver of the bake; `morph_weights` are the bake's
    /// morph weights (`MRPH`'s order) this frame; `pose` says which stored bounds hold: the
    /// clip or envelope bounds when they do (and the part has them), else the any-pose boxes.
    /// Never panics: a part index out of range, too few matrices or weights, or a matrix that
    /// is not finite gives the infinite box (never culled).
    pub fn part_box(
        &self,
        part: usize,
        to_target: &Affine3A,
        joint_globals: &[Affine3A],
        morph_weights: &[f32],
        pose: PoseBounds,
    ) -> Box3 {
        let Some(r) = self.ranges.get(part) else { return Box3::ALL };
        if joint_globals.len() < self.drivers || morph_weights.len() < self.weights {
            return Box3::ALL;
        }
        if let PoseBounds::ClipAt { clip, time } = pose
            && let Some(w) = self.window(clip, time)
        {
            return self.window_box(part, w, to_target, joint_globals);
        }
        let range = self.range(r, pose);
        self.moved(range, to_target, joint_globals, morph_weights)
    }

    /// Part `part`'s box over window `w`, moved by `to_target · global(anchor) · inverse_bind`.
    /// The f32 products and the move round by at most a few ulps of `|T|·|G|·reach` (the
    /// magnitudes multiplied, `T = to_target`, `G` the anchor's global matrix): the box grows
    /// by `MOVE_MARGIN` of that.
    fn window_box(&self, part: usize, w: usize, to_target: &Affine3A, joint_globals: &[Affine3A]) -> Box3 {
        let (Some(&(anchor, inverse_bind)), Some(b)) =
            (self.anchors.get(part), self.windows.get(part * self.window_count + w))
        else {
            return Box3::ALL;
        };
        let g = joint_globals[anchor as usize];
        let m = *to_target * g * inverse_bind;
        let a = &m.matrix3;
        let center = a.x_axis * b.center.x + a.y_axis * b.center.y + a.z_axis * b.center.z + m.translation;
        let half = a.x_axis.abs() * b.half.x
            + a.y_axis.abs() * b.half.y
            + a.z_axis.abs() * b.half.z
            + abs_move(to_target, abs_move(&g, b.reach)) * MOVE_MARGIN;
        let (lo, hi) = (center - half, center + half);
        if lo.is_finite() && hi.is_finite() { Box3 { min: lo.into(), max: hi.into() } } else { Box3::ALL }
    }

    /// The boxes `range`, moved and morphed, and their union.
    fn moved(&self, range: [u32; 2], to_target: &Affine3A, joint_globals: &[Affine3A], morph_weights: &[f32]) -> Box3 {
        let (mut lo, mut hi, mut magnitude) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, Vec3A::ZERO);
        for b in &self.boxes[range[0] as usize..range[1] as usize] {
            let (mut c, mut h) = (b.center, b.half);
            if b.morphs[0] < b.morphs[1] {
                for m in &self.morphs[b.morphs[0] as usize..b.morphs[1] as usize] {
                    let w = morph_weights[m.weight as usize];
                    (c, h) = (c + m.center * w, h + m.half * w.abs());
                }
                // The sums' rounding, and the move's margin for the new center.
                h += c.abs() * MOVE_MARGIN + h * 1e-6;
            }
            let g = *to_target * joint_globals[b.driver as usize];
            let a = &g.matrix3;
            let center = a.x_axis * c.x + a.y_axis * c.y + a.z_axis * c.z + g.translation;
            let mut half = a.x_axis.abs() * h.x + a.y_axis.abs() * h.y + a.z_axis.abs() * h.z;
            if b.radius > 0.0 {
                let rows = (a.x_axis * a.x_axis + a.y_axis * a.y_axis + a.z_axis * a.z_axis).sqrt();
                half += rows * b.radius;
            }
            // The rounding of `center` (its `|A|·|c|` part is in `h`) and of `half`.
            let half = half * (1.0 + MOVE_MARGIN) + g.translation.abs() * MOVE_MARGIN;
            // NaN and infinity propagate into the sum: one check at the end.
            magnitude += center.abs() + half;
            lo = lo.min(center - half);
            hi = hi.max(center + half);
        }
        if magnitude.is_finite() && lo.is_finite() && hi.is_finite() {
            Box3 { min: lo.into(), max: hi.into() }
        } else {
            Box3::ALL
        }
    }
}
