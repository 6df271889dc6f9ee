//! `skinlet gpu-bench`: the paper's crowd scene (fig. 10) drawn on the GPU by each skinning
//! pipeline (vertex, compute, mesh shader, mesh shader with common-influences slim meshlets)
//! and each culling pipeline (none, frustum, backface, both), timed with GPU timestamps.

use crate::RefineArgs;
use anyhow::{Context, Result};
use glam::{Affine3A, Vec3};
use serde_json::json;
use skinlet::cull::crowd::{CrowdParams, posed_crowd};
use skinlet::cull::meshlet::{JointFrame, MeshletCuller, Tests};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_gpu::render::{CrowdDraw, Culling, Instance, Renderer, Skinning};
use skinlet_gpu::{Gpu, GpuOptions};

#[derive(clap::Args)]
pub struct Args {
    /// The glTF file a bake was made from (required with a bake file).
    #[arg(long)]
    gltf: Option<String>,
    #[arg(long, default_value_t = 64)]
    instances: usize,
    /// Timed frames per configuration (after one untimed frame); the median is reported.
    #[arg(long, default_value_t = 5)]
    frames: usize,
    /// Image width (the height follows the crowd camera's 16:9).
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Only a software adapter (lavapipe), even where a GPU exists.
    #[arg(long)]
    software: bool,
    /// Also write the crowd, drawn with culling, as a PNG.
    #[arg(short, long)]
    out: Option<std::path::PathBuf>,
    #[command(flatten)]
    refine: RefineArgs,
    #[arg(long)]
    json: bool,
}

/// One instance in one frame: world-space skinning and joint matrices, morph weights.
struct InstancePose {
    skinning: Vec<Affine3A>,
    joints: Vec<Affine3A>,
    weights: Vec<f32>,
}

/// One measured configuration.
struct Row {
    pipeline: &'static str,
    culling: &'static str,
    gpu_ms: Option<f64>,
    wall_ms: f64,
    culled_pct: Option<f64>,
    /// Triangles drawn per frame.
    triangles: u64,
}

