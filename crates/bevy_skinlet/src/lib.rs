//! skinlet in Bevy: conservative bounds for skinned and morphing glTF characters, every frame.
//!
//! Bevy culls each mesh entity by its `Aabb`. For a skinned mesh that box is Bevy's per-joint
//! box (`DynamicSkinnedMeshBounds`), which misses morph targets; skinlet's covers them, and
//! while one baked clip plays alone moves one box per entity, baked over the clip's window
//! holding the player's time in one joint's space, where Bevy's moves one per joint. Add
//! [`SkinletPlugin`], load the character's bake (a `.skinlet` file from `skinlet bake`) and put
//! [`SkinletBounds`] beside the scene's `WorldAssetRoot`:
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_skinlet::{SkinletBounds, SkinletPlugin};
//!
//! fn main() {
//!     App::new().add_plugins((DefaultPlugins, SkinletPlugin::default())).add_systems(Startup, spawn).run();
//! }
//!
//! fn spawn(mut commands: Commands, assets: Res<AssetServer>) {
//!     commands.spawn((
//!         WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("Fox.glb"))),
//!         SkinletBounds(assets.load("Fox.skinlet")),
//!     ));
//! }
//! ```
//!
//! - [`gltf_tags`]: what ties spawned entities to a bake (glTF node, mesh and primitive
//!   indices; the scene's file and clips), added by a hook into Bevy's glTF loader.
//! - [`bake_asset`]: the `.skinlet` asset and its loader (checked by `skinlet_runtime`).
//! - [`instance`]: binding a scene instance to its bake (errors name both files), and the
//!   per-frame boxes (`skinlet_runtime::part_bounds`), between transform propagation and
//!   Bevy's visibility check.
//!
//! - [`meshlet_draw`] (feature `meshlets`): [`SkinletMeshletPlugin`] draws marked scene
//!   instances by meshlet in Bevy's opaque pass, culled per meshlet and per triangle on Bevy's
//!   device, shaded by Bevy's PBR functions.
//!
//! The plugin never links the baker; the asset-processor step that bakes glTF files when Bevy
//! processes assets is behind the `bake` feature. [`skinlet_gpu`] is re-exported: its GPU
//! culling runs on Bevy's own wgpu device.

pub mod bake_asset;
#[cfg(feature = "bake")]
pub mod bake_processor;
pub mod gltf_tags;
pub mod instance;
#[cfg(feature = "meshlets")]
pub mod meshlet_draw;

pub use bake_asset::{Bake, BakeLoader, BakeSettings};
pub use instance::{PoseEdited, SkinletBounds, SkinletError, SkinletInstance};
#[cfg(feature = "meshlets")]
pub use meshlet_draw::{
    MeshletStats, SkinletDrawnPart, SkinletMeshletPlugin, SkinletMeshletSettings, SkinletMeshletStats, SkinletMeshlets,
};
pub use skinlet_gpu;
pub use skinlet_runtime;

/// The README's Rust examples (baker, runtime, GPU and Bevy crates), compiled as doc-tests so
/// they cannot rot (this crate's dev-dependencies reach every crate they use).
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
struct ReadmeExamples;

use bevy::camera::primitives::MeshAabb;
use bevy::camera::visibility::{DynamicSkinnedMeshBounds, NoAutoAabb, VisibilitySystems};
use bevy::gltf::extensions::GltfExtensionHandlers;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;

/// Whose boxes Bevy culls the bound entities with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BoundsSource {
    /// skinlet's (morph targets included; clip and envelope bounds where they hold).
    #[default]
    Skinlet,
    /// Bevy's own `DynamicSkinnedMeshBounds` on skinned entities and the mesh's box on the
    /// others, on the same entities: for comparing the two.
    Bevy,
}

/// The plugin's settings, a resource: changing `bounds` at run time switches every bound
/// instance over.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SkinletSettings {
    pub bounds: BoundsSource,
}

/// skinlet's systems in `PostUpdate`, for ordering an app's own systems against them.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SkinletSystems {
    /// Binds ready scene instances to their bakes (before Bevy's `CalculateBounds`).
    Bind,
    /// Sets the `Aabb` of every bound part entity (after `CalculateBounds`, before
    /// `CheckVisibility`).
    UpdateBounds,
}

/// Loads `.skinlet` bakes, tags glTF scenes as they load, and keeps the `Aabb` of every mesh
/// entity of a scene with [`SkinletBounds`] conservative every frame.
#[derive(Default)]
pub struct SkinletPlugin {
    pub settings: SkinletSettings,
}

impl Plugin for SkinletPlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<Bake>()
            .register_asset_loader(BakeLoader)
            .insert_resource(self.settings)
            .register_type::<gltf_tags::GltfNodeIndex>()
            .register_type::<gltf_tags::GltfPrimitiveIndex>()
            .register_type::<gltf_tags::GltfSceneSource>()
            .init_resource::<GltfExtensionHandlers>();
        app.world_mut()
            .resource_mut::<GltfExtensionHandlers>()
            .0
            .write_blocking()
            .push(Box::new(gltf_tags::TagHandler::default()));
        app.add_observer(instance::rebind_respawned);
        app.configure_sets(
            PostUpdate,
            (
                SkinletSystems::Bind.before(VisibilitySystems::CalculateBounds),
                SkinletSystems::UpdateBounds
                    .after(VisibilitySystems::CalculateBounds)
                    .before(VisibilitySystems::CheckVisibility),
            ),
        );
        app.add_systems(
            PostUpdate,
            (
                (instance::rebind_changed_bakes, instance::bind_instances, apply_settings)
                    .chain()
                    .in_set(SkinletSystems::Bind),
                instance::update_bounds.in_set(SkinletSystems::UpdateBounds),
            ),
        );
    }
}

/// When the settings change, hands every bound entity to the chosen bounds.
fn apply_settings(
    mut commands: Commands,
    settings: Res<SkinletSettings>,
    instances: Query<&SkinletInstance>,
    skinned: Query<(Has<SkinnedMesh>, &Mesh3d)>,
    meshes: Res<Assets<Mesh>>,
    mut aabbs: Query<&mut bevy::camera::primitives::Aabb>,
) {
    if !settings.is_changed() || settings.is_added() {
        return;
    }
    for &e in instances.iter().flat_map(SkinletInstance::part_entities) {
        match settings.bounds {
            BoundsSource::Skinlet => {
                commands.entity(e).remove::<DynamicSkinnedMeshBounds>().insert(NoAutoAabb);
            }
            BoundsSource::Bevy => {
                commands.entity(e).remove::<NoAutoAabb>();
                let Ok((is_skinned, mesh)) = skinned.get(e) else { continue };
                if is_skinned {
                    commands.entity(e).insert(DynamicSkinnedMeshBounds);
                } else if let (Some(aabb), Ok(mut a)) =
                    (meshes.get(mesh).and_then(|m| m.compute_aabb()), aabbs.get_mut(e))
                {
                    *a = aabb;
                }
            }
        }
    }
}
