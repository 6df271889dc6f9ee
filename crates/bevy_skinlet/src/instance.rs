//! Binding a spawned glTF scene to its bake, and its bounds every frame.
//!
//! Binding (once, when the scene instance is ready and the bake loaded): every driver, part
//! and morph weight of the bake is found among the instance's entities by glTF node index
//! (and mesh and primitive index for parts, see [`crate::gltf_tags`]); a missing entity or a
//! node whose name differs is a [`SkinletError`] on the root that names the bake and the
//! scene, never a wrong box. Entities of the scene that draw a mesh the bake does not hold
//! keep Bevy's own bounds, and the error-free binding says which in a warning. A scene spawned
//! again (a reloaded glTF file) or a reloaded bake is bound again.
//!
//! Every frame (after transform propagation, before Bevy's visibility check), each part's
//! entity gets its `Aabb` from `skinlet_runtime::part_bounds`, in the entity's space: when
//! the instance's animation player plays one baked clip alone (weight 1, no mask, straight
//! under the graph's root; the nodes it has no curve for that move one driver relative to
//! another, and the morph weights it has no curve for, at rest), the part's box over the clip
//! window holding the player's seek time (one box, one joint), or the clip bounds for a bake
//! without windows; else the envelope bounds when the bake's pose guard admits the pose, else
//! the any-pose boxes (morph targets always covered). Only the joints those boxes read are
//! fetched; a bake with neither windows nor clip or envelope bounds (pruned) skips the pose
//! checks. An app that edits animated joints after Bevy's animation (IK) marks the instance
//! [`PoseEdited`], which turns the clip bounds off for it.

use crate::bake_asset::Bake;
use crate::gltf_tags::{GltfNodeIndex, GltfPrimitiveIndex, GltfSceneSource};
use bevy::animation::animation_curves::AnimatableProperty;
use bevy::animation::graph::{AnimationGraph, AnimationGraphHandle, AnimationNodeType};
use bevy::animation::{AnimationClip, AnimationPlayer, AnimationTargetId, animated_field};
use bevy::asset::{AssetId, LoadState};
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{DynamicSkinnedMeshBounds, NoAutoAabb};
use bevy::ecs::system::SystemParam;
use bevy::math::{Affine3A, Vec3A};
use bevy::mesh::morph::MorphWeights;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstance, WorldInstanceReady, WorldInstanceSpawner};
use skinlet_runtime::Trs;
use skinlet_runtime::part_bounds::PoseBounds;

/// Put on a glTF scene's root entity (the one with `WorldAssetRoot`): its mesh entities get
/// skinlet's bounds from this bake, every frame.
#[derive(Component, Clone, Debug)]
pub struct SkinletBounds(pub Handle<Bake>);

/// Put on a scene root whose pose an app edits after Bevy's animation and before transform
/// propagation (IK, look-at or physics on joints a clip animates): skinlet cannot see such
/// edits, so for this instance it never uses the bounds baked over the clips; the envelope
/// bounds (the pose guard checks the edited pose itself) and the any-pose boxes still hold.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct PoseEdited;

/// Why a scene could not be bound to its bake (on the root entity; the scene keeps Bevy's
/// own bounds). Also logged once.
#[derive(Component, Clone, Debug, PartialEq, Eq)]
pub struct SkinletError(pub String);

