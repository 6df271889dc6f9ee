//! Compressed and quantized glTF: variants of the shared assets made here with the real
//! tools (gltfpack; glTF Transform for Draco, versions pinned in `tools/package.json`) import
//! to the same character as the original, within the quantization step. The tools live in
//! `tools/node_modules` (`npm install --prefix tools`); without them the tests skip with a
//! note, unless `SKINLET_REQUIRE_TOOLS=1` (CI sets it).

mod common;

use common::assets_dir;
use glam::Vec3;
use skinlet::Asset;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The tool `bin` of npm package `package`.
fn tool(package: &str, bin: &str) -> Option<PathBuf> {
    common::tools_dir(package).map(|d| d.join("node_modules/.bin").join(bin))
}

fn run(tool: &Path, args: &[&str]) {
    let out = Command::new(tool).args(args).output().unwrap();
    assert!(out.status.success(), "{} {args:?}: {}", tool.display(), String::from_utf8_lossy(&out.stderr));
}

/// The `extensionsRequired` of a .glb.
fn required(path: &Path) -> Vec<String> {
    let bytes = std::fs::read(path).unwrap();
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + n]).unwrap();
    json["extensionsRequired"].as_array().map_or(Vec::new(), |a| a.iter().map(|e| e.to_string()).collect())
}

/// The whole character's vertices posed in scene space, morphs applied (`None`: the rest
/// pose with default weights), and the
/// diagonal of their box.
fn posed(asset: &Asset, t: Option<f32>) -> (Vec<Vec3>, f32) {
    let c = asset.character().unwrap();
    let clip = t.and(asset.clips.first());
    let (p, _) = c.posed(&asset.skeleton, clip, t.unwrap_or(0.0)).unwrap();
    // Only vertices that a triangle uses: gltfpack drops the others.
    let mut used = vec![false; p.len()];
    c.mesh.triangles.iter().flatten().for_each(|&v| used[v as usize] = true);
    let p: Vec<Vec3> = p.into_iter().zip(used).filter(|(_, u)| *u).map(|(p, _)| p).collect();
    let (lo, hi) = p.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    (p, (hi - lo).length())
}

/// The largest distance from a point of `a` to the nearest point of `b` (a grid of cells of
/// `cell`, searched ring by ring up to `rings` cells away; farther counts as infinite).
fn farthest_nearest(a: &[Vec3], b: &[Vec3], cell: f32, rings: i32) -> f32 {
    let key = |p: Vec3| (p / cell).floor().as_ivec3();
    let mut grid: HashMap<glam::IVec3, Vec<Vec3>> = HashMap::new();
    b.iter().for_each(|&p| grid.entry(key(p)).or_default().push(p));
    let mut worst = 0f32;
    for &p in a {
        let k = key(p);
        let mut best = f32::INFINITY;
        for dx in -rings..=rings {
            for dy in -rings..=rings {
                for dz in -rings..=rings {
                    for q in grid.get(&(k + glam::IVec3::new(dx, dy, dz))).into_iter().flatten() {
                        best = best.min(p.distance(*q));
                    }
                }
            }
        }
        worst = worst.max(best);
    }
    worst
}

/// Posed vertex sets agree both ways within `tolerance` (relative to the original's size).
fn same_shape(name: &str, original: &Asset, packed: &Asset, t: Option<f32>, tolerance: f32) {
    let (a, size) = posed(original, t);
    let (b, _) = posed(packed, t);
    let tol = tolerance * size;
    let d = farthest_nearest(&a, &b, tol, 1).max(farthest_nearest(&b, &a, tol, 1));
    eprintln!(
        "{name} at {t:?}: {} vs {} vertices, farthest {:.2e} of the size (tolerance {tolerance:.1e})",
        a.len(),
        b.len(),
        d / size
    );
    assert!(d <= tol, "{name} at {t:?}: a vertex is {d} away ({} of the size)", d / size);
}

fn variants(dir: &Path) -> Vec<PathBuf> {
    let skinned =
        ["CesiumMan.glb", "Fox.glb", "RiggedFigure.glb", "BrainStem.glb"].map(|f| dir.join("skinned").join(f));
    // Morph targets: gltfpack quantizes their deltas too (8-bit integers).
    skinned.into_iter().chain([dir.join("morph/MorphStressTest.gltf")]).collect()
}

