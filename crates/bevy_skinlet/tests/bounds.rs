//! skinlet's bounds in a Bevy app (headless, no GPU): scenes of the shared characters, the
//! morph-target test and the demo character (two skins, rigid and instanced parts, a morph
//! face) play clips alone, crossfade two clips, are posed by hand (a pose no clip makes), or
//! play a clip whose joints a system turns after Bevy's animation (marked `PoseEdited`);
//! every frame, every vertex of every bound mesh entity, morphed and skinned on the CPU from
//! the joint matrices and morph weights in Bevy's ECS, lies in the entity's `Aabb`. A bake
//! of another file is an error that names both files. The bakes are loaded unpruned
//! (`BakeSettings { prune: false }`): every clip and envelope bound is used where it holds.

mod common;

use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeIndex};
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{DynamicSkinnedMeshBounds, NoAutoAabb};
use bevy::prelude::*;
use bevy_skinlet::gltf_tags::GltfNodeIndex;
use bevy_skinlet::{Bake, BakeSettings, PoseEdited, SkinletBounds, SkinletError, SkinletInstance};
use common::{Character, app, asset_folder, node_entities, part_entity, skinned_from_ecs, update_until};
use skinlet_runtime::part_bounds::PoseBounds;

/// How an instance moves.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion {
    /// One clip alone (its index).
    Clip(usize),
    /// Two clips at half weight each.
    Blend,
    /// Every node turned by hand each frame, no player.
    ByHand,
    /// Clip 0, and every node it has no curve for turned by hand each frame (the clip's
    /// bounds then no longer hold).
    ClipAndHand,
    /// Clip 0, and every node it animates turned by a system after Bevy's animation (as IK
    /// would), the root marked [`PoseEdited`].
    ClipEdited,
}

/// On a root whose animated nodes [`edit_after_animation`] turns.
#[derive(Component)]
struct EditAfterAnimation(Vec<u32>);

/// Turns the nodes an instance's clip animates, after Bevy's animation wrote them.
fn edit_after_animation(
    roots: Query<(Entity, &EditAfterAnimation)>,
    mut transforms: Query<(&mut Transform, &GltfNodeIndex)>,
    children: Query<&Children>,
) {
    for (root, edit) in &roots {
        for e in children.iter_descendants(root) {
            if let Ok((mut t, node)) = transforms.get_mut(e)
                && edit.0.contains(&node.index)
            {
                t.rotate_local(Quat::from_axis_angle(Vec3::new(0.3, 1.0, 0.2).normalize(), 0.6));
            }
        }
    }
}

