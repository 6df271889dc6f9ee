//! Run-time culling guarantees: the crowd scene never culls a triangle that brute force finds
//! visible (every shared asset and the demo, perspective and orthographic; clips played
//! alone, and crossfades, additive layers and IK with the pose envelope's guard), and per-joint
//! boxes contain every skinned vertex at every sampled time (shared assets, morph targets
//! included, random rigs with negative and zero scale and shear through non-uniform parent
//! scale).

mod common;
mod rig;
use common::assets_dir;

use glam::Vec3;
use skinlet::Asset;
use skinlet::bake::{Baked, bake};
use skinlet::bounds::refine::Refinement;
use skinlet::clip::Clip;
use skinlet::cull::joint_aabb::{Box3, JointBoxes, JointSpace, fold_leaves, joint_boxes};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::model::{Skeleton, Skin, SkinnedMesh};
use skinlet::pose::Poser;
use skinlet_lab::crowd::{CrowdParams, CrowdStats, posed_crowd, run};
use skinlet_lab::demo;

fn baked(asset: &Asset) -> Baked {
    baked_with(asset, Builder::SkinAware)
}

fn baked_with(asset: &Asset, builder: Builder) -> Baked {
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    bake(asset, &asset.character().unwrap(), &clips, builder, MeshletLimits::NVIDIA, &Refinement::NONE, &mut |_| {})
        .unwrap()
        .0
}

/// Every shared skinned character and the morph-target test.
fn shared_assets() -> Vec<(String, Asset)> {
    let Some(dir) = assets_dir() else { return Vec::new() };
    let mut files: Vec<_> = std::fs::read_dir(dir.join("skinned")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    files.push(dir.join("morph/MorphStressTest.gltf"));
    files
        .iter()
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), skinlet::import::load(p).unwrap()))
        .collect()
}

fn check_crowd(name: &str, asset: &Asset, params: &CrowdParams) -> (f64, f64) {
    let stats = check_crowd_with(name, asset, params, Builder::SkinAware);
    (stats.frustum_only_pct(), stats.backface_only_pct())
}

fn check_crowd_with(name: &str, asset: &Asset, params: &CrowdParams, builder: Builder) -> CrowdStats {
    let b = baked_with(asset, builder);
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let skin = &b.palette();
    let scene = posed_crowd(&asset.skeleton, skin, &b.mesh, &clips, params).unwrap();
    let stats = run(&b, &asset.skeleton, skin, &clips, &scene, params, true).unwrap();
    eprintln!(
        "{name} (ortho {}): {} triangles checked, {} false culls; culled {:.1}% (frustum only {:.1}%, backface only {:.1}%), triangles saved {:.1}%",
        params.orthographic,
        stats.checked_triangles,
        stats.false_culls,
        stats.both_pct(),
        stats.frustum_only_pct(),
        stats.backface_only_pct(),
        stats.triangles_saved_pct()
    );
    assert_eq!(stats.false_culls, 0, "{name}: {stats:?}");
    assert!(stats.checked_triangles > 0, "{name}: nothing was culled, nothing checked");
    // A meshlet the backface test culls holds only triangles that face away (or are edge-on)
    // one by one: at most the per-triangle count, up to the f32 rounding the brute force
    // allows a few near-edge-on triangles.
    assert!(
        stats.backface_only_triangles <= stats.backfacing_triangles + stats.triangles / 1000,
        "{name}: {} triangles in backface-culled meshlets, {} back-facing",
        stats.backface_only_triangles,
        stats.backfacing_triangles
    );
    stats
}