pub fn command(file: &str, a: &Args) -> Result<()> {
    anyhow::ensure!(a.instances >= 1 && a.frames >= 1, "--instances and --frames must be at least 1");
    anyhow::ensure!((64..=8192).contains(&a.width), "--width must be between 64 and 8192");
    let (asset, character, baked) = crate::crowd::load(file, a.gltf.as_deref(), a.refine, a.json)?;
    let clips = crate::bake::clips_of(&baked, &asset, a.gltf.as_deref().unwrap_or(file))?;
    let palette = baked.palette();
    let skin = &palette;
    let params = CrowdParams { instances: a.instances, frames: a.frames + 1, ..CrowdParams::default() };
    let scene = posed_crowd(&asset.skeleton, skin, &baked.mesh, &clips, &params)?;
    let gpu = Gpu::new(GpuOptions { software: a.software, ..GpuOptions::default() })?;
    let height = (a.width * 9 / 16).max(1);
    let renderer = Renderer::new(&gpu, a.width, height)?;
    let mesh = GpuMesh::new(&gpu, &baked.mesh, Some(&baked.meshlets))?;
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len())?;
    // MS-CI draws common-influences meshlets: baked too, over the same clips, for their bounds.
    let how = a.refine.refinement()?;
    let (ci, _) = skinlet::bake::bake(
        &asset,
        &character,
        &clips,
        Builder::CommonInfluences,
        MeshletLimits::NVIDIA,
        &how,
        &mut |_| {},
    )?;
    let ci_mesh = GpuMesh::new(&gpu, &ci.mesh, Some(&ci.meshlets))?;
    let ci_culler = MeshletCuller::new(&ci.bounds, &ci.classes, skin.joints.len())?;
    // Per frame and instance: world-space skinning matrices, joint matrices, morph weights.
    let mut poser = Poser::default();
    let mut frames: Vec<Vec<InstancePose>> = Vec::new();
    for f in 0..params.frames {
        let mut instances = Vec::new();
        for pl in &scene.placements {
            let clip = clips.get(pl.clip).copied();
            let t = pl.time(clip, f, params.fps);
            let (mut joints, mut skinning, mut weights) = (Vec::new(), Vec::new(), Vec::new());
            pl.world_matrices(skin, poser.globals(&asset.skeleton, clip, t), &mut joints, &mut skinning);
            baked.mesh.morphs.weights_at(clip, t, &mut weights);
            instances.push(InstancePose { skinning, joints, weights });
        }
        frames.push(instances);
    }
    let mut pipelines =
        vec![("VS", Skinning::Vertex, &mesh, &culler, &baked), ("CS", Skinning::Compute, &mesh, &culler, &baked)];
    if gpu.has_mesh_shaders() {
        pipelines.push(("MS", Skinning::Mesh, &mesh, &culler, &baked));
        pipelines.push(("MS-CI", Skinning::MeshSlim, &ci_mesh, &ci_culler, &ci));
    }
    let total_triangles = baked.mesh.triangles.len() as u64;
    let cullings = [
        ("none", None),
        ("frustum", Some(Tests::Frustum)),
        ("backface", Some(Tests::Backface)),
        ("both", Some(Tests::Both)),
        ("both-by-class", Some(Tests::Both)),
    ];
    let light = Vec3::new(0.4, 0.8, 0.6);
    let mut rows = Vec::new();
    let mut picture = None;
    for &(name, skinning, gpu_mesh, culler, bake) in &pipelines {
        for &(culling, tests) in &cullings {
            // Culling runs in task shaders (MS, MS-CI: one pipeline reading per-meshlet class
            // flags, or three by class) or a compute pass writing indirect draws (VS, CS).
            let task = matches!(skinning, Skinning::Mesh | Skinning::MeshSlim);
            let culling_path = match (task, culling) {
                (_, "none") => None,
                (true, "both-by-class") => Some(Culling::TaskByClass),
                (true, _) => Some(Culling::Task),
                (false, "both-by-class") => continue,
                (false, _) => Some(Culling::ComputeIndirect),
            };
            let (mut gpu_ms, mut wall_ms, mut culled, mut triangles) = (Vec::new(), Vec::new(), 0usize, None);
            for (f, instances) in frames.iter().enumerate() {
                let prepared: Vec<JointFrame> = match tests {
                    Some(tests) => instances
                        .iter()
                        .map(|i| {
                            let mut frame = JointFrame::default();
                            culler.prepare(&i.joints, &scene.camera, tests, &mut frame);
                            frame
                        })
                        .collect(),
                    None => Vec::new(),
                };
                if f > 0 {
                    for frame in &prepared {
                        let c = culler.cull(frame, &mut Vec::new(), &mut Vec::new());
                        culled += c.meshlets - c.visible;
                    }
                }
                let list: Vec<Instance> = (instances.iter().enumerate())
                    .map(|(k, i)| Instance {
                        pose: Pose { matrices: &i.skinning, morph_weights: &i.weights },
                        frame: prepared.get(k),
                    })
                    .collect();
                let how = match culling_path {
                    Some(culling) => CrowdDraw::Culled { culler, culling, skinning, triangles: None },
                    None => CrowdDraw::Plain(skinning),
                };
                let started = std::time::Instant::now();
                let drawn = renderer.render_crowd(&gpu, gpu_mesh, &list, scene.camera.view_proj, light, how)?;
                if f > 0 {
                    wall_ms.push(started.elapsed().as_secs_f64() * 1e3);
                    gpu_ms.extend(drawn.gpu_ms);
                    triangles = drawn.triangles.map(|t| t as u64 + triangles.unwrap_or(0));
                }
                // Culling is conservative: every configuration draws this same picture.
                if f == 1 && picture.is_none() {
                    picture = Some(drawn.image);
                }
            }
            let tested = (a.frames * a.instances * bake.meshlets.len()) as f64;
            rows.push(Row {
                pipeline: name,
                culling,
                gpu_ms: crate::bench::median(gpu_ms),
                wall_ms: crate::bench::median(wall_ms).unwrap_or(0.0),
                culled_pct: tests.map(|_| 100.0 * culled as f64 / tested),
                triangles: triangles.map_or(total_triangles * a.instances as u64, |t| t / a.frames as u64),
            });
        }
    }
    if let (Some(out), Some(image)) = (&a.out, &picture) {
        crate::write_png(out, image.width, image.height, png::ColorType::Rgba, &image.rgba)?;
    }
    let m = ci_mesh.meshlets.as_ref().context("uploaded with meshlets")?;
    if a.json {
        let rows: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({"pipeline": r.pipeline, "culling": r.culling, "gpu_ms": r.gpu_ms, "wall_ms": r.wall_ms,
                    "culled_pct": r.culled_pct, "triangles_per_frame": r.triangles})
            })
            .collect();
        let out = json!({"file": file, "adapter": gpu.info.name, "timestamps": gpu.has_timestamps(),
            "instances": a.instances, "frames": a.frames, "width": a.width, "height": height,
            "meshlets": baked.meshlets.len(), "triangles_per_instance": total_triangles,
            "ci_meshlets": m.count, "ci_slim_meshlets": m.slim, "rows": rows});
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!(
        "{file}: crowd of {} instances ({} skin-aware meshlets, {} common-influences meshlets of which {} slim, \
         {total_triangles} triangles each), {}x{height}, on {}",
        a.instances,
        baked.meshlets.len(),
        m.count,
        m.slim,
        a.width,
        gpu.info.name
    );
    println!("  pipeline  culling         GPU ms/frame  wall ms/frame  meshlets culled  triangles drawn");
    for r in &rows {
        // GPU time against the same pipeline without culling.
        let base = rows.iter().find(|b| b.culling == "none" && b.pipeline == r.pipeline).and_then(|b| b.gpu_ms);
        let gpu_ms = r.gpu_ms.map_or("-".into(), |t| format!("{t:.3}"));
        let culled = r.culled_pct.map_or("-".into(), |c| format!("{c:.1}%"));
        let saved = match (base, r.gpu_ms) {
            (Some(b), Some(t)) if r.culling != "none" => format!("  ({:+.0}% vs none)", 100.0 * (t / b - 1.0)),
            _ => String::new(),
        };
        println!(
            "  {:<9} {:<13} {gpu_ms:>12}  {:>13.2}  {culled:>15}  {:>15}{saved}",
            r.pipeline, r.culling, r.wall_ms, r.triangles
        );
    }
    if rows.iter().all(|r| r.gpu_ms.is_none()) {
        println!("  (the adapter has no timestamp queries: wall-clock times only)");
    }
    Ok(())
}
