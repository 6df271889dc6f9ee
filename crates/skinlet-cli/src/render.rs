//! `skinlet render`: a posed character drawn offscreen on the GPU, written as a PNG.

use anyhow::{Context, Result};
use glam::{DMat4, Vec3};
use serde_json::json;
use skinlet::bounds::refine::Refinement;
use skinlet::bounds::sphere_cone::Class;
use skinlet::clip::Clip;
use skinlet::contour::skinned::{SkinnedMethod, SkinnedParams, refinement, skinned_edges};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::model::SkinnedMesh;
use skinlet::overdraw::cluster::ClusterParams;
use skinlet::pose::Poser;
use skinlet_gpu::contours::{ContourExtraction, ContourView, GpuContours};
use skinlet_gpu::crowd_culling::CullMode;
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_lab::gpu_crowd::{CrowdFrame, CrowdView, GpuCrowd};
use skinlet_lab::headless::{self, GpuOptions};
use skinlet_lab::render::{Image, Renderer, Skinning, framing};
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};

/// The default view direction (toward the eye) and the culled view's observer direction.
const FRONT: Vec3 = Vec3::new(0.3, 0.2, 1.0);
const OBSERVER: Vec3 = Vec3::new(-1.0, 0.6, -0.8);
const LIGHT: Vec3 = Vec3::new(0.4, 0.8, 0.6);

/// What `--view` asks for.
#[derive(clap::Args)]
pub struct Args {
    /// Clip name or index (default: the first clip; none: the rest pose).
    #[arg(long)]
    clip: Option<String>,
    /// Time in seconds from the clip's start.
    #[arg(long, default_value_t = 0.0)]
    time: f32,
    /// shaded: the posed character. meshlets: skin-aware meshlets, each in its own color
    /// (mesh shaders). culled: the meshlets the conservative bounds cull for a camera 1.6×
    /// closer than a fit, seen by an observer behind and above it: kept ones light,
    /// frustum-culled red, backface-culled blue, as skinlet's GPU crowd culling culls them
    /// (mesh shaders; bounds from key intervals).
    /// classes: meshlets by culling class (paper table 2): both tests green, frustum test
    /// only amber, never culled grey (mesh shaders). contours: the contour edges extracted
    /// on the GPU from patches bounded over the clips, visible orange, hidden dim. overdraw:
    /// heat maps of the fragments shaded per pixel, measured on the GPU, with the prepared
    /// triangle order (left) and the overdraw-reducing order the bake picks for this time and
    /// view (right; Han & Sander 2016): blue 1, green 2, yellow 3, orange 4, red 5+.
    #[arg(long, default_value = "shaded", value_parser = ["shaded", "meshlets", "culled", "classes", "contours", "overdraw"])]
    view: String,
    /// The pipeline of the shaded view: vertex (skinned in the vertex shader), compute (by a
    /// compute pass, then drawn), mesh (one mesh-shader workgroup per skin-aware meshlet) or
    /// mesh-slim (common-influences meshlets: joints once per meshlet, weight-only vertices).
    #[arg(long, default_value = "compute", value_parser = ["vertex", "compute", "mesh", "mesh-slim"])]
    skinning: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Only a software adapter (lavapipe), even where a GPU exists.
    #[arg(long)]
    software: bool,
    #[arg(short, long)]
    out: std::path::PathBuf,
    #[arg(long)]
    json: bool,
}

/// A color per meshlet id: hues around the wheel by the golden ratio.
fn id_color(i: usize) -> [u8; 4] {
    let h = (i as f32 * 0.618_034).fract() * 6.0;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    let [r, g, b] = [r, g, b].map(|c| (60.0 + 195.0 * c) as u8);
    [r, g, b, 255]
}

