//! Shared by the GPU tests: the device (or a skip, unless SKINLET_REQUIRE_GPU=1), the shared
//! skinned assets and morph-target test plus the demo character, and posing on the CPU.
#![allow(dead_code)]

use glam::{Affine3A, Vec3};
use skinlet::Asset;
use skinlet_gpu::Gpu;
use skinlet_gpu::mesh::Pose;
use skinlet_lab::headless::{self, GpuOptions};
use skinlet_runtime::meshlet_cull::MeshletCuller;
use std::path::PathBuf;

#[path = "../../../skinlet/tests/common/mod.rs"]
mod shared;
pub use shared::{assets_dir, required};

/// The default device, or `None` with a note (a failure with `SKINLET_REQUIRE_GPU=1`).
pub fn gpu() -> Option<Gpu> {
    match headless::gpu(GpuOptions::default()) {
        Ok(g) => Some(g),
        Err(e) if required("SKINLET_REQUIRE_GPU") => panic!("{e} (SKINLET_REQUIRE_GPU=1)"),
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

/// The shared skinned characters and the morph-target test (when the assets are there: see
/// [`assets_dir`]), then the demo character.
pub fn assets() -> Vec<(String, Asset)> {
    let mut out = Vec::new();
    if let Some(dir) = assets_dir() {
        let mut paths: Vec<PathBuf> =
            std::fs::read_dir(dir.join("skinned")).unwrap().flatten().map(|e| e.path()).collect();
        paths.sort();
        paths.push(dir.join("morph/MorphStressTest.gltf"));
        for p in paths.into_iter().filter(|p| p.extension().is_some_and(|e| e == "glb" || e == "gltf")) {
            let asset = skinlet::import::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            out.push((p.file_name().unwrap().to_string_lossy().into_owned(), asset));
        }
    }
    let demo = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    out.push(("@demo".into(), demo));
    out
}

/// A bake of the whole character over every clip: skin-aware meshlets with NVIDIA's limits,
/// bounds from key intervals only.
pub fn bake(asset: &Asset, character: &skinlet::Character) -> skinlet::bake::Baked {
    let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
    let limits = skinlet::meshlet::MeshletLimits::NVIDIA;
    let how = skinlet::bounds::refine::Refinement::NONE;
    skinlet::bake::bake(asset, character, &clips, skinlet::meshlet::Builder::SkinAware, limits, &how, &mut |_| {})
        .unwrap()
        .0
}

/// The culler of `baked`'s bounds with the any-pose boxes of its clips' morph weight ranges.
pub fn boxed_culler(asset: &Asset, character: &skinlet::Character, baked: &skinlet::bake::Baked) -> MeshletCuller {
    let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
    let skin = &character.palette;
    let ranges = skinlet::bounds::vertex::clip_weight_ranges(&baked.mesh.morphs, &clips).unwrap();
    let boxes = skinlet::cull::any_pose::build(skin, &baked.mesh, &baked.meshlets, &ranges).unwrap();
    MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap().with_any_pose(&boxes).unwrap()
}

/// A mesh posed on the CPU: the skinning matrices and morph weights of `clip` at `t` (what a
/// draw takes), and the reference positions.
pub struct Posed {
    pub matrices: Vec<Affine3A>,
    pub weights: Vec<f32>,
    pub positions: Vec<Vec3>,
}

impl Posed {
    pub fn new(
        asset: &Asset,
        skin: &skinlet::Skin,
        mesh: &skinlet::SkinnedMesh,
        clip: Option<&skinlet::clip::Clip>,
        t: f32,
    ) -> Posed {
        let (mut matrices, mut weights) = (Vec::new(), Vec::new());
        skinlet::pose::Poser::default().skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
        mesh.morphs.weights_at(clip, t, &mut weights);
        let mut positions = vec![Vec3::ZERO; mesh.positions.len()];
        skinlet::skinning::skin_mesh(mesh, &weights, &matrices, &mut positions, &mut []).unwrap();
        Posed { matrices, weights, positions }
    }

    pub fn pose(&self) -> Pose<'_> {
        Pose { matrices: &self.matrices, morph_weights: &self.weights }
    }
}

/// Copies the first `size` bytes of `buffer` (which needs COPY_SRC) back, as `T`s.
pub fn read_buffer<T: bytemuck::Pod>(gpu: &Gpu, buffer: &wgpu::Buffer, size: u64) -> Vec<T> {
    let size = size.max(4).next_multiple_of(4);
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
    let index = gpu.queue.submit([encoder.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |r| r.unwrap());
    gpu.device.poll(wgpu::PollType::Wait { submission_index: Some(index), timeout: None }).unwrap();
    let out = bytemuck::pod_collect_to_vec(&staging.slice(..).get_mapped_range());
    staging.unmap();
    out
}