#[test]
fn every_vertex_lies_in_its_entitys_box_every_frame() {
    let files = ["skinned/Fox.glb", "skinned/CesiumMan.glb", "morph/MorphStressTest.gltf", "@demo"];
    let Some((dir, characters)) = asset_folder("bounds", &files) else { return };
    let mut app = app(&dir, false);
    app.add_systems(
        PostUpdate,
        edit_after_animation.after(bevy::app::AnimationSystems).before(bevy::transform::TransformSystems::Propagate),
    );
    let mut spawned: Vec<(Entity, usize, Motion)> = Vec::new();
    {
        let world = app.world_mut();
        let assets = world.resource::<AssetServer>().clone();
        for (c, character) in characters.iter().enumerate() {
            let stem = character.file.rsplit_once('.').unwrap().0.to_string();
            // Every stored bound kept, so the clip and envelope bounds are checked too (pruned
            // bakes use fewer of them; `tests/rendered.rs` and the example use those).
            let unpruned = |s: &mut BakeSettings| s.prune = false;
            let bake: Handle<Bake> = assets.load_builder().with_settings(unpruned).load(format!("{stem}.skinlet"));
            let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(character.file.clone()));
            let clips = character.asset.clips.len();
            let mut motions = vec![Motion::ByHand];
            motions.extend((0..clips).map(Motion::Clip));
            if clips >= 2 {
                motions.push(Motion::Blend);
            }
            if clips >= 1 {
                motions.extend([Motion::ClipAndHand, Motion::ClipEdited]);
            }
            for (k, &motion) in motions.iter().enumerate() {
                let at = Transform::from_xyz(3.0 * k as f32, 0.0, 4.0 * c as f32)
                    .with_rotation(Quat::from_rotation_y(k as f32));
                let e = world.spawn((WorldAssetRoot(scene.clone()), SkinletBounds(bake.clone()), at)).id();
                if motion == Motion::ClipEdited {
                    let clip = &character.asset.clips[0];
                    let nodes = clip.rotations.iter().map(|ch| ch.node).collect();
                    world.entity_mut(e).insert((PoseEdited, EditAfterAnimation(nodes)));
                }
                spawned.push((e, c, motion));
            }
        }
    }
    update_until(&mut app, 2000, "every instance bound", |w| {
        spawned.iter().all(|&(e, _, _)| w.get::<SkinletInstance>(e).is_some() || w.get::<SkinletError>(e).is_some())
    });
    for &(e, _, _) in &spawned {
        assert!(app.world().get::<SkinletError>(e).is_none(), "{:?}", app.world().get::<SkinletError>(e));
    }
    // Animation: a graph of the file's clips per character, played as each instance says.
    let mut players = Vec::new();
    for &(root, c, motion) in &spawned {
        let world = app.world_mut();
        let character: &Character = &characters[c];
        let assets = world.resource::<AssetServer>().clone();
        let clips: Vec<Handle<AnimationClip>> = (0..character.asset.clips.len())
            .map(|i| assets.load(GltfAssetLabel::Animation(i).from_asset(character.file.clone())))
            .collect();
        let (graph, nodes): (AnimationGraph, Vec<AnimationNodeIndex>) = AnimationGraph::from_clips(clips);
        let graph = world.resource_mut::<Assets<AnimationGraph>>().add(graph);
        let mut q = world.query_filtered::<Entity, With<AnimationPlayer>>();
        let descendants: Vec<Entity> = world.query::<&Children>().query(world).iter_descendants(root).collect();
        let Some(player) = descendants.into_iter().find(|&d| q.get(world, d).is_ok()) else { continue };
        let mut p = world.get_mut::<AnimationPlayer>(player).unwrap();
        match motion {
            Motion::Clip(i) => {
                p.play(nodes[i]).repeat();
            }
            Motion::ClipAndHand | Motion::ClipEdited => {
                p.play(nodes[0]).repeat();
            }
            Motion::Blend => {
                p.play(nodes[0]).repeat().set_weight(0.5);
                p.play(nodes[1]).repeat().set_weight(0.5).set_speed(1.3);
            }
            Motion::ByHand => {}
        }
        world.entity_mut(player).insert(AnimationGraphHandle(graph));
        players.push(player);
    }
    // The entities skinlet bounds, and Bevy's own skinned bounds switched off on them.
    let mut checked = 0usize;
    let mut poses = std::collections::BTreeMap::<String, usize>::new();
    for frame in 0..45 {
        // Hand-posed instances: every node of the scene turned a little, differently each frame.
        for &(root, c, motion) in &spawned {
            let animated: Vec<u32> = match motion {
                Motion::ByHand => Vec::new(),
                Motion::ClipAndHand => {
                    let clip = &characters[c].asset.clips[0];
                    (clip.translations.iter().map(|ch| ch.node))
                        .chain(clip.rotations.iter().map(|ch| ch.node))
                        .chain(clip.scales.iter().map(|ch| ch.node))
                        .chain(clip.weights.iter().map(|ch| ch.channel.node))
                        .collect()
                }
                _ => continue,
            };
            let world = app.world_mut();
            let nodes = node_entities(world, root).into_iter().enumerate();
            let turned = nodes.filter_map(|(i, n)| n.filter(|_| !animated.contains(&(i as u32))));
            for (k, n) in turned.enumerate() {
                let angle = 0.05 * ((frame * 7 + k * 3) % 11) as f32;
                world
                    .get_mut::<Transform>(n)
                    .unwrap()
                    .rotate_local(Quat::from_axis_angle(Vec3::new(1.0, 0.5, 0.2).normalize(), angle));
            }
        }
        app.update();
        let world = app.world_mut();
        for &(root, c, motion) in &spawned {
            let character = &characters[c];
            let nodes = node_entities(world, root);
            let skinned = skinned_from_ecs(world, character, &nodes);
            let pose = world.get::<SkinletInstance>(root).unwrap().pose;
            if let (Motion::Clip(k), PoseBounds::ClipAt { clip, .. }) = (motion, pose) {
                assert_eq!(clip as usize, k, "{}: clip {k} taken for baked clip {clip}", character.file);
            }
            let kind = format!("{pose:?}");
            *poses.entry(format!("{motion:?} {}", kind.split(' ').next().unwrap())).or_default() += 1;
            for (i, part) in character.character.parts.iter().enumerate() {
                let e = part_entity(world, &nodes, part);
                assert!(
                    world.get::<NoAutoAabb>(e).is_some() && world.get::<DynamicSkinnedMeshBounds>(e).is_none(),
                    "{} frame {frame} part {i}: Bevy's own box is not switched off (NoAutoAabb {}, DynamicSkinnedMeshBounds {})",
                    character.file,
                    world.get::<NoAutoAabb>(e).is_some(),
                    world.get::<DynamicSkinnedMeshBounds>(e).is_some()
                );
                let aabb = *world.get::<Aabb>(e).unwrap();
                let to_entity = world.get::<GlobalTransform>(e).unwrap().to_matrix().as_dmat4().inverse();
                let (lo, hi) = (aabb.min().as_dvec3(), aabb.max().as_dvec3());
                for v in part.vertices.clone() {
                    let p = to_entity.transform_point3(skinned[v as usize].as_dvec3());
                    // The box is in f32; the vertex moved into the entity's space in f64.
                    let slack = 1e-6 * (p.abs().max_element() + 1.0);
                    assert!(
                        p.cmpge(lo - slack).all() && p.cmple(hi + slack).all(),
                        "{} ({motion:?}, frame {frame}, pose bounds {pose:?}): vertex {v} of part {i} at {p} is outside its Aabb {lo}..{hi}",
                        character.file
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 0);
    // Each kind of bounds was used: clip windows for clips alone, the envelope for blends,
    // any-pose boxes.
    for want in ["Clip(0) ClipAt", "Blend Envelope", "ByHand Any", "ClipAndHand Envelope", "ClipEdited Any"] {
        assert!(poses.contains_key(want), "no {want:?} frame: {poses:?}");
    }
}

#[test]
fn a_bake_of_another_file_is_an_error_naming_both() {
    let Some((dir, _)) = asset_folder("mismatch", &["skinned/Fox.glb", "skinned/CesiumMan.glb"]) else { return };
    let mut app = app(&dir, false);
    let world = app.world_mut();
    let assets = world.resource::<AssetServer>().clone();
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset("CesiumMan.glb"));
    let e = world.spawn((WorldAssetRoot(scene), SkinletBounds(assets.load("Fox.skinlet")))).id();
    let broken = world
        .spawn((
            WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"))),
            SkinletBounds(assets.load("missing.skinlet")),
        ))
        .id();
    update_until(&mut app, 2000, "the errors", |w| {
        w.get::<SkinletError>(e).is_some() && w.get::<SkinletError>(broken).is_some()
    });
    let message = &app.world().get::<SkinletError>(e).unwrap().0;
    assert!(message.contains("Fox.skinlet") && message.contains("CesiumMan.glb"), "{message}");
    let message = &app.world().get::<SkinletError>(broken).unwrap().0;
    assert!(message.contains("missing.skinlet"), "{message}");
}
