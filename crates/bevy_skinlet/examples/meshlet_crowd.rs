//! A crowd drawn by Bevy's own skinned mesh pipeline and by skinlet's meshlet draw
//! (`SkinletMeshletPlugin`), switching between them in one app, headless: Xbot, mannequiny,
//! BrainStem (the shared assets) and the demo character play and crossfade their clips on a
//! grid while a camera walks through it at eye height.
//!
//! ```sh
//! cargo run --release -p bevy_skinlet --example meshlet_crowd -- --json
//! ```
//!
//! The timed frames come in blocks that alternate between the pipelines (the first frames
//! after a switch are not timed); per frame it measures the whole update, the render world's
//! schedule, and within it the render graph (skinlet's culling, encoding and submission; on a
//! CPU Vulkan driver such as lavapipe submission also runs the GPU's work, so the time outside
//! the render graph is the CPU time an app spends on either path there). At `--compare`
//! points along the camera's path the animation pauses and the same frame is drawn three
//! times: by Bevy's pipeline, by skinlet's with culling (occlusion culling among the
//! characters in `--occlusion-rounds` rounds), and by skinlet's without; the images are
//! compared and skinlet's counts (read back from the GPU) are reported.

#[path = "../tests/common/mod.rs"]
mod common;

use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::gpu_readback::Readback;
use bevy::render::{Render, RenderApp, RenderSystems};
use bevy_skinlet::{
    MeshletStats, SkinletBounds, SkinletInstance, SkinletMeshletPlugin, SkinletMeshletSettings, SkinletMeshletStats,
    SkinletMeshlets,
};
use clap::Parser;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A crowd of skinned characters drawn by Bevy's pipeline and by skinlet's meshlet draw, same
/// app, same frames: CPU time per frame of each, skinlet's meshlet counts, and the images
/// compared.
#[derive(Parser, Clone, Debug)]
pub struct Args {
    /// Instances of each character (Xbot, mannequiny, BrainStem, the demo).
    #[arg(long, default_value_t = 250)]
    pub per_character: usize,
    /// Frames timed per pipeline (at 30 frames per second of animation).
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Timed frames in a row before switching to the other pipeline.
    #[arg(long, default_value_t = 10)]
    pub block: usize,
    /// Frames compared (paused, drawn by each pipeline), spread along the camera's path.
    #[arg(long, default_value_t = 2)]
    pub compare: usize,
    /// The camera's image, in pixels.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 360)]
    pub height: u32,
    /// Occlusion culling among the characters in this many rounds
    /// (`SkinletMeshletSettings::occlusion_rounds`; 0: none).
    #[arg(long, default_value_t = 16)]
    pub occlusion_rounds: u32,
    /// Walls across the crowd every four rows (Bevy meshes, open where the camera walks) and
    /// Bevy's occlusion culling on the camera (`OcclusionCulling`, `DepthPrepass`): Bevy culls
    /// its meshes (in its pipeline, the characters too) by occlusion, and skinlet's occlusion
    /// culling starts from Bevy's depth (the walls hide characters).
    #[arg(long)]
    pub bevy_occlusion: bool,
    /// Which pipeline draws: both (alternating, compared), or one of them alone (for a
    /// profiler; nothing compared).
    #[arg(long, value_enum, default_value_t = Pipelines::Both)]
    pub pipeline: Pipelines,
    /// Write each compared frame (Bevy's, skinlet's and the difference × 8, side by side) as
    /// a PNG into this folder.
    #[arg(long)]
    pub pictures: Option<PathBuf>,
    /// One JSON object on standard output instead of a summary.
    #[arg(long)]
    pub json: bool,
}

/// The render world's schedule timed per frame (the render app may run on its own thread):
/// when it started and when its `Render` set (the render graph: encoding and submission)
/// started, then per frame (whole schedule, `Render` set).
#[derive(Resource, Clone, Default)]
struct RenderSpans(Arc<Mutex<RenderTimes>>);

#[derive(Default)]
struct RenderTimes {
    started: Option<Instant>,
    graph_started: Option<Instant>,
    graph: Duration,
    frames: Vec<(Duration, Duration)>,
}

fn render_started(spans: Res<RenderSpans>) {
    spans.0.lock().unwrap().started = Some(Instant::now());
}

fn graph_started(spans: Res<RenderSpans>) {
    spans.0.lock().unwrap().graph_started = Some(Instant::now());
}

fn graph_ended(spans: Res<RenderSpans>) {
    let mut s = spans.0.lock().unwrap();
    s.graph = s.graph_started.take().map_or(Duration::ZERO, |t| t.elapsed());
}

