//! Conservative-bounds precomputation throughput, single core, in vertex-influence-intervals
//! per second (criterion's "elements": for every meshlet vertex, its non-zero influences
//! times the key intervals), spheres and normal cones together. Xbot.glb's "walk" clip and
//! the 20k-triangle demo character's clips; then the same with refinement until converged
//! (elements: every piece evaluated). Run: `cargo bench -p skinlet --bench bounds`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use skinlet::Asset;
use skinlet::bounds::refine::{Refinement, refine};
use skinlet::bounds::sphere_cone::{key_intervals, meshlet_bounds};
use skinlet::clip::Clip;
use skinlet::meshlet::{Builder, MeshletLimits, build};
use skinlet_lab::demo::{DemoParams, demo_character};
use std::path::PathBuf;

fn bench_asset(c: &mut Criterion, label: &str, asset: &Asset, clips: &[&Clip]) {
    let character = asset.character().unwrap();
    let skin = &character.palette;
    let prepared = skinlet::bake::prepare_character(&character).unwrap();
    let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
    let inf = prepared.mesh.influences.as_ref().unwrap();
    let intervals: usize = clips.iter().map(|c| key_intervals(c).len()).sum();
    let work: usize = meshlets.vertices.iter().map(|&v| inf.count(v as usize)).sum::<usize>() * intervals;
    let one_core = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut group = c.benchmark_group("bounds");
    group.throughput(Throughput::Elements(work as u64));
    group.sample_size(10);
    group.bench_function(format!("{label}/1-core"), |b| {
        b.iter(|| one_core.install(|| meshlet_bounds(&asset.skeleton, skin, clips, &prepared.mesh, &meshlets).unwrap()))
    });
    // Refinement until converged: work counted by the refinement itself (every piece evaluated).
    let how = Refinement { max_rounds: usize::MAX, ..Refinement::NONE };
    let work = refine(&asset.skeleton, skin, clips, &prepared.mesh, &meshlets, &how).unwrap().work;
    group.throughput(Throughput::Elements(work));
    group.bench_function(format!("{label}/refined-1-core"), |b| {
        b.iter(|| one_core.install(|| refine(&asset.skeleton, skin, clips, &prepared.mesh, &meshlets, &how).unwrap()))
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    let xbot = dir.join("skinned/Xbot.glb");
    if xbot.is_file() {
        let asset = skinlet::import::load(&xbot).unwrap();
        let walk: Vec<&Clip> = asset.clips.iter().filter(|c| c.name == "walk").collect();
        bench_asset(c, "Xbot-walk", &asset, &walk);
    }
    let demo = demo_character(&DemoParams::default());
    let clips: Vec<&Clip> = demo.clips.iter().collect();
    bench_asset(c, "demo-20k-all-clips", &demo, &clips);
}

criterion_group!(bounds_benches, benches);
criterion_main!(bounds_benches);
