//! Shared by the Bevy tests: an asset folder with the characters and their bakes, a
//! headless Bevy app, and the ground truth: every vertex of a scene's mesh entities morphed
//! and skinned on the CPU (skinlet's reference skinning of the same glTF file) with the joint
//! matrices and morph weights Bevy's ECS holds that frame.
#![allow(dead_code)]

use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy_skinlet::gltf_tags::{GltfNodeIndex, GltfPrimitiveIndex};
use skinlet::Asset;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

#[path = "../../../skinlet/tests/common/mod.rs"]
mod shared;
pub use shared::{assets_dir, required};

/// One character in the test folder: its glTF file name, the asset, the bake's name.
pub struct Character {
    pub file: String,
    pub asset: Asset,
    pub character: skinlet::Character,
}

/// A folder under the test target directory holding `files` (from the shared assets, or
/// `@demo` for the demo character as `demo.glb`, `@demo-materials` for
/// [`demo_with_materials`] as `demo_materials.glb`), each with a bake beside it
/// (`NAME.skinlet`, baked as a default recipe bakes: skin-aware meshlets, every clip, an
/// envelope around the clips widened by 10°). `None` (with a note) without the shared assets, unless they are required.
pub fn asset_folder(name: &str, files: &[&str]) -> Option<(PathBuf, Vec<Character>)> {
    // Tests have a scratch folder under the target directory; examples use the system's.
    let scratch =
        option_env!("CARGO_TARGET_TMPDIR").map_or_else(|| std::env::temp_dir().join("bevy_skinlet"), PathBuf::from);
    let dir = scratch.join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let shared = assets_dir();
    let mut out = Vec::new();
    for &f in files {
        let (file, bytes) = if f == "@demo" {
            ("demo.glb".to_string(), demo_glb())
        } else if f == "@demo-materials" {
            ("demo_materials.glb".to_string(), demo_with_materials(&dir))
        } else {
            let Some(shared) = &shared else {
                if required("SKINLET_REQUIRE_ASSETS") {
                    panic!("no shared assets (SKINLET_REQUIRE_ASSETS=1)");
                }
                eprintln!("skipping: no shared assets");
                return None;
            };
            let path = shared.join(f);
            (path.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&path).unwrap())
        };
        std::fs::write(dir.join(&file), &bytes).unwrap();
        let asset = skinlet::import::load_bytes(&bytes, &dir.join(&file)).unwrap();
        let character = asset.character().unwrap();
        let stem = Path::new(&file).file_stem().unwrap().to_string_lossy().into_owned();
        let recipe = bevy_skinlet::bake_processor::BakeRecipe::new(file.clone());
        let baked = bevy_skinlet::bake_processor::bake_gltf(&bytes, Path::new(&file), &recipe).unwrap();
        std::fs::write(dir.join(format!("{stem}.skinlet")), baked).unwrap();
        out.push(Character { file, asset, character });
    }
    Some((dir, out))
}

/// The demo character (3,000 triangles) as a GLB file.
fn demo_glb() -> Vec<u8> {
    let params = skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() };
    skinlet::export::to_glb(&skinlet_lab::demo::demo_character(&params)).unwrap()
}

