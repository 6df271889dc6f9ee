//! Real-asset tests of import, sampling and reference skinning on ../shared/assets
//! (override with SKINLET_ASSETS). Skipped with a note when the folder is absent.

mod common;
use common::assets_dir;

use glam::{Affine3A, DMat4, Vec3};
use skinlet::clip::Clip;
use skinlet::model::Trs;
use skinlet::pose::{Poser, global_transforms, skinning_matrices};
use skinlet::{Asset, skinning};
use std::path::PathBuf;

fn skinned_assets() -> Vec<(String, Asset)> {
    let Some(dir) = assets_dir() else { return Vec::new() };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("skinned")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert!(files.len() >= 8, "expected the shared skinned assets");
    files
        .into_iter()
        .map(|f| {
            let asset = skinlet::import::load(&f).unwrap_or_else(|e| panic!("{e}"));
            (f.file_name().unwrap().to_string_lossy().into_owned(), asset)
        })
        .collect()
}

fn extent(p: &[Vec3]) -> f32 {
    let (lo, hi) = p.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    (hi - lo).length()
}

fn skin_all(asset: &Asset, skin: u32, mats: &[Affine3A], mut f: impl FnMut(&skinlet::SkinnedMesh, &[Vec3])) {
    for inst in asset.instances.iter().filter(|i| i.skin == Some(skin)) {
        for p in &asset.meshes[inst.mesh as usize].primitives {
            let g = &p.geometry;
            let Some(inf) = &g.influences else { continue };
            let mut out = vec![Vec3::ZERO; g.positions.len()];
            skinning::skin(inf, &g.positions, &[], mats, &mut out, &mut []).unwrap();
            f(g, &out);
        }
    }
}

/// With every joint at its bind transform (the inverse of its inverse bind matrix) skinning
/// reproduces the input positions; where the file's rest pose is the bind pose (checked
/// independently on the matrices), so does skinning the rest pose.
#[test]
fn bind_pose_reproduces_input_positions() {
    for (name, asset) in skinned_assets() {
        for (s, skin) in asset.skins.iter().enumerate() {
            let mut globals = vec![DMat4::IDENTITY; asset.skeleton.nodes.len()];
            for (j, ibm) in skin.joints.iter().zip(&skin.inverse_bind) {
                globals[*j as usize] = ibm.as_dmat4().inverse();
            }
            let mut mats = Vec::new();
            skinning_matrices(skin, &globals, &mut mats);
            let mut rest = Poser::default();
            let rest_globals = rest.globals(&asset.skeleton, None, 0.0).to_vec();
            let rest_is_bind = skin.joints.iter().zip(&skin.inverse_bind).all(|(j, ibm)| {
                let m = rest_globals[*j as usize] * ibm.as_dmat4();
                (m - DMat4::IDENTITY).to_cols_array().iter().all(|x| x.abs() < 1e-4)
            });
            let mut rest_mats = Vec::new();
            skinning_matrices(skin, &rest_globals, &mut rest_mats);
            let mut checked = 0;
            for m in [&mats, &rest_mats] {
                if std::ptr::eq(m, &rest_mats) && !rest_is_bind {
                    continue;
                }
                skin_all(&asset, s as u32, m, |g, out| {
                    let tol = 1e-5 * extent(&g.positions);
                    for (v, (a, b)) in g.positions.iter().zip(out).enumerate() {
                        assert!((*a - *b).length() <= tol, "{name} skin {s} vertex {v}: {a} became {b}");
                    }
                    checked += g.positions.len();
                });
            }
            assert!(checked > 0, "{name}: nothing skinned");
            eprintln!("{name} skin {s}: rest pose is the bind pose: {rest_is_bind}");
        }
    }
}

/// Local transforms taken straight from the stored key values (not through the sampler).
fn key_pose(asset: &Asset, clip: &Clip, t: f32) -> Vec<Trs> {
    let mut locals: Vec<Trs> = asset.skeleton.nodes.iter().map(|n| n.rest).collect();
    let at = |times: &[f32]| times.iter().position(|&x| x == t);
    let value = |c: skinlet::clip::Interpolation, k: usize| {
        if c == skinlet::clip::Interpolation::CubicSpline { 3 * k + 1 } else { k }
    };
    for c in &clip.translations {
        if let Some(k) = at(&c.times) {
            locals[c.node as usize].translation = c.values[value(c.interpolation, k)];
        }
    }
    for c in &clip.rotations {
        if let Some(k) = at(&c.times) {
            locals[c.node as usize].rotation = c.values[value(c.interpolation, k)];
        }
    }
    for c in &clip.scales {
        if let Some(k) = at(&c.times) {
            locals[c.node as usize].scale = c.values[value(c.interpolation, k)];
        }
    }
    locals
}

