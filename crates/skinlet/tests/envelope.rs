//! Pose envelopes on random rigs (rig/mod.rs: branching hierarchies with shear, clips in all
//! three interpolation modes, non-uniform and negative scale, half with morph targets):
//! envelopes made from the clips (with a random margin) and random envelopes; random poses
//! inside them and blends of two such poses are admitted by the guard, and every vertex and
//! face normal of them lies in its meshlet's envelope bounds, checked in the culler's space
//! ([`skinlet::bounds::verify`]). Every sampled pose of the clips themselves is admitted by
//! the envelope made from them, and poses outside are refused.

mod rig;

use glam::{Quat, Vec3};
use proptest::prelude::*;
use rig::{Rng, random_character, random_morphs, random_triangles};
use skinlet::bounds::envelope::{Envelope, GUARD_SLACK, NodeRange, envelope_bounds};
use skinlet::bounds::verify::verify_poses;
use skinlet::meshlet::{Builder, MeshletLimits, build, prepare};
use skinlet::model::{Skeleton, Trs};

/// A random envelope around the rest pose: caps up to 80° (so blends stay inside; never
/// below the guard's `2 × GUARD_SLACK`, as the baker's envelopes), boxes up to 0.5 wide
/// around the rest translation and scale (scales kept away from zero).
fn random_envelope(r: &mut Rng, skeleton: &Skeleton, weights: usize) -> Envelope {
    let nodes = (skeleton.nodes.iter().enumerate())
        .filter(|(_, n)| n.matrix.is_none())
        .map(|(i, n)| {
            let around = |r: &mut Rng, v: Vec3| {
                let (a, b) = (v - r.v3(0.25).abs(), v + r.v3(0.25).abs());
                (a, b)
            };
            let mut scale = around(r, n.rest.scale);
            // Keep each scale axis on one side of zero.
            for k in 0..3 {
                if scale.0[k] <= 0.0 && scale.1[k] >= 0.0 {
                    (scale.0[k], scale.1[k]) =
                        if n.rest.scale[k] > 0.0 { (0.3, scale.1[k].max(0.4)) } else { (scale.0[k].min(-0.4), -0.3) };
                }
            }
            NodeRange {
                node: i as u32,
                centre: (Quat::from_axis_angle(r.axis(), r.range(0.0, 0.5)) * n.rest.rotation).normalize(),
                angle: r.range(0.0, 1.4) + 2.0 * GUARD_SLACK as f32,
                translation: around(r, n.rest.translation),
                scale,
            }
        })
        .collect();
    Envelope { nodes, weights: (0..weights).map(|_| (r.range(-0.5, 0.2), r.range(0.3, 1.2))).collect() }
}

/// Blend of two poses: translation, scale and weights linearly, rotations by shortest-path
/// slerp, as animation blending does.
fn blend(a: &(Vec<Trs>, Vec<f32>), b: &(Vec<Trs>, Vec<f32>), f: f32) -> (Vec<Trs>, Vec<f32>) {
    let locals =
        a.0.iter()
            .zip(&b.0)
            .map(|(x, y)| Trs {
                translation: x.translation.lerp(y.translation, f),
                rotation: x.rotation.slerp(y.rotation, f),
                scale: x.scale.lerp(y.scale, f),
            })
            .collect();
    (locals, a.1.iter().zip(&b.1).map(|(x, y)| x + (y - x) * f).collect())
}

