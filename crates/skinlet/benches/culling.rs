//! Run-time culling costs, one core.
//!
//! - `meshlets/*`: per-meshlet culling (both tests, per-joint setup included) of every
//!   instance of a crowd for one frame; criterion's elements are meshlets.
//! - `joint-aabb/*`: whole-mesh box updates from per-joint boxes for 100 and 1,000 instances
//!   (the PR's many_foxes scene); elements are joint boxes. `bevy-baseline` and
//!   `bevy-baseline-flat` are the PR's update ([`skinlet_lab::bevy_baseline`], with and
//!   without the ECS lookup); `skinlet` is `JointBoxes::update_all` on joint-space boxes
//!   with one palette of entity-space joint matrices; `skinlet-folded` the same after folding
//!   leaf joints twice (elements still count the unfolded joint boxes: the work of bounding
//!   the same skin).
//!
//! Run: `cargo bench -p skinlet --bench culling`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Affine3A;
use skinlet::bake::bake;
use skinlet::bounds::refine::Refinement;
use skinlet::clip::Clip;
use skinlet::cull::joint_aabb::Box3;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use skinlet::{Asset, Character};
use skinlet_lab::bevy_baseline::Workload;
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
use std::hint::black_box;
use std::path::PathBuf;

fn assets() -> Vec<(String, Asset)> {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    ["Xbot.glb", "Fox.glb"]
        .iter()
        .filter_map(|f| skinlet::import::load(&dir.join("skinned").join(f)).ok().map(|a| (f.to_string(), a)))
        .collect()
}

/// Joint matrices of `n` instances at random times: (entity-space joint globals, world-space
/// joint globals, model matrices).
fn poses(asset: &Asset, character: &Character, n: usize) -> (Vec<Vec<Affine3A>>, Vec<Vec<Affine3A>>, Vec<Affine3A>) {
    let skin = &character.palette;
    let scene =
        crowd(&character.mesh.positions, asset.clips.len(), &CrowdParams { instances: n, ..CrowdParams::default() })
            .unwrap();
    let mut poser = Poser::default();
    let (mut local, mut world, mut models) = (Vec::new(), Vec::new(), Vec::new());
    for p in &scene.placements {
        let clip = asset.clips.get(p.clip);
        let t = clip.map_or(0.0, |c| c.start + p.offset * c.duration());
        let g = poser.globals(&asset.skeleton, clip, t);
        let mut joints = Vec::new();
        skinlet::pose::joint_globals(skin, g, &mut joints);
        local.push(joints);
        world.push(skin.joints.iter().map(|&j| Affine3A::from_mat4((p.model * g[j as usize]).as_mat4())).collect());
        models.push(Affine3A::from_mat4(p.model.as_mat4()));
    }
    (local, world, models)
}

fn meshlet_culling(c: &mut Criterion, name: &str, asset: &Asset, instances: usize) {
    let character = asset.character().unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let (baked, _) =
        bake(asset, &character, &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &Refinement::NONE, &mut |_| {})
            .unwrap();
    let skin = &character.palette;
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let (_, world, _) = poses(asset, &character, instances);
    // One palette of world-space joint matrices for the whole crowd, as an engine keeps it.
    let joints = skin.joints.len();
    let world: Vec<Affine3A> = world.concat();
    let scene =
        crowd(&baked.mesh.positions, clips.len(), &CrowdParams { instances, ..CrowdParams::default() }).unwrap();
    let mut group = c.benchmark_group("meshlets");
    group.throughput(Throughput::Elements((culler.len() * instances) as u64));
    group.sample_size(20);
    let (mut frame, mut flags, mut visible) = (JointFrame::default(), Vec::new(), Vec::with_capacity(culler.len()));
    group.bench_function(format!("{name}-{instances}-instances/1-core"), |b| {
        b.iter(|| {
            let mut n = 0;
            for m in world.chunks_exact(joints) {
                visible.clear();
                culler.prepare(m, &scene.camera, Tests::Both, &mut frame);
                n += culler.cull(&frame, &mut flags, &mut visible).visible;
            }
            black_box(n)
        })
    });
    group.finish();
}

fn joint_aabbs(c: &mut Criterion, name: &str, asset: &Asset, instances: usize) {
    let w = Workload::new(asset, instances, 1).unwrap();
    let mut group = c.benchmark_group("joint-aabb");
    group.sample_size(30);
    group.throughput(Throughput::Elements((w.bevy.boxes() * instances) as u64));
    let mut out = Vec::with_capacity(instances);
    group.bench_function(format!("{name}-{instances}/bevy-baseline"), |b| {
        b.iter(|| {
            w.bevy.update(false, &mut out);
            black_box(&out);
        })
    });
    group.bench_function(format!("{name}-{instances}/bevy-baseline-flat"), |b| {
        b.iter(|| {
            w.bevy_flat.update(true, &mut out);
            black_box(&out);
        })
    });
    let mut boxes = vec![Box3::EMPTY; instances];
    group.bench_function(format!("{name}-{instances}/skinlet"), |b| {
        b.iter(|| {
            w.boxes.update_all(&w.palette, w.stride, &mut boxes).unwrap();
            black_box(&boxes);
        })
    });
    // Leaf joints folded twice into their ancestors (conservative for the asset's clips).
    let (skin, mesh) = (&w.character.palette, &w.character.mesh);
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let folded = skinlet::cull::joint_aabb::fold_leaves(&w.boxes, &asset.skeleton, skin, mesh, &clips, 2).unwrap();
    group.bench_function(format!("{name}-{instances}/skinlet-folded"), |b| {
        b.iter(|| {
            folded.update_all(&w.palette, w.stride, &mut boxes).unwrap();
            black_box(&boxes);
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    for (name, asset) in assets() {
        // 100 characters: the poses stay in cache; 1,000 (the PR's many_foxes): they stream
        // from memory.
        joint_aabbs(c, &name, &asset, 100);
        joint_aabbs(c, &name, &asset, 1000);
        meshlet_culling(c, &name, &asset, 2000);
    }
    // A dense character: ~4,000 meshlets over 33 joints, 250 instances ≈ 1M meshlets.
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 500_000, ..Default::default() });
    meshlet_culling(c, "demo-500k", &demo, 250);
}

criterion_group!(culling_benches, benches);
criterion_main!(culling_benches);
