//! The whole character: every node of a scene that draws a mesh is baked, posed as glTF
//! draws it, bounded and culled conservatively. Checked on the shared files (triangles
//! counted independently from the glTF document), on the demo character (two skins, rigid,
//! animated and instanced parts) and on random scenes of that kind.

mod common;
mod rig;

use common::assets_dir;
use glam::{DVec3, Quat, Vec3};
use proptest::prelude::*;
use rig::Rng;
use skinlet::bake::{Baked, bake, prepare_character};
use skinlet::bounds::refine::Refinement;
use skinlet::clip::{Channel, Clip, Interpolation, WeightChannel};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::model::{Influences, Instance, Mesh, MorphTarget, Node, Primitive, Skeleton, Skin, SkinnedMesh, Trs};
use skinlet::pose::Poser;
use skinlet::{Asset, PartKind};
use skinlet_lab::crowd::{CrowdParams, posed_crowd, run};

/// Triangles and drawings (node, primitive) of a glTF file's default scene, read from the
/// document by the gltf crate alone: what a glTF viewer draws.
fn scene_triangles(path: &std::path::Path) -> (usize, usize) {
    let doc = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).unwrap().document;
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => doc.nodes().filter(|n| !doc.nodes().any(|p| p.children().any(|c| c.index() == n.index()))).collect(),
    };
    let (mut triangles, mut drawings) = (0, 0);
    let mut stack = roots;
    while let Some(node) = stack.pop() {
        stack.extend(node.children());
        let Some(mesh) = node.mesh() else { continue };
        for p in mesh.primitives() {
            let n = p.indices().map_or_else(|| p.get(&gltf::Semantic::Positions).unwrap().count(), |a| a.count());
            let t = match p.mode() {
                gltf::mesh::Mode::Triangles => n / 3,
                gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => n.saturating_sub(2),
                _ => continue,
            };
            triangles += t;
            drawings += 1;
        }
    }
    (triangles, drawings)
}

fn bake_all(asset: &Asset) -> (Baked, usize) {
    let character = asset.character().unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let how = Refinement::NONE;
    let (baked, _) =
        bake(asset, &character, &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &how, &mut |_| {}).unwrap();
    let dropped = prepare_character(&character).unwrap().dropped_triangles;
    (baked, dropped)
}

#[test]
fn the_bake_holds_every_triangle_the_scene_draws() {
    let mut cases: Vec<(String, Asset, usize, usize)> = Vec::new();
    if let Some(dir) = assets_dir() {
        let mut files: Vec<_> = std::fs::read_dir(dir.join("skinned")).unwrap().map(|e| e.unwrap().path()).collect();
        files.push(dir.join("morph/MorphStressTest.gltf"));
        files.sort();
        for path in files {
            let asset = skinlet::import::load(&path).unwrap();
            let (triangles, drawings) = scene_triangles(&path);
            cases.push((path.display().to_string(), asset, triangles, drawings));
        }
    }
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
    let drawn = demo.instances.iter().map(|i| demo.meshes[i.mesh as usize].primitives[0].geometry.triangles.len());
    let (triangles, drawings) = (drawn.sum(), demo.instances.len());
    cases.push(("@demo".into(), demo, triangles, drawings));
    for (name, asset, triangles, drawings) in &cases {
        let character = asset.character().unwrap();
        assert_eq!(character.triangle_count(), *triangles, "{name}: the character has every drawn triangle");
        let (baked, dropped) = bake_all(asset);
        let stored: usize = baked.parts.iter().map(|p| p.triangles.len()).sum();
        eprintln!("{name}: {triangles} triangles in {drawings} drawings; {stored} stored, {dropped} draw nothing");
        assert_eq!(baked.parts.len(), *drawings, "{name}: parts");
        assert_eq!(stored, baked.mesh.triangles.len(), "{name}");
        assert_eq!(stored + dropped, *triangles, "{name}: every drawn triangle is baked (or draws nothing)");
        // No meshlet mixes two parts.
        for p in &baked.parts {
            for m in &baked.meshlets.meshlets[p.meshlets.start as usize..p.meshlets.end as usize] {
                assert!(baked.meshlets.vertices_of(m).iter().all(|v| p.vertices.contains(v)), "{name}");
            }
        }
        check_sources(name, asset, &baked, dropped);
    }
}

