//! One box per part (an entity an engine culls whole) and time window of each clip, in the
//! skinning space of one driver, the part's *anchor* (the lowest driver above every joint that
//! moves the part, so that the box turns with the character rather than with a limb). A frame
//! in which one baked clip plays alone moves one box per part with one matrix, where per-joint
//! boxes (Bevy's method) move one box per joint.
//!
//! Built from the conservative vertex boxes of [`super::vertex`] (conservative-bounds paper,
//! sections 3.1 and 3.3): per key interval, every vertex of the part, morph targets included,
//! in the anchor's node space (`global(anchor, t)⁻¹·p(t)`); each box is then taken to the
//! anchor's skinning space (`inverse_bind⁻¹·x`, which is mesh space at the bind pose, so the
//! boxes stay aligned with the mesh rather than with the joint's axes), grown by
//! [`super::INFLATE`] for the f32 rounding of skinning, and united over the key intervals
//! that touch the window (with a little slack at its ends).
//!
//! Guarantee: for every time `t` of the clip whose window is `w`
//! ([`ClipWindows::at`], times clamped to the clip's keys), every vertex of the part, morphed
//! and reference-skinned, lies in `global(anchor, t) · inverse_bind(anchor) · box`.

use super::sphere_cone::key_intervals;
use super::vertex::{IntervalMotions, vertex_box};
use super::{Aabb, INFLATE};
use crate::Result;
use crate::clip::Clip;
use crate::meshlet::stats::principal_joint;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

pub use skinlet_runtime::bake_view::BakedPartWindows as PartWindows;
pub use skinlet_runtime::contour_patches::ClipWindows;
use skinlet_runtime::meshlet_bounds::round_up;

/// Windows per second of clip (at most [`MAX_WINDOWS`] per clip): a clip keyed at 30 Hz
/// gets a window per two key intervals.
pub const WINDOWS_PER_SECOND: f32 = 15.0;
/// Most windows of one clip.
pub const MAX_WINDOWS: u32 = 256;

/// The windows of `clips`: [`WINDOWS_PER_SECOND`] over each clip's keys, at least one.
pub fn clip_windows(clips: &[&Clip]) -> Vec<ClipWindows> {
    let mut first = 0;
    (clips.iter())
        .map(|c| {
            let keys = c.key_times();
            let (start, end) = (keys.first().copied().unwrap_or(0.0), keys.last().copied().unwrap_or(0.0));
            let count = if end > start {
                ((end - start) * WINDOWS_PER_SECOND).ceil().clamp(1.0, MAX_WINDOWS as f32) as u32
            } else {
                1
            };
            let w = ClipWindows { start, end, count, first };
            first += count;
            w
        })
        .collect()
}

/// The anchor of the part with vertices `vertices`: the lowest common ancestor of the nodes
/// of the joints that move them that is a driver (a box in its space turns with the
/// character's frame, not with one limb), else the joint with the largest summed weight.
fn anchor(skeleton: &Skeleton, palette: &Skin, mesh: &SkinnedMesh, vertices: Range<u32>) -> u32 {
    let vertices: Vec<u32> = vertices.collect();
    let principal = principal_joint(mesh, &vertices).map_or(0, |(j, _)| j as u32);
    let Some(inf) = &mesh.influences else { return principal };
    let mut joints: Vec<u16> = vertices.iter().flat_map(|&v| inf.of(v as usize).map(|(j, _)| j)).collect();
    joints.sort_unstable();
    joints.dedup();
    // The ancestry of the first joint's node, cut to the nodes above every other one.
    let mut common: Vec<u32> =
        joints.first().map_or(Vec::new(), |&j| skeleton.ancestry(palette.joints[j as usize]).collect());
    for &j in joints.iter().skip(1) {
        let path: Vec<u32> = skeleton.ancestry(palette.joints[j as usize]).collect();
        common.retain(|n| path.contains(n));
    }
    common.iter().find_map(|n| palette.joints.iter().position(|j| j == n)).map_or(principal, |d| d as u32)
}