#[test]
fn crowd_never_culls_a_visible_triangle() {
    let params = CrowdParams { instances: 16, frames: 4, ..CrowdParams::default() };
    let (mut any_frustum, mut any_backface) = (false, false);
    for (name, asset) in shared_assets() {
        let base = check_crowd_with(&name, &asset, &params, Builder::SkinAware);
        any_frustum |= base.frustum_only_pct() > 0.0;
        any_backface |= base.backface_only_pct() > 0.0;
        if name == "Xbot.glb" {
            check_crowd(&name, &asset, &CrowdParams { orthographic: true, ..params });
        }
        if name == "Xbot.glb" || name == "BrainStem.glb" || name == "mannequiny.glb" {
            // Meshlets built for culling: more of them culled by the backface test alone,
            // and fewer vertices left to skin, although cuts duplicate vertices.
            let split = check_crowd_with(&name, &asset, &params, Builder::ConeSplit);
            let (a, b) = (split.backface_only_pct(), base.backface_only_pct());
            assert!(a > b, "{name}: cone-split {a:.1}% vs skin-aware {b:.1}% culled as back-facing");
            let (a, b) = (split.vertex_refs_per_instance_frame()[1], base.vertex_refs_per_instance_frame()[1]);
            assert!(a < b, "{name}: cone-split skins {a:.0} vertex references per instance-frame, skin-aware {b:.0}");
        }
    }
    let d = demo::demo_character(&demo::DemoParams { triangles: 4000, ..Default::default() });
    let (frustum, backface) = check_crowd("demo", &d, &params);
    check_crowd("demo", &d, &CrowdParams { orthographic: true, seed: 5, ..params });
    assert!(any_frustum || frustum > 0.0, "frustum culling never happened");
    assert!(any_backface || backface > 0.0, "backface culling never happened");
}

/// Games' poses: crossfades, additive layers and IK on every shared asset and the demo, baked
/// with an envelope around the clips widened by 10°. Every culled triangle (envelope bounds
/// where the guard admits the pose, any-pose boxes where it does not) is checked against the
/// pose drawn; the guard must fire in IK mode (some joints set 20° beyond their range).
#[test]
fn game_poses_never_cull_a_visible_triangle() {
    use skinlet::bounds::envelope::Envelope;
    use skinlet_lab::crowd::Animation;
    let d = demo::demo_character(&demo::DemoParams { triangles: 4000, ..Default::default() });
    let mut assets = shared_assets();
    assets.push(("demo".into(), d));
    let (mut checked, mut fallbacks, mut admitted) = (0, 0, 0);
    for (name, asset) in &assets {
        let mut b = baked(asset);
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let skin = &b.palette();
        let envelope = Envelope::from_clips(&asset.skeleton, skin, &b.mesh, &clips, 10f64.to_radians()).unwrap();
        skinlet::bake::add_envelope(&mut b, asset, envelope).unwrap();
        for animation in [Animation::Blend, Animation::Additive(10f32.to_radians()), Animation::Ik] {
            let params = CrowdParams { instances: 16, frames: 3, animation, ..CrowdParams::default() };
            let scene = posed_crowd(&asset.skeleton, skin, &b.mesh, &clips, &params).unwrap();
            let stats = run(&b, &asset.skeleton, skin, &clips, &scene, &params, true).unwrap();
            eprintln!(
                "{name} {}: {} triangles checked, {} false culls; culled {:.1}%; guard: {} inside, {} any-pose, {} unculled",
                animation.name(),
                stats.checked_triangles,
                stats.false_culls,
                stats.both_pct(),
                stats.envelope_frames,
                stats.any_pose_frames,
                stats.unculled_frames
            );
            assert_eq!(stats.false_culls, 0, "{name} {}: {stats:?}", animation.name());
            checked += stats.checked_triangles;
            admitted += stats.envelope_frames;
            if animation == Animation::Ik {
                fallbacks += stats.any_pose_frames + stats.unculled_frames;
            }
        }
    }
    assert!(checked > 0 && admitted > 0, "nothing culled with the envelope bounds");
    assert!(fallbacks > 0, "the guard never fired on IK poses beyond the envelope");
}

