//! Meshlet build throughput in triangles per second (criterion's "elements") for every
//! builder, on the largest shared asset (BrainStem.glb, 61,666 triangles) and on the
//! 1M-triangle demo character, plus meshoptimizer called directly on the same prepared
//! input, so the meshopt builder's overhead is a ratio measured in one run.
//! Run: `cargo bench -p skinlet --bench meshlets`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use skinlet::meshlet::{Builder, MeshletLimits, PreparedMesh, build, prepare};
use skinlet_lab::demo::{DemoParams, demo_character};
use std::hint::black_box;
use std::path::PathBuf;

fn bench_mesh(c: &mut Criterion, label: &str, prepared: &PreparedMesh) {
    let limits = MeshletLimits::NVIDIA;
    let mut group = c.benchmark_group(format!("meshlets/{label}"));
    group.throughput(Throughput::Elements(prepared.mesh.triangles.len() as u64));
    group.sample_size(10);
    for b in Builder::ALL {
        group.bench_function(b.name(), |bench| bench.iter(|| build(black_box(prepared), b, limits).unwrap()));
    }
    let indices: Vec<u32> = prepared.mesh.triangles.iter().flatten().copied().collect();
    let bytes = meshopt::typed_to_bytes(&prepared.mesh.positions);
    group.bench_function("meshoptimizer-direct", |bench| {
        bench.iter(|| {
            let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).unwrap();
            let mut m = meshopt::build_meshlets(black_box(&indices), &adapter, 64, 124, 0.25);
            // meshoptimizer's recommended per-meshlet optimization, as the builder does.
            for i in 0..m.meshlets.len() {
                let h = m.meshlets[i];
                let (vo, to) = (h.vertex_offset as usize, h.triangle_offset as usize);
                let (vertices, triangles) = (&mut m.vertices, &mut m.triangles);
                meshopt::optimize_meshlet_level(
                    &mut vertices[vo..vo + h.vertex_count as usize],
                    &mut triangles[to..to + 3 * h.triangle_count as usize],
                    0,
                );
            }
            m
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    let brainstem = dir.join("skinned/BrainStem.glb");
    if brainstem.is_file() {
        let asset = skinlet::import::load(&brainstem).expect("BrainStem.glb loads");
        bench_mesh(c, "BrainStem", &skinlet::bake::prepare_character(&asset.character().unwrap()).unwrap());
    } else {
        eprintln!("note: {} not found; skipping", brainstem.display());
    }
    let demo = demo_character(&DemoParams { triangles: 1_000_000, ..DemoParams::default() });
    let prepared = skinlet::bake::prepare_character(&demo.character().unwrap()).unwrap();
    c.bench_function("meshlets/demo-1M/prepare", |b| {
        b.iter(|| prepare(black_box(&demo.meshes[0].primitives[0].geometry)).unwrap())
    });
    bench_mesh(c, "demo-1M", &prepared);
}

criterion_group!(meshlet_benches, benches);
criterion_main!(meshlet_benches);
