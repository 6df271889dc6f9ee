//! Many skinned and morphing characters in one Bevy app, like Bevy's `many_foxes`: 1,000 Fox,
//! 100 MorphStressTest and 100 Xbot (the shared assets) play their clips and crossfade between
//! them while a camera moves through the crowd, headless. Every frame, after Bevy's update,
//! both kinds of per-entity box are computed for every mesh entity, on one thread, in
//! alternating order: skinlet's (`bevy_skinlet::instance::update_instance`) and Bevy's own
//! (`entity_aabb_from_skinned_mesh_bounds`, what `DynamicSkinnedMeshBounds` runs; the mesh's
//! box for entities that are not skinned). Each box is culled against the camera's frustum
//! with Bevy's own test, and every culled entity is checked: a false cull is a mesh entity
//! culled while a vertex of it, morphed and skinned on the CPU from the joint matrices and
//! morph weights in Bevy's ECS that frame, lies inside the frustum.
//!
//! ```sh
//! cargo run --release -p bevy_skinlet --example many_characters -- --json
//! ```
//!
//! The characters and their bakes (skin-aware meshlets, every clip, an envelope 10° around
//! the clips) are written to a scratch folder first, from `../shared/assets` (or
//! `$SKINLET_ASSETS`).

#[path = "../tests/common/mod.rs"]
mod common;

use bevy::camera::primitives::{Aabb, Frustum, MeshAabb, Sphere};
use bevy::ecs::system::SystemState;
use bevy::math::{Affine3A, Vec3A};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes, entity_aabb_from_skinned_mesh_bounds};
use bevy::prelude::*;
use bevy_skinlet::instance::{PoseInputs, update_instance};
use bevy_skinlet::{Bake, BakeSettings, SkinletBounds, SkinletInstance};
use clap::Parser;
use skinlet_runtime::part_bounds::PoseBounds;
use std::time::{Duration, Instant};

/// A crowd of skinned and morphing characters: skinlet's per-entity bounds against Bevy's,
/// same app, same frames.
#[derive(Parser)]
struct Args {
    /// Fox instances (skinned, 3 clips).
    #[arg(long, default_value_t = 1000)]
    foxes: usize,
    /// MorphStressTest instances (morph targets only, 3 clips).
    #[arg(long, default_value_t = 100)]
    morphs: usize,
    /// Xbot instances (skinned, 2 meshes, 7 clips).
    #[arg(long, default_value_t = 100)]
    xbots: usize,
    /// Frames measured (at 30 frames per second of animation), after the crowd is loaded.
    #[arg(long, default_value_t = 240)]
    frames: usize,
    /// Load the bakes unpruned (`BakeSettings { prune: false }`): clip and envelope bounds
    /// are used wherever they hold, also where they are no tighter than the any-pose boxes.
    #[arg(long)]
    keep_all_bounds: bool,
    /// One JSON object on standard output instead of a summary.
    #[arg(long)]
    json: bool,
}

/// What the measurement reads of the world after each update.
type Measured = (
    Query<'static, 'static, &'static mut SkinletInstance>,
    Res<'static, Assets<Bake>>,
    PoseInputs<'static, 'static>,
    Query<'static, 'static, &'static SkinletBounds>,
    Res<'static, Assets<Mesh>>,
    Res<'static, Assets<SkinnedMeshInverseBindposes>>,
    Query<'static, 'static, (&'static Mesh3d, Option<&'static SkinnedMesh>)>,
);

/// One character instance: its scene root, which file, and its node entities by glTF index.
struct Instance {
    root: Entity,
    character: usize,
    nodes: Vec<Option<Entity>>,
}

/// Per frame and entity, what each method decided.
#[derive(Default)]
struct Tally {
    entity_frames: usize,
    skinlet_culled: usize,
    bevy_culled: usize,
    skinlet_false: usize,
    bevy_false: usize,
    skinlet_time: Duration,
    bevy_time: Duration,
    frames: usize,
}

