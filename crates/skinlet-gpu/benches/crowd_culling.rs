//! What culling a crowd costs the caller's CPU per frame, 1,000 instances: CPU culling (per
//! instance the joint matrices from the skinning palette, `MeshletCuller::prepare` and `cull`)
//! against GPU culling (`CrowdCulling::encode` into a fresh encoder, `finish` and `submit`; the
//! GPU's work is waited for outside the timed region), both from the same palettes in memory;
//! and the GPU culling pass's own time from timestamp queries (named `lavapipe` on Mesa's
//! software Vulkan, where the CPU runs the GPU's work). Characters: the 20k-triangle demo and,
//! when the shared assets are there, Xbot.glb. Run: `cargo bench -p skinlet-gpu --bench crowd_culling`.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Affine3A, Mat4};
use skinlet_gpu::Gpu;
use skinlet_gpu::crowd_culling::{CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter};
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_lab::headless::{self, GpuOptions};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests, joints_from_skinning};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

const INSTANCES: usize = 1000;

fn bench_asset(c: &mut Criterion, gpu: &Gpu, label: &str, asset: &skinlet::Asset) {
    let character = asset.character().unwrap();
    let clips: Vec<_> = asset.clips.iter().collect();
    let (builder, limits) = (skinlet::meshlet::Builder::SkinAware, skinlet::meshlet::MeshletLimits::NVIDIA);
    let how = skinlet::bounds::refine::Refinement::NONE;
    let (baked, _) = skinlet::bake::bake(asset, &character, &clips, builder, limits, &how, &mut |_| {}).unwrap();
    let (skin, joints) = (baked.palette(), baked.inverse_bind.len());
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, joints).unwrap();
    let (_, draws) = skinlet_gpu::mesh::meshlet_index_buffer(
        &baked.meshlets.view(&baked.meshlets.headers()),
        baked.mesh.positions.len(),
    )
    .unwrap();
    let params = CrowdParams { instances: INSTANCES, ..CrowdParams::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let camera = &scene.camera;
    // The frame's inputs, on both sides: per instance its model matrix and skinning palette.
    let mut poser = skinlet::pose::Poser::default();
    let palettes: Vec<Vec<Affine3A>> = (scene.placements.iter())
        .map(|p| {
            let clip = clips.get(p.clip).copied();
            let mut m = Vec::new();
            poser.skinning_matrices(&asset.skeleton, &skin, clip, p.time(clip, 0, params.fps), &mut m);
            m
        })
        .collect();
    let models: Vec<Affine3A> = scene.placements.iter().map(|p| Affine3A::from_mat4(p.model.as_mat4())).collect();
    let bind: Vec<Affine3A> = baked.inverse_bind.iter().map(|m| Affine3A::from_mat4(m.inverse())).collect();

    let device = &gpu.device;
    let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
    let flat: Vec<f32> = palettes.iter().flatten().flat_map(|&m| Mat4::from(m).to_cols_array()).collect();
    let instances: Vec<CullInstance> =
        models.iter().map(|m| CullInstance::new(Mat4::from(*m), CullMode::Bounds)).collect();
    let init = |contents: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents, usage: storage })
    };
    let (palette, instance_buffer) = (init(bytemuck::cast_slice(&flat)), init(bytemuck::cast_slice(&instances)));
    let pipelines = CullPipelines::new(device).unwrap();
    let gpu_character = GpuCharacter::new(device, &culler, &baked.inverse_bind, &draws).unwrap();
    let n = INSTANCES as u32;
    let survivors = n * gpu_character.meshlets();
    let culling =
        CrowdCulling::new(device, &pipelines, &gpu_character, &palette, &instance_buffer, n, survivors).unwrap();
    let wait = || device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).unwrap();

    let mut group = c.benchmark_group(format!("crowd_culling/{label}/{INSTANCES}"));
    group.sample_size(20);
    let (mut world, mut frame, mut flags, mut visible) = (Vec::new(), JointFrame::default(), Vec::new(), Vec::new());
    group.bench_function("cpu_culling", |b| {
        b.iter(|| {
            let mut drawn = 0;
            for (model, skinning) in models.iter().zip(&palettes) {
                joints_from_skinning(model, skinning, &bind, &mut world);
                culler.prepare(&world, camera, Tests::Both, &mut frame);
                visible.clear();
                drawn += culler.cull(&frame, &mut flags, &mut visible).visible;
            }
            drawn
        })
    });
    group.bench_function("gpu_culling_cpu_side", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let start = Instant::now();
                let mut encoder = device.create_command_encoder(&Default::default());
                culling.encode(&gpu.queue, &mut encoder, camera, Tests::Both, n, None).unwrap();
                gpu.queue.submit([encoder.finish()]);
                total += start.elapsed();
                wait();
            }
            total
        })
    });
    if gpu.has_timestamps() {
        let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: None,
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label: None, size: 16, usage, mapped_at_creation: false })
        };
        let resolve = buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC);
        let read = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        let period = gpu.queue.get_timestamp_period() as f64;
        let device_name = if gpu.info.device_type == wgpu::DeviceType::Cpu { "lavapipe" } else { "gpu" };
        group.bench_function(format!("gpu_pass_time_{device_name}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let mut encoder = device.create_command_encoder(&Default::default());
                    let timestamps = wgpu::ComputePassTimestampWrites {
                        query_set: &queries,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    };
                    culling.encode(&gpu.queue, &mut encoder, camera, Tests::Both, n, Some(timestamps)).unwrap();
                    encoder.resolve_query_set(&queries, 0..2, &resolve, 0);
                    encoder.copy_buffer_to_buffer(&resolve, 0, &read, 0, 16);
                    gpu.queue.submit([encoder.finish()]);
                    read.slice(..).map_async(wgpu::MapMode::Read, |r| r.unwrap());
                    wait();
                    let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&read.slice(..).get_mapped_range());
                    read.unmap();
                    total += Duration::from_nanos((ticks[1].saturating_sub(ticks[0]) as f64 * period) as u64);
                }
                total
            })
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    let gpu = match headless::gpu(GpuOptions::default()) {
        Ok(gpu) => gpu,
        Err(e) => return eprintln!("skipping: {e}"),
    };
    bench_asset(c, &gpu, "demo-20k", &skinlet_lab::demo::demo_character(&Default::default()));
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    if let Ok(asset) = skinlet::import::load(&dir.join("skinned/Xbot.glb")) {
        bench_asset(c, &gpu, "Xbot", &asset);
    }
}

criterion_group!(group, benches);
criterion_main!(group);