/// The boxes of every part (`parts`: vertex ranges of `mesh`, whose influences index
/// `palette`) over every window of `clips`, rounded outward to f32. Errors as
/// [`IntervalMotions::new`] does.
pub fn part_windows(
    skeleton: &Skeleton,
    palette: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    parts: &[Range<u32>],
) -> Result<PartWindows> {
    let windows = clip_windows(clips);
    let anchors: Vec<u32> = parts.iter().map(|r| anchor(skeleton, palette, mesh, r.clone())).collect();
    let intervals: Vec<(usize, f32, f32)> = (clips.iter().enumerate())
        .flat_map(|(c, clip)| key_intervals(clip).into_iter().map(move |(a, b)| (c, a, b)))
        .collect();
    // Per key interval, per part: the box of its vertices in the anchor's skinning space.
    let per_interval: Vec<Vec<Aabb>> = intervals
        .par_iter()
        .map(|&(c, t1, t2)| {
            let motions = IntervalMotions::new(skeleton, &mesh.morphs, Some(clips[c]), t1, t2)?;
            Ok((parts.iter().zip(&anchors))
                .map(|(r, &anchor)| {
                    let to_skinning = palette.inverse_bind[anchor as usize].as_dmat4().inverse();
                    r.clone().fold(Aabb::EMPTY, |acc, v| {
                        let b = vertex_box(skeleton, palette, &motions, mesh, v as usize, anchor as u16);
                        acc.union(&b.transformed(&to_skinning).inflated(INFLATE))
                    })
                })
                .collect())
        })
        .collect::<Result<_>>()?;
    let total: usize = windows.iter().map(|w| w.count as usize).sum();
    let mut boxes = vec![Aabb::EMPTY; parts.len() * total];
    for (c, w) in windows.iter().enumerate() {
        // Intervals touching the closed window, with slack for the rounding of its ends.
        let slack = 1e-4 * (w.end - w.start) / w.count as f32;
        for k in 0..w.count {
            let (a, z) = w.range(k);
            let touching = (intervals.iter().zip(&per_interval))
                .filter(|((ic, t1, t2), _)| *ic == c && *t1 <= z + slack && *t2 >= a - slack);
            for (_, part_boxes) in touching {
                for (p, b) in part_boxes.iter().enumerate() {
                    let slot = &mut boxes[p * total + (w.first + k) as usize];
                    *slot = slot.union(b);
                }
            }
        }
    }
    // Rounded outward; a part without vertices gets a point, and an unbounded box (a scale
    // through zero) the largest finite one, which the runtime's move overflows to "never cull".
    let up = |x: f64| round_up(x).clamp(-f32::MAX, f32::MAX);
    let down = |x: f64| -up(-x);
    let boxes = (boxes.iter())
        .map(|b| match b.min.cmple(b.max).all() {
            true => [b.min.to_array().map(down).into(), b.max.to_array().map(up).into()],
            false => [Vec3::ZERO; 2],
        })
        .collect();
    Ok(PartWindows { clips: windows, anchors, boxes })
}