#[test]
fn every_builder_keeps_where_each_triangle_came_from() {
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
    let character = asset.character().unwrap();
    let dropped = prepare_character(&character).unwrap().dropped_triangles;
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    for builder in Builder::ALL {
        let (baked, _) =
            bake(&asset, &character, &clips, builder, MeshletLimits::SMALL, &Refinement::NONE, &mut |_| {}).unwrap();
        check_sources(builder.name(), &asset, &baked, dropped);
    }
}

#[test]
fn a_bad_source_table_is_an_error_that_says_where() {
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 1000, ..Default::default() });
    let (baked, _) = bake_all(&asset);
    let bytes = skinlet::bake::to_bytes(&baked);
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let sections = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let entry = (0..sections).map(|k| 16 + 24 * k).find(|&e| &bytes[e..e + 4] == b"SRCT").expect("an SRCT section");
    let at = word(entry + 8);
    let error = |patch: &dyn Fn(&mut Vec<u8>)| {
        let mut b = bytes.clone();
        patch(&mut b);
        skinlet::bake::from_bytes(&b).unwrap_err().to_string()
    };
    let e = error(&|b| b[at + 4..at + 8].copy_from_slice(&(3u32 << 30).to_le_bytes()));
    assert!(e.contains("bake section SRCT") && e.contains("entry 0: rotation 3"), "{e}");
    let e = error(&|b| b[at..at + 4].copy_from_slice(&1u32.to_le_bytes()));
    assert!(e.contains("bake section SRCT") && e.contains("1 entries, where MLET has"), "{e}");
}

/// Every meshlet triangle's source (`Baked::sources`) is a distinct triangle of its part's
/// glTF primitive whose corners, rotated as stored, are at the baked corners' positions (the
/// welded vertices keep bit-identical positions); the source triangles left over are the
/// `dropped` ones, which repeat a welded vertex. Also through the file's bytes.
fn check_sources(name: &str, asset: &Asset, baked: &Baked, dropped: usize) {
    let sources = baked.sources.as_ref().expect("bake writes the sources");
    let reread = skinlet::bake::from_bytes(&skinlet::bake::to_bytes(baked))
        .unwrap_or_else(|e| panic!("{name}: {e}; bounds {:?}", &baked.bounds[..1]));
    assert_eq!(reread.sources.as_ref(), Some(sources), "{name}: SRCT round trip");
    let mut unused = 0;
    for (k, part) in baked.parts.iter().enumerate() {
        let primitive = asset.meshes[part.mesh as usize].primitives.iter().find(|p| p.index == part.primitive as usize);
        let source = &primitive.unwrap().geometry;
        let mut used = vec![false; source.triangles.len()];
        for m in &baked.meshlets.meshlets[part.meshlets.start as usize..part.meshlets.end as usize] {
            for (t, baked_triangle) in baked.meshlets.mesh_triangles(m).enumerate() {
                let code = sources[m.triangle_offset as usize / 3 + t];
                let (index, rotation) = ((code & ((1 << 30) - 1)) as usize, (code >> 30) as usize);
                assert!(rotation < 3 && index < used.len() && !used[index], "{name} part {k}: source {code:#x}");
                used[index] = true;
                for (c, &v) in baked_triangle.iter().enumerate() {
                    let s = source.triangles[index][(c + rotation) % 3] as usize;
                    assert_eq!(baked.mesh.positions[v as usize], source.positions[s], "{name} part {k}");
                }
            }
        }
        unused += used.iter().filter(|u| !**u).count();
    }
    assert_eq!(unused, dropped, "{name}: the source triangles no meshlet holds are the degenerate ones");
    check_source_corners(name, asset, baked);
}