#[test]
fn meshopt_compressed_files_import_like_the_originals() {
    let (Some(dir), Some(gltfpack)) = (assets_dir(), tool("gltfpack", "gltfpack")) else { return };
    let tmp = std::env::temp_dir().join(format!("skinlet-compressed-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for src in variants(&dir) {
        let name = src.file_stem().unwrap().to_string_lossy().into_owned();
        let original = skinlet::import::load(&src).unwrap();
        let times: Vec<f32> = original
            .clips
            .first()
            .map(|c| [0.13, 0.5, 0.87].map(|f| c.start + f * c.duration()).to_vec())
            .unwrap_or_default();
        // Compression alone (no quantization, animation not resampled): the rest pose is
        // lossless. gltfpack still stores weights in 8 bits: posed, each of up to 4 weights
        // is off by at most half a step (1/510), which moves a vertex by at most 4/510 of
        // the largest distance between its joints' images of it (bounded by the size).
        let exact = tmp.join(format!("{name}-noq.glb"));
        run(&gltfpack, &["-i", src.to_str().unwrap(), "-o", exact.to_str().unwrap(), "-c", "-noq", "-af", "0", "-kn"]);
        assert!(required(&exact).iter().any(|e| e.contains("EXT_meshopt_compression")), "{:?}", required(&exact));
        let a = skinlet::import::load(&exact).unwrap();
        same_shape(&format!("{name} (meshopt)"), &original, &a, None, 1e-5);
        for &t in &times {
            same_shape(&format!("{name} (meshopt)"), &original, &a, Some(t), 4.0 / 510.0);
        }
        // gltfpack's defaults with the ratified extension: 14-bit positions in integer
        // attributes, 8-bit weights, quantized animation, all meshopt-compressed.
        let quantized = tmp.join(format!("{name}-q.glb"));
        run(
            &gltfpack,
            &["-i", src.to_str().unwrap(), "-o", quantized.to_str().unwrap(), "-cc", "-ce", "khr", "-af", "0"],
        );
        let req = required(&quantized);
        assert!(
            req.iter().any(|e| e.contains("KHR_meshopt_compression"))
                && req.iter().any(|e| e.contains("KHR_mesh_quantization")),
            "{req:?}"
        );
        let q = skinlet::import::load(&quantized).unwrap();
        // Rest pose: every skinning matrix is the same, so only the position step counts
        // (1/2^14 of the mesh's box per axis; twice that as the bound).
        same_shape(&format!("{name} (quantized)"), &original, &q, None, 2.0 * 3f32.sqrt() / 16384.0);
        // Posed, 8-bit skin and morph weights and 12-bit rotation keys add to that: 4/510 of
        // the size from the weights (above), 2^-12 rad per joint of a chain, loosely 1/100.
        for &t in &times {
            same_shape(&format!("{name} (quantized)"), &original, &q, Some(t), 1e-2);
        }
        // gltfpack may merge meshes and drop degenerate triangles; it keeps the rest.
        let (c0, c1) = (original.character().unwrap(), q.character().unwrap());
        assert!(c1.triangle_count() <= c0.triangle_count() && 100 * c1.triangle_count() >= 99 * c0.triangle_count());
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn draco_files_import_like_the_originals() {
    let (Some(dir), Some(transform)) = (assets_dir(), tool("@gltf-transform/cli", "gltf-transform")) else { return };
    let tmp = std::env::temp_dir().join(format!("skinlet-draco-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    // The skinned characters (Draco does not compress morph-target primitives).
    for src in variants(&dir).into_iter().filter(|p| p.starts_with(dir.join("skinned"))) {
        let name = src.file_stem().unwrap().to_string_lossy().into_owned();
        let draco = tmp.join(format!("{name}-draco.glb"));
        run(&transform, &["draco", src.to_str().unwrap(), draco.to_str().unwrap()]);
        assert!(required(&draco).iter().any(|e| e.contains("KHR_draco_mesh_compression")), "{:?}", required(&draco));
        let original = skinlet::import::load(&src).unwrap();
        let d = skinlet::import::load(&draco).unwrap();
        // glTF Transform's defaults: 14-bit positions over each primitive's box (the same
        // bound as gltfpack's above), 12-bit generic attributes (skin weights): posed, each
        // of up to 4 weights is off by at most half a step, 4/8190 of the size, plus the
        // position step: 1e-3 holds both.
        same_shape(&format!("{name} (draco)"), &original, &d, None, 2.0 * 3f32.sqrt() / 16384.0);
        if let Some(c) = original.clips.first() {
            for f in [0.13, 0.5, 0.87] {
                same_shape(&format!("{name} (draco)"), &original, &d, Some(c.start + f * c.duration()), 1e-3);
            }
        }
        let (c0, c1) = (original.character().unwrap(), d.character().unwrap());
        assert_eq!(c0.triangle_count(), c1.triangle_count(), "{name}");
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

/// The morph-target test through glTF Transform's `draco` (morph targets stay outside the
/// Draco stream, in the order of the decoded points) and `sparse` (morph deltas and weight
/// keys as sparse accessors, the all-zero targets as accessors without a buffer view): the
/// weight channels read back as the original's, `sparse`'s targets too, and at 3 times of
/// each clip the morphed mesh poses like the original within the position step (Draco: 14
/// bits over each primitive's box), far less than the morphs move it.
#[test]
fn morph_targets_through_draco_and_sparse() {
    let (Some(dir), Some(transform)) = (assets_dir(), tool("@gltf-transform/cli", "gltf-transform")) else { return };
    let tmp = std::env::temp_dir().join(format!("skinlet-morphs-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let src = dir.join("morph/MorphStressTest.gltf");
    let original = skinlet::import::load(&src).unwrap();
    for (command, tolerance) in [("draco", 2.0 * 3f32.sqrt() / 16384.0), ("sparse", 1e-6)] {
        let out = tmp.join(format!("morph-{command}.glb"));
        run(&transform, &[command, src.to_str().unwrap(), out.to_str().unwrap()]);
        let bytes = std::fs::read(&out).unwrap();
        let text =
            String::from_utf8_lossy(&bytes[20..20 + u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize]);
        let made = if command == "draco" { "KHR_draco_mesh_compression" } else { "\"sparse\"" };
        assert!(text.contains(made) && text.contains("\"targets\""), "{command}: the tool did not write {made}");
        let a = skinlet::import::load(&out).unwrap_or_else(|e| panic!("{command}: {e}"));
        for (m0, m1) in original.meshes.iter().zip(&a.meshes) {
            for (p0, p1) in m0.primitives.iter().zip(&m1.primitives) {
                assert_eq!((p0.targets.len(), p1.targets.len()), (8, 8), "{command}");
                // `sparse` keeps the vertex order, so the targets are the original's; Draco
                // stores the vertices in another order (the morphed poses below compare them).
                if command == "sparse" {
                    assert!(p0.targets == p1.targets, "{command}: mesh {:?} primitive {}", m0.name, p0.index);
                }
            }
        }
        for (c0, c1) in original.clips.iter().zip(&a.clips) {
            assert_eq!(c0.weights, c1.weights, "{command}: clip {}", c0.name);
        }
        same_shape(&format!("MorphStressTest ({command})"), &original, &a, None, tolerance);
        for c in &original.clips {
            for f in [0.13, 0.5, 0.87] {
                same_shape(
                    &format!("MorphStressTest ({command}, {})", c.name),
                    &original,
                    &a,
                    Some(c.start + f * c.duration()),
                    tolerance,
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn corrupt_compressed_data_is_an_error_not_a_panic() {
    let Some(dir) = assets_dir() else { return };
    let (Some(gltfpack), Some(transform)) =
        (tool("gltfpack", "gltfpack"), tool("@gltf-transform/cli", "gltf-transform"))
    else {
        return;
    };
    let src = dir.join("skinned/RiggedFigure.glb");
    let tmp = std::env::temp_dir().join(format!("skinlet-corrupt-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let (packed, draco) = (tmp.join("meshopt.glb"), tmp.join("draco.glb"));
    run(&gltfpack, &["-i", src.to_str().unwrap(), "-o", packed.to_str().unwrap(), "-cc"]);
    run(&transform, &["draco", src.to_str().unwrap(), draco.to_str().unwrap()]);
    for (file, what) in [(&packed, "meshopt"), (&draco, "KHR_draco_mesh_compression")] {
        let bytes = std::fs::read(file).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let bin = 20 + json_len + 8;
        // Zeroed compressed bytes do not decode: an error naming the view or primitive.
        let mut zeroed = bytes.clone();
        zeroed[bin..].fill(0);
        let e = skinlet::import::load_bytes(&zeroed, Path::new("zeroed.glb")).unwrap_err().to_string();
        assert!(e.contains(what), "{e}");
        // Random byte flips in the compressed data: an error or a file, never a panic.
        let mut rng = 0x2545F4914F6CDD1Du64;
        for _ in 0..300 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                let at = bin + (rng % (b.len() - bin) as u64) as usize;
                b[at] ^= 1 << (rng >> 61);
            }
            if let Ok(a) = skinlet::import::load_bytes(&b, Path::new("flipped.glb")) {
                let _ = a.character();
            }
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
}