/// A scene bound to its bake: the entities of its drivers, parts and morph weights, and
/// what the last frame's bounds were.
#[derive(Component, Debug)]
pub struct SkinletInstance {
    bake: AssetId<Bake>,
    drivers: Vec<Entity>,
    /// The entity drawing each part.
    parts: Vec<Entity>,
    /// Per morph weight, the node entity holding its `MorphWeights` (if any).
    morph_nodes: Vec<Option<Entity>>,
    /// Per glTF node index up to the bake's largest, its entity and rest transform.
    nodes: Vec<Option<(Entity, Transform)>>,
    /// Per glTF node index, whether its local transform changes where a driver the bounds use
    /// is relative to another (it is above some of them, and not above all).
    relative: Vec<bool>,
    player: Option<Entity>,
    /// The animation targets of the scene's nodes (glTF index, target id).
    targets: Vec<(usize, AnimationTargetId)>,
    /// The glTF file's asset path, and per animation of the file the bake's clip that is it
    /// (an index into the bake's clips), if any.
    scene: String,
    baked: Vec<Option<u32>>,
    /// Per clip asset seen playing: `None` when it is no baked clip of this file, else which
    /// baked clip and what it leaves at rest (Bevy reloads a file's clips under new asset ids
    /// when their handles were dropped; clips are matched by asset path, `FILE#AnimationK`).
    /// A few entries: a list, searched in order.
    clips: Vec<(AssetId<AnimationClip>, Option<BakedClip>)>,
    // Scratch space, reused every frame: the drivers' matrices, fetched when a box needs them.
    globals: Vec<Affine3A>,
    fetched: Vec<bool>,
    weights: Vec<f32>,
    locals: Vec<Trs>,
    /// Which stored bounds held last frame.
    pub pose: PoseBounds,
    /// Whether the root has [`PoseEdited`] (set each frame by the plugin).
    pub pose_edited: bool,
}

impl SkinletInstance {
    /// The entities that get skinlet's bounds, one per part of the bake.
    pub fn part_entities(&self) -> &[Entity] {
        &self.parts
    }

    /// The entities of the bake's drivers (joints and rigid parts' nodes), in its order.
    pub fn drivers(&self) -> &[Entity] {
        &self.drivers
    }

    /// This frame's morph weights, in the bake's order (after the bounds' update).
    pub fn morph_weights(&self) -> &[f32] {
        &self.weights
    }
}

/// A baked clip (its index among the bake's clips) and what it leaves alone, which must be at
/// rest for its bounds to hold: nodes (their entities and rest transforms) and morph weights
/// (indices into the bake's).
#[derive(Debug)]
struct BakedClip {
    index: u32,
    nodes: Vec<(Entity, Transform)>,
    weights: Vec<usize>,
}

/// What binding reads of the scene's entities.
type Tags<'a> = (
    Option<&'a GltfNodeIndex>,
    Option<&'a GltfPrimitiveIndex>,
    Option<&'a GltfSceneSource>,
    Option<&'a AnimationTargetId>,
    Has<AnimationPlayer>,
    Has<Mesh3d>,
);

/// Scene roots not bound yet (nor failed), and those bound or failed.
type Unbound = (Without<SkinletInstance>, Without<SkinletError>);
type Bound = (With<SkinletInstance>, With<SkinletError>);

/// Binds every ready scene instance with [`SkinletBounds`] to its loaded bake.
#[allow(clippy::too_many_arguments)]
pub(crate) fn bind_instances(
    mut commands: Commands,
    roots: Query<(Entity, &SkinletBounds, &WorldInstance, Option<&WorldAssetRoot>), Unbound>,
    spawner: Res<WorldInstanceSpawner>,
    bakes: Res<Assets<Bake>>,
    assets: Res<AssetServer>,
    tags: Query<Tags>,
    children: Query<&Children>,
    mode: Res<crate::SkinletSettings>,
) {
    for (root, bounds, instance, scene) in &roots {
        let bake_name = || assets.get_path(&bounds.0).map_or_else(|| format!("{:?}", bounds.0.id()), |p| p.to_string());
        let failed = match (assets.get_load_state(&bounds.0), scene.and_then(|s| assets.get_load_state(&s.0))) {
            (Some(LoadState::Failed(e)), _) => Some(format!("bake {}: {e}", bake_name())),
            (_, Some(LoadState::Failed(e))) => Some(format!("scene of bake {}: {e}", bake_name())),
            _ => None,
        };
        if let Some(message) = failed {
            error!("{message}");
            commands.entity(root).insert(SkinletError(message));
            continue;
        }
        let (Some(bake), true) = (bakes.get(&bounds.0), spawner.instance_is_ready(**instance)) else { continue };
        match bind(root, bake, bounds.0.id(), &bake_name(), &tags, &children) {
            Ok((bound, unbaked)) => {
                if !unbaked.is_empty() {
                    warn!(
                        "bake {}: {} mesh entities of the scene are not in it and keep Bevy's bounds: {unbaked:?}",
                        bake_name(),
                        unbaked.len()
                    );
                }
                if mode.bounds == crate::BoundsSource::Skinlet {
                    for &e in &bound.parts {
                        commands.entity(e).remove::<DynamicSkinnedMeshBounds>().insert(NoAutoAabb);
                    }
                }
                commands.entity(root).insert(bound);
            }
            Err(message) => {
                error!("{message}");
                commands.entity(root).insert(SkinletError(message));
            }
        }
    }
}

