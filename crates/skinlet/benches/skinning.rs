//! Reference skinning throughput, in vertex-influences per second (criterion's
//! "elements"), serial and parallel, on Xbot.glb (when the shared assets are present) and
//! on the 1M-triangle demo character; and the cost of morph targets: the whole demo
//! character skinned with its face's morphs and without them, in one run.
//! Run: `cargo bench -p skinlet --bench skinning`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use skinlet::pose::Poser;
use skinlet::{Asset, skinning};
use skinlet_lab::demo::{DemoParams, demo_character};
use std::hint::black_box;
use std::path::PathBuf;

fn assets_dir() -> PathBuf {
    std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")))
}

fn bench_asset(c: &mut Criterion, label: &str, asset: &Asset) {
    let inst = asset.instances.iter().find(|i| i.skin.is_some()).expect("a skinned instance");
    let skin = &asset.skins[inst.skin.unwrap() as usize];
    let clip = asset.clips.first();
    let t = clip.map_or(0.0, |c| c.start + 0.37 * c.duration());
    let mut mats = Vec::new();
    Poser::default().skinning_matrices(&asset.skeleton, skin, clip, t, &mut mats);
    // Every skinned primitive of every instance that uses this skin.
    let prims: Vec<_> = asset
        .instances
        .iter()
        .filter(|i| i.skin == inst.skin)
        .flat_map(|i| asset.meshes[i.mesh as usize].primitives.iter().map(|p| &p.geometry))
        .filter(|g| g.influences.is_some())
        .collect();
    let influences: usize = prims
        .iter()
        .map(|g| {
            let inf = g.influences.as_ref().unwrap();
            (0..inf.vertex_count()).map(|v| inf.count(v)).sum::<usize>()
        })
        .sum();
    let mut outs: Vec<(Vec<Vec3>, Vec<Vec3>)> =
        prims.iter().map(|g| (vec![Vec3::ZERO; g.positions.len()], vec![Vec3::ZERO; g.normals.len()])).collect();
    let mut group = c.benchmark_group(format!("skinning/{label}"));
    group.throughput(Throughput::Elements(influences as u64));
    group.sample_size(20);
    for (name, parallel) in [("serial", false), ("parallel", true)] {
        group.bench_function(name, |b| {
            b.iter(|| {
                for (g, (op, on)) in prims.iter().zip(outs.iter_mut()) {
                    let inf = g.influences.as_ref().unwrap();
                    let f = if parallel { skinning::skin } else { skinning::skin_serial };
                    f(inf, &g.positions, &g.normals, black_box(&mats), op, on).unwrap();
                }
            })
        });
    }
    group.finish();
    let mut poser = Poser::default();
    c.bench_function(&format!("pose/{label}"), |b| {
        b.iter(|| poser.skinning_matrices(&asset.skeleton, skin, clip, black_box(t), &mut mats))
    });
}

/// The whole demo character (every part) skinned by `skin_mesh` with its morph deltas and
/// weights, and the same mesh without morphs: what morph targets add to a frame.
fn bench_morphs(c: &mut Criterion, asset: &Asset) {
    let character = asset.character().expect("the demo is a character");
    let clip = &asset.clips[0];
    let t = clip.start + 0.37 * clip.duration();
    let (mut mats, mut weights) = (Vec::new(), Vec::new());
    Poser::default().skinning_matrices(&asset.skeleton, &character.palette, Some(clip), t, &mut mats);
    character.mesh.morphs.weights_at(Some(clip), t, &mut weights);
    let plain = skinlet::SkinnedMesh { morphs: Default::default(), ..character.mesh.clone() };
    let n = character.mesh.positions.len();
    let (mut op, mut on) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; character.mesh.normals.len()]);
    let mut group = c.benchmark_group("skinning/demo-whole-character");
    group.throughput(Throughput::Elements(n as u64));
    group.sample_size(30);
    for (name, mesh, w) in [("with-morphs", &character.mesh, &weights[..]), ("without-morphs", &plain, &[][..])] {
        group.bench_function(name, |b| {
            b.iter(|| skinning::skin_mesh(mesh, black_box(w), black_box(&mats), &mut op, &mut on).unwrap())
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_morphs(c, &demo_character(&DemoParams::default()));
    let xbot = assets_dir().join("skinned/Xbot.glb");
    if xbot.is_file() {
        bench_asset(c, "Xbot", &skinlet::import::load(&xbot).expect("Xbot.glb loads"));
    } else {
        eprintln!("note: {} not found; skipping the Xbot benchmark", xbot.display());
    }
    let demo = demo_character(&DemoParams { triangles: 1_000_000, ..DemoParams::default() });
    bench_asset(c, "demo-1M", &demo);
}

criterion_group!(skinning_benches, benches);
criterion_main!(skinning_benches);
