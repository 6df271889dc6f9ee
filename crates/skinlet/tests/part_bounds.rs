//! `skinlet_runtime::part_bounds`, the per-part boxes an engine gives its culling, against
//! reference skinning (morphs, then skinning over the palette: `skinning::skin_mesh`): on the
//! shared characters, the morph-target test and the demo character (two skins, rigid and
//! instanced parts, a morph face), every vertex of every part lies in its part's box, read
//! from the bake file's bytes as a game reads them:
//! - any-pose boxes: random local transforms of every node (shear from non-uniform scales
//!   down the hierarchy, negative scales) and random morph weights, also moved into a random
//!   entity space;
//! - clip boxes: every baked clip at dense times (with its morph weights), and the boxes of
//!   the clip window holding each time, also in a random entity space;
//! - envelope boxes: poses sampled inside an envelope made from the clips (half on its
//!   boundary) that the bake's pose guard admits.

mod common;
mod rig;

use common::assets_dir;
use glam::{Affine3A, DMat4, Quat, Vec3};
use rig::Rng;
use skinlet::Asset;
use skinlet::bake::{add_envelope, bake, to_bytes};
use skinlet::bounds::envelope::Envelope;
use skinlet::bounds::refine::Refinement;
use skinlet::bounds::verify::sample_times;
use skinlet::clip::Clip;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::model::Trs;
use skinlet::pose::{Poser, global_transforms};
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::part_bounds::{PartBounds, PoseBounds};

fn cases() -> Vec<(String, Asset)> {
    let mut out = Vec::new();
    if let Some(dir) = assets_dir() {
        for file in
            ["skinned/Fox.glb", "skinned/CesiumMan.glb", "skinned/RiggedFigure.glb", "morph/MorphStressTest.gltf"]
        {
            let path = dir.join(file);
            out.push((file.to_string(), skinlet::import::load(&path).unwrap_or_else(|e| panic!("{file}: {e}"))));
        }
    }
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
    out.push(("@demo".into(), demo));
    out
}

/// One posed frame: every vertex, each driver's global matrix, the morph weights.
struct Frame {
    posed: Vec<Vec3>,
    drivers: Vec<Affine3A>,
    weights: Vec<f32>,
}

/// The frame of node globals `globals` and morph weights `weights`.
fn pose(character: &skinlet::Character, globals: &[DMat4], weights: Vec<f32>) -> Frame {
    let palette = &character.palette;
    let skinning: Vec<Affine3A> = (palette.joints.iter().zip(&palette.inverse_bind))
        .map(|(&j, ibm)| Affine3A::from_mat4((globals[j as usize] * ibm.as_dmat4()).as_mat4()))
        .collect();
    let mut out = vec![Vec3::ZERO; character.mesh.positions.len()];
    skinlet::skinning::skin_mesh(&character.mesh, &weights, &skinning, &mut out, &mut []).unwrap();
    let drivers = palette.joints.iter().map(|&j| Affine3A::from_mat4(globals[j as usize].as_mat4())).collect();
    Frame { posed: out, drivers, weights }
}

/// Every vertex of every part inside its box (moved into `to_target`'s space); returns the
/// number of vertices checked.
fn check(
    (name, bounds, character): (&str, &PartBounds, &skinlet::Character),
    what: &str,
    frame: &Frame,
    to_target: &Affine3A,
    pose: PoseBounds,
) -> usize {
    let mut checked = 0;
    let to = glam::Mat4::from(*to_target).as_dmat4();
    for (i, part) in character.parts.iter().enumerate() {
        let b = bounds.part_box(i, to_target, &frame.drivers, &frame.weights, pose);
        // It reads no matrix but those `drivers_read` names (an engine fetches only those).
        let mut only = vec![Affine3A::NAN; frame.drivers.len()];
        bounds.drivers_read(i, pose).for_each(|d| only[d] = frame.drivers[d]);
        assert_eq!(b, bounds.part_box(i, to_target, &only, &frame.weights, pose), "{name}, {what}: part {i}");
        for v in part.vertices.clone() {
            let p = to.transform_point3(frame.posed[v as usize].as_dvec3()).as_vec3();
            assert!(b.contains(p), "{name}, {what}: vertex {v} of part {i} at {p} is outside its box {b:?}");
            checked += 1;
        }
    }
    checked
}