/// A bound scene spawned again (its glTF file reloaded, or loaded anew when a labeled asset of
/// it was asked for after its handles were dropped): its entities are new, so bind it again
/// (an error is retried too).
pub(crate) fn rebind_respawned(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    bound: Query<(), With<SkinletBounds>>,
) {
    if bound.contains(ready.entity) {
        commands.entity(ready.entity).remove::<(SkinletInstance, SkinletError)>();
    }
}

/// A bake changed (reloaded): the scenes bound to it are bound again.
pub(crate) fn rebind_changed_bakes(
    mut commands: Commands,
    mut events: MessageReader<AssetEvent<Bake>>,
    roots: Query<(Entity, &SkinletBounds), Or<Bound>>,
) {
    for event in events.read() {
        if let AssetEvent::Modified { id } = event {
            for (root, _) in roots.iter().filter(|(_, b)| b.0.id() == *id) {
                commands.entity(root).remove::<(SkinletInstance, SkinletError)>();
            }
        }
    }
}

/// The binding of one instance, with the mesh entities the bake does not hold; or the error.
fn bind(
    root: Entity,
    bake: &Bake,
    id: AssetId<Bake>,
    bake_name: &str,
    tags: &Query<Tags>,
    children: &Query<&Children>,
) -> Result<(SkinletInstance, Vec<Entity>), String> {
    let entities: Vec<Entity> = children.iter_descendants(root).collect();
    let source = entities.iter().find_map(|&e| tags.get(e).ok().and_then(|t| t.2.cloned()));
    let scene = source.as_ref().map_or("the scene (not loaded by Bevy's glTF loader with SkinletPlugin)", |s| &s.path);
    let fail = |what: String| Err(format!("bake {bake_name} does not match scene {scene}: {what}"));
    let Some(source) = source.as_ref() else { return fail("no glTF tags on its entities".into()) };
    // Node entities by glTF index, with their rest transforms.
    let mut nodes: Vec<Option<(Entity, Transform)>> = vec![None; bake.nodes];
    let mut names: HashMap<u32, &str> = HashMap::default();
    let mut targets: Vec<(usize, AnimationTargetId)> = Vec::new();
    let mut player = None;
    for &e in &entities {
        let Ok((node, _, _, target, has_player, _)) = tags.get(e) else { continue };
        let Some(node) = node else { continue };
        names.insert(node.index, &node.name);
        if let Some(slot) = nodes.get_mut(node.index as usize) {
            *slot = Some((e, node.rest));
        }
        if let Some(&t) = target {
            targets.push((node.index as usize, t));
        }
        if has_player && player.is_none() {
            player = Some(e);
        }
    }
    let node_entity = |n: u32, what: &str| match nodes.get(n as usize).copied().flatten() {
        Some((e, _)) => Ok(e),
        None => Err(format!("bake {bake_name} does not match scene {scene}: {what} node {n} is not in the scene")),
    };
    let mut drivers = Vec::with_capacity(bake.drivers.len());
    for (j, (n, name)) in bake.drivers.iter().enumerate() {
        drivers.push(node_entity(*n, &format!("driver {j}'s"))?);
        if names.get(n).is_some_and(|s| s != name) {
            return fail(format!("node {n} is {:?} in the scene, {name:?} in the bake", names[n]));
        }
    }
    // Parts: the node's child entity drawing the same mesh primitive.
    let mut parts = Vec::with_capacity(bake.parts.parts().len());
    for (i, p) in bake.parts.parts().iter().enumerate() {
        let node = node_entity(p.node, &format!("part {i}'s"))?;
        let drawn = children.get(node).ok().and_then(|c| {
            c.iter().find(|&c| {
                tags.get(c).is_ok_and(|t| t.1.is_some_and(|q| (q.mesh, q.primitive) == (p.mesh, p.primitive)))
            })
        });
        match drawn {
            Some(e) => parts.push(e),
            None => {
                return fail(format!(
                    "part {i} (node {}, mesh {} primitive {}) is not drawn in the scene",
                    p.node, p.mesh, p.primitive
                ));
            }
        }
    }
    let unbaked: Vec<Entity> =
        entities.iter().copied().filter(|e| tags.get(*e).is_ok_and(|t| t.5) && !parts.contains(e)).collect();
    let morph_nodes =
        bake.morph_weights.iter().map(|w| nodes.get(w.0 as usize).copied().flatten().map(|n| n.0)).collect();
    // Nodes above some drivers the bounds read and not above all of them: only their local
    // transforms change one driver relative to another (a common ancestor moves them all
    // alike, which every stored bound follows).
    let index: HashMap<Entity, usize> =
        nodes.iter().enumerate().filter_map(|(n, e)| Some((e.as_ref()?.0, n))).collect();
    let mut parent = vec![None; nodes.len()];
    for (n, node) in nodes.iter().enumerate() {
        for c in node.and_then(|(e, _)| children.get(e).ok()).into_iter().flatten() {
            if let Some(&m) = index.get(c) {
                parent[m] = Some(n);
            }
        }
    }
    let mut read = vec![false; bake.drivers.len()];
    for i in 0..bake.parts.parts().len() {
        // The any-pose boxes read every driver that moves a vertex of the part.
        bake.parts.drivers_read(i, PoseBounds::Any).for_each(|d| read[d] = true);
    }
    let mut above = vec![0usize; nodes.len()];
    for (d, _) in read.iter().enumerate().filter(|r| *r.1) {
        let mut n = Some(bake.drivers[d].0 as usize);
        while let Some(m) = n {
            above[m] += 1;
            n = parent[m];
        }
    }
    let total = read.iter().filter(|r| **r).count();
    let relative = above.iter().map(|&a| 0 < a && a < total).collect();
    // Baked clips: the file's clips by position when the bake holds every clip of the file in
    // file order (what `skinlet bake` and the recipes do: unnamed clips too), else a clip
    // whose glTF name is one, and only one, baked clip's.
    let names: Vec<&str> = source.clips.iter().map(String::as_str).collect();
    let in_order = names.iter().copied().eq(bake.clips.iter().map(String::as_str));
    let once = |list: &mut dyn Iterator<Item = &str>, name: &str| list.filter(|n| *n == name).count() == 1;
    let baked = (names.iter().enumerate())
        .map(|(k, &name)| {
            if in_order {
                return Some(k as u32);
            }
            let unique = !name.is_empty()
                && once(&mut bake.clips.iter().map(String::as_str), name)
                && once(&mut names.iter().copied(), name);
            unique.then(|| bake.clips.iter().position(|c| c == name)).flatten().map(|i| i as u32)
        })
        .collect();
    let instance = SkinletInstance {
        bake: id,
        drivers,
        parts,
        morph_nodes,
        nodes,
        relative,
        player,
        targets,
        scene: source.path.clone(),
        baked,
        clips: Vec::new(),
        globals: vec![Affine3A::NAN; bake.drivers.len()],
        fetched: vec![false; bake.drivers.len()],
        weights: Vec::new(),
        locals: Vec::new(),
        pose: PoseBounds::Any,
        pose_edited: false,
    };
    Ok((instance, unbaked))
}

