//! What ties a spawned glTF scene to a bake: Bevy's glTF loader keeps no node or primitive
//! index on the entities it spawns, so a glTF extension handler (Bevy's hooks into its own
//! loader) tags them as they are made: every node entity with its glTF node index and name,
//! every primitive entity with its mesh and primitive index, and the scene's root entity
//! with the file it came from and the names of the file's animations. The tags are plain
//! reflected components, so they survive scene spawning.

use bevy::asset::LoadContext;
use bevy::ecs::world::{EntityWorldMut, World};
use bevy::gltf::extensions::{ErasedGltfExtensionHandler, GltfExtensionHandler};
use bevy::prelude::*;

/// The glTF node an entity was spawned for: its index in the file, its name (empty when the
/// node has none) and its rest transform as spawned (what the node's `Transform` is when
/// nothing animates it).
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component)]
pub struct GltfNodeIndex {
    pub index: u32,
    pub name: String,
    pub rest: Transform,
}

/// The glTF mesh primitive an entity draws: mesh index and primitive index in that mesh.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component)]
pub struct GltfPrimitiveIndex {
    pub mesh: u32,
    pub primitive: u32,
}

/// On a glTF scene's root entity: the file's asset path and the glTF names of its animations in
/// file order (empty when unnamed; animation `k` is the file's `Animation{k}` labeled asset).
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component)]
pub struct GltfSceneSource {
    pub path: String,
    pub clips: Vec<String>,
}

/// The extension handler that adds the tags (cloned by Bevy for every glTF load).
#[derive(Clone, Default)]
pub(crate) struct TagHandler {
    names: Vec<String>,
}

impl GltfExtensionHandler for TagHandler {
    fn dyn_clone(&self) -> Box<dyn ErasedGltfExtensionHandler> {
        Box::new(self.clone())
    }

    fn on_root(&mut self, _: &mut LoadContext<'_>, gltf: &gltf::Gltf, _: &bevy::gltf::GltfLoaderSettings) {
        self.names = gltf.animations().map(|a| a.name().unwrap_or("").to_string()).collect();
    }

    fn on_gltf_node(&mut self, _: &mut LoadContext<'_>, node: &gltf::Node, entity: &mut EntityWorldMut) {
        let rest = entity.get::<Transform>().copied().unwrap_or_default();
        entity.insert(GltfNodeIndex { index: node.index() as u32, name: node.name().unwrap_or("").to_string(), rest });
    }

    fn on_spawn_mesh_and_material(
        &mut self,
        _: &mut LoadContext<'_>,
        primitive: &gltf::Primitive,
        mesh: &gltf::Mesh,
        _: &gltf::Material,
        entity: &mut EntityWorldMut,
        _: &str,
    ) {
        entity.insert(GltfPrimitiveIndex { mesh: mesh.index() as u32, primitive: primitive.index() as u32 });
    }

    fn on_scene_completed(&mut self, context: &mut LoadContext<'_>, _: &gltf::Scene, root: Entity, world: &mut World) {
        let path = context.path().without_label().to_string();
        world.entity_mut(root).insert(GltfSceneSource { path, clips: self.names.clone() });
    }
}