/// The demo character with materials, as exporters write them: the body double-sided with a
/// normal map at its second texture coordinates and a base colour texture at its first (two
/// sets projected from its positions apart; the one image, `demo_normal.png` written into
/// `dir`, a field of bumps), the other meshes single-sided; every fourth
/// triangle of every mesh turned around (from outside a back face: a hole in a single-sided
/// mesh, in the double-sided body a face drawn with its normal reversed).
pub fn demo_with_materials(dir: &Path) -> Vec<u8> {
    use serde_json::{Value, json};
    let glb = demo_glb();
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = word(12);
    let mut gltf: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let mut bin = glb[bin_at + 8..bin_at + 8 + word(bin_at)].to_vec();
    // An accessor's first byte in the buffer and its count (tightly packed views).
    let place = |gltf: &Value, a: &Value| {
        let accessor = &gltf["accessors"][a.as_u64().unwrap() as usize];
        let view = &gltf["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
        assert!(view.get("byteStride").is_none());
        let at = view["byteOffset"].as_u64().unwrap_or(0) + accessor["byteOffset"].as_u64().unwrap_or(0);
        (at as usize, accessor["count"].as_u64().unwrap() as usize, accessor["componentType"].as_u64().unwrap())
    };
    let f32_at = |bin: &[u8], at: usize| f32::from_le_bytes(bin[at..at + 4].try_into().unwrap());
    for m in 0..gltf["meshes"].as_array().unwrap().len() {
        for p in 0..gltf["meshes"][m]["primitives"].as_array().unwrap().len() {
            let primitive = gltf["meshes"][m]["primitives"][p].clone();
            let (at, count, kind) = place(&gltf, &primitive["indices"]);
            assert_eq!(kind, 5125, "32-bit indices");
            for t in (0..count / 3).step_by(4) {
                let (b, c) = (at + 12 * t + 4, at + 12 * t + 8);
                for k in 0..4 {
                    bin.swap(b + k, c + k);
                }
            }
            gltf["meshes"][m]["primitives"][p]["material"] = json!(if m == 0 { 0 } else { 1 });
            if m == 0 {
                // Two sets of texture coordinates, each from the vertex's x and y.
                let (at, vertices, _) = place(&gltf, &primitive["attributes"]["POSITION"]);
                for (set, uv) in [|x: f32, y: f32| [3.0 * x + 0.5, 3.0 * y], |x: f32, y: f32| [2.0 * y + 0.25, 2.0 * x]]
                    .iter()
                    .enumerate()
                {
                    let offset = bin.len().next_multiple_of(4);
                    bin.resize(offset, 0);
                    for v in 0..vertices {
                        let (x, y) = (f32_at(&bin, at + 12 * v), f32_at(&bin, at + 12 * v + 4));
                        bin.extend(uv(x, y).iter().flat_map(|c| c.to_le_bytes()));
                    }
                    let views = gltf["bufferViews"].as_array_mut().unwrap();
                    views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 8 * vertices}));
                    let view = views.len() - 1;
                    let accessors = gltf["accessors"].as_array_mut().unwrap();
                    let accessor =
                        json!({"bufferView": view, "componentType": 5126, "count": vertices, "type": "VEC2"});
                    accessors.push(accessor);
                    let name = format!("TEXCOORD_{set}");
                    gltf["meshes"][m]["primitives"][p]["attributes"][name] = json!(accessors.len() - 1);
                }
            }
        }
    }
    gltf["buffers"][0]["byteLength"] = json!(bin.len());
    gltf["materials"] = json!([
        {
            "name": "two-sided, normal-mapped",
            "doubleSided": true,
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.9, 0.6, 0.4, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5,
                "baseColorTexture": {"index": 1}
            },
            "normalTexture": {"index": 0, "texCoord": 1}
        },
        {"name": "one-sided", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.5, 0.9, 1.0]}}
    ]);
    // The normal map's image is the base colour's too (sampled at the first coordinates).
    gltf["textures"] = json!([{"source": 0, "sampler": 0}, {"source": 0, "sampler": 0}]);
    gltf["samplers"] = json!([{}]);
    gltf["images"] = json!([{"uri": "demo_normal.png"}]);
    // The normal map: bumps h = sin(2π·4u)·sin(2π·4v), normals (−∂h/∂u, −∂h/∂v, 1) / 4.
    const SIZE: usize = 64;
    let tau = std::f32::consts::TAU;
    let texels: Vec<u8> = (0..SIZE * SIZE)
        .flat_map(|i| {
            let (u, v) = ((i % SIZE) as f32 / SIZE as f32, (i / SIZE) as f32 / SIZE as f32);
            let du = 4.0 * tau * (4.0 * tau * u).cos() * (4.0 * tau * v).sin() / 4.0 / 8.0;
            let dv = 4.0 * tau * (4.0 * tau * u).sin() * (4.0 * tau * v).cos() / 4.0 / 8.0;
            let n = Vec3::new(-du, -dv, 1.0).normalize();
            n.to_array().map(|c| ((c * 0.5 + 0.5) * 255.0).round() as u8)
        })
        .collect();
    let file = std::io::BufWriter::new(std::fs::File::create(dir.join("demo_normal.png")).unwrap());
    let mut encoder = png::Encoder::new(file, SIZE as u32, SIZE as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.write_header().unwrap().write_image_data(&texels).unwrap();
    // The file again: header, JSON chunk (padded with spaces), binary chunk (with zeros).
    let mut json = serde_json::to_vec(&gltf).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut out = Vec::with_capacity(28 + json.len() + bin.len());
    out.extend(b"glTF".iter().chain(&2u32.to_le_bytes()).chain(&((28 + json.len() + bin.len()) as u32).to_le_bytes()));
    out.extend((json.len() as u32).to_le_bytes().iter().chain(b"JSON").chain(&json));
    out.extend((bin.len() as u32).to_le_bytes().iter().chain(b"BIN\0").chain(&bin));
    out
}

