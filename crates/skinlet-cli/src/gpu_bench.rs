//! `skinlet gpu-bench`: a crowd (the paper's scene, fig. 10, or a dense street-level one)
//! drawn on the GPU by each skinning pipeline (vertex, compute, mesh shader, mesh shader with
//! common-influences slim meshlets) and each culling pipeline (none, frustum, backface, both),
//! timed with GPU timestamps.
//!
//! Vertex skinning is drawn GPU-driven (`skinlet_lab::gpu_crowd` on
//! `skinlet_gpu::crowd_culling`): culling prepared and run on the GPU, the survivors drawn
//! with one call (pulled; `VS-indexed`: one indexed multi-draw with a GPU count). Mesh-shader
//! skinning is culled in task shaders on the joint records the same culling prepares on the
//! GPU. Per row:
//! meshlets drawn, draw calls issued per frame, and whether the image equals the unculled one
//! (up to depth ties between meshlets, where draw order picks the color); per frame the
//! meshlets with a visible fragment in the unculled ID buffer, the limit no culling beats.
//!
//! After one untimed warm-up round over every configuration, each repeat measures every
//! configuration once, forwards on even repeats and backwards on odd ones (A B C … C B A), so
//! that warming, clocks and drift fall on all of them alike. A configuration's time is the
//! median over repeats of its per-repeat median frame; the spread is the range over repeats;
//! "vs none" is the median (and range) of per-repeat ratios against the same pipeline without
//! culling.

use crate::RefineArgs;
use anyhow::{Context, Result};
use glam::{Affine3A, Vec3};
use serde_json::json;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::global_transforms;
use skinlet_gpu::crowd_culling::{CullMode, GpuCharacter};
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_lab::crowd::{Animation, CrowdParams, Layout, instance_pose, posed_crowd};
use skinlet_lab::crowd_lod::{CrowdLod, silhouette_displacement};
use skinlet_lab::gpu_crowd::{CrowdFrame, CrowdView, GpuCrowd};
use skinlet_lab::headless::{self, GpuOptions};
use skinlet_lab::occlusion_limits::{DepthPyramid, pose_limits};
use skinlet_lab::render::{CrowdDraw, Culling, Image, PosedInstance, Renderer, Skinning, TaskCulling};
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};
use skinlet_runtime::part_bounds::PoseBounds;
use std::collections::HashSet;

#[derive(clap::Args)]
pub struct Args {
    /// The glTF file a bake was made from (required with a bake file).
    #[arg(long)]
    gltf: Option<String>,
    /// The crowd: `paper` (the conservative-bounds paper's, seen from above) or `dense`
    /// (rows of characters seen from street level: mostly hidden behind nearer ones).
    #[arg(long, default_value = "paper", value_parser = ["paper", "dense"])]
    crowd: String,
    /// Instances (default: 64 for the paper's crowd, 1,024 for the dense one).
    #[arg(long)]
    instances: Option<usize>,
    /// The meshlet builder a glTF file is baked with (default skin-aware; a bake keeps its
    /// own). MS-CI always draws common-influences meshlets.
    #[arg(long, value_parser = crate::builder_names(false))]
    builder: Option<String>,
    /// The skinning pipelines measured, comma-separated: VS (vertex skinning, GPU-driven),
    /// VS-indexed (its survivors as indexed draws), CS, MS, MS-CI (mesh shaders).
    #[arg(long, default_value = "VS,VS-indexed,CS,MS,MS-CI", value_delimiter = ',',
          value_parser = ["VS", "VS-indexed", "CS", "MS", "MS-CI"])]
    pipelines: Vec<String>,
    /// The cullings measured, comma-separated (default: every one the pipelines have):
    /// none, frustum, backface, both (frustum and backface), both-by-class (task shaders),
    /// both+occlusion, both+triangles, both+occl+tri (VS), both+lod, both+occl+lod (`--lod`).
    /// A crowd too large to draw many times can be measured on a few rows.
    #[arg(long, value_delimiter = ',', value_parser = CULLINGS)]
    cullings: Vec<String>,
    /// Timed frames per configuration and repeat.
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Repeats: every configuration is measured once per repeat, in alternating order.
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Image width (the height follows the crowd camera's 16:9).
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Only a software adapter (lavapipe), even where a GPU exists.
    #[arg(long)]
    software: bool,
    /// Also write the crowd, drawn with culling, as a PNG.
    #[arg(short, long)]
    out: Option<std::path::PathBuf>,
    /// How the instances are posed, as in `skinlet cull`: `clips` culls with the clip
    /// bounds; `blend`, `additive` and `ik` with the pose envelope's bounds where the CPU pose
    /// guard admits an instance's pose, and draw the others whole.
    #[arg(long, default_value = "clips", value_parser = ["clips", "blend", "additive", "ik"])]
    animation: String,
    /// Rounds of occlusion culling: each tests a range of the instances (nearest first)
    /// against the depth drawn so far, in both phases, and draws each phase's survivors before
    /// the next step (1 to 64; two draws each).
    #[arg(long, default_value_t = skinlet_lab::gpu_crowd::OCCLUSION_ROUNDS)]
    occlusion_rounds: u32,
    /// Every frame the crowd's pose of frame 0 (a still crowd: occlusion culling's steady
    /// state without motion between frames).
    #[arg(long)]
    still: bool,
    /// Largest rotation of the additive layer, degrees (and the envelope margin when a glTF
    /// file is baked here).
    #[arg(long, default_value_t = 10.0)]
    additive_deg: f32,
    /// Cluster LOD (`skinlet bake --lod`; built here where the bake has none): adds the rows
    /// `both+lod` and `both+occl+lod` (each instance draws the visible part of its cut at
    /// `--lod-pixels`) and per timed frame compares the cuts with full detail, both culled:
    /// triangles and vertex references drawn, pixels differing, and how far the silhouettes
    /// moved (`max_silhouette_px`). With `--animation blend|additive|ik`, the instances the
    /// pose guard admits use the errors and bounds within the envelope (a bake made with
    /// `--envelope` and `--lod`, or bounded here for a glTF file); the others draw full detail.
    #[arg(long)]
    lod: bool,
    /// The LOD threshold: the largest screen displacement allowed, in pixels.
    #[arg(long, default_value_t = 1.0)]
    lod_pixels: f32,
    /// With `--lod`: also write the first timed frame's cuts as a PNG, each triangle coloured by
    /// its cluster's level (white at full detail, then blue, green, yellow, orange, red, …).
    #[arg(long, requires = "lod")]
    lod_out: Option<std::path::PathBuf>,
    #[command(flatten)]
    refine: RefineArgs,
    #[arg(long)]
    json: bool,
}