fn render_ended(spans: Res<RenderSpans>) {
    let mut s = spans.0.lock().unwrap();
    if let Some(t) = s.started.take() {
        let graph = s.graph;
        s.frames.push((t.elapsed(), graph));
    }
}

/// Which pipelines the run uses.
#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq, Debug)]
pub enum Pipelines {
    Both,
    Bevy,
    Skinlet,
}

/// Which pipeline draws the crowd.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Pipeline {
    Bevy,
    Skinlet,
}

fn set_pipeline(world: &mut World, roots: &[(Entity, usize)], pipeline: Pipeline) {
    for &(root, _) in roots {
        let mut e = world.entity_mut(root);
        match pipeline {
            Pipeline::Bevy => e.remove::<SkinletMeshlets>(),
            Pipeline::Skinlet => e.insert(SkinletMeshlets),
        };
    }
}

/// Per pipeline: timed frames, whole updates, render schedules and their `Render` sets.
#[derive(Default)]
struct Timing {
    frames: usize,
    update: Duration,
    render: Duration,
    graph: Duration,
    render_frames: usize,
}

/// skinlet's counts over the moving frames: per bake, the distinct frames read back.
#[derive(Default)]
struct Counts {
    seen: HashSet<(AssetId<bevy_skinlet::Bake>, u64)>,
    sums: HashMap<AssetId<bevy_skinlet::Bake>, (usize, MeshletStats)>,
}

impl Counts {
    fn add(&mut self, stats: &HashMap<AssetId<bevy_skinlet::Bake>, MeshletStats>) {
        for (&id, s) in stats {
            if !s.culled || !self.seen.insert((id, s.frame)) {
                continue;
            }
            let (n, sum) = self.sums.entry(id).or_default();
            *n += 1;
            sum.instances = s.instances;
            sum.meshlets_total = s.meshlets_total;
            sum.triangles_total = s.triangles_total;
            sum.meshlets_tested_visible += s.meshlets_tested_visible;
            sum.meshlets_drawn += s.meshlets_drawn;
            sum.triangles_drawn += s.triangles_drawn;
            sum.triangles_dropped += s.triangles_dropped;
        }
    }

    /// Per frame, summed over the bakes (each bake's mean over its frames).
    fn per_frame(&self) -> serde_json::Value {
        let mean = |f: fn(&MeshletStats) -> u64| -> f64 {
            self.sums.values().map(|(n, s)| f(s) as f64 / (*n).max(1) as f64).sum()
        };
        serde_json::json!({
            "frames_read_back": self.sums.values().map(|(n, _)| *n).min().unwrap_or(0),
            "meshlets_total": self.sums.values().map(|(_, s)| s.meshlets_total).sum::<u64>(),
            "meshlets_tested_visible": mean(|s| s.meshlets_tested_visible),
            "meshlets_drawn": mean(|s| s.meshlets_drawn),
            "triangles_total": self.sums.values().map(|(_, s)| s.triangles_total).sum::<u64>(),
            "triangles_drawn": mean(|s| s.triangles_drawn),
            "triangles_dropped": mean(|s| s.triangles_dropped),
        })
    }
}

/// One compared frame.
struct Compared {
    pixels: usize,
    drawn_by_bevy: usize,
    max_diff: u8,
    over_2: usize,
    equal_to_unculled: bool,
    /// With Bevy's occlusion culling: the pixels it changes in Bevy's own frame (drawn again
    /// without it).
    bevy_occlusion_changed: Option<usize>,
    stats: Vec<MeshletStats>,
}