/// Skins `mesh` at `times` of `clip` and checks that every vertex lies in the boxes' union
/// (mesh and joint space), the sphere, and `folded` when given (up to f32 rounding).
fn check_boxes(
    label: &str,
    skeleton: &Skeleton,
    skin: &Skin,
    mesh: &SkinnedMesh,
    clip: Option<&Clip>,
    folded: Option<&JointBoxes>,
) -> usize {
    let clips: Vec<&Clip> = clip.into_iter().collect();
    let in_mesh = joint_boxes(mesh, skin, JointSpace::Mesh, &clips).unwrap();
    let in_joint = joint_boxes(mesh, skin, JointSpace::Joint, &clips).unwrap();
    let mut weights = Vec::new();
    let mut poser = Poser::default();
    let (mut skinning, mut skinned) = (Vec::new(), vec![Vec3::ZERO; mesh.positions.len()]);
    let times: Vec<f32> = match clip {
        Some(c) => (0..=24).map(|k| c.start + c.duration() * k as f32 / 24.0).collect(),
        None => vec![0.0],
    };
    let mut checked = 0;
    for t in times {
        let globals = poser.globals(skeleton, clip, t).to_vec();
        skinlet::pose::skinning_matrices(skin, &globals, &mut skinning);
        let mut joint_globals = Vec::new();
        skinlet::pose::joint_globals(skin, &globals, &mut joint_globals);
        mesh.morphs.weights_at(clip, t, &mut weights);
        skinlet::skinning::skin_mesh(mesh, &weights, &skinning, &mut skinned, &mut []).unwrap();
        let mut boxes: Vec<(&str, Box3)> =
            vec![("mesh space", in_mesh.update(&skinning)), ("joint space", in_joint.update(&joint_globals))];
        if let Some(f) = folded {
            boxes.push(("folded", f.update(&joint_globals)));
        }
        let (sc, sr) = in_joint.sphere(&joint_globals);
        for p in &skinned {
            if !p.is_finite() {
                continue;
            }
            let tol = 1e-5 * (1.0 + p.abs().max_element());
            for (what, b) in &boxes {
                let grown = Box3 { min: b.min - tol, max: b.max + tol };
                assert!(grown.contains(*p), "{label} t={t}: vertex {p} outside the {what} box {b:?}");
            }
            assert!(p.distance(sc) <= sr + tol, "{label} t={t}: vertex {p} outside the sphere");
            checked += 1;
        }
    }
    checked
}

#[test]
fn joint_boxes_contain_every_skinned_vertex_on_shared_assets() {
    for (name, asset) in shared_assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let mesh = character.mesh.clone();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let in_joint = joint_boxes(&mesh, skin, JointSpace::Joint, &clips).unwrap();
        let folded = fold_leaves(&in_joint, &asset.skeleton, skin, &mesh, &clips, 2).unwrap();
        let mut checked = 0;
        for clip in &clips {
            checked +=
                check_boxes(&format!("{name} {}", clip.name), &asset.skeleton, skin, &mesh, Some(clip), Some(&folded));
        }
        eprintln!(
            "{name}: {checked} vertex checks; {} joint boxes, {} after folding leaves twice",
            in_joint.joints.len(),
            folded.joints.len()
        );
    }
}

#[test]
fn joint_boxes_contain_every_skinned_vertex_on_random_rigs() {
    let mut checked = 0;
    for seed in 0..400u64 {
        let (skeleton, skin, mut clip, positions, inf) = rig::random_character(seed);
        // A third of the rigs get a scale key of zero on one axis.
        if seed.is_multiple_of(3)
            && let Some(ch) = clip.scales.first_mut()
        {
            let k = seed as usize % ch.values.len();
            ch.values[k].y = 0.0;
        }
        let mesh = SkinnedMesh { positions, influences: Some(inf), ..SkinnedMesh::default() };
        let boxes = joint_boxes(&mesh, &skin, JointSpace::Joint, &[&clip]).unwrap();
        let folded = fold_leaves(&boxes, &skeleton, &skin, &mesh, &[&clip], 1).ok();
        checked += check_boxes(&format!("seed {seed}"), &skeleton, &skin, &mesh, Some(&clip), folded.as_ref());
        checked += check_boxes(&format!("seed {seed} rest"), &skeleton, &skin, &mesh, None, None);
    }
    assert!(checked > 100_000, "{checked}");
}