/// The culler of `baked`'s meshlets then its hierarchy's clusters (`all`, in that order),
/// with the bounds of the clips or, `within_envelope`, of the pose envelope, and any-pose
/// boxes over the morph weight `ranges`: how the GPU crowd culls a character drawn with LOD
/// (`skinlet lod --culled` counts with it too).
pub(crate) fn lod_culler(
    baked: &skinlet::bake::Baked,
    lod: &skinlet::bake::BakedLod,
    all: &skinlet::meshlet::Meshlets,
    ranges: &[(f64, f64)],
    within_envelope: bool,
) -> skinlet::Result<MeshletCuller> {
    let skin = baked.palette();
    let (bounds, classes) = match (within_envelope, &baked.envelope, &lod.envelope) {
        (false, ..) => ([&baked.bounds[..], &lod.bounds].concat(), [&baked.classes[..], &lod.classes].concat()),
        (true, Some(e), Some(l)) => ([&e.bounds[..], &l.bounds].concat(), [&e.classes[..], &l.classes].concat()),
        _ => {
            let message = "the bake has no LOD bounds within a pose envelope".into();
            return Err(skinlet::Error::Invalid { location: "LOD culler".into(), message });
        }
    };
    let boxes = skinlet::cull::any_pose::build(&skin, &baked.mesh, all, ranges)?;
    Ok(MeshletCuller::new(&bounds, &classes, skin.joints.len())?.with_any_pose(&boxes)?)
}

/// Every culling row `gpu-bench` draws.
const CULLINGS: [&str; 10] = [
    "none",
    "frustum",
    "backface",
    "both",
    "both-by-class",
    "both+occlusion",
    "both+triangles",
    "both+occl+tri",
    "both+lod",
    "both+occl+lod",
];

/// One instance in one frame: world-space skinning matrices, morph weights, and
/// whether the bounds the culling uses hold for the pose (the pose guard's answer).
struct InstancePose {
    skinning: Vec<Affine3A>,
    weights: Vec<f32>,
    /// The pose guard admits the pose (clips: always).
    admitted: bool,
    /// The any-pose boxes hold (morph weights inside the envelope's ranges; clips: always).
    boxes: bool,
    /// The LOD threshold (`--lod`), else negative.
    lod_threshold: f32,
}

/// One frame of the GPU-driven crowd, instance after instance: palettes, culling modes (the
/// pose guard's answer), morph weights, LOD thresholds.
struct FlatFrame {
    palette: Vec<glam::Mat4>,
    modes: Vec<CullMode>,
    weights: Vec<f32>,
    lod_thresholds: Vec<f32>,
}

/// One configuration: a skinning pipeline (with its mesh, culler and bake) and a culling,
/// drawn by skinlet's renderer (task culling) or by the GPU-driven crowd (`view`).
struct Config<'a> {
    pipeline: &'static str,
    skinning: Skinning,
    mesh: &'a GpuMesh,
    culler: &'a MeshletCuller,
    baked: &'a skinlet::bake::Baked,
    culling: &'static str,
    tests: Option<Tests>,
    path: Option<Culling>,
    view: Option<CrowdView>,
    /// Each instance draws its LOD cut.
    lod: bool,
}

/// One drawn frame of a configuration.
struct Frame {
    image: Image,
    gpu_ms: Option<f64>,
    triangles: u64,
    meshlets: u64,
    /// Vertex references skinned by the draw (GPU-driven rows): of the meshlets drawn, or
    /// with the triangle pass, the distinct (instance, vertex) of the triangles drawn.
    vertex_refs: Option<u64>,
    /// Vertices the triangle pass skinned (those of the meshlets it tested, once each).
    pass_vertices: Option<u64>,
    draw_calls: u32,
    wall_ms: f64,
}

/// A median with the range it came from.
#[derive(Clone, Copy)]
struct Spread {
    median: f64,
    min: f64,
    max: f64,
}