/// Draws the paused frame with each pipeline (switching back to `back` after); where
/// `occlusion_camera` (the camera, with Bevy's occlusion culling) is given, Bevy's frame also
/// without Bevy's occlusion culling.
fn compare(
    app: &mut App,
    roots: &[(Entity, usize)],
    readback: (Entity, &Readback),
    back: Pipeline,
    (picture, width): (Option<PathBuf>, u32),
    occlusion_camera: Option<Entity>,
) -> Compared {
    use bevy::render::occlusion_culling::OcclusionCulling;
    app.world_mut().resource_mut::<Time<Virtual>>().pause();
    app.world_mut().entity_mut(readback.0).insert(readback.1.clone());
    set_pipeline(app.world_mut(), roots, Pipeline::Bevy);
    let bevy = common::settled_image(app);
    let bevy_occlusion_changed = occlusion_camera.map(|camera| {
        app.world_mut().entity_mut(camera).remove::<OcclusionCulling>();
        let without = common::settled_image(app);
        app.world_mut().entity_mut(camera).insert(OcclusionCulling);
        common::differing_pixels(&bevy, &without)
    });
    let before: u64 = stats_now(app).values().map(|s| s.frame).max().unwrap_or(0);
    set_pipeline(app.world_mut(), roots, Pipeline::Skinlet);
    let skinlet = common::settled_image(app);
    // The counts of a paused frame drawn by skinlet (read back a frame or two late).
    let bakes = stats_now(app).len().max(1);
    common::update_until(app, 100, "skinlet's counts read back", |w| {
        let s = w.resource::<SkinletMeshletStats>().latest();
        s.len() >= bakes && s.values().all(|s| s.culled && s.frame > before + 3)
    });
    let stats: Vec<MeshletStats> = stats_now(app).into_values().collect();
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = false;
    let unculled = common::settled_image(app);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = true;
    set_pipeline(app.world_mut(), roots, back);
    app.world_mut().entity_mut(readback.0).remove::<Readback>();
    app.world_mut().resource_mut::<Time<Virtual>>().unpause();

    let differences = common::pixel_differences(&bevy, &skinlet);
    if let Some(path) = picture {
        let diff = common::difference_image(&differences);
        common::write_png(&path, &common::side_by_side(&[&bevy, &skinlet, &diff], width), 3 * width);
    }
    Compared {
        pixels: differences.len(),
        drawn_by_bevy: common::drawn_pixels(&bevy),
        max_diff: differences.iter().copied().max().unwrap_or(0),
        over_2: differences.iter().filter(|&&d| d > 2).count(),
        equal_to_unculled: skinlet == unculled,
        bevy_occlusion_changed,
        stats,
    }
}

fn stats_now(app: &App) -> HashMap<AssetId<bevy_skinlet::Bake>, MeshletStats> {
    app.world().resource::<SkinletMeshletStats>().latest()
}