/// A headless app (no window) reading assets from `dir`, with skinlet's plugin and a fixed
/// 1/30 s step. `render`: Bevy's renderer on the machine's Vulkan device (lavapipe on CPU-only
/// machines); otherwise no GPU is touched.
pub fn app(dir: &Path, render: bool) -> App {
    // Where Bevy's processor would write (the `bake` feature turns it on): beside the folder.
    let processed = format!("{}-processed", dir.display());
    app_with(
        AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            processed_file_path: processed,
            ..Default::default()
        },
        render,
    )
}

/// [`app`] with Bevy's asset settings given (e.g. asset processing on).
pub fn app_with(assets: AssetPlugin, render: bool) -> App {
    let mut app = App::new();
    let plugins = DefaultPlugins.set(assets).set(bevy::window::WindowPlugin {
        primary_window: None,
        exit_condition: bevy::window::ExitCondition::DontExit,
        ..Default::default()
    });
    if render {
        app.add_plugins(plugins);
    } else {
        // Bevy's renderer with no device: nothing is drawn, every main-world system runs.
        app.add_plugins(plugins.set(bevy::render::RenderPlugin {
            render_creation: bevy::render::settings::WgpuSettings { backends: None, ..Default::default() }.into(),
            ..Default::default()
        }));
        // What the renderer would say of compressed textures without a device: none.
        app.insert_resource(bevy::image::CompressedImageFormatSupport(bevy::image::CompressedImageFormats::NONE));
    }
    app.add_plugins(bevy_skinlet::SkinletPlugin::default());
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(std::time::Duration::from_secs_f64(1.0 / 30.0)));
    app
}

/// Finishes building `app`'s plugins as `App::run` would (the renderer's device is made
/// asynchronously; `finish` registers, among others, Bevy's image loader), once.
pub fn start(app: &mut App) {
    use bevy::app::PluginsState;
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    if app.plugins_state() == PluginsState::Ready {
        app.finish();
        app.cleanup();
    }
}

/// Spawns `characters` in rows, row `c` (character `c`, each scaled to about 1.6 units across)
/// at depth `z[c]`, `per_row` instances 1.4 apart centered on x = 0, each turned its own way,
/// every one with its bake (`NAME.skinlet` beside the file); returns (scene root, character).
pub fn spawn_rows(world: &mut World, characters: &[Character], z: &[f32], per_row: usize) -> Vec<(Entity, usize)> {
    let assets = world.resource::<AssetServer>().clone();
    let mut roots = Vec::new();
    for (c, (character, &z)) in characters.iter().zip(z).enumerate() {
        let scale = 1.6 / rest_size(character);
        let stem = character.file.rsplit_once('.').unwrap().0.to_string();
        let bake: Handle<bevy_skinlet::Bake> = assets.load(format!("{stem}.skinlet"));
        let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(character.file.clone()));
        for k in 0..per_row {
            let at = Transform::from_xyz(1.4 * k as f32 - 0.7 * (per_row - 1) as f32, 0.0, z)
                .with_rotation(Quat::from_rotation_y(0.9 * (k + c) as f32))
                .with_scale(Vec3::splat(scale));
            let root = world.spawn((WorldAssetRoot(scene.clone()), bevy_skinlet::SkinletBounds(bake.clone()), at));
            roots.push((root.id(), c));
        }
    }
    roots
}