/// Bevy's CPU frustum test (`check_visibility`): a sphere around the box first, then the
/// oriented box; the far plane is not tested. True when the entity is culled.
fn culled(frustum: &Frustum, aabb: &Aabb, world_from_local: &Affine3A, transform: &GlobalTransform) -> bool {
    let sphere = Sphere {
        center: world_from_local.transform_point3a(aabb.center),
        radius: transform.radius_vec3a(aabb.half_extents),
    };
    !frustum.intersects_sphere(&sphere, false) || !frustum.intersects_obb(aabb, world_from_local, true, false)
}

/// Whether a world-space point is strictly inside every plane Bevy tests (not the far one).
fn inside(frustum: &Frustum, p: Vec3) -> bool {
    let p = Vec3A::from(p).extend(1.0);
    frustum.half_spaces[..5].iter().all(|h| h.normal_d().dot(p) > 0.0)
}

fn main() {
    let args = Args::parse();
    let files = ["skinned/Fox.glb", "morph/MorphStressTest.gltf", "skinned/Xbot.glb"];
    let Some((dir, characters)) = common::asset_folder("many_characters", &files) else {
        eprintln!("no shared assets: set SKINLET_ASSETS to the folder holding skinned/ and morph/");
        std::process::exit(2);
    };
    let mut app = common::app(&dir, false);

    // The crowd on a grid, each character scaled to a plausible size, facing random ways.
    let counts = [args.foxes, args.morphs, args.xbots];
    let heights = [0.8, 1.0, 1.8];
    let total: usize = counts.iter().sum();
    let side = (total as f32).sqrt().ceil() as usize;
    let spacing = 2.0;
    let mut order: Vec<usize> = (0..3).flat_map(|c| std::iter::repeat_n(c, counts[c])).collect();
    // Interleave the kinds deterministically (a fixed-stride shuffle).
    let stride = (0..).map(|k| 7919 + k).find(|s| gcd(*s, total.max(1)) == 1).unwrap();
    order = (0..total).map(|i| order[(i * stride) % total]).collect();
    let mut roots = Vec::with_capacity(total);
    let camera;
    // One animation graph per file, made first (it keeps the clips loaded).
    let graphs = common::clip_graphs(app.world_mut(), &characters);
    {
        let world = app.world_mut();
        let assets = world.resource::<AssetServer>().clone();
        let handles: Vec<(Handle<WorldAsset>, Handle<Bake>, f32)> = characters
            .iter()
            .zip(heights)
            .map(|(c, h)| {
                let stem = c.file.rsplit_once('.').unwrap().0.to_string();
                let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(c.file.clone()));
                let settings = BakeSettings { prune: !args.keep_all_bounds };
                let bake = assets.load_builder().with_settings(move |s: &mut BakeSettings| *s = settings);
                (scene, bake.load(format!("{stem}.skinlet")), h / common::rest_size(c))
            })
            .collect();
        for (i, &c) in order.iter().enumerate() {
            let (x, z) = ((i % side) as f32 * spacing, (i / side) as f32 * spacing);
            let at = Transform::from_xyz(x, 0.0, -z)
                .with_rotation(Quat::from_rotation_y(i as f32 * 2.4))
                .with_scale(Vec3::splat(handles[c].2));
            roots.push((
                world.spawn((WorldAssetRoot(handles[c].0.clone()), SkinletBounds(handles[c].1.clone()), at)).id(),
                c,
            ));
        }
        camera = world.spawn((Camera3d::default(), Transform::default())).id();
    }
    common::update_until(&mut app, 100_000, "every instance bound", |w| {
        roots
            .iter()
            .all(|&(e, _)| w.get::<SkinletInstance>(e).is_some() || w.get::<bevy_skinlet::SkinletError>(e).is_some())
    });
    if let Some(e) = roots.iter().find_map(|&(e, _)| app.world().get::<bevy_skinlet::SkinletError>(e)) {
        eprintln!("{}", e.0);
        std::process::exit(1);
    }

    // Every instance starts a clip at its own phase.
    let mut crossfades = common::Crossfades::start(app.world_mut(), &roots, &graphs);
    let instances: Vec<Instance> = (roots.iter())
        .map(|&(root, character)| Instance { root, character, nodes: common::node_entities(app.world_mut(), root) })
        .collect();

    let mut state: SystemState<Measured> = SystemState::new(app.world_mut());
    // Bevy computes an unskinned mesh's box once, when the mesh is added: so does the
    // measurement, before timing.
    let mesh_boxes: bevy::platform::collections::HashMap<Entity, Aabb> = {
        let (skinlet_instances, _, _, _, meshes, _, drawn) = state.get_mut(app.world_mut()).unwrap();
        (instances.iter())
            .flat_map(|inst| skinlet_instances.get(inst.root).unwrap().part_entities().iter().copied())
            .filter_map(|e| {
                let (mesh3d, skinned) = drawn.get(e).unwrap();
                skinned.is_none().then(|| (e, meshes.get(mesh3d).unwrap().compute_aabb().unwrap()))
            })
            .collect()
    };
    let mut tally = Tally::default();
    // Per character file: (skinlet's false culls, Bevy's).
    let mut false_by_file = vec![(0usize, 0usize); characters.len()];
    let (mut skinlet_boxes, mut bevy_boxes): (Vec<(Entity, Aabb)>, Vec<Aabb>) = (Vec::new(), Vec::new());
    let (mut entities, mut parts): (Vec<Entity>, Vec<usize>) = (Vec::new(), Vec::new());
    // Instance frames per kind of bounds skinlet used: any pose, clips, clip windows, envelope.
    let mut poses = [0usize; 4];
    for frame in 0..args.frames {
        // Crossfade to the next clip (0.6 s) when an instance's period is up.
        crossfades.advance(app.world_mut(), 1.0 / 30.0);
        // The camera walks through the crowd at eye height, turning slowly.
        let t = frame as f32 / args.frames.max(1) as f32;
        let extent = side as f32 * spacing;
        let eye = Vec3::new(extent * (0.2 + 0.6 * t), 1.6, -extent * (0.1 + 0.7 * t));
        let look = Vec3::new((t * 9.0).sin(), -0.1, -(t * 9.0).cos());
        {
            let world = app.world_mut();
            *world.get_mut::<Transform>(camera).unwrap() = Transform::from_translation(eye).looking_to(look, Vec3::Y);
        }
        app.update();

        // Both methods' boxes, one thread, alternating which goes first.
        let world = app.world_mut();
        {
            let (mut skinlet_instances, bakes, inputs, bounds, meshes, bindposes, drawn) =
                state.get_mut(world).unwrap();
            // The mesh entities, in skinlet's order.
            entities.clear();
            for inst in &instances {
                entities.extend_from_slice(skinlet_instances.get(inst.root).unwrap().part_entities());
            }
            let mut run_skinlet = |out: &mut Vec<(Entity, Aabb)>, parts: &mut Vec<usize>| {
                out.clear();
                parts.clear();
                for inst in &instances {
                    let mut si = skinlet_instances.get_mut(inst.root).unwrap();
                    let bake = bakes.get(&bounds.get(inst.root).unwrap().0).unwrap();
                    let before = out.len();
                    update_instance(&mut si, bake, &inputs, |e, aabb| out.push((e, aabb)));
                    parts.push(out.len() - before);
                }
            };
            let run_bevy = |entities: &[Entity], out: &mut Vec<Aabb>| {
                out.clear();
                for &e in entities {
                    let (mesh3d, skinned) = drawn.get(e).unwrap();
                    let aabb = match skinned {
                        Some(skinned) => {
                            let mesh = meshes.get(mesh3d).unwrap();
                            let ibp = bindposes.get(&skinned.inverse_bindposes).unwrap();
                            let g = &inputs.globals;
                            entity_aabb_from_skinned_mesh_bounds(g, mesh, skinned, ibp, g.get(e).ok()).unwrap().into()
                        }
                        None => mesh_boxes[&e],
                    };
                    out.push(aabb);
                }
            };
            let t0 = Instant::now();
            if frame % 2 == 0 {
                run_skinlet(&mut skinlet_boxes, &mut parts);
                let t1 = Instant::now();
                run_bevy(&entities, &mut bevy_boxes);
                tally.skinlet_time += t1 - t0;
                tally.bevy_time += t1.elapsed();
            } else {
                run_bevy(&entities, &mut bevy_boxes);
                let t1 = Instant::now();
                run_skinlet(&mut skinlet_boxes, &mut parts);
                tally.bevy_time += t1 - t0;
                tally.skinlet_time += t1.elapsed();
            }
            for inst in &instances {
                poses[match skinlet_instances.get(inst.root).unwrap().pose {
                    PoseBounds::Any => 0,
                    PoseBounds::Clips => 1,
                    PoseBounds::ClipAt { .. } => 2,
                    PoseBounds::Envelope => 3,
                }] += 1;
            }
        }
        tally.frames += 1;

        // Culling with Bevy's test, and every culled entity checked against its vertices.
        let world = app.world();
        let frustum = *world.get::<Frustum>(camera).unwrap();
        let mut j = 0;
        for (inst, &count) in instances.iter().zip(&parts) {
            let mut decisions = Vec::with_capacity(count);
            for (&(e, ours), bevys) in skinlet_boxes[j..j + count].iter().zip(&bevy_boxes[j..j + count]) {
                let g = world.get::<GlobalTransform>(e).unwrap();
                let affine = g.affine();
                decisions.push((culled(&frustum, &ours, &affine, g), culled(&frustum, bevys, &affine, g)));
            }
            j += count;
            tally.entity_frames += count;
            tally.skinlet_culled += decisions.iter().filter(|d| d.0).count();
            tally.bevy_culled += decisions.iter().filter(|d| d.1).count();
            if decisions.iter().all(|d| !d.0 && !d.1) {
                continue;
            }
            let character = &characters[inst.character];
            let skinned = common::skinned_from_ecs(world, character, &inst.nodes);
            for (part, &(ours, bevys)) in character.character.parts.iter().zip(&decisions) {
                if !(ours || bevys) {
                    continue;
                }
                let seen = part.vertices.clone().any(|v| inside(&frustum, skinned[v as usize]));
                tally.skinlet_false += (ours && seen) as usize;
                tally.bevy_false += (bevys && seen) as usize;
                false_by_file[inst.character].0 += (ours && seen) as usize;
                false_by_file[inst.character].1 += (bevys && seen) as usize;
            }
        }
    }
    let per_frame = |d: Duration| d.as_secs_f64() * 1e6 / tally.frames.max(1) as f64;
    let pct = |n: usize| 100.0 * n as f64 / tally.entity_frames.max(1) as f64;
    let pose_pct = |n: usize| 100.0 * n as f64 / poses.iter().sum::<usize>().max(1) as f64;
    let out = serde_json::json!({
        "instances": { "fox": args.foxes, "morph_stress_test": args.morphs, "xbot": args.xbots },
        "pruned": !args.keep_all_bounds,
        "mesh_entities": tally.entity_frames / tally.frames.max(1),
        "frames": tally.frames,
        "skinlet_bounds_us_per_frame": per_frame(tally.skinlet_time),
        "bevy_bounds_us_per_frame": per_frame(tally.bevy_time),
        "skinlet_culled_pct": pct(tally.skinlet_culled),
        "bevy_culled_pct": pct(tally.bevy_culled),
        "skinlet_false_culls": tally.skinlet_false,
        "bevy_false_culls": tally.bevy_false,
        "false_culls_by_file": characters.iter().zip(&false_by_file)
            .map(|(c, &(ours, bevys))| (c.file.clone(), serde_json::json!({ "skinlet": ours, "bevy": bevys })))
            .collect::<serde_json::Map<_, _>>(),
        "skinlet_pose_bounds_pct": {
            "clip_windows": pose_pct(poses[2]),
            "clips": pose_pct(poses[1]),
            "envelope": pose_pct(poses[3]),
            "any_pose": pose_pct(poses[0]),
        },
    });
    if args.json {
        println!("{out}");
    } else {
        println!("{}", serde_json::to_string_pretty(&out).unwrap());
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}