/// `skinlet_runtime::source_corners` on the bake's bytes and the asset's primitives (their
/// indices and positions, as an engine loads them): every meshlet corner gets its bake vertex
/// and a source vertex at the same position; positions moved, a primitive missing and a bake
/// without `SRCT` are errors.
fn check_source_corners(name: &str, asset: &Asset, baked: &Baked) {
    use skinlet_runtime::source_corners::{PartSource, source_corners};
    // A bake's bytes in 4-byte aligned storage.
    let words = |baked: &Baked| -> (Vec<u32>, usize) {
        let mut bytes = skinlet::bake::to_bytes(baked);
        let n = bytes.len();
        bytes.resize(n.next_multiple_of(4), 0);
        (bytemuck::pod_collect_to_vec(&bytes), n)
    };
    let (bytes, n) = words(baked);
    let view = skinlet_runtime::bake_view::BakeView::new(&bytemuck::cast_slice(&bytes)[..n]).unwrap();
    let primitives: Vec<(Vec<u32>, Vec<[f32; 3]>)> = (baked.parts.iter())
        .map(|part| {
            let p = asset.meshes[part.mesh as usize].primitives.iter().find(|p| p.index == part.primitive as usize);
            let g = &p.unwrap().geometry;
            (g.triangles.iter().flatten().copied().collect(), g.positions.iter().map(|v| v.to_array()).collect())
        })
        .collect();
    let sources: Vec<PartSource> = (primitives.iter())
        .map(|(i, p)| PartSource { indices: Some(i), vertices: p.len() as u32, positions: Some(p) })
        .collect();
    let corners = source_corners(&view, &sources).unwrap_or_else(|e| panic!("{name}: {e}"));
    for m in &baked.meshlets.meshlets {
        for (t, tri) in baked.meshlets.mesh_triangles(m).enumerate() {
            for (k, &v) in tri.iter().enumerate() {
                let c = corners[m.triangle_offset as usize + 3 * t + k];
                assert_eq!(c.vertex, v, "{name}");
                let (_, positions) = &primitives[c.part as usize];
                assert_eq!(positions[c.source as usize], baked.mesh.positions[v as usize].to_array(), "{name}");
            }
        }
    }
    let mut moved = primitives[0].1.clone();
    moved.iter_mut().for_each(|p| p[0] += 1.0);
    let wrong: Vec<PartSource> = (sources.iter().enumerate())
        .map(|(p, s)| if p == 0 { PartSource { positions: Some(&moved), ..*s } } else { *s })
        .collect();
    let e = source_corners(&view, &wrong).unwrap_err().to_string();
    assert!(e.contains("part 0") && e.contains("not of this file"), "{name}: {e}");
    let e = source_corners(&view, &sources[1..]).unwrap_err().to_string();
    assert!(e.contains("source primitives for"), "{name}: {e}");
    let (bytes, n) = words(&Baked { sources: None, ..baked.clone() });
    let view = skinlet_runtime::bake_view::BakeView::new(&bytemuck::cast_slice(&bytes)[..n]).unwrap();
    assert!(source_corners(&view, &sources).unwrap_err().to_string().contains("no SRCT"), "{name}");
}

/// Random soft weights over `joints` joints, 1 to 4 per vertex, sorted by decreasing weight.
fn random_influences(r: &mut Rng, vertices: usize, joints: usize) -> Influences {
    let mut inf = Influences { stride: 4, joints: vec![0; 4 * vertices], weights: vec![0.0; 4 * vertices] };
    for v in 0..vertices {
        let mut pairs: Vec<(u16, f32)> = Vec::new();
        for _ in 0..1 + r.below(4.min(joints)) {
            let j = r.below(joints) as u16;
            if !pairs.iter().any(|p| p.0 == j) {
                pairs.push((j, r.range(0.05, 1.0)));
            }
        }
        let sum: f32 = pairs.iter().map(|p| p.1).sum();
        pairs.sort_by(|a, b| b.1.total_cmp(&a.1));
        for (k, (j, w)) in pairs.into_iter().enumerate() {
            (inf.joints[4 * v + k], inf.weights[4 * v + k]) = (j, w / sum);
        }
    }
    inf
}