/// The images read back from [`readback_camera`]'s target, every frame.
#[derive(Resource, Clone, Default)]
pub struct Frames(pub Arc<Mutex<Vec<Vec<u8>>>>);

/// Whether every pipeline of the render world is compiled (set by a render-world system that
/// [`watch_pipelines`] adds: the render app may run on its own thread).
#[derive(Resource, Clone, Default)]
pub struct PipelinesReady(pub Arc<AtomicBool>);

/// Makes [`settled_image`] wait for every pipeline to compile (pipelines compile
/// asynchronously: frames can repeat while one is still missing).
pub fn watch_pipelines(app: &mut App) {
    use bevy::render::render_resource::{CachedPipelineState, PipelineCache};
    use bevy::render::{Render, RenderApp, RenderSystems};
    fn report(cache: Res<PipelineCache>, ready: Res<PipelinesReady>) {
        let all = cache.waiting_pipelines().next().is_none()
            && cache.pipelines().all(|p| matches!(p.state, CachedPipelineState::Ok(_)));
        ready.0.store(all, Ordering::Relaxed);
    }
    let ready = PipelinesReady::default();
    app.insert_resource(ready.clone());
    app.sub_app_mut(RenderApp).insert_resource(ready).add_systems(Render, report.in_set(RenderSystems::Cleanup));
}

/// Spawns a camera (tonemapping and MSAA off) at `at` drawing into a `width` × `height` RGBA8
/// image read back into [`Frames`] every frame, and a directional light; returns the camera.
pub fn readback_camera(world: &mut World, width: u32, height: u32, at: Transform) -> Entity {
    world.spawn((DirectionalLight::default(), Transform::from_xyz(3.0, 8.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y)));
    let frames = world.get_resource_or_init::<Frames>().clone();
    camera_read_into(world, width, height, at, frames)
}

/// A camera at `at` rendering a `width` × `height` image, each frame read back into `frames`.
pub fn camera_read_into(world: &mut World, width: u32, height: u32, at: Transform, frames: Frames) -> Entity {
    use bevy::camera::RenderTarget;
    use bevy::render::gpu_readback::{Readback, ReadbackComplete};
    use bevy::render::render_resource::{TextureFormat, TextureUsages};
    let mut target = Image::new_target_texture(width, height, TextureFormat::Rgba8UnormSrgb, None);
    target.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    let target = world.resource_mut::<Assets<Image>>().add(target);
    let camera = world
        .spawn((
            Camera3d::default(),
            RenderTarget::Image(target.clone().into()),
            bevy::core_pipeline::tonemapping::Tonemapping::None,
            Msaa::Off,
            at,
        ))
        .id();
    world.spawn(Readback::texture(target)).observe(move |event: On<ReadbackComplete>| {
        frames.0.lock().unwrap().push(event.data.clone());
    });
    camera
}

/// Updates until three images in a row are equal and drawn (not one color: while Bevy still
/// compiles pipelines, frames are blank), and every pipeline has been compiled for five
/// updates where [`watch_pipelines`] watches them; returns that image.
pub fn settled_image(app: &mut App) -> Vec<u8> {
    let frames = app.world().resource::<Frames>().clone();
    let ready = app.world().get_resource::<PipelinesReady>().cloned();
    frames.0.lock().unwrap().clear();
    let mut ready_updates = 0;
    for _ in 0..2000 {
        app.update();
        let now = ready.as_ref().is_none_or(|r| r.0.load(Ordering::Relaxed));
        ready_updates = if now { ready_updates + 1 } else { 0 };
        let got = frames.0.lock().unwrap();
        if ready_updates >= 5
            && let [.., a, b, c] = &got[..]
            && got.len() >= 6
            && a == b
            && b == c
            && c.chunks(4).any(|p| p != &c[..4])
        {
            return c.clone();
        }
    }
    let got = frames.0.lock().unwrap();
    let n = got.len();
    let equal = n >= 2 && got[n - 1] == got[n - 2];
    let drawn = got.last().is_some_and(|c| c.chunks(4).any(|p| p != &c[..4]));
    panic!(
        "the image did not settle: {n} images read back, the last two equal: {equal}, the last drawn: {drawn}, pipelines ready for {ready_updates} updates"
    );
}