/// At a key time shared by every channel the pose equals the key pose, bit for bit.
#[test]
fn pose_at_key_time_is_the_key_pose() {
    let mut checked = 0;
    for (name, asset) in skinned_assets() {
        for clip in &asset.clips {
            let all = clip
                .translations
                .iter()
                .map(|c| &c.times)
                .chain(clip.rotations.iter().map(|c| &c.times))
                .chain(clip.scales.iter().map(|c| &c.times));
            let shared: Vec<f32> =
                clip.key_times().into_iter().filter(|t| all.clone().all(|ts| ts.contains(t))).collect();
            for &t in shared.iter().step_by(shared.len().div_ceil(5).max(1)) {
                let mut poser = Poser::default();
                let sampled = poser.globals(&asset.skeleton, Some(clip), t).to_vec();
                let mut keyed = Vec::new();
                global_transforms(&asset.skeleton, &key_pose(&asset, clip, t), &mut keyed);
                assert_eq!(sampled, keyed, "{name} clip {:?} t = {t}", clip.name);
                checked += 1;
            }
        }
    }
    if assets_dir().is_some() {
        assert!(checked > 20, "only {checked} key poses checked");
    }
}

/// Skinned vertices move continuously: between two nearby times of a LINEAR clip no vertex
/// jumps further than the sampled motion allows (a check that sampling, posing and skinning
/// fit together on real data).
#[test]
fn poses_are_finite_and_continuous() {
    for (name, asset) in skinned_assets() {
        let Some(clip) = asset.clips.first() else { continue };
        let inst = asset.instances.iter().find(|i| i.skin.is_some()).unwrap();
        let skin = &asset.skins[inst.skin.unwrap() as usize];
        let mut poser = Poser::default();
        let (mut m0, mut m1) = (Vec::new(), Vec::new());
        let steps = 50;
        let mut max_step = 0f32;
        let mut size = 0f32;
        for k in 0..steps {
            let t0 = clip.start + clip.duration() * k as f32 / steps as f32;
            let t1 = clip.start + clip.duration() * (k as f32 + 0.001) / steps as f32;
            poser.skinning_matrices(&asset.skeleton, skin, Some(clip), t0, &mut m0);
            poser.skinning_matrices(&asset.skeleton, skin, Some(clip), t1, &mut m1);
            let mut a = Vec::new();
            skin_all(&asset, inst.skin.unwrap(), &m0, |_, out| a.extend_from_slice(out));
            let mut i = 0;
            skin_all(&asset, inst.skin.unwrap(), &m1, |_, out| {
                for p in out {
                    assert!(p.is_finite(), "{name}: non-finite skinned vertex");
                    max_step = max_step.max((*p - a[i]).length());
                    i += 1;
                }
            });
            size = size.max(extent(&a));
        }
        assert!(max_step < 0.05 * size, "{name}: a vertex moved {max_step} in 1/1000 of a step (size {size})");
    }
}

/// A .gltf whose buffers live in external .bin files loads the same as with data URIs.
#[test]
fn external_buffers_load_like_embedded_ones() {
    use base64::Engine as _;
    let Some(dir) = assets_dir() else { return };
    let text = std::fs::read_to_string(dir.join("skinned/SimpleSkin.gltf")).unwrap();
    let tmp = std::env::temp_dir().join(format!("skinlet-ext-{}", std::process::id()));
    std::fs::create_dir_all(tmp.join("bin files")).unwrap();
    let mut out = String::new();
    let mut rest = text.as_str();
    let mut k = 0;
    while let Some(i) = rest.find("\"data:application/gltf-buffer;base64,") {
        out.push_str(&rest[..i]);
        let body = &rest[i + 1..];
        let end = body.find('"').unwrap();
        let payload = body[..end].split_once(";base64,").unwrap().1;
        let bytes = base64::engine::general_purpose::STANDARD.decode(payload).unwrap();
        std::fs::write(tmp.join(format!("bin files/b{k}.bin")), bytes).unwrap();
        out.push_str(&format!("\"bin%20files/b{k}.bin\""));
        rest = &body[end + 1..];
        k += 1;
    }
    out.push_str(rest);
    assert!(k >= 1, "SimpleSkin.gltf has embedded buffers");
    let path = tmp.join("SimpleSkin.gltf");
    std::fs::write(&path, out).unwrap();
    let external = skinlet::import::load(&path).unwrap();
    let embedded = skinlet::import::load(&dir.join("skinned/SimpleSkin.gltf")).unwrap();
    assert_eq!(external.meshes, embedded.meshes);
    assert_eq!(external.clips, embedded.clips);
    assert_eq!(external.skins, embedded.skins);
    std::fs::remove_dir_all(&tmp).ok();
}
