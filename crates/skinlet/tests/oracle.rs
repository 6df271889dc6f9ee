//! skinlet's reference posing against code nobody here wrote: three.js (pinned in
//! `tools/package.json`) loads every shared character, the morph-target test and the demo
//! (written as .glb by `skinlet::export`), samples a clip at several times
//! (`tools/oracle.mjs`; morph targets applied on the CPU), and every part's every vertex must
//! agree with skinlet's whole-character posing (morphs, then skinning) to 1e-5 of the size.
//! Without the tools the test skips with a note, unless `SKINLET_REQUIRE_TOOLS=1` (CI).

mod common;

use common::assets_dir;
use glam::Vec3;
use skinlet::Asset;
use std::path::{Path, PathBuf};
use std::process::Command;

fn output(cmd: &mut Command) -> Vec<u8> {
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{cmd:?}: {}", String::from_utf8_lossy(&out.stderr));
    out.stdout
}

/// Compares three's poses of `glb` with skinlet's of `asset` at three times of clip 0;
/// returns the vertices compared and the largest distance found, relative to the size.
fn check(name: &str, tools: &Path, glb: &Path, asset: &Asset) -> (usize, f32) {
    let character = asset.character().unwrap();
    let clip = asset.clips.first();
    let times: Vec<f32> = match clip {
        Some(c) => [0.13, 0.5, 0.87].iter().map(|f| c.start + f * c.duration()).collect(),
        None => vec![0.0],
    };
    let mut cmd = Command::new("node");
    cmd.arg(tools.join("oracle.mjs")).arg(glb).arg("0").args(times.iter().map(|t| t.to_string()));
    let three: serde_json::Value = serde_json::from_slice(&output(&mut cmd)).unwrap();
    let (mut checked, mut worst, mut morphed) = (0, 0f32, 0f32);
    for (sample, &t) in three["samples"].as_array().unwrap().iter().zip(&times) {
        let (posed, _) = character.posed(&asset.skeleton, clip, t).unwrap();
        let (lo, hi) = posed.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
        let size = (hi - lo).length();
        let base = skinlet::SkinnedMesh { morphs: Default::default(), ..character.mesh.clone() };
        let unmorphed =
            skinlet::skinning::posed_positions(&asset.skeleton, &character.palette, &base, clip, Some(t)).unwrap();
        let moved = posed.iter().zip(&unmorphed).map(|(a, b)| a.distance(*b)).fold(0f32, f32::max);
        morphed = morphed.max(moved / size);
        let parts = sample["parts"].as_array().unwrap();
        assert_eq!(parts.len(), character.parts.len(), "{name}: three.js draws {} primitives", parts.len());
        for p in parts {
            let key = ["node", "mesh", "primitive"].map(|k| p[k].as_u64().unwrap_or(u64::MAX) as u32);
            let part = (character.parts.iter())
                .find(|q| [q.node, q.mesh, q.primitive] == key)
                .unwrap_or_else(|| panic!("{name}: three.js draws {key:?}, skinlet has no such part"));
            let theirs = p["positions"].as_array().unwrap();
            let ours = &posed[part.vertices.start as usize..part.vertices.end as usize];
            assert_eq!(theirs.len(), 3 * ours.len(), "{name} {key:?}");
            for (v, ours) in ours.iter().enumerate() {
                let theirs = Vec3::from_array(std::array::from_fn(|k| theirs[3 * v + k].as_f64().unwrap() as f32));
                let d = theirs.distance(*ours) / size;
                if d > 1e-5 {
                    eprintln!(
                        "{name} {key:?} at {t}: vertex {v} is {ours}, three.js says {theirs} ({d:.2e} of the size)"
                    );
                }
                worst = worst.max(d);
            }
            checked += ours.len();
        }
    }
    if !character.mesh.morphs.is_empty() {
        // The morph file is static but for its morphs: at some sampled time they must move it
        // far more than the tolerance, or this could not tell whether morphs are applied.
        assert!(morphed > 1e-3, "{name}: morphs moved vertices by only {morphed:.2e} of the size");
    }
    (checked, worst)
}

#[test]
fn poses_agree_with_three_js() {
    let Some(tools) = common::tools_dir("three") else { return };
    let tmp = std::env::temp_dir().join(format!("skinlet-oracle-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let mut cases: Vec<(String, PathBuf, Asset)> = Vec::new();
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let demo_glb = tmp.join("demo.glb");
    std::fs::write(&demo_glb, skinlet::export::to_glb(&demo).unwrap()).unwrap();
    cases.push(("@demo".into(), demo_glb, demo));
    if let Some(dir) = assets_dir() {
        let mut files: Vec<_> = std::fs::read_dir(dir.join("skinned")).unwrap().map(|e| e.unwrap().path()).collect();
        files.push(dir.join("morph/MorphStressTest.gltf"));
        files.sort();
        for path in files {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let asset = skinlet::import::load(&path).unwrap();
            // .gltf files become .glb by glTF Transform (not by skinlet), for three's loader.
            let glb = if path.extension().is_some_and(|e| e == "glb") {
                path.clone()
            } else {
                let out = tmp.join(format!("{name}.glb"));
                output(Command::new(tools.join("node_modules/.bin/gltf-transform")).arg("copy").arg(&path).arg(&out));
                out
            };
            cases.push((name, glb, asset));
        }
    }
    for (name, glb, asset) in &cases {
        let (n, worst) = check(name, &tools, glb, asset);
        eprintln!("{name}: {n} vertex positions, farthest {worst:.2e} of the size from three.js");
        assert!(worst <= 1e-5, "{name}: a vertex is {worst:.2e} of the size from three.js");
    }
    let _ = std::fs::remove_dir_all(&tmp);
}