/// Plays on the animation player under `root` the clips `pick` chooses (node and weight, each
/// repeating) from a graph of every clip of `character`'s file; nothing for a file without
/// clips.
pub fn play_clips(
    world: &mut World,
    root: Entity,
    character: &Character,
    pick: impl FnOnce(
        &[bevy::animation::graph::AnimationNodeIndex],
    ) -> Vec<(bevy::animation::graph::AnimationNodeIndex, f32)>,
) {
    use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle};
    let assets = world.resource::<AssetServer>().clone();
    let clips: Vec<Handle<AnimationClip>> = (0..character.asset.clips.len())
        .map(|k| assets.load(GltfAssetLabel::Animation(k).from_asset(character.file.clone())))
        .collect();
    if clips.is_empty() {
        return;
    }
    let (graph, nodes) = AnimationGraph::from_clips(clips);
    let graph = world.resource_mut::<Assets<AnimationGraph>>().add(graph);
    let mut players = world.query_filtered::<Entity, With<AnimationPlayer>>();
    let descendants: Vec<Entity> = world.query::<&Children>().query(world).iter_descendants(root).collect();
    let player = descendants.into_iter().find(|&d| players.get(world, d).is_ok()).unwrap();
    let mut p = world.get_mut::<AnimationPlayer>(player).unwrap();
    for (node, weight) in pick(&nodes) {
        p.play(node).repeat().set_weight(weight);
    }
    world.entity_mut(player).insert(AnimationGraphHandle(graph));
}

/// One animation graph per character holding every clip of its file (made before the scenes
/// are spawned: the graphs keep the clips loaded; a clip asked for after its handles were
/// dropped reloads the whole file, and its scenes are spawned again).
pub fn clip_graphs(
    world: &mut World,
    characters: &[Character],
) -> Vec<(Handle<bevy::animation::graph::AnimationGraph>, Vec<bevy::animation::graph::AnimationNodeIndex>)> {
    use bevy::animation::graph::AnimationGraph;
    let assets = world.resource::<AssetServer>().clone();
    (characters.iter())
        .map(|c| {
            let clips =
                (0..c.asset.clips.len()).map(|k| assets.load(GltfAssetLabel::Animation(k).from_asset(c.file.clone())));
            let (graph, nodes) = AnimationGraph::from_clips(clips);
            (world.resource_mut::<Assets<AnimationGraph>>().add(graph), nodes)
        })
        .collect()
}

/// Scene instances playing their file's clips: instance `i` starts clip `i` (mod the clips)
/// at its own phase and crossfades (0.6 s) to the next clip every 1.5–3.9 s.
pub struct Crossfades {
    /// Per instance: its animation player, its clips, seconds between changes, the next change.
    players: Vec<(Entity, Vec<bevy::animation::graph::AnimationNodeIndex>, f32, f32)>,
    time: f32,
}