/// Ground truth for [`part_windows`], in the space and with the test the runtime relies on:
/// each clip at `sample_times(clip, uniform)` and before and after its keys, every vertex of
/// every part morphed and skinned in f64 (`Σ wⱼ·Gⱼ·Bⱼ·p`), moved into its anchor's skinning
/// space (`(G·B)⁻¹`), must lie in the box of the window holding the time (within 1e-9 of its
/// magnitude: f64 rounding). Returns the vertex checks and the violations.
pub fn verify_part_windows(
    skeleton: &Skeleton,
    palette: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    parts: &[Range<u32>],
    windows: &PartWindows,
    uniform: usize,
) -> (usize, usize) {
    let Some(inf) = &mesh.influences else { return (0, 0) };
    let times: Vec<(usize, f32)> = (clips.iter().enumerate())
        .flat_map(|(c, clip)| {
            let mut t = super::verify::sample_times(clip, uniform);
            t.extend([clip.start - 1.0, clip.end + 1.0]);
            t.into_iter().map(move |t| (c, t))
        })
        .collect();
    let total = windows.windows();
    let per_time = |&(c, t): &(usize, f32)| -> (usize, usize) {
        let Some(w) = windows.clips.get(c) else { return (0, 0) };
        let globals = crate::pose::Poser::default().globals(skeleton, Some(clips[c]), t).to_vec();
        let skinning: Vec<glam::DMat4> = (palette.joints.iter().zip(&palette.inverse_bind))
            .map(|(&j, b)| globals[j as usize] * b.as_dmat4())
            .collect();
        let mut weights = Vec::new();
        mesh.morphs.weights_at(Some(clips[c]), t, &mut weights);
        let (morphed, _) = mesh.morphed(&weights);
        let (mut checks, mut violations) = (0, 0);
        for (p, (r, &anchor)) in parts.iter().zip(&windows.anchors).enumerate() {
            let to_box = skinning[anchor as usize].inverse();
            let [lo, hi] = windows.boxes[p * total + w.at(t) as usize];
            for v in r.clone() {
                let q = morphed[v as usize].as_dvec3();
                let skinned = inf
                    .of(v as usize)
                    .fold(glam::DVec3::ZERO, |acc, (j, wt)| acc + skinning[j as usize].transform_point3(q) * wt as f64);
                let x = to_box.transform_point3(skinned);
                let slack = 1e-9 * (x.abs().max_element() + 1.0);
                checks += 1;
                violations += !(x.cmpge(lo.as_dvec3() - slack).all() && x.cmple(hi.as_dvec3() + slack).all()) as usize;
            }
        }
        (checks, violations)
    };
    times.par_iter().map(per_time).reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clip::{Channel, Interpolation};
    use crate::model::{Influences, Node, Trs};
    use crate::pose::Poser;
    use glam::{Mat4, Quat};

    /// A bar along x: its first five vertices on the root joint, the rest on a joint that
    /// turns about y by 1.2 rad over one second (keys every 0.1 s).
    fn turning_bar() -> (Skeleton, Skin, Clip, SkinnedMesh) {
        let skeleton = Skeleton::new(vec![
            Node { name: "root".into(), parent: None, rest: Trs::IDENTITY, matrix: None },
            Node {
                name: "bar".into(),
                parent: Some(0),
                rest: Trs { translation: Vec3::Y, ..Trs::IDENTITY },
                matrix: None,
            },
        ])
        .unwrap();
        let skin = Skin {
            name: "skin".into(),
            joints: vec![0, 1],
            inverse_bind: vec![Mat4::IDENTITY, Mat4::from_translation(-Vec3::Y)],
        };
        let times: Vec<f32> = (0..=10).map(|k| k as f32 / 10.0).collect();
        let values = times.iter().map(|&t| Quat::from_rotation_y(1.2 * t)).collect();
        let turn = Channel { node: 1, interpolation: Interpolation::Linear, times, values };
        let clip = Clip { name: "turn".into(), rotations: vec![turn], start: 0.0, end: 1.0, ..Clip::default() };
        let positions: Vec<Vec3> = (0..8).map(|i| Vec3::new(i as f32 * 0.25, 1.0, 0.0)).collect();
        let joints = (0..8u16).flat_map(|i| [(i >= 5) as u16, 0, 0, 0]).collect();
        let influences = Influences { stride: 4, joints, weights: [1.0, 0.0, 0.0, 0.0].repeat(8) };
        let mesh = SkinnedMesh { positions, influences: Some(influences), ..SkinnedMesh::default() };
        (skeleton, skin, clip, mesh)
    }

    #[test]
    fn windows_split_each_clip_and_hold_its_poses() {
        let (skeleton, skin, clip, mesh) = turning_bar();
        let parts = [std::ops::Range { start: 0, end: 8 }];
        let w = part_windows(&skeleton, &skin, &[&clip], &mesh, &parts).unwrap();
        assert_eq!(w.clips, vec![ClipWindows { start: 0.0, end: 1.0, count: 15, first: 0 }]);
        assert_eq!((w.anchors.as_slice(), w.boxes.len()), (&[0u32][..], 15));
        let boxes: Vec<Aabb> = w.boxes.iter().map(|b| Aabb { min: b[0].as_dvec3(), max: b[1].as_dvec3() }).collect();
        let mut poser = Poser::default();
        let mut hit = [false; 15];
        for k in 0..=300 {
            let t = k as f32 / 300.0;
            let window = w.clips[0].at(t) as usize;
            hit[window] = true;
            let g = poser.globals(&skeleton, Some(&clip), t);
            let skinning = |j: usize| g[j] * skin.inverse_bind[j].as_dmat4();
            let to_box = skinning(0).inverse();
            for (v, p) in mesh.positions.iter().enumerate() {
                // Each vertex on one joint: moved by that joint's skinning matrix.
                let skinned = skinning((v >= 5) as usize).transform_point3(p.as_dvec3());
                let b = &boxes[window];
                let x = to_box.transform_point3(skinned);
                assert!(b.inflated(1e-9).contains(x), "t {t}: {x} outside {b:?}");
            }
        }
        assert!(hit.iter().all(|h| *h));
        let times = super::super::verify::sample_times(&clip, 50).len() + 2;
        assert_eq!(verify_part_windows(&skeleton, &skin, &[&clip], &mesh, &parts, &w, 50), (8 * times, 0));
        // Each box a tenth narrower in z (the sweep's axis): caught.
        let mut narrow = w.clone();
        narrow.boxes.iter_mut().for_each(|b| b[0].z += 0.1 * (b[1].z - b[0].z));
        assert!(verify_part_windows(&skeleton, &skin, &[&clip], &mesh, &parts, &narrow, 50).1 > 0);
        // The first window (1/15 s) touches the first key interval (0.1 s), in which the bar's
        // end (1.75 from the root) turns by 0.12 rad about y; the clip turns it by 1.2 rad.
        let all = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let reach = |angle: f64| -1.75 * angle.sin();
        assert!(boxes[0].min.z > reach(0.125) && all.min.z < reach(1.19), "{:?} {all:?}", boxes[0]);
    }
}