/// Returns the vertex checks made.
fn check_envelope(seed: u64) -> Result<usize, String> {
    let (skeleton, skin, mut clip, mut positions, mut inf) = random_character(seed);
    let triangles = random_triangles(seed, skin.joints.len(), &mut positions, &mut inf);
    if triangles.is_empty() {
        return Ok(0);
    }
    let morphs = if seed % 4 < 2 { random_morphs(seed, positions.len(), 0, &mut clip) } else { Default::default() };
    let mesh = skinlet::SkinnedMesh { positions, triangles, influences: Some(inf), morphs, ..Default::default() };
    let prepared = prepare(&mesh).unwrap();
    let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits { max_vertices: 8, max_triangles: 8 })
        .map_err(|e| e.to_string())?;
    let mut r = Rng(seed ^ 0xE7E1);
    let from_clips = !seed.is_multiple_of(3);
    let env = if from_clips {
        let margin = if r.u() < 0.5 { 0.0 } else { r.range(0.0, 0.4) as f64 };
        Envelope::from_clips(&skeleton, &skin, &prepared.mesh, &[&clip], margin).map_err(|e| e.to_string())?
    } else {
        random_envelope(&mut r, &skeleton, prepared.mesh.morphs.weights.len())
    };
    let bounds = envelope_bounds(&skeleton, &skin, &prepared.mesh, &meshlets, &env).map_err(|e| e.to_string())?;
    let guard = env.guard().unwrap();
    // Half of them on the envelope's boundary (`Envelope::sample_poses`).
    let mut poses = env.sample_poses(&skeleton, 48, seed);
    for p in &poses {
        if !guard.admits(&p.0, &p.1) {
            return Err(format!("seed {seed}: the guard refused a pose inside"));
        }
    }
    // Blends stay inside where every cap is below 90°.
    if env.nodes.iter().all(|n| n.angle < std::f32::consts::FRAC_PI_2) {
        for k in 0..8 {
            let b = blend(&poses[k], &poses[k + 8], r.u());
            if !guard.admits(&b.0, &b.1) {
                return Err(format!("seed {seed}: the guard refused a blend of two poses inside"));
            }
            poses.push(b);
        }
    }
    let report =
        verify_poses(&skeleton, &skin, &poses, &prepared.mesh, &meshlets, &bounds).map_err(|e| e.to_string())?;
    if report.violations() > 0 {
        return Err(format!("seed {seed}: {report:?}"));
    }
    // The clip's own poses are inside the envelope made from it.
    if from_clips {
        let mut locals = Vec::new();
        let mut weights = Vec::new();
        for k in 0..=40 {
            let t = clip.start + clip.duration() * k as f32 / 40.0;
            clip.sample_locals(&skeleton, t, &mut locals);
            prepared.mesh.morphs.weights_at(Some(&clip), t, &mut weights);
            if !guard.admits(&locals, &weights) {
                return Err(format!("seed {seed}: the guard refused the clip's pose at {t}"));
            }
        }
    }
    // Outside: one node turned past its cap, or moved out of its box.
    if let Some(n) = env.nodes.iter().find(|n| n.angle < 3.0) {
        let (mut locals, weights) = env.sample_poses(&skeleton, 1, seed ^ 1).remove(0);
        locals[n.node as usize].rotation = (Quat::from_axis_angle(r.axis(), n.angle + 0.05) * n.centre).normalize();
        if guard.admits(&locals, &weights) {
            return Err(format!("seed {seed}: the guard admitted a rotation outside node {}'s cap", n.node));
        }
        let (mut locals, weights) = env.sample_poses(&skeleton, 2, seed ^ 2).remove(1);
        locals[n.node as usize].translation.x = n.translation.1.x + 0.01;
        if guard.admits(&locals, &weights) {
            return Err(format!("seed {seed}: the guard admitted a translation outside node {}'s box", n.node));
        }
    }
    Ok(report.vertex_checks)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]
    #[test]
    fn envelope_bounds_hold_for_every_pose_inside(seed in any::<u64>()) {
        check_envelope(seed).map_err(TestCaseError::fail)?;
    }
}

#[test]
fn envelopes_are_checked_often_enough_to_matter() {
    let checks: usize = (0..60u64).map(|s| check_envelope(s).unwrap()).sum();
    assert!(checks > 20_000, "only {checks} vertex checks");
}