impl Crossfades {
    /// Starts the clips of `graphs[c]` (from [`clip_graphs`]) under each bound root `(root, c)`.
    pub fn start(
        world: &mut World,
        roots: &[(Entity, usize)],
        graphs: &[(Handle<bevy::animation::graph::AnimationGraph>, Vec<bevy::animation::graph::AnimationNodeIndex>)],
    ) -> Crossfades {
        use bevy::animation::graph::AnimationGraphHandle;
        use bevy::animation::transition::AnimationTransitions;
        let mut players = world.query_filtered::<Entity, With<AnimationPlayer>>();
        let mut out = Vec::with_capacity(roots.len());
        for (i, &(root, c)) in roots.iter().enumerate() {
            let (graph, clips) = graphs[c].clone();
            if clips.is_empty() {
                continue;
            }
            let descendants: Vec<Entity> = world.query::<&Children>().query(world).iter_descendants(root).collect();
            let player = descendants.into_iter().find(|&d| players.get(world, d).is_ok()).expect("an animation player");
            let mut transitions = AnimationTransitions::new();
            let mut p = world.get_mut::<AnimationPlayer>(player).unwrap();
            let first = clips[i % clips.len()];
            transitions.play(&mut p, first, std::time::Duration::ZERO).repeat().seek_to(0.37 * i as f32 % 1.0);
            world.entity_mut(player).insert((AnimationGraphHandle(graph), transitions));
            let period = 1.5 + (i % 7) as f32 * 0.4;
            out.push((player, clips, period, period));
        }
        Crossfades { players: out, time: 0.0 }
    }

    /// Moves on by `seconds`: the instances whose period is up start crossfading.
    pub fn advance(&mut self, world: &mut World, seconds: f32) {
        use bevy::animation::transition::AnimationTransitions;
        self.time += seconds;
        for (player, clips, period, next) in &mut self.players {
            if self.time < *next || clips.len() < 2 {
                continue;
            }
            *next += *period;
            let mut entity = world.entity_mut(*player);
            let mut transitions = entity.take::<AnimationTransitions>().unwrap();
            let mut p = entity.get_mut::<AnimationPlayer>().unwrap();
            let current = transitions.get_main_animation().unwrap();
            let k = clips.iter().position(|&n| n == current).unwrap();
            let to = clips[(k + 1) % clips.len()];
            transitions.play(&mut p, to, std::time::Duration::from_millis(600)).repeat();
            entity.insert(transitions);
        }
    }
}

/// Writes an RGBA8 image `width` pixels wide as a PNG.
pub fn write_png(path: &Path, rgba: &[u8], width: u32) {
    let height = (rgba.len() / 4) as u32 / width;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(std::fs::File::create(path).unwrap()), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header().unwrap().write_image_data(rgba).unwrap();
}