/// What the per-frame boxes read of Bevy's world: joint and entity transforms, local
/// transforms, morph weights, animation players, their graphs and clips.
#[derive(SystemParam)]
pub struct PoseInputs<'w, 's> {
    pub globals: Query<'w, 's, &'static GlobalTransform>,
    pub transforms: Query<'w, 's, &'static Transform>,
    pub morphs: Query<'w, 's, &'static MorphWeights>,
    pub players: Query<'w, 's, (&'static AnimationPlayer, Option<&'static AnimationGraphHandle>)>,
    pub graphs: Res<'w, Assets<AnimationGraph>>,
    pub clips: Res<'w, Assets<AnimationClip>>,
    pub assets: Res<'w, AssetServer>,
}

/// Sets the `Aabb` of every bound part entity from skinlet's bounds for this frame.
pub(crate) fn update_bounds(
    mut instances: Query<(&mut SkinletInstance, Has<PoseEdited>)>,
    bakes: Res<Assets<Bake>>,
    inputs: PoseInputs,
    mut aabbs: Query<&mut Aabb>,
    settings: Res<crate::SkinletSettings>,
) {
    if settings.bounds != crate::BoundsSource::Skinlet {
        return;
    }
    for (mut instance, edited) in &mut instances {
        instance.pose_edited = edited;
        let Some(bake) = bakes.get(instance.bake) else { continue };
        update_instance(&mut instance, bake, &inputs, |e, aabb| {
            if let Ok(mut a) = aabbs.get_mut(e) {
                *a = aabb;
            }
        });
    }
}