/// Any pose (random rotations, translations, scales with negative and zero axes; matrix
/// nodes keep their matrix) and random morph weights within the ranges the boxes were made
/// for, seen by a random camera: every meshlet the any-pose boxes cull has every skinned
/// vertex outside one frustum plane. Returns the meshlets culled.
fn check_any_pose(seed: u64) -> Result<usize, String> {
    use skinlet::cull::Camera;
    use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
    let (skeleton, skin, mut clip, mut positions, mut inf) = random_character(seed);
    let triangles = random_triangles(seed, skin.joints.len(), &mut positions, &mut inf);
    let morphs = if seed % 4 < 2 { random_morphs(seed, positions.len(), 0, &mut clip) } else { Default::default() };
    let mesh = skinlet::SkinnedMesh { positions, triangles, influences: Some(inf), morphs, ..Default::default() };
    let prepared = prepare(&mesh).unwrap();
    let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits { max_vertices: 8, max_triangles: 8 })
        .map_err(|e| e.to_string())?;
    let ranges =
        skinlet::bounds::vertex::clip_weight_ranges(&prepared.mesh.morphs, &[&clip]).map_err(|e| e.to_string())?;
    let boxes = skinlet::cull::any_pose::build(&skin, &prepared.mesh, &meshlets, &ranges).map_err(|e| e.to_string())?;
    let culler = MeshletCuller::from_any_pose(&boxes, skin.joints.len()).map_err(|e| e.to_string())?;
    let mut frame = JointFrame::default();
    let mut r = Rng(seed ^ 0xA4E);
    let mut culled = 0;
    for _ in 0..8 {
        let locals: Vec<Trs> = (0..skeleton.nodes.len())
            .map(|_| {
                let mut scale = r.scale();
                if r.u() < 0.1 {
                    scale.y = 0.0;
                }
                Trs { translation: r.v3(1.5), rotation: Quat::from_axis_angle(r.axis(), r.range(-3.1, 3.1)), scale }
            })
            .collect();
        let weights: Vec<f32> = ranges.iter().map(|&(lo, hi)| r.range(lo as f32, hi as f32)).collect();
        let mut globals = Vec::new();
        skinlet::pose::global_transforms(&skeleton, &locals, &mut globals);
        let (mut mats, mut joints) = (Vec::new(), Vec::new());
        skinlet::pose::skinning_matrices(&skin, &globals, &mut mats);
        skinlet::pose::joint_globals(&skin, &globals, &mut joints);
        let mut p = vec![Vec3::ZERO; prepared.mesh.positions.len()];
        skinlet::skinning::skin_mesh(&prepared.mesh, &weights, &mats, &mut p, &mut []).map_err(|e| e.to_string())?;
        let scale = p.iter().map(|v| v.abs().max_element()).fold(1.0f32, f32::max) as f64;
        for _ in 0..4 {
            let eye = r.v3(6.0);
            let Ok(cam) = Camera::perspective(
                eye,
                r.v3(2.0),
                Vec3::Y,
                r.range(0.3, 1.5),
                r.range(0.5, 2.0),
                0.1,
                r.range(2.0, 30.0),
            ) else {
                continue;
            };
            let mut visible = Vec::new();
            culler.prepare_boxes_only(&joints, &cam, Tests::Both, &mut frame);
            culler.cull(&frame, &mut Vec::new(), &mut visible);
            visible.sort_unstable();
            for (m, meshlet) in meshlets.meshlets.iter().enumerate() {
                if visible.binary_search(&(m as u32)).is_ok() {
                    continue;
                }
                culled += 1;
                let verts = meshlets.vertices_of(meshlet);
                let out = cam.planes.iter().any(|pl| {
                    verts
                        .iter()
                        .all(|&v| pl.truncate().as_dvec3().dot(p[v as usize].as_dvec3()) + (pl.w as f64) < 1e-5 * scale)
                });
                if !out {
                    return Err(format!("seed {seed}: meshlet {m} culled, but no plane has all its vertices outside"));
                }
            }
        }
    }
    Ok(culled)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]
    #[test]
    fn any_pose_boxes_cull_only_what_is_outside(seed in any::<u64>()) {
        check_any_pose(seed).map_err(TestCaseError::fail)?;
    }
}

#[test]
fn any_pose_boxes_cull_often_enough_to_matter() {
    let culled: usize = (0..100u64).map(|s| check_any_pose(s).unwrap()).sum();
    assert!(culled > 500, "only {culled} meshlets culled");
}

/// Seeds that once failed: a random envelope whose cap was narrower than the guard's slack
/// (the guard refused every pose; caps now cover at least `2 × GUARD_SLACK`), and an
/// envelope from a clip whose cap was clamped at π, where the guard's slack refused the
/// clip's own rotation 6.5e-6 rad short of π (a cap of π now admits every rotation).
#[test]
fn seeds_that_once_failed() {
    for seed in [12654716821585209138, 10040265092934127543] {
        check_envelope(seed).unwrap();
    }
}