/// Runs the crowd; `None` without the shared assets (or a Vulkan device).
pub fn run(args: &Args) -> Option<serde_json::Value> {
    if !common::vulkan_available() {
        return None;
    }
    let files = ["skinned/Xbot.glb", "skinned/mannequiny.glb", "skinned/BrainStem.glb", "@demo"];
    let (dir, characters) = common::asset_folder("meshlet_crowd", &files)?;
    let mut app = common::app(&dir, true);
    app.add_plugins(SkinletMeshletPlugin);
    common::watch_pipelines(&mut app);
    let spans = RenderSpans::default();
    app.sub_app_mut(RenderApp)
        .insert_resource(spans.clone())
        .add_systems(Render, render_started.in_set(RenderSystems::ExtractCommands))
        .add_systems(Render, graph_started.after(RenderSystems::PrepareBindGroups).before(RenderSystems::Render))
        .add_systems(Render, graph_ended.after(RenderSystems::Render).before(RenderSystems::Cleanup))
        .add_systems(Render, render_ended.in_set(RenderSystems::PostCleanup));

    // The crowd on a grid 2 units apart, the characters interleaved, each about 1.6 units
    // across, facing its own way.
    let graphs = common::clip_graphs(app.world_mut(), &characters);
    let total = args.per_character * characters.len();
    let side = (total as f32).sqrt().ceil().max(1.0) as usize;
    let spacing = 2.0;
    let mut roots = Vec::with_capacity(total);
    {
        let world = app.world_mut();
        let assets = world.resource::<AssetServer>().clone();
        let handles: Vec<_> = (characters.iter())
            .map(|c| {
                let stem = c.file.rsplit_once('.').unwrap().0.to_string();
                let scene: Handle<WorldAsset> = assets.load(GltfAssetLabel::Scene(0).from_asset(c.file.clone()));
                (scene, assets.load::<bevy_skinlet::Bake>(format!("{stem}.skinlet")), 1.6 / common::rest_size(c))
            })
            .collect();
        for i in 0..total {
            let c = i % characters.len();
            let (x, z) = ((i % side) as f32 * spacing, (i / side) as f32 * spacing);
            let at = Transform::from_xyz(x, 0.0, -z)
                .with_rotation(Quat::from_rotation_y(i as f32 * 2.4))
                .with_scale(Vec3::splat(handles[c].2));
            let root = world.spawn((WorldAssetRoot(handles[c].0.clone()), SkinletBounds(handles[c].1.clone()), at));
            roots.push((root.id(), c));
        }
    }
    let camera = common::readback_camera(app.world_mut(), args.width, args.height, Transform::default());
    let aisle = ((side - 1) / 2) as f32 * spacing + spacing / 2.0;
    if args.bevy_occlusion {
        let world = app.world_mut();
        world
            .entity_mut(camera)
            .insert((bevy::core_pipeline::prepass::DepthPrepass, bevy::render::occlusion_culling::OcclusionCulling));
        // Each wall in two pieces, left and right of the aisle, 2.4 high (above the eye).
        let (left, right) = (aisle - 0.8 + spacing / 2.0, (side - 1) as f32 * spacing + spacing / 2.0 - aisle - 0.8);
        let gray = world.resource_mut::<Assets<StandardMaterial>>().add(Color::srgb(0.5, 0.5, 0.55));
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        let pieces = [(left, (left - spacing) / 2.0), (right, aisle + 0.8 + right / 2.0)]
            .map(|(width, x)| (meshes.add(Cuboid::new(width, 2.4, 0.3)), x));
        for row in (1..total.div_ceil(side).saturating_sub(1)).step_by(4) {
            let z = -(row as f32 + 0.5) * spacing;
            for (mesh, x) in &pieces {
                world.spawn((Mesh3d(mesh.clone()), MeshMaterial3d(gray.clone()), Transform::from_xyz(*x, 1.2, z)));
            }
        }
    }
    app.world_mut().resource_mut::<SkinletMeshletSettings>().occlusion_rounds = args.occlusion_rounds;
    common::update_until(&mut app, 100_000, "every instance bound", |w| {
        roots.iter().all(|&(e, _)| w.get::<SkinletInstance>(e).is_some())
    });
    let mut crossfades = common::Crossfades::start(app.world_mut(), &roots, &graphs);
    // Frames are read back only when compared.
    let readback = {
        let world = app.world_mut();
        let mut q = world.query::<(Entity, &Readback)>();
        let (e, r) = q.single(world).expect("the readback camera's target");
        (e, r.clone())
    };
    app.world_mut().entity_mut(readback.0).remove::<Readback>();
    // Both pipelines compiled before anything is timed.
    let ready = app.world().resource::<common::PipelinesReady>().clone();
    for pipeline in [Pipeline::Skinlet, Pipeline::Bevy] {
        set_pipeline(app.world_mut(), &roots, pipeline);
        let mut updates = 0;
        common::update_until(&mut app, 100_000, "the pipelines compiled", |_| {
            updates = if ready.0.load(std::sync::atomic::Ordering::Relaxed) { updates + 1 } else { 0 };
            updates >= 5
        });
    }

    let block_frames = args.block.max(1);
    let blocks = if args.pipeline == Pipelines::Both { 2 } else { 1 } * args.frames.div_ceil(block_frames);
    let warm = 3;
    let steps = blocks * (block_frames + warm);
    let compare_at: Vec<usize> = (0..args.compare).map(|k| (2 * k + 1) * blocks / (2 * args.compare)).collect();
    let depth = (total.div_ceil(side) - 1) as f32 * spacing;
    let mut timing = [Timing::default(), Timing::default()];
    let mut counts = Counts::default();
    let mut compared = Vec::new();
    let mut step = 0;
    for block in 0..blocks {
        let pipeline = match args.pipeline {
            Pipelines::Both if block % 2 == 0 => Pipeline::Bevy,
            Pipelines::Both | Pipelines::Skinlet => Pipeline::Skinlet,
            Pipelines::Bevy => Pipeline::Bevy,
        };
        if args.pipeline == Pipelines::Both && compare_at.contains(&block) {
            let picture = args.pictures.as_ref().map(|d| d.join(format!("meshlet_crowd_{}.png", compared.len())));
            let occlusion_camera = args.bevy_occlusion.then_some(camera);
            let readback = (readback.0, &readback.1);
            compared.push(compare(&mut app, &roots, readback, pipeline, (picture, args.width), occlusion_camera));
        }
        set_pipeline(app.world_mut(), &roots, pipeline);
        for f in 0..warm + block_frames {
            // The camera walks into the crowd at eye height between two columns, from in
            // front of it to halfway through, looking ahead and swaying left and right.
            let t = step as f32 / steps as f32;
            step += 1;
            let eye = Vec3::new(aisle, 1.6, 3.0 - t * (3.0 + depth / 2.0));
            let yaw = 0.6 * (t * std::f32::consts::TAU * 1.5).sin();
            let look = Vec3::new(-yaw.sin(), -0.15, -yaw.cos());
            *app.world_mut().get_mut::<Transform>(camera).unwrap() =
                Transform::from_translation(eye).looking_to(look, Vec3::Y);
            crossfades.advance(app.world_mut(), 1.0 / 30.0);
            spans.0.lock().unwrap().frames.clear();
            let t0 = Instant::now();
            app.update();
            let dt = t0.elapsed();
            if f < warm {
                continue;
            }
            let t = &mut timing[pipeline as usize];
            t.frames += 1;
            t.update += dt;
            let rendered = std::mem::take(&mut spans.0.lock().unwrap().frames);
            t.render += rendered.iter().map(|r| r.0).sum::<Duration>();
            t.graph += rendered.iter().map(|r| r.1).sum::<Duration>();
            t.render_frames += rendered.len();
            if pipeline == Pipeline::Skinlet {
                counts.add(&stats_now(&app));
            }
        }
    }

    let ms = |d: Duration, n: usize| d.as_secs_f64() * 1e3 / n.max(1) as f64;
    let cpu = |t: &Timing| {
        serde_json::json!({
            "frames": t.frames,
            "update_ms_per_frame": ms(t.update, t.frames),
            "render_schedule_ms_per_frame": ms(t.render, t.render_frames),
            // The render graph: encoding and submission (on a CPU Vulkan driver, also the
            // GPU's work).
            "render_graph_ms_per_frame": ms(t.graph, t.render_frames),
            // Everything else: the main world, extraction, preparation and queueing.
            "outside_render_graph_ms_per_frame": ms(t.update, t.frames) - ms(t.graph, t.render_frames),
        })
    };
    let moving = counts.per_frame();
    let equal = compared.iter().all(|c| c.equal_to_unculled);
    let max_diff = compared.iter().map(|c| c.max_diff).max();
    Some(serde_json::json!({
        "instances": total,
        "characters": characters.iter().map(|c| c.file.clone()).collect::<Vec<_>>(),
        "image": [args.width, args.height],
        "meshlets_total": moving["meshlets_total"],
        "meshlets_drawn": moving["meshlets_drawn"],
        // Bevy's opaque pass: one draw per bake, two with occlusion culling (its two lists);
        // before it, skinlet's own depth pass draws each round's two lists.
        "draws_issued": counts.sums.len() * if args.occlusion_rounds > 0 { 2 } else { 1 },
        "occlusion_rounds": args.occlusion_rounds,
        "bevy_occlusion": args.bevy_occlusion,
        "occlusion_depth_draws": counts.sums.len() * 2 * args.occlusion_rounds as usize,
        "max_pixel_diff_vs_bevy": max_diff,
        "equal_to_unculled": equal,
        "cpu": { "bevy": cpu(&timing[0]), "skinlet": cpu(&timing[1]) },
        "skinlet_per_moving_frame": moving,
        "compared": compared.iter().map(|c| serde_json::json!({
            "pixels": c.pixels,
            "drawn_by_bevy": c.drawn_by_bevy,
            "max_pixel_diff_vs_bevy": c.max_diff,
            "pixels_over_2_levels": c.over_2,
            "equal_to_unculled": c.equal_to_unculled,
            "bevy_occlusion_changed_pixels": c.bevy_occlusion_changed,
            // Whether skinlet's occlusion culling started from Bevy's depth (every bake).
            "bevy_occluders": c.stats.iter().all(|s| s.bevy_occluders),
            "meshlets_total": c.stats.iter().map(|s| s.meshlets_total).sum::<u64>(),
            "meshlets_tested_visible": c.stats.iter().map(|s| s.meshlets_tested_visible).sum::<u64>(),
            "meshlets_drawn": c.stats.iter().map(|s| s.meshlets_drawn).sum::<u64>(),
            "triangles_total": c.stats.iter().map(|s| s.triangles_total).sum::<u64>(),
            "triangles_drawn": c.stats.iter().map(|s| s.triangles_drawn).sum::<u64>(),
            // The room of the camera's lists, summed over the bakes (24 bytes a triangle).
            "list_triangles": c.stats.iter().map(|s| s.list_triangles as u64).sum::<u64>(),
        })).collect::<Vec<_>>(),
    }))
}

#[allow(dead_code)]
fn main() {
    let args = Args::parse();
    let Some(out) = run(&args) else {
        eprintln!("no shared assets or no Vulkan device: set SKINLET_ASSETS to the folder holding skinned/");
        std::process::exit(2);
    };
    if args.json {
        println!("{out}");
    } else {
        println!("{}", serde_json::to_string_pretty(&out).unwrap());
    }
}
