//! `skinlet render`: a posed character drawn offscreen on the GPU, written as a PNG.

use anyhow::{Context, Result};
use glam::Vec3;
use serde_json::json;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use skinlet_gpu::mesh::GpuMesh;
use skinlet_gpu::render::{Renderer, Skinning, framing};
use skinlet_gpu::{Gpu, GpuOptions};
use std::path::Path;

#[allow(clippy::too_many_arguments)]
pub fn command(
    file: &str,
    clip: Option<&str>,
    time: f32,
    skinning: &str,
    size: u32,
    software: bool,
    out: &Path,
    json: bool,
) -> Result<()> {
    anyhow::ensure!((16..=8192).contains(&size), "--size must be between 16 and 8192");
    let (asset, skin_index) = crate::load_skinned(file)?;
    let clip = crate::find_clip(&asset, clip)?;
    let skin = &asset.skins[skin_index as usize];
    let mesh = asset.combined_mesh(Some(skin_index));
    let inf = mesh.influences.as_ref().context("the skinned mesh has no weights")?;
    let t = clip.map_or(0.0, |c| c.start + time);
    let mut matrices = Vec::new();
    Poser::default().skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
    let mut posed = vec![Vec3::ZERO; mesh.positions.len()];
    skinlet::skinning::skin(inf, &mesh.positions, &[], &matrices, &mut posed, &mut [])?;
    let gpu = Gpu::new(GpuOptions { software, ..GpuOptions::default() })?;
    let renderer = Renderer::new(&gpu, size, size)?;
    let (gpu_mesh, path) = match skinning {
        "vertex" => (GpuMesh::new(&gpu, &mesh, None)?, Skinning::Vertex),
        "compute" => (GpuMesh::new(&gpu, &mesh, None)?, Skinning::Compute),
        _ => {
            anyhow::ensure!(gpu.has_mesh_shaders(), "{} has no mesh shaders; use --skinning compute", gpu.info.name);
            let prepared = skinlet::meshlet::prepare(&mesh);
            let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA)?;
            (GpuMesh::new(&gpu, &prepared.mesh, Some(&meshlets))?, Skinning::Mesh)
        }
    };
    let view_proj = framing(&posed, Vec3::new(0.3, 0.2, 1.0), 1.0).view_proj;
    let image = renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, Vec3::new(0.4, 0.8, 0.6), path)?;
    crate::write_png(out, image.width, image.height, png::ColorType::Rgba, &image.rgba)?;
    if json {
        let out = json!({"file": file, "out": out.display().to_string(), "adapter": gpu.info.name, "skinning": skinning,
            "clip": clip.map(|c| c.name.clone()), "time": time, "size": size});
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("{}: {file} at {:.2} s, {skinning} skinning on {}", out.display(), time, gpu.info.name);
    }
    Ok(())
}
