//! Cluster LOD errors under animation, against reference skinning
//! (`skinlet::bounds::lod_verify`): at the start, end and inner times of every clip the errors
//! were bounded over, on the shared characters, the demo and random demo characters, part by
//! part, every point of every group's clusters is within the group's error of the full detail
//! part, and every point of the full detail part within a cut's largest error of the cut, both
//! skinned. One violation fails.

mod common;
use common::{assets_dir, part_meshlets};

use glam::Vec3;
use proptest::prelude::*;
use skinlet::bounds::lod_error::bound_errors;
use skinlet::bounds::lod_verify::{LodReport, verify_errors};
use skinlet::clip::Clip;
use skinlet::meshlet::lod::{LodHierarchy, LodParams, build, posed_attributes};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::{Asset, Character};

/// Builds every part's hierarchy of `character` with errors over `clips`, checks them at the
/// start, end and `poses` inner times of every clip (fails on any violation) and returns the
/// report.
fn check(name: &str, asset: &Asset, character: &Character, clips: &[&Clip], poses: usize) -> LodReport {
    let limits = MeshletLimits::NVIDIA;
    let prepared = skinlet::bake::prepare_character(character).unwrap();
    let mesh = &prepared.mesh;
    let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, limits).unwrap();
    let mut parts: Vec<(std::ops::Range<u32>, LodHierarchy)> = Vec::new();
    let started = std::time::Instant::now();
    let attributes = posed_attributes(&asset.skeleton, &character.palette, clips, mesh, 8).unwrap();
    for part in &prepared.parts {
        let mine = part_meshlets(&meshlets, &part.vertices);
        let mut lod = build(&mesh.positions, &attributes, &mine, limits, LodParams::default()).unwrap();
        bound_errors(&asset.skeleton, &character.palette, clips, mesh, &mut lod).unwrap();
        for g in &lod.groups {
            assert!(g.error.is_finite() && g.error >= 0.0, "{name}: error {}", g.error);
            for &c in &g.children {
                assert!(lod.cluster_errors(c as usize).0 <= g.error, "{name}: errors not monotone");
            }
        }
        parts.push((part.triangles.clone(), lod));
    }
    let height = {
        let rest = skinlet::skinning::posed_positions(&asset.skeleton, &character.palette, mesh, None, None).unwrap();
        let (lo, hi) = rest.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &q| (a.min(q), b.max(q)));
        (hi - lo).max_element()
    };
    let drawn = |share: f32| -> usize {
        let cut = |lod: &LodHierarchy| {
            lod.cut(share * height).iter().map(|&c| lod.clusters[c as usize].triangles.len() / 3).sum::<usize>()
        };
        parts.iter().map(|(_, lod)| cut(lod)).sum()
    };
    eprintln!(
        "{name}: hierarchies and errors in {:.1} s; of {} triangles, cuts at 1% and 3% of the height {height:.3} keep {} and {}",
        started.elapsed().as_secs_f64(),
        mesh.triangles.len(),
        drawn(0.01),
        drawn(0.03)
    );
    let mut times: Vec<(Option<&Clip>, f32)> = Vec::new();
    for &clip in clips {
        let duration = clip.end - clip.start;
        times.push((Some(clip), clip.start));
        times.push((Some(clip), clip.end));
        // Away from keys: a low-discrepancy walk through the clip.
        times.extend((0..poses).map(|k| (Some(clip), clip.start + duration * (0.1 + 0.618_034 * k as f32).fract())));
    }
    if clips.is_empty() {
        times.push((None, 0.0));
    }
    let refs: Vec<(std::ops::Range<u32>, &LodHierarchy)> = parts.iter().map(|(r, l)| (r.clone(), l)).collect();
    let r = verify_errors(&asset.skeleton, &character.palette, &times, mesh, &refs).unwrap();
    eprintln!(
        "{name}: {} points at {} poses, largest distance ÷ error {:.3}; per group, median largest distance ÷ error {:.3}",
        r.points, r.poses, r.max_ratio, r.median_ratio
    );
    assert_eq!(r.violations, 0, "{name}: {} points farther from the other surface than the error", r.violations);
    r
}

#[test]
fn errors_hold_at_sampled_poses_of_the_demo_character() {
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { seed: 7, triangles: 6_000 });
    let character = asset.character().unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let report = check("demo", &asset, &character, &clips, 1);
    assert!(report.max_ratio > 0.0 && report.points > 0);
}

#[test]
fn errors_hold_at_sampled_poses_of_the_shared_characters() {
    let Some(dir) = assets_dir() else { return };
    // Not BrainStem: bounding the errors over its clip takes minutes (its bake does it).
    for (file, clip) in [("CesiumMan.glb", None), ("Fox.glb", None), ("Xbot.glb", Some("walk"))] {
        let asset = skinlet::import::load(&dir.join("skinned").join(file)).unwrap();
        let character = asset.character().unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().filter(|c| clip.is_none_or(|n| c.name == n)).collect();
        check(file, &asset, &character, &clips, 1);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1, ..ProptestConfig::default() })]
    #[test]
    fn errors_hold_at_sampled_poses_of_random_characters(seed in 0u64..1_000_000) {
        let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { seed, triangles: 3_000 });
        let character = asset.character().unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        check(&format!("demo seed {seed}"), &asset, &character, &clips, 1);
    }
}