impl Spread {
    fn of(v: &[f64]) -> Option<Spread> {
        let median = crate::bench::median(v.to_vec())?;
        Some(Spread {
            median,
            min: v.iter().copied().fold(f64::INFINITY, f64::min),
            max: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }

    fn json(s: Option<Spread>) -> serde_json::Value {
        s.map_or(serde_json::Value::Null, |s| json!({"median": s.median, "min": s.min, "max": s.max}))
    }
}

/// One measured configuration.
struct Row {
    pipeline: &'static str,
    culling: &'static str,
    gpu_ms: Option<Spread>,
    wall_ms: Option<Spread>,
    /// GPU time ÷ the same pipeline's without culling, minus one, in percent, per repeat.
    vs_none_pct: Option<Spread>,
    culled_pct: Option<f64>,
    /// Triangles drawn per frame.
    triangles: u64,
    /// Meshlets drawn per frame (mean over timed frames).
    meshlets_drawn: f64,
    /// Their vertex references per frame (GPU-driven rows).
    vertex_refs: Option<u64>,
    /// Vertices the triangle pass skinned per frame (its rows).
    pass_vertices: Option<u64>,
    /// API draw calls per frame.
    draws_issued: u32,
    /// The warm-up frame's image equals the unculled one (up to depth ties); none for the LOD
    /// rows (their cuts are compared with full detail in the JSON's `lod`).
    image_equal: Option<bool>,
}

pub fn command(file: &str, a: &Args) -> Result<()> {
    anyhow::ensure!(
        a.instances != Some(0) && a.frames >= 1 && a.repeats >= 1,
        "--instances, --frames and --repeats must be at least 1"
    );
    anyhow::ensure!((64..=8192).contains(&a.width), "--width must be between 64 and 8192");
    anyhow::ensure!((0.0..=180.0).contains(&a.additive_deg), "--additive-deg must be from 0 to 180");
    anyhow::ensure!(!a.lod || (a.lod_pixels > 0.0 && a.lod_pixels.is_finite()), "--lod needs a positive --lod-pixels");
    let animation = match a.animation.as_str() {
        "blend" => Animation::Blend,
        "additive" => Animation::Additive(a.additive_deg.to_radians()),
        "ik" => Animation::Ik,
        _ => Animation::Clips,
    };
    let builder = a.builder.as_deref().map(|b| Builder::from_name(b).context("unknown meshlet builder")).transpose()?;
    let (asset, character, mut baked) = crate::crowd::load(file, a.gltf.as_deref(), builder, a.refine, a.json)?;
    let clips = crate::bake::clips_of(&baked, &asset, a.gltf.as_deref().unwrap_or(file))?;
    let envelope_spec = format!("clips:{}", a.additive_deg);
    if animation != Animation::Clips && baked.envelope.is_none() {
        anyhow::ensure!(
            a.gltf.is_none(),
            "--animation {} needs a pose envelope: bake {file} with --envelope",
            a.animation
        );
        let env = crate::bake::envelope_of(&envelope_spec, &asset, &baked)?;
        skinlet::bake::add_envelope(&mut baked, &asset, env)?;
    }
    // The hierarchy's build time where it is built here (after the envelope: its errors
    // within it are bounded with the others).
    let mut lod_s = None;
    if a.lod && baked.lod.is_none() {
        let started = std::time::Instant::now();
        skinlet::bake::add_lod(&mut baked, &asset, &skinlet::meshlet::lod::LodParams::default())?;
        lod_s = Some(started.elapsed().as_secs_f64());
    }
    // Instances posed inside the envelope select and cull their cuts with the hierarchy's
    // errors and bounds within it.
    let within_envelope = animation != Animation::Clips;
    if a.lod && within_envelope && baked.lod.as_ref().is_some_and(|l| l.envelope.is_none()) {
        anyhow::ensure!(
            a.gltf.is_none(),
            "--animation {} --lod: {file}'s LOD hierarchy has no errors within its pose envelope (bake with --envelope and --lod)",
            a.animation
        );
        skinlet::bake::add_lod_envelope(&mut baked, &asset)?;
    }
    let palette = baked.palette();
    let skin = &palette;
    let layout = if a.crowd == "dense" { Layout::Dense } else { Layout::Paper };
    let instances = a.instances.unwrap_or(if layout == Layout::Dense { 1024 } else { 64 });
    let params = CrowdParams { instances, frames: a.frames + 1, animation, layout, ..CrowdParams::default() };
    let scene = posed_crowd(&asset.skeleton, skin, &baked.mesh, &clips, &params)?;
    let gpu = headless::gpu(GpuOptions { software: a.software, ..GpuOptions::default() })?;
    let height = (a.width * 9 / 16).max(1);
    let renderer = Renderer::new(&gpu, a.width, height)?;
    let mesh = GpuMesh::new(&gpu, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers()))))?;
    // The bounds the culling uses, with the any-pose boxes: the clip bounds and boxes over the
    // clips' morph weight ranges for clips, else the envelope's.
    let clip_ranges = match animation {
        Animation::Clips => crate::bake::envelope_of("clips", &asset, &baked)?.weight_ranges(),
        _ => Vec::new(),
    };
    let culler_of = |b: &skinlet::bake::Baked| -> Result<MeshletCuller> {
        Ok(match (&b.envelope, animation) {
            (Some(e), a) if a != Animation::Clips => {
                MeshletCuller::new(&e.bounds, &e.classes, skin.joints.len())?.with_any_pose(&e.any_pose)?
            }
            _ => {
                let boxes = skinlet::cull::any_pose::build(skin, &b.mesh, &b.meshlets, &clip_ranges)?;
                MeshletCuller::new(&b.bounds, &b.classes, skin.joints.len())?.with_any_pose(&boxes)?
            }
        })
    };
    let culler = culler_of(&baked)?;
    // With LOD, the GPU-driven crowd culls the meshlets and then the hierarchy's clusters.
    let all_meshlets_lod = baked.lod.as_ref().filter(|_| a.lod).map(|lod| {
        let mut all = baked.meshlets.clone();
        all.append(&lod.meshlets, 0);
        all
    });
    let crowd_culler = match (&all_meshlets_lod, &baked.lod, &baked.envelope) {
        (Some(all), Some(lod), Some(e)) if within_envelope => {
            Some(lod_culler(&baked, lod, all, &e.envelope.weight_ranges(), true)?)
        }
        (Some(all), Some(lod), _) => Some(lod_culler(&baked, lod, all, &clip_ranges, false)?),
        _ => None,
    };
    // The errors the cuts are selected with (the clips', or within the envelope).
    let lod_errors = match all_meshlets_lod {
        Some(_) => skinlet::bake::with_view(&baked, |v| {
            Ok(v.lod().and_then(|l| if within_envelope { l.envelope().map(|e| e.errors()) } else { Some(l.errors()) }))
        })?,
        None => None,
    };
    let crowd_lod = match a.lod {
        true => Some(skinlet::bake::with_view(&baked, |v| CrowdLod::new(v, &scene.camera, a.width, height))?),
        false => None,
    };
    let want = |p: &str| a.pipelines.iter().any(|q| q == p);
    // MS-CI draws common-influences meshlets: baked too, over the same clips, for their bounds.
    let ci = match want("MS-CI") && gpu.has_mesh_shaders() {
        true => {
            let how = a.refine.refinement()?;
            let (mut ci, _) = skinlet::bake::bake(
                &asset,
                &character,
                &clips,
                Builder::CommonInfluences,
                MeshletLimits::NVIDIA,
                &how,
                &mut |_| {},
            )?;
            if animation != Animation::Clips {
                let env = crate::bake::envelope_of(&envelope_spec, &asset, &ci)?;
                skinlet::bake::add_envelope(&mut ci, &asset, env)?;
            }
            let ci_mesh = GpuMesh::new(&gpu, &ci.mesh.mesh_data(Some(ci.meshlets.view(&ci.meshlets.headers()))))?;
            let ci_culler = culler_of(&ci)?;
            Some((ci, ci_mesh, ci_culler))
        }
        false => None,
    };
    // Per frame and instance: world-space skinning matrices, joint matrices, morph weights,
    // the pose guard's answer (clips: always).
    let guard =
        baked.envelope.as_ref().filter(|_| animation != Animation::Clips).map(|e| e.envelope.guard()).transpose()?;
    let mut frames: Vec<Vec<InstancePose>> = Vec::new();
    let (mut locals, mut weights, mut globals) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..params.frames {
        let f = if a.still { 0 } else { frame };
        let mut instances = Vec::new();
        for (i, pl) in scene.placements.iter().enumerate() {
            instance_pose(&asset.skeleton, &clips, &baked, &params, i, pl, f, &mut locals, &mut weights);
            global_transforms(&asset.skeleton, &locals, &mut globals);
            let (mut joints, mut skinning) = (Vec::new(), Vec::new());
            pl.world_matrices(skin, &globals, &mut joints, &mut skinning);
            let admitted = guard.as_ref().is_none_or(|g| g.admits(&locals, &weights));
            let boxes = guard.as_ref().is_none_or(|g| g.admits_weights(&weights));
            // Within the envelope only where the guard admits the pose (full detail otherwise).
            let lod_threshold = crowd_lod.as_ref().filter(|_| admitted).map_or(-1.0, |l| {
                let clip = clips.get(pl.clip).map(|&c| (pl.clip as u32, pl.time(Some(c), f, params.fps)));
                let pose = match clip {
                    _ if within_envelope => PoseBounds::Envelope,
                    Some((clip, time)) => PoseBounds::ClipAt { clip, time },
                    None => PoseBounds::Clips,
                };
                l.threshold(a.lod_pixels, &joints, &weights, pose)
            });
            instances.push(InstancePose { skinning, weights: weights.clone(), admitted, boxes, lod_threshold });
        }
        frames.push(instances);
    }
    // The GPU-driven crowd's frames.
    let flat: Vec<FlatFrame> = (frames.iter())
        .map(|instances| {
            let palette = instances.iter().flat_map(|i| i.skinning.iter().map(|&m| glam::Mat4::from(m))).collect();
            let modes = (instances.iter())
                .map(|i| match (i.admitted, i.boxes) {
                    (true, true) => CullMode::BoundsAndBoxes,
                    (true, false) => CullMode::Bounds,
                    (false, true) => CullMode::BoxesOnly,
                    (false, false) => CullMode::Keep,
                })
                .collect();
            let weights = instances.iter().flat_map(|i| i.weights.iter().copied()).collect();
            let lod_thresholds = instances.iter().map(|i| i.lod_threshold).collect();
            FlatFrame { palette, modes, weights, lod_thresholds }
        })
        .collect();
    // No occlusion culling where no row asked for uses it: one survivor list, not two (room
    // for more instances in the device's storage bindings).
    let occlusion = a.cullings.is_empty() || a.cullings.iter().any(|c| c.contains("occl"));
    let (n, rounds) = (instances as u32, if occlusion { a.occlusion_rounds } else { 0 });
    let crowd_culler = crowd_culler.as_ref().unwrap_or(&culler);
    let gpu_crowd = GpuCrowd::with_depth_range(
        &gpu,
        &baked,
        crowd_culler,
        n,
        a.width,
        height,
        false,
        rounds,
        lod_errors.as_deref(),
    )?;
    let keep_all = vec![CullMode::Keep; instances];
    // Frame `f` of the GPU-driven crowd; `keep`: every instance drawn whole; `lod`: each
    // instance's cut.
    let crowd_frame = |f: usize, tests: Tests, keep: bool, lod: bool| CrowdFrame {
        palette: &flat[f].palette,
        modes: if keep { &keep_all } else { &flat[f].modes },
        weights: &flat[f].weights,
        lod_thresholds: if lod { &flat[f].lod_thresholds } else { &[] },
        camera: &scene.camera,
        tests,
    };
    let timed = (frames[1..].iter().flatten()).count().max(1);
    let fallback_pct = 100.0 * (frames[1..].iter().flatten()).filter(|i| !i.admitted).count() as f64 / timed as f64;
    let mut pipelines =
        vec![("VS", Skinning::Vertex, &mesh, &culler, &baked), ("CS", Skinning::Compute, &mesh, &culler, &baked)];
    if gpu.has_mesh_shaders() {
        pipelines.push(("MS", Skinning::Mesh, &mesh, &culler, &baked));
    }
    if let Some((ci, ci_mesh, ci_culler)) = &ci {
        pipelines.push(("MS-CI", Skinning::MeshSlim, ci_mesh, ci_culler, ci));
    }
    pipelines.retain(|p| want(p.0));
    let total_triangles = baked.mesh.triangles.len() as u64;
    let cullings = [
        ("none", None),
        ("frustum", Some(Tests::Frustum)),
        ("backface", Some(Tests::Backface)),
        ("both", Some(Tests::Both)),
        ("both-by-class", Some(Tests::Both)),
        ("both+occlusion", Some(Tests::Both)),
        ("both+triangles", Some(Tests::Both)),
        ("both+occl+tri", Some(Tests::Both)),
    ];
    let mut configs = Vec::new();
    for &(pipeline, skinning, mesh, culler, baked) in &pipelines {
        for &(culling, tests) in &cullings {
            // Culling runs in task shaders (MS, MS-CI: one pipeline reading per-meshlet class
            // flags, or three by class) or a compute pass writing indirect draws (VS, CS).
            let task = matches!(skinning, Skinning::Mesh | Skinning::MeshSlim);
            let (path, view) = match (task, skinning, culling) {
                (true, _, "none") => (None, None),
                (true, _, "both-by-class") => (Some(Culling::TaskByClass), None),
                (_, _, "both+occlusion" | "both+triangles" | "both+occl+tri") if skinning != Skinning::Vertex => {
                    continue;
                }
                (_, _, "both+occlusion") => (None, Some(CrowdView::Occluded)),
                (_, _, "both+triangles") => (None, Some(CrowdView::Triangles)),
                (_, _, "both+occl+tri") => (None, Some(CrowdView::OccludedTriangles)),
                (true, ..) => (Some(Culling::Task), None),
                (false, _, "both-by-class") => continue,
                (false, Skinning::Vertex, "none") => (None, Some(CrowdView::Unculled)),
                (false, Skinning::Vertex, _) => (None, Some(CrowdView::Pulled)),
                // Compute skinning skins every vertex whatever is culled: drawn unculled only.
                (false, _, "none") => (None, None),
                (false, ..) => continue,
            };
            configs.push(Config { pipeline, skinning, mesh, culler, baked, culling, tests, path, view, lod: false });
        }
    }
    if a.lod && want("VS") {
        for (culling, view) in [("both+lod", CrowdView::Pulled), ("both+occl+lod", CrowdView::Occluded)] {
            let (pipeline, skinning, tests, path, view) = ("VS", Skinning::Vertex, Some(Tests::Both), None, Some(view));
            configs.push(Config {
                pipeline,
                skinning,
                mesh: &mesh,
                culler: &culler,
                baked: &baked,
                culling,
                tests,
                path,
                view,
                lod: true,
            });
        }
    }
    if gpu.has_indirect_count() && want("VS-indexed") {
        for (culling, tests, view) in
            [("none", None, CrowdView::Unculled), ("both", Some(Tests::Both), CrowdView::Indexed)]
        {
            let (path, skinning, mesh, culler, baked) = (None, Skinning::Vertex, &mesh, &culler, &baked);
            let pipeline = "VS-indexed";
            let view = Some(view);
            configs.push(Config { pipeline, skinning, mesh, culler, baked, culling, tests, path, view, lod: false });
        }
    }
    configs.retain(|c| a.cullings.is_empty() || a.cullings.iter().any(|x| x == c.culling));
    anyhow::ensure!(!configs.is_empty(), "no row to draw: --pipelines and --cullings (and --lod) have none in common");
    // Task-culled rows: each mesh's meshlets uploaded for culling once.
    let characters = (configs.iter())
        .map(|c| match c.path {
            Some(_) => {
                let headers = c.baked.meshlets.headers();
                let view = c.baked.meshlets.view(&headers);
                let (_, draws) = skinlet_gpu::mesh::meshlet_index_buffer(&view, c.baked.mesh.positions.len())?;
                Ok(Some(GpuCharacter::new(&gpu.device, c.culler, &c.baked.inverse_bind, &draws)?))
            }
            None => Ok(None),
        })
        .collect::<Result<Vec<_>>>()?;
    let light = Vec3::new(0.4, 0.8, 0.6);
    let all_meshlets = (instances * baked.meshlets.len()) as u64;
    // Triangles per meshlet (the GPU-driven crowd's survivors are counted by meshlet).
    // (With LOD, the hierarchy's clusters after the meshlets: the crowd's survivors number them so.)
    let uploaded = all_meshlets_lod.as_ref().unwrap_or(&baked.meshlets);
    let meshlet_triangles: Vec<u64> = uploaded.meshlets.iter().map(|m| m.triangle_count as u64).collect();
    let meshlet_vertices: Vec<u64> = uploaded.meshlets.iter().map(|m| m.vertex_count as u64).collect();
    let all_vertex_refs = instances as u64 * meshlet_vertices[..baked.meshlets.len()].iter().sum::<u64>();
    // One frame of configuration `k`: image, GPU ms, triangles and meshlets drawn, draw calls,
    // wall ms.
    let draw = |k: usize, f: usize| -> Result<Frame> {
        let c = &configs[k];
        if let Some(view) = c.view {
            let started = std::time::Instant::now();
            let d = gpu_crowd.draw(&gpu, &crowd_frame(f, c.tests.unwrap_or(Tests::Both), false, c.lod), view, light)?;
            let wall_ms = started.elapsed().as_secs_f64() * 1e3;
            let (mut meshlets, mut triangles, mut vertex_refs, mut pass_vertices) =
                (all_meshlets, total_triangles * instances as u64, Some(all_vertex_refs), None);
            if !d.headers.is_empty() {
                let survivors = gpu_crowd.survivors(&gpu)?;
                let sum = |per: &[u64]| survivors.iter().map(|&[_, m]| per[m as usize]).sum::<u64>();
                (meshlets, triangles, vertex_refs) =
                    (survivors.len() as u64, sum(&meshlet_triangles), Some(sum(&meshlet_vertices)));
                if !d.triangle_headers.is_empty() {
                    // The pass skinned the survivors' vertices; the draw skins each distinct
                    // (instance, vertex) of the triangles it kept at least once.
                    pass_vertices = vertex_refs;
                    let drawn = gpu_crowd.drawn_triangles(&gpu)?;
                    let pairs: HashSet<[u32; 2]> = drawn.iter().map(|t| [t.instance, t.meshlet]).collect();
                    let corners: HashSet<[u32; 2]> =
                        drawn.iter().flat_map(|t| t.vertices.map(|v| [t.instance, v])).collect();
                    (meshlets, triangles, vertex_refs) =
                        (pairs.len() as u64, drawn.len() as u64, Some(corners.len() as u64));
                }
            }
            let image = d.image.context("the crowd draws an image")?;
            return Ok(Frame {
                image,
                gpu_ms: d.gpu_ms,
                triangles,
                meshlets,
                vertex_refs,
                pass_vertices,
                draw_calls: d.draw_calls,
                wall_ms,
            });
        }
        let list: Vec<PosedInstance> = (frames[f].iter().zip(&flat[f].modes))
            .map(|(p, &mode)| PosedInstance {
                pose: Pose { matrices: &p.skinning, morph_weights: &p.weights },
                cull: Some(mode),
            })
            .collect();
        let how = match (c.path, &characters[k], c.tests) {
            (Some(culling), Some(character), Some(tests)) => {
                let camera = &scene.camera;
                CrowdDraw::Culled(TaskCulling { character, camera, tests, culling, triangles: None }, c.skinning)
            }
            _ => CrowdDraw::Plain(c.skinning),
        };
        let started = std::time::Instant::now();
        let drawn = renderer.render_crowd(&gpu, c.mesh, &list, scene.camera.view_proj, light, how)?;
        let wall_ms = started.elapsed().as_secs_f64() * 1e3;
        // Draw calls: one per instance, or per instance one per non-empty class pipeline.
        let per_instance = match (c.path, &characters[k]) {
            (Some(Culling::TaskByClass), Some(character)) => {
                character.class_ranges().iter().filter(|r| r[1] > 0).count() as u32
            }
            _ => 1,
        };
        Ok(Frame {
            image: drawn.image,
            gpu_ms: drawn.gpu_ms,
            triangles: drawn.triangles.map_or(total_triangles * instances as u64, u64::from),
            meshlets: drawn.meshlets.map_or((instances * c.baked.meshlets.len()) as u64, u64::from),
            vertex_refs: None,
            pass_vertices: None,
            draw_calls: per_instance * instances as u32,
            wall_ms,
        })
    };
    // The references of frame 0: every meshlet drawn the same way (the GPU-driven crowd's
    // survivors with every instance kept, pulled or indexed: lavapipe rasterizes a pixel here
    // and there differently between one instanced draw, a pulled draw and a multi-draw of the
    // same triangles; each renderer pipeline's own unculled draw), and where meshlets tie in
    // depth (draw order picks the color there).
    let oracle0 = gpu_crowd.draw(&gpu, &crowd_frame(0, Tests::Both, false, false), CrowdView::Ids, light)?;
    let ties = oracle0.ties.context("the ID view finds ties")?;
    let same =
        |a: &Image, b: &Image| a.rgba.chunks(4).zip(b.rgba.chunks(4)).zip(&ties).all(|((x, y), &tie)| x == y || tie);
    // Warm-up: frame 0 of every configuration, untimed, checked against its reference. Culling
    // is conservative: every configuration draws the same picture, so the first one's is written.
    let mut picture = None;
    let mut image_equal = vec![None; configs.len()];
    // The occlusion rows share the crowd's visibility bits: each one's timed frames start
    // after an untimed frame 0 of its own.
    let occluding = |c: &Config| matches!(c.view, Some(CrowdView::Occluded | CrowdView::OccludedTriangles));
    for k in 0..configs.len() {
        let c = &configs[k];
        // Occlusion culling starts with no history: its first frame draws every survivor of
        // the frustum and backface tests in its second phase and marks them all visible, so
        // its second frame draws them all in its first phase. From the third frame on its
        // lists follow the scene (as in an application's steady state): frame 0 twice first.
        if occluding(c) {
            draw(k, 0)?;
        }
        let frame = draw(k, 0)?;
        // LOD rows draw other triangles than full detail: compared below, not here.
        let reference = match (c.view, c.path) {
            _ if c.lod => None,
            (Some(CrowdView::Unculled), _) => Some(frame.image.clone()),
            (Some(view), _) => {
                let same_way = if view == CrowdView::Indexed { view } else { CrowdView::Pulled };
                gpu_crowd.draw(&gpu, &crowd_frame(0, Tests::Both, true, false), same_way, light)?.image
            }
            (None, None) => Some(frame.image.clone()),
            (None, Some(_)) => {
                let plain = configs.iter().position(|b| b.pipeline == c.pipeline && b.culling == "none");
                plain.map(|p| draw(p, 0)).transpose()?.map(|f| f.image)
            }
        };
        image_equal[k] = reference.map(|r| same(&r, &frame.image));
        picture.get_or_insert(frame.image);
    }
    // The limit: meshlets with a visible fragment, per timed frame. And what a box test
    // against the frame's unculled depth could keep of the frustum and backface survivors, with
    // boxes of this pose (the CPU skinning the reference's): at full resolution, and on the
    // pyramid as the occlusion pass reads it; and per triangle (a meshlet kept when one of its
    // front-facing triangles' boxes is not behind the depth at full resolution).
    // And what drawing last frame's visible meshlets first cannot avoid: the meshlets
    // visible in this frame or the one before (two-phase occlusion culling draws last frame's
    // in its first phase whether they are still visible or not).
    let (mut oracle, mut box_exact, mut box_pyramid, mut box_triangles) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut last: HashSet<u32> = oracle0.ids.iter().flatten().copied().filter(|&id| id != 0).collect();
    let mut last_or_this = Vec::new();
    for (f, poses) in frames.iter().enumerate().skip(1) {
        gpu_crowd.draw(&gpu, &crowd_frame(f, Tests::Both, false, false), CrowdView::Pulled, light)?;
        let survivors = gpu_crowd.survivors(&gpu)?;
        let d = gpu_crowd.draw(&gpu, &crowd_frame(f, Tests::Both, false, false), CrowdView::Ids, light)?;
        let ids = d.ids.context("the ID view reads ids")?;
        let visible: HashSet<u32> = ids.iter().copied().filter(|&id| id != 0).collect();
        oracle.push(visible.len() as f64);
        last_or_this.push(visible.union(&last).count() as f64);
        last = visible;
        let depth = DepthPyramid::new(a.width, height, gpu_crowd.depth(&gpu)?);
        let poses: Vec<_> = poses.iter().map(|p| (&p.skinning[..], &p.weights[..])).collect();
        let [exact, pyramid, triangles] = pose_limits(&baked, &poses, &survivors, &depth, &scene.camera)?;
        box_exact.push(exact as f64);
        box_pyramid.push(pyramid as f64);
        box_triangles.push(triangles as f64);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let visible_oracle = mean(&oracle);
    // Per configuration and repeat: median GPU and wall time over the timed frames.
    let (mut gpu_ms, mut wall_ms) = (vec![Vec::new(); configs.len()], vec![Vec::new(); configs.len()]);
    let (mut triangles, mut meshlets, mut draw_calls) =
        (vec![0u64; configs.len()], vec![0u64; configs.len()], vec![0u32; configs.len()]);
    let (mut vertex_refs, mut pass_vertices) = (vec![None; configs.len()], vec![None; configs.len()]);
    for repeat in 0..a.repeats {
        let order: Vec<usize> =
            if repeat % 2 == 0 { (0..configs.len()).collect() } else { (0..configs.len()).rev().collect() };
        for k in order {
            let (mut g, mut w, mut t, mut m, mut v, mut p) = (Vec::new(), Vec::new(), 0u64, 0u64, None, None);
            if occluding(&configs[k]) {
                draw(k, 0)?;
            }
            for f in 1..=a.frames {
                let frame = draw(k, f)?;
                w.push(frame.wall_ms);
                g.extend(frame.gpu_ms);
                t += frame.triangles;
                m += frame.meshlets;
                v = frame.vertex_refs.map(|x| x + v.unwrap_or(0));
                p = frame.pass_vertices.map(|x| x + p.unwrap_or(0));
                draw_calls[k] = frame.draw_calls;
            }
            gpu_ms[k].extend(crate::bench::median(g));
            wall_ms[k].extend(crate::bench::median(w));
            (triangles[k], meshlets[k]) = (t / a.frames as u64, m / a.frames as u64);
            vertex_refs[k] = v.map(|v| v / a.frames as u64);
            pass_vertices[k] = p.map(|p| p / a.frames as u64);
        }
    }
    // LOD against full detail, both culled (pulled), per timed frame: triangles and vertex
    // references drawn, pixels differing, the silhouettes' displacement (coverage from depth).
    let lod = match a.lod {
        false => None,
        true => {
            let (mut t, mut v, mut diff, mut worst) = ([0u64; 2], [0u64; 2], 0u64, 0f32);
            for f in 1..=a.frames {
                let mut images = Vec::new();
                for (k, with_lod) in [false, true].into_iter().enumerate() {
                    let d = gpu_crowd.draw(
                        &gpu,
                        &crowd_frame(f, Tests::Both, false, with_lod),
                        CrowdView::Pulled,
                        light,
                    )?;
                    let survivors = gpu_crowd.survivors(&gpu)?;
                    t[k] += survivors.iter().map(|&[_, m]| meshlet_triangles[m as usize]).sum::<u64>();
                    v[k] += survivors.iter().map(|&[_, m]| meshlet_vertices[m as usize]).sum::<u64>();
                    let covered: Vec<bool> = gpu_crowd.depth(&gpu)?.iter().map(|&z| z < 1.0).collect();
                    images.push((d.image.context("the crowd draws an image")?, covered));
                }
                let [(full, full_covered), (cut, cut_covered)] = &images[..] else { unreachable!() };
                diff += full.rgba.chunks(4).zip(cut.rgba.chunks(4)).filter(|(x, y)| x != y).count() as u64;
                let (w, h) = (a.width as usize, height as usize);
                worst = worst.max(silhouette_displacement(full_covered, cut_covered, w, h));
            }
            if let Some(out) = &a.lod_out {
                let d =
                    gpu_crowd.draw(&gpu, &crowd_frame(1, Tests::Both, false, true), CrowdView::PulledByLevel, light)?;
                let image = d.image.context("the crowd draws an image")?;
                crate::write_png(out, image.width, image.height, png::ColorType::Rgba, &image.rgba)?;
            }
            let per_frame = |x: u64| x / a.frames as u64;
            let lod = baked.lod.as_ref().context("the bake has a LOD hierarchy")?;
            Some(json!({
                "pixels": a.lod_pixels, "lod_s": lod_s, "groups": lod.groups.len(), "clusters": lod.meshlets.len(),
                "triangles_full_detail": per_frame(t[0]), "triangles_drawn": per_frame(t[1]),
                "triangle_reduction": t[0] as f64 / t[1].max(1) as f64,
                "vertex_refs_full_detail": per_frame(v[0]), "vertex_refs_drawn": per_frame(v[1]),
                "pixels_differing": per_frame(diff), "image_pixels": a.width as u64 * height as u64,
                "max_silhouette_px": worst,
            }))
        }
    };
    let rows: Vec<Row> = (0..configs.len())
        .map(|k| {
            let c = &configs[k];
            let none = configs.iter().position(|b| b.culling == "none" && b.pipeline == c.pipeline);
            let ratios: Vec<f64> = match none {
                Some(n) if n != k && gpu_ms[n].len() == gpu_ms[k].len() => {
                    gpu_ms[k].iter().zip(&gpu_ms[n]).map(|(t, b)| 100.0 * (t / b - 1.0)).collect()
                }
                _ => Vec::new(),
            };
            let culled_pct = c.tests.is_some().then(|| 100.0 * (1.0 - meshlets[k] as f64 / all_meshlets.max(1) as f64));
            Row {
                pipeline: c.pipeline,
                culling: c.culling,
                gpu_ms: Spread::of(&gpu_ms[k]),
                wall_ms: Spread::of(&wall_ms[k]),
                vs_none_pct: Spread::of(&ratios),
                culled_pct,
                triangles: triangles[k],
                meshlets_drawn: meshlets[k] as f64,
                vertex_refs: vertex_refs[k],
                pass_vertices: pass_vertices[k],
                draws_issued: draw_calls[k],
                image_equal: image_equal[k],
            }
        })
        .collect();
    if let (Some(out), Some(image)) = (&a.out, &picture) {
        crate::write_png(out, image.width, image.height, png::ColorType::Rgba, &image.rgba)?;
    }
    let ci_counts = ci.as_ref().and_then(|c| c.1.meshlets.as_ref()).map(|m| (m.count, m.slim));
    if a.json {
        let rows: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({"pipeline": r.pipeline, "culling": r.culling, "gpu_ms": Spread::json(r.gpu_ms),
                    "wall_ms": Spread::json(r.wall_ms), "vs_none_pct": Spread::json(r.vs_none_pct),
                    "culled_pct": r.culled_pct, "triangles_per_frame": r.triangles,
                    "meshlets_drawn": r.meshlets_drawn, "vertex_refs_per_frame": r.vertex_refs,
                    "triangle_pass_vertices_per_frame": r.pass_vertices,
                    "draws_issued": r.draws_issued,
                    "image_equal_to_unculled": r.image_equal})
            })
            .collect();
        let out = json!({"file": file, "adapter": gpu.info.name, "timestamps": gpu.has_timestamps(),
            "subpixel_bits": gpu.subpixel_bits, "crowd": a.crowd, "meshlets_visible_oracle": visible_oracle,
            "meshlets_visible_last_or_this_frame": mean(&last_or_this),
            "meshlets_unhidden_pose_box": mean(&box_exact), "meshlets_unhidden_pose_box_pyramid": mean(&box_pyramid),
            "meshlets_unhidden_pose_triangles": mean(&box_triangles), "meshlets_per_frame": all_meshlets,
            "animation": a.animation, "still": a.still, "occlusion_rounds": a.occlusion_rounds, "guard_fallback_pct": fallback_pct,
            "instances": instances, "frames": a.frames, "repeats": a.repeats, "width": a.width, "height": height,
            "meshlets": baked.meshlets.len(), "triangles_per_instance": total_triangles,
            "builder": baked.settings.builder.name(), "ci_meshlets": ci_counts.map(|c| c.0),
            "ci_slim_meshlets": ci_counts.map(|c| c.1), "lod": lod, "rows": rows});
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let ci_text =
        ci_counts.map_or(String::new(), |(n, slim)| format!(", {n} common-influences meshlets of which {slim} slim"));
    println!(
        "{file}: {} crowd of {instances} instances ({} {} meshlets{ci_text}, {total_triangles} triangles each), \
         {}x{height}, on {}; {} repeats of {} frames, alternating order",
        a.crowd,
        baked.meshlets.len(),
        baked.settings.builder.name(),
        a.width,
        gpu.info.name,
        a.repeats,
        a.frames
    );
    println!("  meshlets per frame: {all_meshlets}, with a visible fragment (unculled ID buffer): {visible_oracle:.0}");
    println!(
        "  frustum and backface survivors whose box of this pose is not behind the unculled depth: {:.0} at full \
         resolution, {:.0} on the depth pyramid; with a front-facing triangle whose box is not: {:.0}",
        mean(&box_exact),
        mean(&box_pyramid),
        mean(&box_triangles)
    );
    if animation != Animation::Clips {
        println!(
            "  {} animation: envelope bounds where the pose guard admits the pose; {fallback_pct:.1}% of instance-frames \
             refused and drawn whole",
            a.animation
        );
    }
    println!(
        "  {:<10} {:<14} {:>22}  {:>13}  {:>15}  {:>14}  {:>15}  {:>5}  {:>5}  GPU vs none [range]",
        "pipeline",
        "culling",
        "GPU ms/frame [range]",
        "wall ms/frame",
        "meshlets culled",
        "meshlets drawn",
        "triangles drawn",
        "draws",
        "image"
    );
    let range = |s: Option<Spread>, digits: usize| {
        s.map_or("-".into(), |s| format!("{:.digits$} [{:.digits$}, {:.digits$}]", s.median, s.min, s.max))
    };
    for r in &rows {
        let culled = r.culled_pct.map_or("-".into(), |c| format!("{c:.1}%"));
        let vs = r.vs_none_pct.map_or(String::new(), |s| format!("{:+.0}% [{:+.0}, {:+.0}]", s.median, s.min, s.max));
        println!(
            "  {:<10} {:<14} {:>22}  {:>13}  {culled:>15}  {:>14}  {:>15}  {:>5}  {:>5}  {vs}",
            r.pipeline,
            r.culling,
            range(r.gpu_ms, 3),
            r.wall_ms.map_or("-".into(), |s| format!("{:.2}", s.median)),
            r.meshlets_drawn,
            r.triangles,
            r.draws_issued,
            match r.image_equal {
                Some(true) => "equal",
                Some(false) => "DIFF",
                None => "-",
            }
        );
    }
    if let Some(l) = &lod {
        println!(
            "  LOD at {} px ({} groups, {} clusters): {} triangles per frame against {} at full detail ({:.1}x \
             fewer), both culled; {} of {} vertex references; {} pixels differ, silhouettes moved up to {:.2} px",
            l["pixels"],
            l["groups"],
            l["clusters"],
            l["triangles_drawn"],
            l["triangles_full_detail"],
            l["triangle_reduction"].as_f64().unwrap_or(0.0),
            l["vertex_refs_drawn"],
            l["vertex_refs_full_detail"],
            l["pixels_differing"],
            l["max_silhouette_px"].as_f64().unwrap_or(f64::NAN)
        );
    }
    if rows.iter().all(|r| r.gpu_ms.is_none()) {
        println!("  (the adapter has no timestamp queries: wall-clock times only)");
    }
    Ok(())
}
