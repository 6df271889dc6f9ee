//! Compute-shader skinning against skinlet's CPU reference skinning (morph targets, then
//! skinning): every vertex and normal of every shared skinned asset, the morph-target test
//! and the demo character, at several times of each clip; and on a device the caller
//! opened, uploaded from a bake file's bytes through the runtime's view.
//!
//! Runs on any Vulkan adapter; on CPU-only machines that is Mesa's lavapipe. With
//! SKINLET_REQUIRE_GPU=1 (CI) a missing adapter fails the test instead of skipping it.

use glam::{Affine3A, Vec3};
mod common;
use common::{assets, gpu};
use skinlet::pose::Poser;
use skinlet_gpu::Gpu;
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_gpu::skinning::ComputeSkinning;
use skinlet_lab::headless::{self, GpuOptions};

#[test]
fn compute_skinning_matches_the_cpu_reference() {
    let Some(gpu) = gpu() else { return };
    eprintln!("adapter: {} ({:?}), mesh shaders: {}", gpu.info.name, gpu.info.backend, gpu.has_mesh_shaders());
    if common::required("SKINLET_REQUIRE_GPU") {
        // CI installs lavapipe from bookworm-backports precisely for its mesh shaders.
        assert!(gpu.has_mesh_shaders(), "{} has no mesh shaders", gpu.info.name);
    }
    let pipeline = ComputeSkinning::new(&gpu).unwrap();
    let mut worst = (0.0f32, 0.0f32);
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let mesh = character.mesh.clone();
        let buffers = GpuMesh::new(&gpu, &mesh.mesh_data(None)).unwrap();
        let mut poser = Poser::default();
        let mut times: Vec<(Option<usize>, f32)> = vec![(None, 0.0)];
        for (c, clip) in asset.clips.iter().enumerate().take(3) {
            times.extend([0.1f32, 0.5, 0.9].map(|f| (Some(c), clip.start + f * clip.duration())));
        }
        for (clip, t) in times {
            let (mut matrices, mut weights): (Vec<Affine3A>, Vec<f32>) = (Vec::new(), Vec::new());
            let clip = clip.map(|c| &asset.clips[c]);
            poser.skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
            mesh.morphs.weights_at(clip, t, &mut weights);
            let mut cpu_p = vec![Vec3::ZERO; mesh.positions.len()];
            let mut cpu_n = vec![Vec3::ZERO; mesh.normals.len()];
            skinlet::skinning::skin_mesh(&mesh, &weights, &matrices, &mut cpu_p, &mut cpu_n).unwrap();
            pipeline.skin(&gpu, &buffers, Pose { matrices: &matrices, morph_weights: &weights }).unwrap();
            let (gpu_p, gpu_n) = pipeline.read(&gpu, &buffers).unwrap();
            assert_eq!((gpu_p.len(), gpu_n.len()), (cpu_p.len(), cpu_n.len()), "{name}");
            // Errors relative to the posed model's size.
            let (lo, hi) = cpu_p.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
            let size = (hi - lo).length().max(1e-6);
            let p_err = cpu_p.iter().zip(&gpu_p).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max) / size;
            let n_err = cpu_n.iter().zip(&gpu_n).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
            let clip = clip.map(|c| &c.name);
            assert!(p_err <= 1e-5, "{name} clip {clip:?} t {t}: position error {p_err:e} of the model size");
            assert!(n_err <= 1e-5, "{name} clip {clip:?} t {t}: normal error {n_err:e}");
            worst = (worst.0.max(p_err), worst.1.max(n_err));
        }
    }
    eprintln!("worst position error {:e} of the model size, worst normal error {:e}", worst.0, worst.1);
}

#[test]
fn mesh_shaders_can_be_turned_off() {
    let Some(gpu) = gpu() else { return };
    drop(gpu);
    let plain = headless::gpu(GpuOptions { no_mesh_shaders: true, ..GpuOptions::default() }).unwrap();
    assert!(!plain.has_mesh_shaders());
}

#[test]
fn a_bake_file_skins_on_the_callers_device() {
    // An engine's path: its own plain device (no optional features), the bake's bytes viewed
    // by skinlet-runtime, the mesh uploaded from that view; the result equals the baker's
    // reference skinning of the mesh it baked.
    let Some(probe) = gpu() else { return };
    drop(probe);
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).unwrap();
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    let gpu = Gpu::from_device(device, queue, adapter.get_info());
    assert!(!gpu.has_mesh_shaders() && !gpu.has_timestamps());
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
    let baked = common::bake(&asset, &asset.character().unwrap());
    let bytes = skinlet::bake::to_bytes(&baked);
    let view = skinlet_runtime::bake_view::BakeView::new(&bytes).unwrap();
    let data = view.mesh_data();
    assert!(data.morphs.is_some(), "the demo's face has morph targets");
    let buffers = GpuMesh::new(&gpu, &data).unwrap();
    assert_eq!(buffers.meshlets.as_ref().unwrap().count as usize, baked.meshlets.len());
    let pipeline = ComputeSkinning::new(&gpu).unwrap();
    let (mesh, clip) = (&baked.mesh, &asset.clips[0]);
    let t = clip.start + clip.duration() * 0.4;
    let (mut matrices, mut weights) = (Vec::new(), Vec::new());
    Poser::default().skinning_matrices(&asset.skeleton, &baked.palette(), Some(clip), t, &mut matrices);
    mesh.morphs.weights_at(Some(clip), t, &mut weights);
    assert!(weights.iter().any(|&w| w != 0.0), "the clip moves the face");
    let mut cpu_p = vec![Vec3::ZERO; mesh.positions.len()];
    let mut cpu_n = vec![Vec3::ZERO; mesh.normals.len()];
    skinlet::skinning::skin_mesh(mesh, &weights, &matrices, &mut cpu_p, &mut cpu_n).unwrap();
    pipeline.skin(&gpu, &buffers, Pose { matrices: &matrices, morph_weights: &weights }).unwrap();
    let (gpu_p, gpu_n) = pipeline.read(&gpu, &buffers).unwrap();
    let p_err = cpu_p.iter().zip(&gpu_p).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
    let n_err = cpu_n.iter().zip(&gpu_n).map(|(a, b)| (*a - *b).length()).fold(0.0f32, f32::max);
    assert!(p_err <= 1e-5 && n_err <= 1e-5, "position error {p_err:e}, normal error {n_err:e}");
}