/// Per pixel of two RGBA8 images of one size, the largest difference of a color channel.
pub fn pixel_differences(a: &[u8], b: &[u8]) -> Vec<u8> {
    (a.chunks(4).zip(b.chunks(4))).map(|(a, b)| (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap()).collect()
}

/// The pixels of two RGBA images that are not exactly equal.
pub fn differing_pixels(a: &[u8], b: &[u8]) -> usize {
    a.chunks(4).zip(b.chunks(4)).filter(|(a, b)| a != b).count()
}

/// Pixel differences as a gray RGBA8 image, × 8.
pub fn difference_image(differences: &[u8]) -> Vec<u8> {
    differences.iter().flat_map(|&d| [d.saturating_mul(8), d.saturating_mul(8), d.saturating_mul(8), 255]).collect()
}

/// RGBA8 images `width` pixels wide, side by side in one image.
pub fn side_by_side(images: &[&[u8]], width: u32) -> Vec<u8> {
    let row = 4 * width as usize;
    let height = images.first().map_or(0, |i| i.len() / row);
    (0..height).flat_map(|y| images.iter().flat_map(move |img| img[y * row..(y + 1) * row].iter().copied())).collect()
}

/// Pixels of an RGBA8 image that are not its most common color (the clear color, where the
/// scene leaves most of the frame empty).
pub fn drawn_pixels(rgba: &[u8]) -> usize {
    let mut counts = std::collections::HashMap::<&[u8], usize>::new();
    for p in rgba.chunks(4) {
        *counts.entry(p).or_default() += 1;
    }
    rgba.len() / 4 - counts.values().max().copied().unwrap_or(0)
}

/// Updates `app` until `done` holds (at most `limit` updates; panics past it with `what`).
pub fn update_until(app: &mut App, limit: usize, what: &str, mut done: impl FnMut(&mut World) -> bool) {
    start(app);
    for _ in 0..limit {
        app.update();
        if done(app.world_mut()) {
            return;
        }
    }
    panic!("{what}: not after {limit} updates");
}

/// The descendants of `root` tagged with a glTF node index, by index.
pub fn node_entities(world: &mut World, root: Entity) -> Vec<Option<Entity>> {
    let mut q = world.query::<(Entity, &GltfNodeIndex)>();
    let mut children = world.query::<&Children>();
    let descendants: Vec<Entity> = children.query(world).iter_descendants(root).collect();
    let mut out = Vec::new();
    for e in descendants {
        if let Ok((e, n)) = q.get(world, e) {
            let i = n.index as usize;
            if out.len() <= i {
                out.resize(i + 1, None);
            }
            out[i] = Some(e);
        }
    }
    out
}

/// The entity drawing part `part` of `c` (its node's child with the part's mesh primitive).
pub fn part_entity(world: &mut World, nodes: &[Option<Entity>], part: &skinlet::Part) -> Entity {
    let node = nodes[part.node as usize].expect("the part's node is in the scene");
    let children: Vec<Entity> = world.get::<Children>(node).unwrap().iter().collect();
    *children
        .iter()
        .find(|&&c| {
            world.get::<GltfPrimitiveIndex>(c).is_some_and(|p| (p.mesh, p.primitive) == (part.mesh, part.primitive))
        })
        .expect("the part's primitive is drawn")
}

/// Every vertex of `c`, morphed and skinned on the CPU with the joint matrices (each driver
/// node's `GlobalTransform` times its inverse bind matrix) and morph weights (`MorphWeights`
/// of the weight's node, else its default) Bevy's ECS holds now: world space.
pub fn skinned_from_ecs(world: &World, c: &Character, nodes: &[Option<Entity>]) -> Vec<Vec3> {
    let palette = &c.character.palette;
    let skinning: Vec<Affine3A> = (palette.joints.iter().zip(&palette.inverse_bind))
        .map(|(&n, ibm)| {
            let g = nodes[n as usize].and_then(|e| world.get::<GlobalTransform>(e)).expect("a driver's transform");
            Affine3A::from_mat4((g.to_matrix().as_dmat4() * ibm.as_dmat4()).as_mat4())
        })
        .collect();
    let mesh = &c.character.mesh;
    let weights: Vec<f32> = (mesh.morphs.weights.iter())
        .map(|w| {
            let m = nodes
                .get(w.node as usize)
                .copied()
                .flatten()
                .and_then(|e| world.get::<bevy::mesh::morph::MorphWeights>(e));
            m.and_then(|m| m.weights().get(w.target as usize).copied()).unwrap_or(w.default)
        })
        .collect();
    let mut out = vec![Vec3::ZERO; mesh.positions.len()];
    skinlet::skinning::skin_mesh(mesh, &weights, &skinning, &mut out, &mut []).unwrap();
    out
}

/// Whether a Vulkan adapter is there for Bevy's renderer (lavapipe on CPU-only machines);
/// without one the rendering tests skip with a note, unless `SKINLET_REQUIRE_GPU=1` (CI).
pub fn vulkan_available() -> bool {
    match skinlet_lab::headless::gpu(skinlet_lab::headless::GpuOptions {
        software: false,
        no_mesh_shaders: true,
        no_subgroups: true,
    }) {
        Ok(_) => true,
        Err(e) if required("SKINLET_REQUIRE_GPU") => panic!("{e} (SKINLET_REQUIRE_GPU=1)"),
        Err(e) => {
            eprintln!("skipping: {e}");
            false
        }
    }
}

/// The character's size at rest: the largest extent of its vertices' box (scene space).
pub fn rest_size(c: &Character) -> f32 {
    let (positions, _) = c.character.posed(&c.asset.skeleton, None, 0.0).unwrap();
    let (lo, hi) = positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    (hi - lo).max_element()
}