pub fn command(file: &str, a: &Args) -> Result<()> {
    anyhow::ensure!((16..=8192).contains(&a.size), "--size must be between 16 and 8192");
    let (asset, character) = crate::load_character(file)?;
    let clip = crate::find_clip(&asset, a.clip.as_deref())?;
    let skin = &character.palette;
    let t = clip.map_or(0.0, |c| c.start + a.time);
    // Only the meshlet-drawing views need the character prepared (welded, cache-ordered).
    let prepare = || skinlet::bake::prepare_character(&character);
    let mesh = &character.mesh;
    let mut poser = Poser::default();
    let (mut matrices, mut weights) = (Vec::new(), Vec::new());
    poser.skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
    mesh.morphs.weights_at(clip, t, &mut weights);
    let pose = Pose { matrices: &matrices, morph_weights: &weights };
    let mut posed = vec![Vec3::ZERO; mesh.positions.len()];
    skinlet::skinning::skin_mesh(mesh, &weights, &matrices, &mut posed, &mut [])?;
    let gpu = headless::gpu(GpuOptions { software: a.software, ..GpuOptions::default() })?;
    let renderer = Renderer::new(&gpu, a.size, a.size)?;
    let need_mesh_shaders =
        !matches!(a.view.as_str(), "shaded" | "contours" | "overdraw") || a.skinning.starts_with("mesh");
    anyhow::ensure!(
        !need_mesh_shaders || gpu.has_mesh_shaders(),
        "{} has no mesh shaders (needed by --view {} --skinning {})",
        gpu.info.name,
        a.view,
        a.skinning
    );
    let mut summary = json!({});
    let colored = |gpu_mesh: &GpuMesh, colors: &[[u8; 4]]| {
        renderer.render_colored(&gpu, gpu_mesh, pose, framing(&posed, FRONT, 1.0)?.view_proj, LIGHT, colors)
    };
    let image = match a.view.as_str() {
        "meshlets" => {
            let prepared = prepare()?;
            let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA)?;
            let gpu_mesh = GpuMesh::new(&gpu, &prepared.mesh.mesh_data(Some(meshlets.view(&meshlets.headers()))))?;
            let colors: Vec<[u8; 4]> = (0..meshlets.len()).map(id_color).collect();
            summary = json!({"meshlets": meshlets.len()});
            colored(&gpu_mesh, &colors)?
        }
        "culled" => {
            let baked = bake(&asset, &character, None)?;
            let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len())?;
            let camera = framing(&posed, FRONT, 1.6)?;
            // Culled on the GPU by crowd culling (the path an engine links): the survivors of
            // the frustum test alone, and of both tests.
            let crowd = GpuCrowd::new(&gpu, &baked, &culler, 1, 64, 36)?;
            let palette: Vec<glam::Mat4> = matrices.iter().map(|&m| m.into()).collect();
            let survivors = |tests| -> Result<Vec<bool>> {
                let modes = [CullMode::Bounds];
                let frame = CrowdFrame {
                    palette: &palette,
                    modes: &modes,
                    weights: &weights,
                    lod_thresholds: &[],
                    camera: &camera,
                    tests,
                };
                crowd.draw(&gpu, &frame, CrowdView::Pulled, LIGHT)?;
                let mut kept = vec![false; baked.meshlets.len()];
                crowd.survivors(&gpu)?.iter().for_each(|&[_, m]| kept[m as usize] = true);
                Ok(kept)
            };
            let (in_frustum, kept) = (survivors(Tests::Frustum)?, survivors(Tests::Both)?);
            // Per meshlet: kept, or culled by the frustum test, or by the backface test alone.
            let count = |f: &dyn Fn(usize) -> bool| (0..kept.len()).filter(|&m| f(m)).count();
            let mut colors = vec![[240, 240, 235, 255]; baked.meshlets.len()];
            for m in 0..kept.len() {
                if !in_frustum[m] {
                    colors[m] = [235, 85, 70, 255];
                } else if !kept[m] {
                    colors[m] = [90, 130, 235, 255];
                }
            }
            summary = json!({"meshlets": kept.len(), "kept": count(&|m| kept[m]),
                "frustum_culled": count(&|m| !in_frustum[m]), "backface_culled": count(&|m| in_frustum[m] && !kept[m])});
            let gpu_mesh =
                GpuMesh::new(&gpu, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers()))))?;
            let observer = framing(&posed, OBSERVER, 0.95)?.view_proj;
            renderer.render_colored(&gpu, &gpu_mesh, pose, observer, LIGHT, &colors)?
        }
        "classes" => {
            let baked = bake(&asset, &character, None)?;
            let colors: Vec<[u8; 4]> = (baked.classes.iter())
                .map(|c| match c {
                    Class::Both => [120, 210, 120, 255],
                    Class::FrustumOnly => [240, 180, 70, 255],
                    Class::None => [150, 150, 150, 255],
                })
                .collect();
            let count = |k: Class| baked.classes.iter().filter(|&&c| c == k).count();
            summary = json!({"meshlets": baked.meshlets.len(), "both": count(Class::Both),
                "frustum_only": count(Class::FrustumOnly), "none": count(Class::None)});
            let gpu_mesh =
                GpuMesh::new(&gpu, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers()))))?;
            colored(&gpu_mesh, &colors)?
        }
        "contours" => {
            let mut baked = bake(&asset, &character, None)?;
            let params = SkinnedParams::new(SkinnedMethod::Animated, refinement(None, 2));
            skinlet::bake::add_contours(&mut baked, &asset, &params, true)?;
            let patches = &baked.contours.as_ref().context("contours were just added")?.patches;
            let edges = skinned_edges(&baked.mesh, true)?;
            let gpu_mesh = GpuMesh::new(&gpu, &baked.mesh.mesh_data(None))?;
            let shape = GpuContours::skinned(&gpu, &edges, patches)?;
            let extraction = ContourExtraction::new(&gpu)?;
            let camera = framing(&posed, FRONT, 1.0)?;
            let globals = poser.globals(&asset.skeleton, clip, t);
            let inverses: Vec<DMat4> = skin.joints.iter().map(|&j| globals[j as usize].inverse()).collect();
            let at = baked_clip(&baked, clip).map(|c| (c, t));
            let view = ContourView::skinned(patches, &inverses, at, camera.projection);
            let (image, found) =
                renderer.render_contours(&gpu, &gpu_mesh, pose, camera.view_proj, LIGHT, &extraction, &shape, &view)?;
            summary = json!({"edges": edges.len(), "patches": patches.patches.len(), "contour_edges": found.edges.len(),
                "tested_edges": found.tested, "accepted_groups": found.accepted_groups});
            image
        }
        "overdraw" => {
            // Orders for the shown clip only: clustering every clip takes minutes.
            let mut baked = bake(&asset, &character, clip)?;
            skinlet::bake::add_overdraw(&mut baked, &asset, &ClusterParams::default(), 8)?;
            let orders = baked.overdraw.as_ref().context("orders were just added")?;
            let mut on_bake = vec![Vec3::ZERO; baked.mesh.positions.len()];
            skinlet::skinning::skin_mesh(&baked.mesh, &weights, &matrices, &mut on_bake, &mut [])?;
            let framing = skinlet::overdraw::cluster::Framing::of(std::slice::from_ref(&on_bake));
            let eye = framing.eye(FRONT.normalize(), 3.0);
            let chosen = orders.select(baked_clip(&baked, clip).unwrap_or(0) as u32, t, eye);
            let mut halves = Vec::new();
            let mut ratios = Vec::new();
            for order in [&baked.mesh.triangles, &orders.buffers[chosen]] {
                let ordered = SkinnedMesh { triangles: order.clone(), ..baked.mesh.clone() };
                let gpu_mesh = GpuMesh::new(&gpu, &ordered.mesh_data(None))?;
                let (counts, overdraw) = renderer.render_overdraw(&gpu, &gpu_mesh, pose, framing.view_proj(eye))?;
                halves.push(skinlet::overdraw::measure::heatmap(&counts));
                ratios.push(overdraw.ratio());
            }
            summary = json!({"ovr_prepared_order": ratios[0], "ovr_skinlet_order": ratios[1], "buffer": chosen,
                "buffers": orders.buffers.len()});
            // Side by side: the two heat maps, RGBA.
            let n = a.size as usize;
            let rgba = (0..n)
                .flat_map(|row| halves.iter().flat_map(move |h| h[row * n * 3..(row + 1) * n * 3].chunks(3)))
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect();
            Image { width: 2 * a.size, height: a.size, rgba }
        }
        _ => {
            let (gpu_mesh, path) = match a.skinning.as_str() {
                "vertex" => (GpuMesh::new(&gpu, &mesh.mesh_data(None))?, Skinning::Vertex),
                "compute" => (GpuMesh::new(&gpu, &mesh.mesh_data(None))?, Skinning::Compute),
                _ => {
                    let (builder, path) = match a.skinning.as_str() {
                        "mesh" => (Builder::SkinAware, Skinning::Mesh),
                        _ => (Builder::CommonInfluences, Skinning::MeshSlim),
                    };
                    let prepared = prepare()?;
                    let meshlets = skinlet::meshlet::build(&prepared, builder, MeshletLimits::NVIDIA)?;
                    let gpu_mesh =
                        GpuMesh::new(&gpu, &prepared.mesh.mesh_data(Some(meshlets.view(&meshlets.headers()))))?;
                    let m = gpu_mesh.meshlets.as_ref().context("uploaded with meshlets")?;
                    summary = json!({"meshlets": m.count, "slim_meshlets": m.slim,
                        "slim_vertices": m.slim_vertices, "fat_vertices": m.fat_vertices});
                    (gpu_mesh, path)
                }
            };
            renderer.render(&gpu, &gpu_mesh, pose, framing(&posed, FRONT, 1.0)?.view_proj, LIGHT, path)?
        }
    };
    crate::write_png(&a.out, image.width, image.height, png::ColorType::Rgba, &image.rgba)?;
    if a.json {
        let out = json!({"file": file, "out": a.out.display().to_string(), "adapter": gpu.info.name, "view": a.view,
            "skinning": a.skinning, "clip": clip.map(|c| c.name.clone()), "time": a.time, "size": a.size,
            "summary": summary});
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let facts = summary.as_object().filter(|m| !m.is_empty()).map(|_| format!(" {summary}")).unwrap_or_default();
        println!("{}: {file} at {:.2} s, {} view on {}{facts}", a.out.display(), a.time, a.view, gpu.info.name);
    }
    Ok(())
}

/// A bake of the character for the culling views: skin-aware meshlets, bounds over `clips`
/// (all when `None`) from key intervals only (no refinement: quick, and still conservative).
fn bake(asset: &skinlet::Asset, character: &skinlet::Character, clips: Option<&Clip>) -> Result<skinlet::bake::Baked> {
    let clips: Vec<&Clip> = match clips {
        Some(c) => vec![c],
        None => asset.clips.iter().collect(),
    };
    let (baked, _) = skinlet::bake::bake(
        asset,
        character,
        &clips,
        Builder::SkinAware,
        MeshletLimits::NVIDIA,
        &Refinement::NONE,
        &mut |_| {},
    )?;
    Ok(baked)
}

/// The index of `clip` among the clips `baked` was made for.
fn baked_clip(baked: &skinlet::bake::Baked, clip: Option<&Clip>) -> Option<usize> {
    clip.and_then(|c| baked.settings.clips.iter().position(|n| *n == c.name))
}