#[test]
fn every_vertex_lies_in_its_part_box() {
    let mut rng = Rng(0x5eed_b0c5);
    for (name, asset) in cases() {
        let character = asset.character().unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let (mut baked, _) =
            bake(&asset, &character, &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &Refinement::NONE, &mut |_| {})
                .unwrap();
        let envelope = (!clips.is_empty())
            .then(|| Envelope::from_clips(&asset.skeleton, &character.palette, &character.mesh, &clips, 0.05).unwrap());
        if let Some(e) = &envelope {
            add_envelope(&mut baked, &asset, e.clone()).unwrap();
        }
        let bytes = to_bytes(&baked);
        let aligned: Vec<u32> = bytes.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
        let view = BakeView::new(bytemuck::cast_slice(&aligned)).unwrap();
        let bounds = PartBounds::new(&view).unwrap();
        assert_eq!(bounds.parts().len(), character.parts.len(), "{name}");
        assert_eq!(bounds.has_envelope(), !clips.is_empty(), "{name}");
        let nodes = asset.skeleton.nodes.len();
        let morphs = character.mesh.morphs.weights.len();
        let mut checked = 0;
        let case = (name.as_str(), &bounds, &character);
        // Pruned: stored bounds no tighter than the any-pose boxes at the bind pose dropped.
        let pruned = bounds.clone().pruned();
        let pruned_case = (name.as_str(), &pruned, &character);
        assert!(clips.is_empty() || bounds.narrows(PoseBounds::Clips), "{name}: no clip bounds");

        // Any pose: random local transforms and morph weights, in world and entity space.
        for k in 0..24 {
            let locals: Vec<Trs> = (0..nodes)
                .map(|_| Trs {
                    translation: rng.v3(2.0),
                    rotation: Quat::from_axis_angle(rng.axis(), rng.range(-3.1, 3.1)),
                    scale: rng.scale(),
                })
                .collect();
            let mut globals = Vec::new();
            global_transforms(&asset.skeleton, &locals, &mut globals);
            let weights: Vec<f32> = (0..morphs).map(|_| rng.range(-1.0, 2.0)).collect();
            let frame = pose(&character, &globals, weights);
            let to_target = if k % 2 == 0 {
                Affine3A::IDENTITY
            } else {
                Affine3A::from_scale_rotation_translation(
                    rng.scale(),
                    Quat::from_axis_angle(rng.axis(), 1.0),
                    rng.v3(5.0),
                )
            };
            checked += check(case, "any pose", &frame, &to_target, PoseBounds::Any);
        }

        // The baked clips at dense times (every key, every key interval's midpoint, and
        // before and after the clip): the clip boxes and the clip windows' boxes hold.
        let mut poser = Poser::default();
        for (c, clip) in clips.iter().enumerate() {
            let mut times = sample_times(clip, 40);
            times.extend([clip.start - 0.5, clip.end + 0.5]);
            for t in times {
                let globals = poser.globals(&asset.skeleton, Some(clip), t).to_vec();
                let mut weights = Vec::new();
                character.mesh.morphs.weights_at(Some(clip), t, &mut weights);
                let frame = pose(&character, &globals, weights);
                let at = PoseBounds::ClipAt { clip: c as u32, time: t };
                for pose in [PoseBounds::Clips, at, PoseBounds::Any] {
                    let what = format!("clip {:?} at {t}, {pose:?}", clip.name);
                    checked += check(case, &what, &frame, &Affine3A::IDENTITY, pose);
                }
                let to_entity = Affine3A::from_scale_rotation_translation(
                    rng.scale(),
                    Quat::from_axis_angle(rng.axis(), 1.0),
                    rng.v3(5.0),
                );
                check(case, &format!("clip {:?} at {t}, entity space", clip.name), &frame, &to_entity, at);
                check(
                    pruned_case,
                    &format!("clip {:?} at {t}, pruned", clip.name),
                    &frame,
                    &Affine3A::IDENTITY,
                    PoseBounds::Clips,
                );
            }
        }
        // Poses inside the envelope (on its boundary every other one), admitted by the
        // bake's pose guard: the envelope boxes hold.
        if let Some(e) = &envelope {
            let guard = view.envelope().unwrap().guard().unwrap();
            for (k, (locals, weights)) in e.sample_poses(&asset.skeleton, 16, 7).into_iter().enumerate() {
                if !guard.admits(&locals, &weights) {
                    continue;
                }
                let mut globals = Vec::new();
                global_transforms(&asset.skeleton, &locals, &mut globals);
                let frame = pose(&character, &globals, weights);
                let what = format!("envelope pose {k}");
                checked += check(case, &what, &frame, &Affine3A::IDENTITY, PoseBounds::Envelope);
                check(pruned_case, &what, &frame, &Affine3A::IDENTITY, PoseBounds::Envelope);
            }
        }
        assert!(checked > 0, "{name}: no vertex checked");
    }
}

#[test]
fn bad_requests_never_cull() {
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 500, ..Default::default() });
    let character = demo.character().unwrap();
    let clips: Vec<&Clip> = demo.clips.iter().collect();
    let (baked, _) =
        bake(&demo, &character, &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &Refinement::NONE, &mut |_| {})
            .unwrap();
    let bytes = to_bytes(&baked);
    let aligned: Vec<u32> = bytes.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
    let bounds = PartBounds::new(&BakeView::new(bytemuck::cast_slice(&aligned)).unwrap()).unwrap();
    let drivers = vec![Affine3A::IDENTITY; character.palette.joints.len()];
    let weights = vec![0.0; character.mesh.morphs.weights.len()];
    let everything = |b: skinlet_runtime::joint_boxes::Box3| b.min == Vec3::NEG_INFINITY && b.max == Vec3::INFINITY;
    let id = Affine3A::IDENTITY;
    assert!(everything(bounds.part_box(999, &id, &drivers, &weights, PoseBounds::Any)), "no such part");
    assert!(everything(bounds.part_box(0, &id, &drivers[1..], &weights, PoseBounds::Any)), "too few matrices");
    let mut nan = drivers.clone();
    nan[0] = Affine3A::from_translation(Vec3::NAN);
    assert!((0..character.parts.len()).all(|i| {
        let uses_0 = bounds.part_box(i, &id, &drivers, &weights, PoseBounds::Any)
            != bounds.part_box(i, &id, &nan, &weights, PoseBounds::Any);
        !uses_0 || everything(bounds.part_box(i, &id, &nan, &weights, PoseBounds::Any))
    }));
}