/// One instance's boxes for this frame, handed to `out` per part entity (what the plugin
/// runs every frame; public for measuring and for apps that drive it themselves).
pub fn update_instance(
    instance: &mut SkinletInstance,
    bake: &Bake,
    inputs: &PoseInputs,
    mut out: impl FnMut(Entity, Aabb),
) {
    let global = |e: Entity| inputs.globals.get(e).map_or(Affine3A::NAN, |g| g.affine());
    instance.weights.clear();
    // One lookup per node (a node's weights are adjacent in the bake).
    let mut last: Option<(Entity, Option<&MorphWeights>)> = None;
    for (w, &node) in bake.morph_weights.iter().zip(&instance.morph_nodes) {
        let weights = node.and_then(|n| match last {
            Some((e, m)) if e == n => m,
            _ => last.insert((n, inputs.morphs.get(n).ok())).1,
        });
        let value = weights.and_then(|m| m.weights().get(w.1 as usize).copied());
        instance.weights.push(value.unwrap_or(w.2));
    }
    instance.pose = pose_bounds(instance, bake, inputs);
    instance.fetched.fill(false);
    for (i, &e) in instance.parts.iter().enumerate() {
        // Only the joints this part's boxes read (the clip bounds' principal joints, say).
        for d in bake.parts.drivers_read(i, instance.pose) {
            if !instance.fetched[d] {
                instance.globals[d] = global(instance.drivers[d]);
                instance.fetched[d] = true;
            }
        }
        let to_entity = global(e).inverse();
        let b = bake.parts.part_box(i, &to_entity, &instance.globals, &instance.weights, instance.pose);
        let aabb = if b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all() {
            Aabb::from_min_max(b.min, b.max)
        } else {
            // Nothing is known (a matrix that is not finite): a box no frustum misses.
            Aabb { center: Vec3A::ZERO, half_extents: Vec3A::splat(1e30) }
        };
        out(e, aabb);
    }
}