fn random_triangles(r: &mut Rng, vertices: usize, count: usize) -> Vec<[u32; 3]> {
    (0..count)
        .map(|_| [r.below(vertices), r.below(vertices), r.below(vertices)].map(|v| v as u32))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

fn random_trs(r: &mut Rng) -> Trs {
    Trs { translation: r.v3(1.0), rotation: Quat::from_axis_angle(r.axis(), r.range(-3.0, 3.0)), scale: r.scale() }
}

/// A random whole character: a random rig's skin draws a body from a node whose own transform
/// glTF ignores; a second skin over some of its joints, in another order and partly with other
/// bind matrices, draws a cloak; one rigid mesh is drawn by a static node under a joint and by
/// an animated non-joint node.
fn random_scene(seed: u64) -> Asset {
    let (skeleton, skin, mut clip, positions, influences) = rig::random_character(seed);
    let mut r = Rng(seed.wrapping_mul(0xD1B54A32D192ED03) | 1);
    let mut nodes = skeleton.nodes.clone();
    let n = nodes.len() as u32;
    let mut node = |name: &str, parent: Option<u32>, r: &mut Rng| {
        nodes.push(Node { name: name.into(), parent, rest: random_trs(r), matrix: None });
        nodes.len() as u32 - 1
    };
    let body_node = node("body", None, &mut r);
    let cloak_node = node("cloak", Some(r.below(n as usize) as u32), &mut r);
    let prop = node("prop", Some(skin.joints[r.below(skin.joints.len())]), &mut r);
    let spinner = node("spinner", Some(r.below(n as usize) as u32), &mut r);
    let spinner_rest = nodes[spinner as usize].rest.rotation;
    let skeleton = Skeleton::new(nodes).unwrap();
    let end = clip.end.max(0.5);
    let spin = (0..5).map(|k| Quat::from_axis_angle(Vec3::Y, 1.5 * k as f32) * spinner_rest).collect();
    let times = (0..5).map(|k| end * k as f32 / 4.0).collect();
    clip.rotations.push(Channel { node: spinner, interpolation: Interpolation::Linear, times, values: spin });
    clip.end = end;
    let picked: Vec<usize> = (0..skin.joints.len()).rev().filter(|_| r.u() < 0.7).collect();
    let picked = if picked.is_empty() { vec![0] } else { picked };
    let cloak_skin = Skin {
        name: "cloak".into(),
        joints: picked.iter().map(|&i| skin.joints[i]).collect(),
        inverse_bind: (picked.iter())
            .map(|&i| if r.u() < 0.5 { skin.inverse_bind[i] } else { random_trs(&mut r).to_mat4() })
            .collect(),
    };
    let verts = rig::VERTICES;
    let body = SkinnedMesh {
        triangles: random_triangles(&mut r, verts, 2 * verts),
        positions,
        influences: Some(influences),
        ..SkinnedMesh::default()
    };
    let cloak = SkinnedMesh {
        positions: (0..verts).map(|_| r.v3(2.0)).collect(),
        normals: Vec::new(),
        triangles: random_triangles(&mut r, verts, 2 * verts),
        influences: Some(random_influences(&mut r, verts, picked.len())),
        ..SkinnedMesh::default()
    };
    let rigid = SkinnedMesh {
        positions: (0..8).map(|_| r.v3(0.5)).collect(),
        normals: Vec::new(),
        triangles: random_triangles(&mut r, 8, 10),
        ..SkinnedMesh::default()
    };
    let one = |name: &str, geometry| Mesh {
        name: name.into(),
        primitives: vec![Primitive { index: 0, geometry, targets: Vec::new() }],
        weights: Vec::new(),
    };
    Asset {
        skeleton,
        skins: vec![skin, cloak_skin],
        meshes: vec![one("body", body), one("cloak", cloak), one("rigid", rigid)],
        instances: vec![
            Instance { node: body_node, mesh: 0, skin: Some(0) },
            Instance { node: cloak_node, mesh: 1, skin: Some(1) },
            Instance { node: prop, mesh: 2, skin: None },
            Instance { node: spinner, mesh: 2, skin: None },
        ],
        clips: vec![clip],
        ..Asset::default()
    }
}

/// The character posed through its palette equals each part posed as glTF defines it, from
/// the source data: a skinned primitive by its own skin's matrices, a rigid one by its node's
/// global transform (in f64).
fn check_parts_pose_like_gltf(asset: &Asset, clip: Option<&Clip>, t: f32) {
    let character = asset.character().unwrap();
    let mut poser = Poser::default();
    let (posed, _) = character.posed(&asset.skeleton, clip, t).unwrap();
    let globals = poser.globals(&asset.skeleton, clip, t).to_vec();
    let (lo, hi) = posed.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
    let tolerance = 1e-5 * (hi - lo).length().max(1.0);
    for part in &character.parts {
        let mesh = &asset.meshes[part.mesh as usize];
        let prim = &mesh.primitives[0];
        let g = &prim.geometry;
        // glTF's morph weights: the node's, else the mesh's, else zero; a clip's weight
        // channel for the node replaces a target's. Morphs come before skinning.
        let mut weights = (asset.node_weights.get(&part.node).cloned()).unwrap_or_else(|| {
            if mesh.weights.is_empty() { vec![0.0; prim.targets.len()] } else { mesh.weights.clone() }
        });
        for w in clip.iter().flat_map(|c| &c.weights).filter(|w| w.channel.node == part.node) {
            weights[w.target as usize] = w.channel.sample(t);
        }
        let base: Vec<Vec3> = (0..g.positions.len())
            .map(|v| g.positions[v] + prim.targets.iter().zip(&weights).map(|(d, w)| *w * d.positions[v]).sum::<Vec3>())
            .collect();
        let want: Vec<Vec3> = match part.kind {
            PartKind::Skinned { skin } => {
                let mut mats = Vec::new();
                poser.skinning_matrices(&asset.skeleton, &asset.skins[skin as usize], clip, t, &mut mats);
                let mut out = vec![Vec3::ZERO; g.positions.len()];
                let inf = g.influences.as_ref().unwrap();
                skinlet::skinning::skin(inf, &base, &[], &mats, &mut out, &mut []).unwrap();
                out
            }
            PartKind::Rigid => {
                (base.iter()).map(|p| globals[part.node as usize].transform_point3(p.as_dvec3()).as_vec3()).collect()
            }
        };
        let got = &posed[part.vertices.start as usize..part.vertices.end as usize];
        for (v, (a, b)) in got.iter().zip(&want).enumerate() {
            assert!(a.distance(*b) <= tolerance, "node {} vertex {v}: {a} vs {b}", part.node);
        }
    }
}

/// Poses the scene at `poses` times against glTF's definition, bakes it, verifies the bounds
/// and checks every culled triangle of a crowd.
fn check_scene(asset: &Asset, seed: u64, poses: usize) {
    let clip = &asset.clips[0];
    for k in 0..poses {
        check_parts_pose_like_gltf(asset, Some(clip), clip.start + clip.duration() * k as f32 / (poses - 1) as f32);
    }
    check_parts_pose_like_gltf(asset, None, 0.0);
    let character = asset.character().unwrap();
    assert_eq!(character.parts.len(), 4);
    let clips = [clip];
    let how = Refinement { max_rounds: 1, ..Refinement::NONE };
    let (baked, _) =
        bake(asset, &character, &clips, Builder::SkinAware, MeshletLimits::SMALL, &how, &mut |_| {}).unwrap();
    check_sources(&format!("seed {seed}"), asset, &baked, prepare_character(&character).unwrap().dropped_triangles);
    let palette = baked.palette();
    let report = skinlet::bounds::verify::verify_bounds(
        &asset.skeleton,
        &palette,
        &clips,
        &baked.mesh,
        &baked.meshlets,
        &baked.bounds,
        200,
    )
    .unwrap();
    assert_eq!(report.violations(), 0, "seed {seed}: {report:?}");
    let params = CrowdParams { instances: 8, frames: 3, seed, ..CrowdParams::default() };
    let scene = posed_crowd(&asset.skeleton, &palette, &baked.mesh, &clips, &params).unwrap();
    let stats = run(&baked, &asset.skeleton, &palette, &clips, &scene, &params, true).unwrap();
    assert_eq!(stats.false_culls, 0, "seed {seed}: {stats:?}");
}

/// [`random_scene`] with two morph targets on the body and on the rigid mesh: mesh default
/// weights, one drawing node's own weights, and weight channels (random modes) on the body
/// and on the animated node.
fn random_morph_scene(seed: u64) -> Asset {
    let mut asset = random_scene(seed);
    let mut r = Rng(seed.wrapping_mul(0xA24BAED4963EE407) | 1);
    for m in [0, 2] {
        let n = asset.meshes[m].primitives[0].geometry.positions.len();
        let targets =
            (0..2).map(|_| MorphTarget { positions: (0..n).map(|_| r.v3(0.5)).collect(), normals: Vec::new() });
        asset.meshes[m].primitives[0].targets = targets.collect();
    }
    asset.meshes[2].weights = vec![r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
    let (body, prop, spinner) = (asset.instances[0].node, asset.instances[2].node, asset.instances[3].node);
    asset.node_weights.insert(prop, vec![r.range(-1.0, 1.0), r.range(0.0, 1.0)]);
    let end = asset.clips[0].end;
    let modes = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline];
    for (node, target) in [(body, 1), (spinner, 0)] {
        let mode = modes[r.below(3)];
        let per = if mode == Interpolation::CubicSpline { 3 } else { 1 };
        let times: Vec<f32> = (0..4).map(|k| end * k as f32 / 3.0).collect();
        let values = (0..per * times.len()).map(|_| r.range(-1.0, 1.5)).collect();
        let channel = Channel { node, interpolation: mode, times, values };
        asset.clips[0].weights.push(WeightChannel { target, channel });
    }
    asset
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    #[test]
    fn random_whole_characters_pose_bound_and_cull_conservatively(seed in any::<u64>()) {
        check_scene(&random_scene(seed), seed, 4);
    }

    #[test]
    fn random_morph_targets_pose_bound_and_cull_conservatively(seed in any::<u64>()) {
        let asset = random_morph_scene(seed);
        let character = asset.character().unwrap();
        assert_eq!(character.morphed_parts().count(), 3, "body, prop and spinner");
        check_scene(&asset, seed, 7);
    }
}

#[test]
fn the_demo_poses_like_gltf_and_verifies_as_a_whole() {
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
    for clip in &asset.clips {
        for k in 0..5 {
            check_parts_pose_like_gltf(&asset, Some(clip), clip.start + clip.duration() * k as f32 / 4.0);
        }
    }
    let (baked, _) = bake_all(&asset);
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    for set in clips.iter().map(|c| vec![*c]).chain([clips.clone()]) {
        let (b, _) = bake(
            &asset,
            &asset.character().unwrap(),
            &set,
            Builder::SkinAware,
            MeshletLimits::NVIDIA,
            &Refinement::NONE,
            &mut |_| {},
        )
        .unwrap();
        let r = skinlet::bounds::verify::verify_bounds(
            &asset.skeleton,
            &b.palette(),
            &set,
            &b.mesh,
            &b.meshlets,
            &b.bounds,
            300,
        )
        .unwrap();
        assert_eq!(r.violations(), 0, "{:?}: {r:?}", set.iter().map(|c| &c.name).collect::<Vec<_>>());
    }
    // The propeller's meshlets move: its part's vertices turn with the clip.
    let prop = &baked.parts[3];
    let palette = baked.palette();
    let at = |t: f32| {
        skinlet::skinning::posed_positions(&asset.skeleton, &palette, &baked.mesh, Some(clips[0]), Some(t)).unwrap()
            [prop.vertices.start as usize]
            .as_dvec3()
    };
    assert!(DVec3::distance(at(0.0), at(0.5)) > 1e-3);
}
