//! Conservative meshlet bounds (spheres and normal cones, refined until converged) on the
//! shared skinned assets and the morph-target test: zero violations under dense sampling for every clip on its own and
//! for the union of all clips, the sampled baseline (radius from a few uniform samples, like
//! engines' precomputed clip bounds) shown to miss, and the classification target on Xbot.

mod common;
use common::assets_dir;

use skinlet::bounds::refine::{Refinement, Stop, refine};
use skinlet::bounds::sphere_cone::{Class, classify};
use skinlet::bounds::verify::{sampled_bounds, verify_bounds};
use skinlet::meshlet::{Builder, MeshletLimits, Meshlets, PreparedMesh, build};

/// Refinement until nothing improves (what `skinlet bake` does within its budget).
const CONVERGE: Refinement = Refinement { max_rounds: usize::MAX, ..Refinement::NONE };

/// Every shared skinned asset and the morph-target test: name, asset, character, prepared
/// mesh and its skin-aware meshlets.
fn shared_characters() -> Vec<(String, skinlet::Asset, skinlet::Character, PreparedMesh, Meshlets)> {
    let Some(dir) = assets_dir() else { return Vec::new() };
    let mut files: Vec<_> = std::fs::read_dir(dir.join("skinned")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    files.push(dir.join("morph/MorphStressTest.gltf"));
    files
        .iter()
        .map(|path| {
            let asset = skinlet::import::load(path).unwrap();
            let character = asset.character().unwrap();
            let prepared = skinlet::bake::prepare_character(&character).unwrap();
            let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
            (path.file_name().unwrap().to_string_lossy().into_owned(), asset, character, prepared, meshlets)
        })
        .collect()
}

#[test]
fn spheres_hold_on_every_asset_and_clip_and_sampling_misses() {
    let characters = shared_characters();
    if characters.is_empty() {
        return;
    }
    let mut baseline_misses = 0;
    for (name, asset, character, prepared, meshlets) in &characters {
        let skin = &character.palette;
        let all: Vec<_> = asset.clips.iter().collect();
        let mut sets: Vec<(String, Vec<_>)> = all.iter().map(|c| (format!("clip {:?}", c.name), vec![*c])).collect();
        sets.push(("all clips".into(), all.clone()));
        for (label, clips) in &sets {
            let refined = refine(&asset.skeleton, skin, clips, &prepared.mesh, meshlets, &CONVERGE).unwrap();
            assert_eq!(refined.stop, Stop::Converged);
            let bounds = refined.bounds;
            let report = verify_bounds(&asset.skeleton, skin, clips, &prepared.mesh, meshlets, &bounds, 200).unwrap();
            let coned = bounds.iter().filter(|b| b.cone_angle < std::f32::consts::FRAC_PI_2).count();
            eprintln!("{name} {label}: {coned}/{} meshlets with a cone, {report:?}", bounds.len());
            assert_eq!(report.violations(), 0, "{name} {label}: {report:?}");
            assert!(report.mean_radius_ratio >= 1.0 - 1e-5, "{name} {label}: a radius below what samples need");
        }
        let sampled = sampled_bounds(&asset.skeleton, skin, &all, &prepared.mesh, meshlets, 10);
        let report = verify_bounds(&asset.skeleton, skin, &all, &prepared.mesh, meshlets, &sampled, 200).unwrap();
        eprintln!("{name} sampled baseline (10 samples per clip): {report:?}");
        baseline_misses += report.violations();
    }
    assert!(baseline_misses > 0, "the sampled baseline should miss somewhere");
}

/// Pose envelopes around every shared asset's clips (widened by 10°): the envelope bounds hold
/// at 200 poses inside, half on the envelope's boundary.
#[test]
fn envelope_bounds_hold_on_every_asset() {
    use skinlet::bounds::envelope::{Envelope, envelope_bounds};
    for (name, asset, character, prepared, meshlets) in &shared_characters() {
        let skin = &character.palette;
        let clips: Vec<_> = asset.clips.iter().collect();
        let env = Envelope::from_clips(&asset.skeleton, skin, &prepared.mesh, &clips, 10f64.to_radians()).unwrap();
        let bounds = envelope_bounds(&asset.skeleton, skin, &prepared.mesh, meshlets, &env).unwrap();
        let poses = env.sample_poses(&asset.skeleton, 200, 7);
        let guard = env.guard().unwrap();
        assert!(poses.iter().all(|(l, w)| guard.admits(l, w)), "{name}: the guard refused a sampled pose");
        let report =
            skinlet::bounds::verify::verify_poses(&asset.skeleton, skin, &poses, &prepared.mesh, meshlets, &bounds)
                .unwrap();
        eprintln!("{name}: {} envelope nodes, {report:?}", env.nodes.len());
        assert_eq!(report.violations(), 0, "{name}: {report:?}");
        assert!(report.vertex_checks > 0);
    }
}

/// Issue target: on Xbot.glb over all clips, at s_r = 3 and α_T = 20°, at least 85% of the
/// skin-aware meshlets are "both", more than with meshoptimizer's builder.
#[test]
fn xbot_skin_aware_meshlets_are_mostly_both_cullable() {
    let Some(dir) = assets_dir() else { return };
    let asset = skinlet::import::load(&dir.join("skinned/Xbot.glb")).unwrap();
    let character = asset.character().unwrap();
    let skin = &character.palette;
    let prepared = skinlet::bake::prepare_character(&character).unwrap();
    let clips: Vec<_> = asset.clips.iter().collect();
    let both = |builder| {
        let meshlets = build(&prepared, builder, MeshletLimits::NVIDIA).unwrap();
        let b = refine(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &CONVERGE).unwrap().bounds;
        let n = b.iter().filter(|b| classify(b, 3.0, 20f32.to_radians()) == Class::Both).count();
        100.0 * n as f64 / b.len() as f64
    };
    let (ours, meshopt) = (both(Builder::SkinAware), both(Builder::Meshopt));
    eprintln!("Xbot both at 20°: skin-aware {ours:.1}%, meshopt {meshopt:.1}%");
    assert!(ours >= 85.0 && ours > meshopt, "skin-aware {ours:.1}%, meshopt {meshopt:.1}%");
}