/// Which stored bounds hold for the instance's pose this frame.
fn pose_bounds(instance: &mut SkinletInstance, bake: &Bake, inputs: &PoseInputs) -> PoseBounds {
    if (bake.parts.narrows(PoseBounds::Clips) || bake.parts.has_clip_windows())
        && !instance.pose_edited
        && let Some((clip, time)) = playing_clip(instance, inputs)
    {
        // Which baked clip of this file it is, and what it leaves at rest: found once per
        // clip asset (when the asset is there).
        if !instance.clips.iter().any(|c| c.0 == clip)
            && let Some(asset) = inputs.clips.get(clip)
        {
            let k = inputs.assets.get_path(clip).and_then(|p| {
                let k = p.label()?.strip_prefix("Animation")?.parse::<usize>().ok()?;
                (p.without_label().to_string() == instance.scene).then_some(k)
            });
            let index = k.and_then(|k| instance.baked.get(k).copied().flatten());
            instance.clips.push((clip, index.map(|index| baked_clip(instance, bake, asset, index))));
        }
        let baked = instance.clips.iter().find(|c| c.0 == clip).and_then(|c| c.1.as_ref());
        if let Some(baked) = baked {
            let nodes = baked.nodes.iter().all(|(e, rest)| inputs.transforms.get(*e).is_ok_and(|t| t == rest));
            if nodes && baked.weights.iter().all(|&i| instance.weights[i] == bake.morph_weights[i].2) {
                return PoseBounds::ClipAt { clip: baked.index, time };
            }
        }
    }
    let Some(guard) = bake.guard.as_ref().filter(|_| bake.parts.narrows(PoseBounds::Envelope)) else {
        return PoseBounds::Any;
    };
    instance.locals.clear();
    instance.locals.extend(instance.nodes.iter().map(|n| {
        let t = n.and_then(|(e, _)| inputs.transforms.get(e).ok().copied()).unwrap_or_default();
        Trs { translation: t.translation, rotation: t.rotation, scale: t.scale }
    }));
    if guard.admits(&instance.locals, &instance.weights) { PoseBounds::Envelope } else { PoseBounds::Any }
}

/// Baked clip `index` (`clip`) with what it leaves alone of what its bounds depend on: the
/// nodes in the `relative` set it has no curve for, and the morph weights of nodes it has no
/// weight curve for (glTF clips hold translation, rotation, scale and weight curves only: a
/// curve that is none of the first three is taken for weights).
fn baked_clip(instance: &SkinletInstance, bake: &Bake, clip: &AnimationClip, index: u32) -> BakedClip {
    let (t, r, s) = (
        animated_field!(Transform::translation),
        animated_field!(Transform::rotation),
        animated_field!(Transform::scale),
    );
    let transform = [t.evaluator_id(), r.evaluator_id(), s.evaluator_id()];
    // Per node: whether the clip animates it at all, and its weights.
    let mut animated = vec![(false, false); instance.nodes.len()];
    for &(n, target) in &instance.targets {
        for curve in clip.curves_for_target(target).into_iter().flatten() {
            animated[n].0 = true;
            animated[n].1 |= !transform.contains(&curve.0.evaluator_id());
        }
    }
    let nodes = (instance.nodes.iter().enumerate())
        .filter_map(|(n, node)| node.filter(|_| instance.relative[n] && !animated[n].0))
        .collect();
    let weights = (0..bake.morph_weights.len())
        .filter(|&i| !animated.get(bake.morph_weights[i].0 as usize).is_some_and(|a| a.1))
        .collect();
    BakedClip { index, nodes, weights }
}

/// The playing clip and the time Bevy sampled it at this frame, when the instance's player
/// plays exactly one animation, a clip straight under its graph's root, unmasked, at full
/// weight.
fn playing_clip(instance: &SkinletInstance, inputs: &PoseInputs) -> Option<(AssetId<AnimationClip>, f32)> {
    let (player, graph) = inputs.players.get(instance.player?).ok()?;
    let graph = inputs.graphs.get(&graph?.0)?;
    let mut playing = player.playing_animations().filter(|(_, a)| a.weight() != 0.0);
    let (&index, active) = playing.next()?;
    if playing.next().is_some() {
        return None;
    }
    let node = graph.get(index)?;
    let root = graph.get(graph.root)?;
    let AnimationNodeType::Clip(clip) = &node.node_type else { return None };
    let mut parents = graph.graph.raw_edges().iter().filter(|e| e.target() == index).map(|e| e.source());
    let under_root = parents.next() == Some(graph.root) && parents.next().is_none();
    let full = (active.weight() * node.weight - 1.0).abs() <= 1e-6 && root.weight == 1.0;
    (full && node.mask == 0 && root.mask == 0 && under_root).then(|| (clip.id(), active.seek_time()))
}
