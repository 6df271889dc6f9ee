//! `skinlet lod`: what a cluster LOD hierarchy saves on a crowd. Each instance draws the cut
//! at the pixel threshold projected at the nearest point of the box around its per-part
//! boxes (`skinlet_runtime::lod_select`), on the CPU; the triangles and vertex references of
//! those cuts are compared with full detail, before any culling and (`--culled`) after the
//! frustum and backface tests the GPU crowd's culling pass runs (`MeshletCuller` with the
//! any-pose boxes, the same tests on the CPU): what `gpu-bench --lod` draws, for crowds too
//! large for the device.

use anyhow::Result;
use serde_json::json;
use skinlet::meshlet::Builder;
use skinlet::pose::global_transforms;
use skinlet_lab::crowd::{CrowdParams, Layout, instance_pose, posed_crowd};
use skinlet_lab::crowd_lod::CrowdLod;
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::meshlet_cull::{JointFrame, Tests};
use skinlet_runtime::part_bounds::PoseBounds;

#[derive(clap::Args)]
pub struct Args {
    /// The glTF file a bake was made from (required with a bake file).
    #[arg(long)]
    gltf: Option<String>,
    /// The crowd: `dense` (rows of characters seen from street level) or `paper` (the
    /// conservative-bounds paper's, seen from above), as in `skinlet gpu-bench`.
    #[arg(long, default_value = "dense", value_parser = ["paper", "dense"])]
    crowd: String,
    /// Instances.
    #[arg(long, default_value_t = 1024)]
    instances: usize,
    /// Frames of the clips measured (one apart at 30 fps).
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Image width (the height follows the crowd camera's 16:9).
    #[arg(long, default_value_t = 1920)]
    width: u32,
    /// The largest screen displacement allowed, in pixels, comma-separated for several.
    #[arg(long, default_value = "1", value_delimiter = ',')]
    pixels: Vec<f32>,
    /// Also count what survives frustum and backface culling (the clusters' clip bounds and
    /// any-pose boxes, as the GPU crowd culls them), full detail and cuts alike.
    #[arg(long)]
    culled: bool,
    #[command(flatten)]
    refine: crate::RefineArgs,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// Triangles and vertex references of full detail and of the cuts at each threshold, with
/// the clusters drawn per level.
struct Measured {
    height: u32,
    groups: usize,
    clusters: usize,
    levels: u32,
    meshlets: usize,
    full: (u64, u64),
    drawn: Vec<(u64, u64, Vec<u64>)>,
    /// With `--culled`: triangles and vertex references of full detail, then of each cut, that
    /// survive frustum and backface culling.
    culled: Option<Vec<(u64, u64)>>,
}

pub fn command(file: &str, a: &Args) -> Result<()> {
    anyhow::ensure!(a.instances >= 1 && a.frames >= 1 && a.width >= 16, "--instances, --frames ≥ 1, --width ≥ 16");
    anyhow::ensure!(a.pixels.iter().all(|p| *p > 0.0 && p.is_finite()), "--pixels must be positive");
    let (asset, _, mut baked) =
        crate::crowd::load(file, a.gltf.as_deref(), Some(Builder::SkinAware), a.refine, a.json)?;
    let started = std::time::Instant::now();
    if baked.lod.is_none() {
        skinlet::bake::add_lod(&mut baked, &asset, &skinlet::meshlet::lod::LodParams::default())?;
    }
    let lod_s = started.elapsed().as_secs_f64();
    let clips = crate::bake::clips_of(&baked, &asset, a.gltf.as_deref().unwrap_or(file))?;
    let m = skinlet::bake::with_view(&baked, |view| measure(view, &asset, &baked, &clips, a))?;
    let instance_frames = (a.instances * a.frames) as u64;
    let rows: Vec<_> = (a.pixels.iter().zip(&m.drawn).enumerate())
        .map(|(k, (p, d))| {
            json!({
                "pixels": p,
                "triangles_full_detail": m.full.0 * instance_frames, "triangles_lod": d.0,
                "vertex_refs_full_detail": m.full.1 * instance_frames, "vertex_refs_lod": d.1,
                "triangle_reduction": (m.full.0 * instance_frames) as f64 / d.0.max(1) as f64,
                "clusters_per_level": d.2,
                "culled": m.culled.as_ref().map(|c| json!({
                    "triangles_full_detail": c[0].0, "triangles_lod": c[k + 1].0,
                    "vertex_refs_full_detail": c[0].1, "vertex_refs_lod": c[k + 1].1,
                    "triangle_reduction": c[0].0 as f64 / c[k + 1].0.max(1) as f64,
                })),
            })
        })
        .collect();
    if a.json {
        let out = json!({
            "file": file, "crowd": a.crowd, "instances": a.instances, "frames": a.frames, "width": a.width,
            "height": m.height, "lod_groups": m.groups, "lod_clusters": m.clusters, "lod_levels": m.levels,
            "lod_s": lod_s, "thresholds": rows,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!(
        "{file}: {} groups over {} levels, {} clusters above {} meshlets ({lod_s:.1} s)",
        m.groups, m.levels, m.clusters, m.meshlets
    );
    println!(
        "  {} crowd of {} instances, {} frames, {}x{}: each instance's cut at the threshold projected at its parts' \
         boxes (CPU, before culling)",
        a.crowd, a.instances, a.frames, a.width, m.height
    );
    for r in &rows {
        println!(
            "  {} px: {} of {} triangles ({:.1}x fewer), {} of {} vertex references; clusters per level {}",
            r["pixels"],
            r["triangles_lod"],
            r["triangles_full_detail"],
            r["triangle_reduction"].as_f64().unwrap_or(0.0),
            r["vertex_refs_lod"],
            r["vertex_refs_full_detail"],
            r["clusters_per_level"]
        );
        if let Some(c) = r.get("culled").filter(|c| !c.is_null()) {
            println!(
                "    culled (frustum and backface): {} of {} triangles ({:.1}x fewer), {} of {} vertex references",
                c["triangles_lod"],
                c["triangles_full_detail"],
                c["triangle_reduction"].as_f64().unwrap_or(0.0),
                c["vertex_refs_lod"],
                c["vertex_refs_full_detail"]
            );
        }
    }
    Ok(())
}

fn measure(
    view: &BakeView,
    asset: &skinlet::Asset,
    baked: &skinlet::bake::Baked,
    clips: &[&skinlet::clip::Clip],
    a: &Args,
) -> skinlet::Result<Measured> {
    let lod = view.lod().ok_or_else(|| invalid("the bake has no cluster LOD"))?;
    let palette = baked.palette();
    let layout = if a.crowd == "dense" { Layout::Dense } else { Layout::Paper };
    let params = CrowdParams { instances: a.instances, frames: a.frames, layout, ..CrowdParams::default() };
    let scene = posed_crowd(&asset.skeleton, &palette, &baked.mesh, clips, &params)?;
    let height = (a.width * 9 / 16).max(1);
    let thresholds = CrowdLod::new(view, &scene.camera, a.width, height)?;
    // Per cluster (meshlets first): triangles, vertices, level.
    let mut size = Vec::new();
    let meshlets = view.meshlets();
    for i in 0..meshlets.len() {
        let (v, t) = meshlets.counts(i);
        size.push((t as u64, v as u64, 0u32));
    }
    for i in 0..lod.meshlets.len() {
        let (v, t) = lod.meshlets.counts(i);
        size.push((t as u64, v as u64, lod.groups[lod.clusters[i][0] as usize].level));
    }
    let base = &size[..meshlets.len()];
    let full = (base.iter().map(|s| s.0).sum(), base.iter().map(|s| s.1).sum());
    let mut drawn = vec![(0u64, 0u64, Vec::<u64>::new()); a.pixels.len()];
    // Frustum and backface culling of every cluster, kept where the instance draws it: the
    // clusters' clip bounds and their any-pose boxes over the clips' morph weights, as the GPU
    // crowd culls them (`gpu-bench`).
    let culler = match (a.culled, &baked.lod) {
        (true, Some(baked_lod)) => {
            let mut all = baked.meshlets.clone();
            all.append(&baked_lod.meshlets, 0);
            let ranges = crate::bake::envelope_of("clips", asset, baked).map_err(|e| invalid(&e.to_string()))?;
            Some(crate::gpu_bench::lod_culler(baked, baked_lod, &all, &ranges.weight_ranges(), false)?)
        }
        _ => None,
    };
    let mut culled = vec![(0u64, 0u64); a.pixels.len() + 1];
    let (mut joint_frame, mut flags, mut visible, mut kept) =
        (JointFrame::default(), Vec::new(), Vec::new(), Vec::new());
    let (mut locals, mut weights, mut globals) = (Vec::new(), Vec::new(), Vec::new());
    let (mut joints, mut skinning, mut cut) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..a.frames {
        for (i, pl) in scene.placements.iter().enumerate() {
            instance_pose(&asset.skeleton, clips, baked, &params, i, pl, frame, &mut locals, &mut weights);
            global_transforms(&asset.skeleton, &locals, &mut globals);
            pl.world_matrices(&palette, &globals, &mut joints, &mut skinning);
            let clip = clips.get(pl.clip).map(|&c| (pl.clip as u32, pl.time(Some(c), frame, params.fps)));
            let pose = clip.map_or(PoseBounds::Clips, |(clip, time)| PoseBounds::ClipAt { clip, time });
            if let Some(culler) = &culler {
                culler.prepare_with_boxes(&joints, &scene.camera, Tests::Both, &mut joint_frame);
                visible.clear();
                culler.cull(&joint_frame, &mut flags, &mut visible);
                kept.clear();
                kept.resize(size.len(), false);
                visible.iter().for_each(|&c| kept[c as usize] = true);
                let full = visible.iter().filter(|&&c| (c as usize) < meshlets.len());
                culled[0] = full.fold(culled[0], |(t, v), &c| (t + size[c as usize].0, v + size[c as usize].1));
            }
            for (k, &pixels) in a.pixels.iter().enumerate() {
                let d = &mut drawn[k];
                lod.cut(thresholds.threshold(pixels, &joints, &weights, pose), &mut cut);
                for &c in &cut {
                    let (tris, verts, level) = size[c as usize];
                    if kept.get(c as usize) == Some(&true) {
                        culled[k + 1] = (culled[k + 1].0 + tris, culled[k + 1].1 + verts);
                    }
                    (d.0, d.1) = (d.0 + tris, d.1 + verts);
                    if d.2.len() <= level as usize {
                        d.2.resize(level as usize + 1, 0);
                    }
                    d.2[level as usize] += 1;
                }
            }
        }
    }
    let levels = lod.groups.iter().map(|g| g.level).max().unwrap_or(0);
    Ok(Measured {
        height,
        groups: lod.groups.len(),
        clusters: lod.clusters.len(),
        levels,
        meshlets: meshlets.len(),
        full,
        drawn,
        culled: culler.map(|_| culled),
    })
}

fn invalid(message: &str) -> skinlet::Error {
    skinlet::Error::Invalid { location: "lod".into(), message: message.into() }
}
