//! Skinned characters drawn by meshlet in Bevy's own passes, culled on the GPU by skinlet.
//!
//! Put [`SkinletMeshlets`] beside [`crate::SkinletBounds`] on a scene root and add
//! [`SkinletMeshletPlugin`]: once the instance is bound to its bake, Bevy stops drawing its
//! parts (they are hidden, their visibility kept in [`SkinletDrawnPart`]) and skinlet draws
//! them instead, every instance of a bake in one indexed indirect draw:
//! - per frame, each instance's palette comes from the drivers' `GlobalTransform`s (the joints
//!   Bevy animated) times the bake's inverse bind matrices, its morph weights and its pose
//!   guard's answer from the bounds plugin ([`crate::SkinletInstance::pose`]);
//! - before the cameras render (a system in Bevy's `RenderGraph` schedule), skinlet's crowd
//!   culling and triangle pass (`skinlet_gpu::crowd_culling`, `triangle_culling`) run for each
//!   camera (and each shadow view) on Bevy's own device and encoder, each writing its own
//!   compacted list of triangle corners (its room grows to what the culling finds,
//!   [`SkinletMeshletSettings::list_triangles`]); the counts are read back into
//!   [`SkinletMeshletStats`]; with occlusion culling
//!   ([`SkinletMeshletSettings::occlusion_rounds`], the first camera) in rounds over the
//!   instances nearest first, each round's lists drawn depth only into a depth buffer of
//!   skinlet's own (`meshlet_occlusion.wgsl`) that the next round's tests read;
//! - where Bevy culls the first camera by occlusion too (`OcclusionCulling`), that camera's
//!   occlusion culling runs in its `Core3d` schedule between Bevy's early and late prepasses,
//!   skinlet's depth starting as Bevy's after the early prepass: Bevy's meshes hide
//!   characters;
//! - a phase item in `Opaque3d` draws that list (both lists with occlusion culling) with
//!   Bevy's view bindings (groups 0 and 1), skinning each corner's bake vertex with the
//!   function the culling tested (so the culling is conservative for this draw) and its
//!   source vertex's normal, tangent and texture coordinates (the bake's `SRCT` section,
//!   `skinlet_runtime::source_corners`; normals and tangents morphed as Bevy morphs them),
//!   shaded by Bevy's PBR functions with the part's `StandardMaterial` as Bevy uploads it
//!   and its textures, the normal map too (group 3, where the device indexes texture arrays
//!   per fragment);
//! - a double-sided part (`cull_mode: None`) is neither backface-culled by meshlet nor by
//!   triangle, and its bake is drawn with no faces culled, the other parts' back faces
//!   discarded per fragment;
//! - a part is hidden as Bevy would hide it (its visibility when skinlet took it over, else
//!   its node's): a bit per instance and part collapses its triangles in every pass;
//! - a phase item in each shadow view (`Shadow`) draws that view's own culled list (a crowd
//!   culling and triangle pass per shadow view, with the light's projection), depth only,
//!   with Bevy's prepass view bindings (but a part marked `NotShadowCaster`);
//! - a phase item in a camera's prepass (`Opaque3dPrepass`, with `DepthPrepass` or
//!   `NormalPrepass`) draws the camera's culled list: depth, and the world normals and motion
//!   vectors as Bevy's prepass writes them (the frame before's palettes and morph weights
//!   after this frame's in the same buffers).
//!
//! Not yet: occlusion culling in shadow views or cameras but the first, characters hiding
//! Bevy's meshes from Bevy's occlusion culling (they are not in its early prepass), materials
//! other than `StandardMaterial` (such a part stays Bevy's too, with a warning), a visibility
//! set on a part's mesh entity while skinlet draws it (hide its node instead, or set
//! [`SkinletDrawnPart::visibility`]).

use crate::SkinletBounds;
use crate::bake_asset::Bake;
use crate::instance::{SkinletError, SkinletInstance};
use bevy::camera::visibility::{self, NoFrustumCulling, VisibilityClass};
use bevy::core_pipeline::core_3d::{CORE_3D_DEPTH_FORMAT, Opaque3d, Opaque3dBatchSetKey, Opaque3dBinKey};
use bevy::core_pipeline::prepass::DepthPrepass;
use bevy::core_pipeline::prepass::node::{early_prepass, late_prepass};
use bevy::core_pipeline::prepass::{Opaque3dPrepass, OpaqueNoLightmap3dBatchSetKey, OpaqueNoLightmap3dBinKey};
use bevy::core_pipeline::schedule::{Core3d, camera_driver};
use bevy::ecs::query::ROQueryItem;
use bevy::ecs::schedule::ScheduleLabel;
use bevy::ecs::system::{SystemParamItem, lifetimeless::SRes};
use bevy::light::NotShadowCaster;
use bevy::mesh::{Indices, MeshVertexBufferLayouts, PrimitiveTopology, UvChannel, VertexAttributeValues};
use bevy::pbr::{
    LightEntity, MeshPipeline, MeshPipelineKey, MeshPipelineSystems, PrepassPipeline, SetMeshViewBindGroup,
    SetMeshViewBindingArrayBindGroup, SetPrepassViewBindGroup, SetPrepassViewEmptyBindGroup, Shadow, ShadowBatchSetKey,
    ShadowBinKey, StandardMaterialUniform, ViewKeyCache,
};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::camera::{DirtySpecializations, ExtractedCamera, PendingQueues, TemporalJitter};
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::mesh::allocator::MeshSlabs;
use bevy::render::occlusion_culling::OcclusionCulling;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_phase::{
    AddRenderCommand, BinnedPhaseItem, BinnedRenderPhase, BinnedRenderPhaseType, DrawFunctions, InputUniformIndex,
    PhaseItem, RenderCommand, RenderCommandResult, SetItemPipeline, TrackedRenderPass, ViewBinnedRenderPhases,
};
use bevy::render::render_resource::{
    AsBindGroupShaderType, BindGroup, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    CachedRenderPipelineId, ColorTargetState, ColorWrites, CompareFunction, DepthStencilState, Face, FragmentState,
    IndexFormat, MultisampleState, PipelineCache, PrimitiveState, RenderPipelineDescriptor, SamplerBindingType,
    ShaderStages, ShaderType, SpecializedMeshPipeline, SpecializedRenderPipeline, SpecializedRenderPipelines,
    TextureSampleType, VertexState,
    binding_types::{sampler, storage_buffer_read_only_sized, texture_2d, uniform_buffer_sized},
    encase,
};
use bevy::render::renderer::{RenderAdapter, RenderContext, RenderDevice, RenderGraph, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::texture::{FallbackImage, GpuImage};
use bevy::render::view::RetainedViewEntity;
use bevy::render::view::{ExtractedView, NoIndirectDrawing, RenderVisibleEntities, ViewDepthTexture};
use bevy::render::{Extract, ExtractSchedule, Render, RenderApp, RenderStartup, RenderSystems};
use bevy::shader::ShaderDefVal;
use skinlet_gpu::crowd_culling::{
    CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter, List, MAX_OCCLUSION_ROUNDS, OcclusionDepth,
    SurvivorHeader, subpixel_bits,
};
use skinlet_gpu::crowd_skinning::{CROWD_SKIN_WGSL, CrowdMesh, layout_entries};
use skinlet_gpu::triangle_culling::{
    Entries, Raster, TRIANGLES_WGSL, TriangleCulling, TriangleHeader, TriangleSkinning,
};
use skinlet_runtime::camera::{Camera as CullCamera, Projection};
use skinlet_runtime::meshlet_cull::Tests;
use skinlet_runtime::part_bounds::PoseBounds;
use skinlet_runtime::source_corners::{PartSource, source_corners};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

/// Put beside [`crate::SkinletBounds`] on a scene root: skinlet draws the scene's parts by
/// meshlet (culled on the GPU) instead of Bevy's mesh pipeline.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct SkinletMeshlets;

/// On a part entity skinlet draws: the visibility it had. While skinlet draws it, it is
/// `Visibility::Hidden`, so Bevy's pipeline draws neither it nor its shadow (skinlet draws
/// both, as this visibility and its node's say); removing [`SkinletMeshlets`] from the root
/// puts the visibility back. To hide or show the part meanwhile, set this visibility (or its
/// node's), not the entity's.
#[derive(Component, Clone, Copy, Debug)]
pub struct SkinletDrawnPart {
    pub visibility: Visibility,
}

/// The entity whose phase item draws every instance of one bake (spawned by the plugin).
#[derive(Component, Clone, Debug, ExtractComponent)]
#[require(VisibilityClass)]
#[component(on_add = visibility::add_visibility_class::<SkinletMeshletDraw>)]
pub struct SkinletMeshletDraw {
    pub bake: AssetId<Bake>,
}

/// The meshlet draw's settings, a resource (extracted every frame).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, ExtractResource)]
pub struct SkinletMeshletSettings {
    /// Cull on the GPU (meshlets, then triangles); `false` draws every triangle of every
    /// instance (the reference the culled image must equal).
    pub culling: bool,
    /// Occlusion culling in this many rounds (0: none; at most
    /// [`skinlet_gpu::crowd_culling::MAX_OCCLUSION_ROUNDS`]): skinlet draws the characters'
    /// depth into a depth buffer of its own, round by round (instances nearest the camera
    /// first), testing each round's meshlets and triangles against what the earlier rounds
    /// drew; Bevy's passes then draw the survivors of every round. Without Bevy's occlusion
    /// culling on the camera this runs before Bevy's passes and only characters occlude
    /// characters. With it (`OcclusionCulling` and `DepthPrepass` on the camera, its viewport
    /// the whole target, no `TemporalJitter`, Bevy's 3D schedule), it runs between Bevy's
    /// early and late prepasses, in at least one round, and skinlet's depth starts as Bevy's
    /// after its early prepass: Bevy's meshes hide characters too
    /// ([`MeshletStats::bevy_occluders`]).
    pub occlusion_rounds: u32,
    /// Room each view's triangle lists start with, per bake, in triangles (24 bytes each): a
    /// list that overflows (the triangles past its room are not drawn, counted in
    /// [`MeshletStats::triangles_dropped`]) is made again, when its counts are read back a
    /// frame or two later, with room for twice what that frame's culling found (to a power of
    /// two), and never shrinks; at most every triangle of every instance, up to the device's
    /// storage binding limit. `u32::MAX`: that room from the start (no frame
    /// drops a triangle; memory for every triangle of every instance in every view).
    pub list_triangles: u32,
}

impl Default for SkinletMeshletSettings {
    fn default() -> Self {
        SkinletMeshletSettings { culling: true, occlusion_rounds: 0, list_triangles: 1 << 18 }
    }
}

/// What the meshlet draw drew, per bake: a main-world resource the render world fills in as
/// the GPU's counts are read back (a frame or two after they were drawn; nothing waits).
#[derive(Resource, Clone, Default)]
pub struct SkinletMeshletStats(Arc<Mutex<HashMap<AssetId<Bake>, MeshletStats>>>);

impl SkinletMeshletStats {
    /// The latest counts read back for each bake drawn.
    pub fn latest(&self) -> HashMap<AssetId<Bake>, MeshletStats> {
        self.0.lock().map(|m| m.clone()).unwrap_or_default()
    }

    fn set(&self, bake: AssetId<Bake>, stats: MeshletStats) {
        if let Ok(mut m) = self.0.lock() {
            m.insert(bake, stats);
        }
    }
}

/// One bake's counts in one frame (every instance of the bake is in one draw).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshletStats {
    /// The render frame counted (the plugin counts frames from 1).
    pub frame: u64,
    /// Whether the frame was culled ([`SkinletMeshletSettings::culling`]); the counts below
    /// are the first camera's (each other camera culls its own list, not counted).
    pub culled: bool,
    /// Occlusion culling's rounds (0: none).
    pub occlusion_rounds: u32,
    /// Whether occlusion culling started from Bevy's depth after its early prepass (Bevy's
    /// meshes hide characters; see [`SkinletMeshletSettings::occlusion_rounds`]).
    pub bevy_occluders: bool,
    pub instances: u32,
    /// Meshlets of every instance.
    pub meshlets_total: u64,
    /// Meshlets that passed the meshlet tests (frustum and normal cone, and with occlusion
    /// culling the depth pyramid).
    pub meshlets_tested_visible: u64,
    /// Meshlets with at least one triangle drawn.
    pub meshlets_drawn: u64,
    /// Triangles of every instance.
    pub triangles_total: u64,
    pub triangles_drawn: u64,
    /// Triangles kept that the list had no room for (not drawn; 0 unless the list overflowed),
    /// the camera's and the shadow views'.
    pub triangles_dropped: u64,
    /// The room of each of the camera's lists, in triangles
    /// ([`SkinletMeshletSettings::list_triangles`]).
    pub list_triangles: u32,
    /// Shadow views counted (at most [`MAX_COUNTED_SHADOW_VIEWS`]; each draws its own culled
    /// list), the triangles of every instance in each, and those drawn.
    pub shadow_views: u32,
    pub shadow_triangles_total: u64,
    pub shadow_triangles_drawn: u64,
}

/// The shadow views whose counts [`SkinletMeshletStats`] reads back, per bake (a view past
/// them has list room for every triangle).
pub const MAX_COUNTED_SHADOW_VIEWS: usize = 32;

/// The cameras but the first whose counts are read back (to grow their lists), per bake (a
/// camera past them has list room for every triangle).
const READ_CAMERAS: usize = 8;

/// Draws the parts of scene instances marked [`SkinletMeshlets`] by meshlet (see the module
/// documentation). Needs [`crate::SkinletPlugin`] and Bevy's renderer.
#[derive(Default)]
pub struct SkinletMeshletPlugin;

impl Plugin for SkinletMeshletPlugin {
    fn build(&self, app: &mut App) {
        // Both shaders: the crowd skinning in group 2, then group 2's other shared bindings.
        let group2 = [CROWD_SKIN_WGSL.replace("@group(1)", "@group(2)").as_str(), GROUP2_WGSL].concat();
        let shader = {
            let source = [group2.as_str(), MATERIALS_WGSL, TRIANGLES_WGSL, DRAW_WGSL].concat();
            app.world_mut().resource_mut::<Assets<Shader>>().add(Shader::from_wgsl(source, "skinlet/meshlet_draw.wgsl"))
        };
        let depth_shader = {
            let source = [group2.as_str(), MATERIALS_WGSL, TRIANGLES_WGSL, DEPTH_WGSL].concat();
            app.world_mut()
                .resource_mut::<Assets<Shader>>()
                .add(Shader::from_wgsl(source, "skinlet/meshlet_depth.wgsl"))
        };
        let stats = SkinletMeshletStats::default();
        app.init_resource::<BakeDraws>()
            .init_resource::<SkinletMeshletSettings>()
            .insert_resource(stats.clone())
            .add_plugins((
                ExtractComponentPlugin::<SkinletMeshletDraw>::default(),
                ExtractResourcePlugin::<SkinletMeshletSettings>::default(),
            ))
            .add_systems(
                PostUpdate,
                (give_back_parts, take_over_parts, build_bake_draws).chain().after(crate::SkinletSystems::Bind),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        render_app
            .insert_resource(DrawShader(shader))
            .insert_resource(DepthShader(depth_shader))
            .insert_resource(stats)
            .init_resource::<MeshletFrames>()
            .init_resource::<MeshletGpu>()
            .init_resource::<PendingMeshletQueues>()
            .init_resource::<SpecializedRenderPipelines<MeshletDrawPipeline>>()
            .init_resource::<SpecializedRenderPipelines<MeshletDepthPipeline>>()
            .add_render_command::<Opaque3d, DrawMeshletCommands>()
            .add_render_command::<Opaque3dPrepass, DrawMeshletPrepassCommands>()
            .add_render_command::<Shadow, DrawMeshletShadowCommands>()
            .add_systems(RenderStartup, init_pipeline.after(MeshPipelineSystems))
            .add_systems(ExtractSchedule, extract_frames)
            .add_systems(Render, prepare_gpu.in_set(RenderSystems::PrepareResources))
            .add_systems(Render, (queue_draws, queue_shadows, queue_prepass).in_set(RenderSystems::Queue))
            .add_systems(Render, read_back_stats.in_set(RenderSystems::Cleanup))
            .add_systems(RenderGraph, cull.before(camera_driver))
            .add_systems(Core3d, cull_behind_bevy.after(early_prepass).before(late_prepass));
    }
}

const GROUP2_WGSL: &str = include_str!("meshlet_group2.wgsl");
const MATERIALS_WGSL: &str = include_str!("meshlet_materials.wgsl");
const DRAW_WGSL: &str = include_str!("meshlet_draw.wgsl");
const DEPTH_WGSL: &str = include_str!("meshlet_depth.wgsl");

/// Per bake drawn by meshlet: what the render world uploads once.
#[derive(Resource, Default)]
struct BakeDraws(HashMap<AssetId<Bake>, Arc<BakeDraw>>);

/// A bake's static draw data, from the bake and its first bound instance's meshes.
struct BakeDraw {
    /// The bake's bytes, 4-byte aligned (the first `len`).
    words: Vec<u32>,
    len: usize,
    mesh: CrowdMesh,
    /// Per corner id: bake vertex, attribute vertex, part, 0.
    corners: Vec<[u32; 4]>,
    /// The attribute vertices (the parts' source vertices one part after another) as
    /// [`vertex_attributes`] lays them out: normals, tangents and their morph deltas.
    attributes: Vec<[u32; 4]>,
    /// Per attribute vertex, its first and second texture coordinates (the first zero where
    /// the part has none, the second the first where it has none).
    uvs: Vec<[f32; 4]>,
    /// Per driver, its inverse bind matrix.
    inverse_bind: Vec<Mat4>,
    /// Whether the bake has any-pose boxes (its envelope section).
    has_boxes: bool,
}

/// A part entity: whether it has a `StandardMaterial`, its visibility.
type PartShown = (Has<MeshMaterial3d<StandardMaterial>>, Option<&'static Visibility>);

/// Hides from Bevy's pipeline every part of a bound, marked instance that has a
/// `StandardMaterial` (its visibility kept in [`SkinletDrawnPart`]). A part with another kind
/// of material stays Bevy's to draw too (skinlet draws it with `StandardMaterial`'s defaults):
/// a warning names it, once.
fn take_over_parts(
    mut commands: Commands,
    roots: Query<&SkinletInstance, With<SkinletMeshlets>>,
    parts: Query<PartShown, Without<SkinletDrawnPart>>,
    mut warned: Local<bevy::platform::collections::HashSet<Entity>>,
) {
    for instance in &roots {
        for &e in instance.part_entities() {
            match parts.get(e) {
                Ok((true, visibility)) => {
                    let visibility = visibility.copied().unwrap_or_default();
                    commands.entity(e).insert((SkinletDrawnPart { visibility }, Visibility::Hidden));
                }
                Ok((false, _)) if warned.insert(e) => {
                    warn!("skinlet meshlets: part entity {e} has no StandardMaterial: Bevy keeps drawing it too");
                }
                _ => {}
            }
        }
    }
}

/// Gives the parts of instances no longer marked [`SkinletMeshlets`] back to Bevy's pipeline
/// (their visibility again).
fn give_back_parts(
    mut commands: Commands,
    mut unmarked: RemovedComponents<SkinletMeshlets>,
    roots: Query<&SkinletInstance, Without<SkinletMeshlets>>,
    parts: Query<&SkinletDrawnPart>,
) {
    for root in unmarked.read() {
        let Ok(instance) = roots.get(root) else { continue };
        for &e in instance.part_entities() {
            if let Ok(part) = parts.get(e) {
                commands.entity(e).insert(part.visibility).remove::<SkinletDrawnPart>();
            }
        }
    }
}

/// Marked scene roots not in error.
type Marked = (With<SkinletMeshlets>, Without<SkinletError>);

/// Builds each bake's [`BakeDraw`] once its first marked instance is bound and its meshes are
/// loaded; an error (a bake without `SRCT`, a mesh that is not the bake's) goes on the root.
fn build_bake_draws(
    mut commands: Commands,
    mut draws: ResMut<BakeDraws>,
    roots: Query<(Entity, &SkinletInstance, &SkinletBounds), Marked>,
    parts: Query<&Mesh3d>,
    bakes: Res<Assets<Bake>>,
    meshes: Res<Assets<Mesh>>,
) {
    for (root, instance, bounds) in &roots {
        let id = bounds.0.id();
        if draws.0.contains_key(&id) {
            continue;
        }
        let Some(bake) = bakes.get(id) else { continue };
        let loaded: Option<Vec<&Mesh>> =
            instance.part_entities().iter().map(|&e| parts.get(e).ok().and_then(|m| meshes.get(&m.0))).collect();
        let Some(loaded) = loaded else { continue };
        match bake_draw(bake, &loaded) {
            Ok(draw) => {
                commands.spawn((
                    SkinletMeshletDraw { bake: id },
                    Transform::default(),
                    Visibility::default(),
                    NoFrustumCulling,
                ));
                draws.0.insert(id, Arc::new(draw));
            }
            Err(message) => {
                error!("skinlet meshlets: {message}");
                commands.entity(root).insert(SkinletError(message));
            }
        }
    }
}

/// A bake's draw data with `meshes` (one per part, Bevy's meshes of the parts' glTF
/// primitives).
fn bake_draw(bake: &Bake, meshes: &[&Mesh]) -> Result<BakeDraw, String> {
    let view = bake.view().map_err(|e| e.to_string())?;
    let mut sources = Vec::with_capacity(meshes.len());
    let mut attributes = VertexAttributes::default();
    let mut uvs = Vec::new();
    let mut offsets = Vec::with_capacity(meshes.len());
    let mut indices = Vec::with_capacity(meshes.len());
    let mut positions = Vec::with_capacity(meshes.len());
    for (p, mesh) in meshes.iter().enumerate() {
        if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
            return Err(format!("part {p}: a {:?} mesh (triangle lists only)", mesh.primitive_topology()));
        }
        let Some(VertexAttributeValues::Float32x3(pos)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
            return Err(format!("part {p}: no f32 positions"));
        };
        let Some(VertexAttributeValues::Float32x3(nor)) = mesh.attribute(Mesh::ATTRIBUTE_NORMAL) else {
            return Err(format!("part {p}: no f32 normals"));
        };
        offsets.push(uvs.len() as u32);
        let tangents = match mesh.attribute(Mesh::ATTRIBUTE_TANGENT) {
            Some(VertexAttributeValues::Float32x4(t)) if t.len() == nor.len() => Some(t.as_slice()),
            Some(_) => return Err(format!("part {p}: tangents not f32 quadruples, one per vertex")),
            None => None,
        };
        // Per morph target of the mesh, its weight among the bake's (its node's target).
        let morphs = mesh.get_morph_targets().unwrap_or(&[]);
        if !morphs.len().is_multiple_of(nor.len().max(1)) {
            return Err(format!("part {p}: {} morph displacements for {} vertices", morphs.len(), nor.len()));
        }
        let node = view.parts().get(p).map(|r| r.node);
        let baked = view.morphs().map_or(&[][..], |m| m.weights);
        let weights = (0..morphs.len() / nor.len().max(1))
            .map(|t| {
                let k = baked.iter().position(|w| Some(w.node) == node && w.target as usize == t);
                k.map(|k| k as u32).ok_or_else(|| format!("part {p}: morph target {t} is not in the bake"))
            })
            .collect::<Result<Vec<u32>, String>>()?;
        attributes.push_part(nor, tangents, morphs, &weights);
        // Both sets of texture coordinates (the second: the first where the mesh has none, as
        // Bevy samples them).
        let uv = |attribute| match mesh.attribute(attribute) {
            Some(VertexAttributeValues::Float32x2(uv)) if uv.len() == nor.len() => Ok(Some(uv)),
            Some(_) => Err(format!("part {p}: texture coordinates not f32 pairs, one per vertex")),
            None => Ok(None),
        };
        let (a, b) = (uv(Mesh::ATTRIBUTE_UV_0)?, uv(Mesh::ATTRIBUTE_UV_1)?);
        uvs.extend((0..nor.len()).map(|v| {
            let a = a.map_or([0.0; 2], |a| a[v]);
            let b = b.map_or(a, |b| b[v]);
            [a[0], a[1], b[0], b[1]]
        }));
        indices.push(match mesh.indices() {
            Some(Indices::U16(i)) => Some(i.iter().map(|&x| x as u32).collect::<Vec<u32>>()),
            Some(Indices::U32(i)) => Some(i.clone()),
            None => None,
        });
        positions.push(pos.clone());
    }
    for (p, pos) in positions.iter().enumerate() {
        sources.push(PartSource { indices: indices[p].as_deref(), vertices: pos.len() as u32, positions: Some(pos) });
    }
    let corners = source_corners(&view, &sources).map_err(|e| e.to_string())?;
    let corners = (corners.iter())
        .map(|c| if c.part == u32::MAX { [0; 4] } else { [c.vertex, offsets[c.part as usize] + c.source, c.part, 0] })
        .collect();
    let mesh = CrowdMesh::pack(&view.mesh_data(), view.joint_count() as u32).map_err(|e| e.to_string())?;
    Ok(BakeDraw {
        words: bake.words().to_vec(),
        len: bake.bytes().len(),
        mesh,
        corners,
        attributes: attributes.finish(),
        uvs,
        inverse_bind: view.inverse_bind().iter().map(Mat4::from_cols_array).collect(),
        has_boxes: bake.has_envelope(),
    })
}

/// The attribute vertices' normals and tangents and their morph deltas, as
/// `meshlet_group2.wgsl` reads them: two entries per vertex (normal and where its deltas
/// start, tangent), one more whose last word is where the last vertex's deltas end, then two
/// entries per delta (normal delta and its morph weight, tangent delta); the floats' bits.
#[derive(Default)]
struct VertexAttributes {
    vertices: Vec<[u32; 4]>,
    deltas: Vec<[u32; 4]>,
}

impl VertexAttributes {
    /// A part's vertices: `normals`, `tangents` (zero without), and `morphs` (Bevy's morph
    /// displacements, target by target) whose target `t` is the bake's morph weight
    /// `weights[t]`; displacements of neither normal nor tangent are left out.
    fn push_part(
        &mut self,
        normals: &[[f32; 3]],
        tangents: Option<&[[f32; 4]]>,
        morphs: &[bevy::mesh::morph::MorphAttributes],
        weights: &[u32],
    ) {
        let bits = |v: Vec3, w: u32| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), w];
        for (v, n) in normals.iter().enumerate() {
            // (Where the deltas start, from the deltas' first entry: made absolute by `finish`.)
            self.vertices.push(bits(Vec3::from_array(*n), self.deltas.len() as u32));
            self.vertices.push(tangents.map_or([0; 4], |t| t[v].map(f32::to_bits)));
            for (t, &weight) in weights.iter().enumerate() {
                let m = morphs[t * normals.len() + v];
                if m.normal != Vec3::ZERO || m.tangent != Vec3::ZERO {
                    self.deltas.extend([bits(m.normal, weight), bits(m.tangent, 0)]);
                }
            }
        }
    }

    fn finish(mut self) -> Vec<[u32; 4]> {
        let base = self.vertices.len() as u32 + 1;
        for v in self.vertices.iter_mut().step_by(2) {
            v[3] += base;
        }
        self.vertices.push([0, 0, 0, base + self.deltas.len() as u32]);
        self.vertices.extend(self.deltas);
        self.vertices
    }
}

/// This frame's instances of each bake, as the render world uploads them.
#[derive(Resource, Default)]
struct MeshletFrames(HashMap<AssetId<Bake>, BakeFrame>);

struct BakeFrame {
    draw: Arc<BakeDraw>,
    /// The per-instance arrays, in the roots' order.
    arrays: InstanceArrays,
    materials: Vec<StandardMaterialUniform>,
    textures: Vec<PartTextures>,
    /// Per part: whether its material shows back faces (`cull_mode: None`, a glTF
    /// double-sided material).
    two_sided: Vec<bool>,
    /// Per instance, where its scene root is (occlusion culling's order, nearest first).
    positions: Vec<Vec3>,
}

/// A part's base colour, metallic-roughness, emissive, occlusion and normal map textures,
/// and which of them its material samples at the second texture coordinates (bit `k`: the
/// `k`-th; `UvChannel::Uv1`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct PartTextures {
    images: [Option<AssetId<Image>>; 5],
    uv_b: u32,
}

/// A frame's per-instance arrays, as uploaded.
#[derive(Default)]
struct InstanceArrays {
    palette: Vec<Mat4>,
    instances: Vec<CullInstance>,
    weights: Vec<f32>,
    /// Per instance, its palette and morph weights of the frame before (this frame's where it
    /// was not drawn then): the motion vectors' previous positions.
    previous_palette: Vec<Mat4>,
    previous_weights: Vec<f32>,
    /// Per instance, twice [`part_words`] words: bit `p % 32` of word `p / 32` set where part
    /// `p` is hidden, then where it casts no shadow.
    part_bits: Vec<u32>,
}

impl InstanceArrays {
    /// Empty, keeping the vectors' room.
    fn clear(&mut self) {
        self.palette.clear();
        self.instances.clear();
        self.weights.clear();
        self.previous_palette.clear();
        self.previous_weights.clear();
        self.part_bits.clear();
    }
}

/// A frame's per-instance arrays reordered nearest the camera first (occlusion culling's
/// rounds take the instances in order); the vectors are kept from frame to frame.
#[derive(Default)]
struct NearestFirst {
    order: Vec<usize>,
    arrays: InstanceArrays,
}

impl NearestFirst {
    fn sort<'a>(&'a mut self, frame: &BakeFrame, eye: Vec3) -> &'a InstanceArrays {
        let distance = |&i: &usize| frame.positions[i].distance_squared(eye);
        self.order.clear();
        self.order.extend(0..frame.arrays.instances.len());
        self.order.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        fn gather<T: Copy>(out: &mut Vec<T>, all: &[T], order: &[usize]) {
            let per = all.len() / order.len().max(1);
            out.clear();
            out.extend(order.iter().flat_map(|&i| &all[i * per..(i + 1) * per]));
        }
        let (out, all, order) = (&mut self.arrays, &frame.arrays, &self.order);
        gather(&mut out.palette, &all.palette, order);
        gather(&mut out.instances, &all.instances, order);
        gather(&mut out.weights, &all.weights, order);
        gather(&mut out.previous_palette, &all.previous_palette, order);
        gather(&mut out.previous_weights, &all.previous_weights, order);
        gather(&mut out.part_bits, &all.part_bits, order);
        &self.arrays
    }
}

/// Words of one bit per part (hidden, casting no shadow) of a bake with `parts` parts.
fn part_words(parts: usize) -> usize {
    parts.div_ceil(32).max(1)
}

/// A scene root's palette and morph weights of the last frame it was drawn.
type LastPose = (Vec<Mat4>, Vec<f32>);

/// A marked scene root: its entity, instance and bounds.
type MarkedRoot = (Entity, &'static SkinletInstance, &'static SkinletBounds);

#[allow(clippy::too_many_arguments)]
fn extract_frames(
    mut frames: ResMut<MeshletFrames>,
    draws: Extract<Res<BakeDraws>>,
    roots: Extract<Query<MarkedRoot, With<SkinletMeshlets>>>,
    globals: Extract<Query<&GlobalTransform>>,
    parts: Extract<Query<&MeshMaterial3d<StandardMaterial>>>,
    no_shadow: Extract<Query<(), With<NotShadowCaster>>>,
    shown: Extract<Query<(&SkinletDrawnPart, &ChildOf)>>,
    inherited: Extract<Query<&InheritedVisibility>>,
    materials: Extract<Res<Assets<StandardMaterial>>>,
    images: Res<RenderAssets<GpuImage>>,
    mut warned: Local<bool>,
    mut previous: Local<HashMap<Entity, LastPose>>,
) {
    for frame in frames.0.values_mut() {
        frame.arrays.clear();
        frame.positions.clear();
    }
    for (root, instance, bounds) in &roots {
        let id = bounds.0.id();
        let Some(draw) = draws.0.get(&id) else { continue };
        let frame = frames.0.entry(id).or_insert_with(|| BakeFrame {
            draw: draw.clone(),
            arrays: InstanceArrays::default(),
            materials: Vec::new(),
            textures: Vec::new(),
            two_sided: Vec::new(),
            positions: Vec::new(),
        });
        if frame.arrays.instances.is_empty() {
            frame.draw = draw.clone();
            frame.materials.clear();
            frame.textures.clear();
            frame.two_sided.clear();
            for &e in instance.part_entities() {
                let m = parts.get(e).ok().and_then(|p| materials.get(&p.0));
                let cull_mode = m.map_or(Some(Face::Back), |m| m.cull_mode);
                if cull_mode == Some(Face::Front) && !std::mem::replace(&mut *warned, true) {
                    warn!("skinlet meshlets: a material culls front faces: skinlet culls its back faces");
                }
                frame.two_sided.push(cull_mode.is_none());
                frame.materials.push(m.map(|m| m.as_bind_group_shader_type(&images)).unwrap_or_default());
                frame.textures.push(m.map_or_else(PartTextures::default, |m| {
                    PartTextures {
                        images: [
                            &m.base_color_texture,
                            &m.metallic_roughness_texture,
                            &m.emissive_texture,
                            &m.occlusion_texture,
                            &m.normal_map_texture,
                        ]
                        .map(|t| t.as_ref().map(|h| h.id())),
                        uv_b: [
                            &m.base_color_channel,
                            &m.metallic_roughness_channel,
                            &m.emissive_channel,
                            &m.occlusion_channel,
                            &m.normal_map_channel,
                        ]
                        .into_iter()
                        .enumerate()
                        .map(|(k, c)| ((*c == UvChannel::Uv1) as u32) << k)
                        .sum(),
                    }
                }));
            }
        }
        let a = &mut frame.arrays;
        let start = a.palette.len();
        for (&e, inverse_bind) in instance.drivers().iter().zip(&draw.inverse_bind) {
            let global = globals.get(e).map_or(Mat4::NAN, |g| g.to_matrix());
            a.palette.push(global * *inverse_bind);
        }
        // The frame before's palette and weights (this frame's for an instance new to it),
        // then this frame's kept for the next.
        let (palette, weights) = (&a.palette[start..], instance.morph_weights());
        let (last_palette, last_weights) = previous.entry(root).or_default();
        let seen = last_palette.len() == palette.len() && last_weights.len() == weights.len();
        a.previous_palette.extend_from_slice(if seen { last_palette } else { palette });
        a.previous_weights.extend_from_slice(if seen { last_weights } else { weights });
        last_palette.clear();
        last_weights.clear();
        last_palette.extend_from_slice(palette);
        last_weights.extend_from_slice(weights);
        let mode = match instance.pose {
            PoseBounds::Clips | PoseBounds::ClipAt { .. } => CullMode::Bounds,
            _ if draw.has_boxes => CullMode::BoxesOnly,
            _ => CullMode::Keep,
        };
        a.instances.push(CullInstance::new(Mat4::IDENTITY, mode));
        frame.positions.push(globals.get(root).map_or(Vec3::ZERO, |g| g.translation()));
        a.weights.extend_from_slice(instance.morph_weights());
        // The parts hidden (the visibility a part had when skinlet took it over, inherited from
        // its node where it is `Inherited`), and those marked `NotShadowCaster` (as Bevy reads
        // the marker: on the mesh entity), a bit each.
        let parts = instance.part_entities();
        let hidden = |e: Entity| match shown.get(e) {
            Ok((part, node)) => match part.visibility {
                Visibility::Hidden => true,
                Visibility::Visible => false,
                Visibility::Inherited => inherited.get(node.parent()).is_ok_and(|v| !v.get()),
            },
            Err(_) => false,
        };
        for bit in [&hidden as &dyn Fn(Entity) -> bool, &|e| no_shadow.contains(e)] {
            a.part_bits.extend((0..part_words(parts.len())).map(|w| {
                (parts.iter().skip(32 * w).take(32).enumerate())
                    .fold(0u32, |bits, (k, &e)| bits | ((bit(e) as u32) << k))
            }));
        }
    }
    frames.0.retain(|_, f| !f.arrays.instances.is_empty());
    previous.retain(|&root, _| roots.contains(root));
}

/// The draw's shader (made in the main world).
#[derive(Resource)]
struct DrawShader(Handle<Shader>);

/// The render pipeline (Bevy's mesh pipeline's view layouts and shader defs for the view's
/// key, skinlet's shader and group 2).
#[derive(Resource)]
struct MeshletDrawPipeline {
    mesh_pipeline: MeshPipeline,
    group2: BindGroupLayoutDescriptor,
    /// The parts' textures, where the device can index binding arrays per fragment.
    group3: Option<BindGroupLayoutDescriptor>,
    shader: Handle<Shader>,
}

/// Texture slots per bake (slot 0 is Bevy's white fallback image).
const TEXTURE_SLOTS: u32 = 16;

fn draw_layout() -> BindGroupLayoutDescriptor {
    let storage = || storage_buffer_read_only_sized(false, None);
    BindGroupLayoutDescriptor::new(
        "skinlet meshlet draw",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (
                uniform_buffer_sized(false, None),
                storage(),
                storage(),
                storage(),
                storage(),
                storage(),
                storage(),
                uniform_buffer_sized(false, None),
                storage(),
                storage(),
            ),
        ),
    )
}

/// Group 3: the bake's textures and samplers, and per part its textures' slots.
fn texture_layout() -> BindGroupLayoutDescriptor {
    let slots = std::num::NonZeroU32::new(TEXTURE_SLOTS).unwrap();
    BindGroupLayoutDescriptor::new(
        "skinlet meshlet textures",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (
                texture_2d(TextureSampleType::Float { filterable: true }).count(slots),
                sampler(SamplerBindingType::Filtering).count(slots),
                storage_buffer_read_only_sized(false, None),
            ),
        ),
    )
}

/// Whether `device` can index binding arrays of textures per fragment, with room for the
/// draw's slots beside what Bevy's own view bindings use.
fn textures_usable(device: &RenderDevice) -> bool {
    let limits = device.limits();
    let room = 4 * TEXTURE_SLOTS;
    device.features().contains(
        wgpu::Features::TEXTURE_BINDING_ARRAY
            | wgpu::Features::SAMPLED_TEXTURE_AND_STORAGE_BUFFER_ARRAY_NON_UNIFORM_INDEXING,
    ) && limits.max_binding_array_elements_per_shader_stage >= room
        && limits.max_binding_array_sampler_elements_per_shader_stage >= room
}

fn init_pipeline(
    mut commands: Commands,
    mesh_pipeline: Res<MeshPipeline>,
    shader: Res<DrawShader>,
    device: Res<RenderDevice>,
) {
    commands.insert_resource(MeshletDrawPipeline {
        mesh_pipeline: mesh_pipeline.clone(),
        group2: draw_layout(),
        group3: textures_usable(&device).then(texture_layout),
        shader: shader.0.clone(),
    });
}

impl SpecializedRenderPipeline for MeshletDrawPipeline {
    /// The view's key, and whether the bake has parts drawn two-sided.
    type Key = (MeshPipelineKey, bool);

    fn specialize(&self, (key, two_sided): (MeshPipelineKey, bool)) -> RenderPipelineDescriptor {
        // What Bevy's forward mesh pipeline uses for this view: its view layouts (groups 0
        // and 1) and shader defs (view key bits and Bevy's cargo features), from a POSITION +
        // NORMAL mesh layout.
        let mut layouts = MeshVertexBufferLayouts::default();
        let layout_mesh = Mesh::new(PrimitiveTopology::TriangleList, bevy::asset::RenderAssetUsages::default())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]])
            .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]]);
        let vertex_layout = layout_mesh.get_mesh_vertex_buffer_layout(&mut layouts);
        let (layout, shader_defs): (Vec<BindGroupLayoutDescriptor>, Vec<ShaderDefVal>) =
            match <MeshPipeline as SpecializedMeshPipeline>::specialize(&self.mesh_pipeline, key, &vertex_layout) {
                Ok(bevy) => {
                    let mut layout = vec![bevy.layout[0].clone(), bevy.layout[1].clone(), self.group2.clone()];
                    let mut defs = bevy.fragment.map(|f| f.shader_defs).unwrap_or_default();
                    if let Some(group3) = &self.group3 {
                        layout.push(group3.clone());
                        defs.push("SKINLET_TEXTURES".into());
                    }
                    if two_sided {
                        defs.push("SKINLET_TWO_SIDED".into());
                    }
                    (layout, defs)
                }
                Err(e) => {
                    error!("skinlet meshlets: Bevy's mesh pipeline does not specialize for this view: {e}");
                    (Vec::new(), Vec::new())
                }
            };
        RenderPipelineDescriptor {
            label: Some("skinlet meshlet draw".into()),
            layout,
            vertex: VertexState {
                shader: self.shader.clone(),
                shader_defs: shader_defs.clone(),
                entry_point: Some("vertex".into()),
                buffers: vec![],
            },
            fragment: Some(FragmentState {
                shader: self.shader.clone(),
                shader_defs,
                entry_point: Some("fragment".into()),
                targets: vec![Some(ColorTargetState {
                    format: key.target_format(),
                    blend: None,
                    write_mask: ColorWrites::ALL,
                })],
            }),
            primitive: PrimitiveState {
                topology: PrimitiveTopology::TriangleList,
                cull_mode: (!two_sided).then_some(Face::Back),
                ..default()
            },
            depth_stencil: Some(DepthStencilState {
                format: CORE_3D_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(CompareFunction::GreaterEqual),
                stencil: default(),
                bias: default(),
            }),
            multisample: MultisampleState { count: key.msaa_samples(), mask: !0, alpha_to_coverage_enabled: false },
            ..default()
        }
    }
}

/// Per bake, its GPU culling and buffers.
#[derive(Resource, Default)]
struct MeshletGpu {
    /// Frames prepared (the frame [`MeshletStats`] name).
    frame: u64,
    /// The first camera this frame: the bakes' own culling is its (the other views have
    /// theirs).
    first_camera: Option<RetainedViewEntity>,
    pipelines: Option<CullPipelines>,
    bakes: HashMap<AssetId<Bake>, BakeGpu>,
    /// Occlusion culling's depth buffer (every bake's rounds draw into it) and its view.
    depth: Option<(wgpu::Texture, wgpu::TextureView)>,
    /// Whether this frame's occlusion culling starts from Bevy's depth after its early
    /// prepass (Bevy's occlusion culling is on the first camera): it runs in that camera's
    /// `Core3d` schedule ([`cull_behind_bevy`]), and `culled` says whether it ran yet (the
    /// early prepass draws none of the first camera's lists).
    bevy_occluders: bool,
    culled: AtomicBool,
    /// Whether this frame's occlusion culling did start from Bevy's depth.
    started_from_bevy: AtomicBool,
    /// Per bake, the room its lists need (kept when its culling is made again).
    needs: HashMap<AssetId<Bake>, ListNeeds>,
}

/// skinlet's own depth pass of a bake's occlusion culling rounds.
struct OcclusionDraw {
    pipeline: wgpu::RenderPipeline,
    /// The view's clip_from_world and the lists' id bits; the corners.
    uniform: wgpu::Buffer,
    group: wgpu::BindGroup,
}

struct BakeGpu {
    culling: TriangleCulling,
    capacity: u32,
    /// The raster the triangle pass was made for, its occlusion culling's rounds (0: none) and
    /// the samples of the depth buffer that reads.
    raster: Raster,
    rounds: u32,
    samples: u32,
    /// Per part, whether it is drawn two-sided ([`BakeFrame::two_sided`]): its meshlets are
    /// not backface-culled, and the draws cull no faces (the others' back faces are
    /// discarded per fragment).
    two_sided: Vec<bool>,
    occlusion: Option<OcclusionDraw>,
    instances: u32,
    palette: wgpu::Buffer,
    instance_buffer: wgpu::Buffer,
    weights: wgpu::Buffer,
    /// Per instance, the parts hidden and those that cast no shadow ([`BakeFrame::part_bits`]).
    part_bits: wgpu::Buffer,
    materials: Buffer,
    skinning: wgpu::BindGroup,
    draw_group: BindGroup,
    triangles: Buffer,
    /// The draw's parameters (id bits, whether this frame is drawn unculled).
    params: wgpu::Buffer,
    id_bits: u32,
    /// Corner ids (MLET's triangle bytes).
    corners: u32,
    unculled: bool,
    /// Per instance: meshlets, triangles.
    meshlets: u32,
    mesh_triangles: u32,
    /// The counts' copy (the survivors' two headers, then the triangle lists' two) and where
    /// it is: [`IDLE`], [`COPIED`] (encoded this frame) or [`MAPPING`].
    readback: wgpu::Buffer,
    readback_state: Arc<AtomicU8>,
    /// Per part its texture slots (group 3), the parts' textures the group was made for, and
    /// whether an image was still loading then (in a slot of Bevy's white fallback image).
    texture_slots: wgpu::Buffer,
    texture_group: Option<BindGroup>,
    texture_parts: Vec<PartTextures>,
    textures_pending: bool,
    /// What another view's culling is made of: the bake's meshlets on the GPU, the skinning's
    /// layout, per meshlet whether it is two-sided.
    character: GpuCharacter,
    skin_layout: wgpu::BindGroupLayout,
    two_sided_meshlets: Vec<bool>,
    /// The room of the first camera's lists; every triangle of every instance (up to the
    /// storage binding limit); the room each list needs (kept across rebuilds).
    triangles_per_list: u32,
    all_triangles: u32,
    needs: ListNeeds,
    /// Per shadow view (a directional light's cascade, a point light's face, a spot light),
    /// and per camera but the first: its culling.
    shadows: HashMap<RetainedViewEntity, ViewCulling>,
    cameras: HashMap<RetainedViewEntity, ViewCulling>,
}

/// Per list of a bake (`None`: the first camera's, else the view's), the room it needs: twice
/// what a frame's culling found past its room, to a power of two.
type ListNeeds = Arc<Mutex<HashMap<Option<RetainedViewEntity>, u32>>>;

/// The room of a list: `start`, or what it needs, up to `all`.
fn list_room(start: u32, needs: &ListNeeds, list: Option<RetainedViewEntity>, all: u32) -> u32 {
    let need = needs.lock().ok().and_then(|n| n.get(&list).copied()).unwrap_or(0);
    start.max(need).min(all).max(1)
}

/// A view's own culling (no occlusion): its triangle pass, its lists (as Bevy binds them),
/// the raster they were made for, and where its list's counts are read back (shadow views
/// first; none past them: then its room is every triangle).
struct ViewCulling {
    culling: TriangleCulling,
    lists: Buffer,
    raster: Raster,
    slot: Option<usize>,
}

/// Keeps a culling for each view of `shadows` and `cameras` (with the raster each is drawn
/// with): made when the view appears, its raster changes or its list needs more room than
/// it has (`start` at first), dropped when it goes.
fn update_view_cullings(
    device: &wgpu::Device,
    pipelines: &CullPipelines,
    b: &mut BakeGpu,
    draw: &BakeDraw,
    shadows: &[(RetainedViewEntity, Raster)],
    cameras: &[(RetainedViewEntity, Raster)],
    start: u32,
) -> Result<(), String> {
    b.shadows.retain(|v, _| shadows.iter().any(|(s, _)| s == v));
    b.cameras.retain(|v, _| cameras.iter().any(|(c, _)| c == v));
    if let Ok(mut needs) = b.needs.lock() {
        let present = |v: &RetainedViewEntity| shadows.iter().chain(cameras).any(|(s, _)| s == v);
        needs.retain(|v, _| v.as_ref().is_none_or(present));
    }
    let slots = [0..MAX_COUNTED_SHADOW_VIEWS, MAX_COUNTED_SHADOW_VIEWS..MAX_COUNTED_SHADOW_VIEWS + READ_CAMERAS];
    for ((views, shadow), slots) in [(shadows, true), (cameras, false)].into_iter().zip(slots) {
        for &(view, raster) in views {
            let have = if shadow { &b.shadows } else { &b.cameras };
            let slot = have
                .get(&view)
                .map(|v| v.slot)
                .unwrap_or_else(|| slots.clone().find(|&k| have.values().all(|v| v.slot != Some(k))));
            let room = match slot {
                Some(_) => list_room(start, &b.needs, Some(view), b.all_triangles),
                None => b.all_triangles,
            };
            if have.get(&view).is_some_and(|v| v.raster == raster && v.culling.capacity() == room) {
                continue;
            }
            let culling = view_culling(device, pipelines, b, draw, raster, room)?;
            let lists = Buffer::from(culling.triangles().clone());
            let have = if shadow { &mut b.shadows } else { &mut b.cameras };
            have.insert(view, ViewCulling { culling, lists, raster, slot });
        }
    }
    Ok(())
}

const IDLE: u8 = 0;
const COPIED: u8 = 1;
const MAPPING: u8 = 2;

/// The view's projection as Bevy's view uniform has it (`prepare_view_uniforms`, unjittered).
fn clip_from_world(view: &ExtractedView) -> Mat4 {
    let view_from_world = view.world_from_view.to_matrix().inverse();
    view.clip_from_world.unwrap_or(view.clip_from_view * view_from_world)
}

/// A shadow view's projection for culling: a directional light's casters in front of its near
/// plane are drawn clamped to it (and those past its far plane would be too), so its depth
/// row is replaced by a constant inside the clip volume (`z = w / 2`): no near or far plane.
fn shadow_clip_from_world(view: &ExtractedView, directional: bool) -> Mat4 {
    let m = clip_from_world(view);
    if !directional {
        return m;
    }
    let mut rows = m.transpose();
    rows.z_axis = rows.w_axis * 0.5;
    rows.transpose()
}

/// The camera a view's culling runs for, with the projection `clip_from_world` (the first
/// active 3D camera's view, or a shadow view).
fn cull_camera(clip_from_world: Mat4, view: &ExtractedView) -> Option<CullCamera> {
    let eye = view.world_from_view.translation();
    let projection = if view.clip_from_view.w_axis.w == 1.0 {
        Projection::Orthographic { dir: view.world_from_view.forward().into() }
    } else {
        Projection::Perspective { eye }
    };
    CullCamera::from_view_proj(clip_from_world, projection).ok()
}

/// The cameras Bevy culls by occlusion (two prepasses, a depth pyramid), without temporal
/// jitter (skinlet's tests take the unjittered projection; Bevy's depth is jittered).
type BevyOcclusionCulling =
    (With<OcclusionCulling>, With<DepthPrepass>, Without<NoIndirectDrawing>, Without<TemporalJitter>);

#[allow(clippy::too_many_arguments)]
fn prepare_gpu(
    mut gpu: ResMut<MeshletGpu>,
    frames: Res<MeshletFrames>,
    device: Res<RenderDevice>,
    adapter: Res<RenderAdapter>,
    queue: Res<RenderQueue>,
    cache: Res<PipelineCache>,
    settings: Res<SkinletMeshletSettings>,
    stats: Res<SkinletMeshletStats>,
    views: Query<(Entity, &ExtractedView, &Msaa), With<ExtractedCamera>>,
    bevy_occlusion: Query<&ExtractedCamera, BevyOcclusionCulling>,
    lights: Query<&ExtractedView, With<LightEntity>>,
    textures: (Option<Res<MeshletDrawPipeline>>, Res<RenderAssets<GpuImage>>, Res<FallbackImage>),
    mut warned: Local<bool>,
    mut material_bytes: Local<Vec<u8>>,
    mut sorted: Local<NearestFirst>,
    mut rasters: Local<[Vec<(RetainedViewEntity, Raster)>; 2]>,
) {
    gpu.frame += 1;
    *gpu.culled.get_mut() = false;
    let Some((entity, view, msaa)) = views.iter().next() else { return };
    // The first camera's culling is the bake's own (with occlusion culling); every other view
    // (the other cameras, the shadow views) has its own.
    gpu.first_camera = Some(view.retained_view_entity);
    let raster = Raster {
        width: view.viewport.z.max(1),
        height: view.viewport.w.max(1),
        subpixel_bits: subpixel_bits(&adapter),
        cull_back_faces: true,
        multisampled: msaa.samples() > 1,
    };
    // Bevy's depth after its early prepass starts occlusion culling where Bevy culls this
    // camera by occlusion too, its depth texture is the viewport's size (skinlet's is) and
    // it renders with Bevy's 3D schedule (where `cull_behind_bevy` runs).
    gpu.bevy_occluders = settings.culling
        && bevy_occlusion.get(entity).is_ok_and(|c| {
            let whole = c.physical_target_size == Some(view.viewport.zw()) && view.viewport.xy() == UVec2::ZERO;
            whole && c.schedule == Core3d.intern()
        });
    *gpu.started_from_bevy.get_mut() = false;
    let rounds = match settings.culling {
        true if gpu.bevy_occluders => settings.occlusion_rounds.clamp(1, MAX_OCCLUSION_ROUNDS),
        true => settings.occlusion_rounds.min(MAX_OCCLUSION_ROUNDS),
        false => 0,
    };
    let view_raster = |v: &ExtractedView, multisampled| Raster {
        width: v.viewport.z.max(1),
        height: v.viewport.w.max(1),
        multisampled,
        ..raster
    };
    // The other views' rasters: the shadow views', the cameras' but the first.
    let [shadow_rasters, camera_rasters] = &mut *rasters;
    shadow_rasters.clear();
    shadow_rasters.extend(lights.iter().map(|l| (l.retained_view_entity, view_raster(l, false))));
    camera_rasters.clear();
    camera_rasters
        .extend(views.iter().skip(1).map(|(_, v, msaa)| (v.retained_view_entity, view_raster(v, msaa.samples() > 1))));
    let wgpu_device = device.wgpu_device();
    let gpu = &mut *gpu;
    let samples = msaa.samples();
    let size = |t: &wgpu::Texture| (t.width(), t.height(), t.sample_count());
    if rounds > 0 && gpu.depth.as_ref().is_none_or(|(t, _)| size(t) != (raster.width, raster.height, samples)) {
        let texture = wgpu_device.create_texture(&wgpu::TextureDescriptor {
            label: Some("skinlet occlusion depth"),
            size: wgpu::Extent3d { width: raster.width, height: raster.height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format: OCCLUSION_DEPTH,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        gpu.depth = Some((texture, view));
    }
    if gpu.pipelines.is_none() {
        match CullPipelines::new(wgpu_device) {
            Ok(p) => gpu.pipelines = Some(p),
            Err(e) => {
                error!("skinlet meshlets: {e}");
                return;
            }
        }
    }
    gpu.bakes.retain(|id, _| frames.0.contains_key(id));
    gpu.needs.retain(|id, _| frames.0.contains_key(id));
    for (&id, frame) in &frames.0 {
        let n = frame.arrays.instances.len() as u32;
        let fits = gpu.bakes.get(&id).is_some_and(|b| {
            b.capacity >= n
                && b.raster == raster
                && b.rounds == rounds
                && (rounds == 0 || b.samples == samples)
                && b.two_sided == frame.two_sided
                && b.triangles_per_list == list_room(settings.list_triangles, &b.needs, None, b.all_triangles)
        });
        if !fits {
            let capacity = n.next_power_of_two().max(4);
            let occlusion = gpu.depth.as_ref().filter(|_| rounds > 0).map(|(_, view)| (view, rounds));
            let pipelines = gpu.pipelines.as_ref().unwrap();
            let lists = (settings.list_triangles, gpu.needs.entry(id).or_default().clone());
            match bake_gpu(wgpu_device, pipelines, &cache, frame, capacity, raster, occlusion, samples, lists) {
                Ok(b) => {
                    gpu.bakes.insert(id, b);
                }
                Err(e) => {
                    error!("skinlet meshlets: {e}");
                    continue;
                }
            }
        }
        let b = gpu.bakes.get_mut(&id).unwrap();
        b.instances = n;
        b.unculled = !settings.culling;
        // The other views' cullings; where one cannot be made, the bake is drawn unculled
        // everywhere.
        let pipelines = gpu.pipelines.as_ref().unwrap();
        if !b.unculled
            && let Err(e) = update_view_cullings(
                wgpu_device,
                pipelines,
                b,
                &frame.draw,
                shadow_rasters,
                camera_rasters,
                settings.list_triangles,
            )
        {
            error!("skinlet meshlets: a view's culling: {e}");
            b.unculled = true;
        }
        if b.unculled {
            let (meshlets, triangles) = (n as u64 * b.meshlets as u64, n as u64 * b.mesh_triangles as u64);
            stats.set(
                id,
                MeshletStats {
                    frame: gpu.frame,
                    culled: false,
                    occlusion_rounds: 0,
                    bevy_occluders: false,
                    instances: n,
                    meshlets_total: meshlets,
                    meshlets_tested_visible: meshlets,
                    meshlets_drawn: meshlets,
                    triangles_total: triangles,
                    triangles_drawn: triangles,
                    triangles_dropped: 0,
                    list_triangles: 0,
                    shadow_views: 0,
                    shadow_triangles_total: 0,
                    shadow_triangles_drawn: 0,
                },
            );
        }
        queue.write_buffer(&b.params, 0, bytemuck::cast_slice(&[b.id_bits, b.unculled as u32]));
        // With occlusion culling, the instances nearest the camera first (the rounds' order).
        let data = match &b.occlusion {
            Some(occlusion) => {
                let mut words = [0u32; 20];
                words[..16].copy_from_slice(&clip_from_world(view).to_cols_array().map(f32::to_bits));
                words[16] = b.id_bits;
                words[17] = part_words(frame.materials.len()) as u32;
                queue.write_buffer(&occlusion.uniform, 0, bytemuck::cast_slice(&words));
                sorted.sort(frame, view.world_from_view.translation())
            }
            None => &frame.arrays,
        };
        queue.write_buffer(&b.part_bits, 0, bytemuck::cast_slice(&data.part_bits));
        // (The frame before's palettes and weights after `capacity` instances' room.)
        let (joints, morphs) = (frame.draw.mesh.uniform[0] as u64, frame.draw.mesh.uniform[2] as u64);
        queue.write_buffer(&b.palette, 0, bytemuck::cast_slice(&data.palette));
        queue.write_buffer(&b.palette, 64 * joints * b.capacity as u64, bytemuck::cast_slice(&data.previous_palette));
        queue.write_buffer(&b.instance_buffer, 0, bytemuck::cast_slice(&data.instances));
        if !data.weights.is_empty() {
            queue.write_buffer(&b.weights, 0, bytemuck::cast_slice(&data.weights));
            let previous = 4 * morphs * b.capacity as u64;
            queue.write_buffer(&b.weights, previous, bytemuck::cast_slice(&data.previous_weights));
        }
        material_bytes.clear();
        if encase::StorageBuffer::new(&mut *material_bytes).write(&frame.materials).is_ok() {
            queue.write_buffer(&b.materials, 0, &material_bytes);
        }
        let (pipeline, images, fallback) = (&textures.0, &textures.1, &textures.2);
        match pipeline.as_ref().and_then(|p| p.group3.as_ref()) {
            Some(layout) if b.texture_group.is_none() || b.textures_pending || b.texture_parts != frame.textures => {
                let layout = cache.get_bind_group_layout(layout);
                texture_group(wgpu_device, &queue, &layout, b, &frame.textures, images, fallback);
            }
            None if !*warned && frame.textures.iter().flat_map(|t| t.images).any(|t| t.is_some()) => {
                warn!("skinlet meshlets: this device cannot index texture arrays per fragment: textures are not drawn");
                *warned = true;
            }
            _ => {}
        }
    }
}

/// Makes a bake's group 3: each distinct texture of its parts in a slot (slot 0, and the slot
/// of an image still loading, is Bevy's white fallback image: multiplying by it changes
/// nothing), and per part its base colour, metallic-roughness, emissive and occlusion slots.
fn texture_group(
    device: &wgpu::Device,
    queue: &RenderQueue,
    layout: &wgpu::BindGroupLayout,
    b: &mut BakeGpu,
    parts: &[PartTextures],
    images: &RenderAssets<GpuImage>,
    fallback: &FallbackImage,
) {
    let mut distinct: Vec<AssetId<Image>> = Vec::new();
    let mut over = false;
    let slots: Vec<[u32; 8]> = (parts.iter())
        .map(|textures| {
            let [a, b, c, d, e] = textures.images.map(|t| {
                let Some(id) = t else { return 0 };
                match distinct.iter().position(|&d| d == id) {
                    Some(k) => k as u32 + 1,
                    None if distinct.len() + 1 < TEXTURE_SLOTS as usize => {
                        distinct.push(id);
                        distinct.len() as u32
                    }
                    None => {
                        over = true;
                        0
                    }
                }
            });
            // (A normal map still loading is none yet: white is no flat normal.)
            let e = if textures.images[4].is_some_and(|id| images.get(id).is_none()) { 0 } else { e };
            [a, b, c, d, e, textures.uv_b, 0, 0]
        })
        .collect();
    if over {
        warn!("skinlet meshlets: a bake's parts use more than {} textures: the rest are not drawn", TEXTURE_SLOTS - 1);
    }
    let uploaded: Vec<Option<&GpuImage>> = distinct.iter().map(|&id| images.get(id)).collect();
    let image = |k: usize| k.checked_sub(1).and_then(|k| uploaded.get(k).copied().flatten()).unwrap_or(&fallback.d2);
    let views: Vec<&wgpu::TextureView> = (0..TEXTURE_SLOTS as usize).map(|k| &*image(k).texture_view).collect();
    let samplers: Vec<&wgpu::Sampler> = (0..TEXTURE_SLOTS as usize).map(|k| &*image(k).sampler).collect();
    queue.write_buffer(&b.texture_slots, 0, bytemuck::cast_slice(&slots));
    b.texture_group = Some(BindGroup::from(device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("skinlet meshlet textures"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureViewArray(&views) },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::SamplerArray(&samplers) },
            wgpu::BindGroupEntry { binding: 2, resource: b.texture_slots.as_entire_binding() },
        ],
    })));
    b.texture_parts = parts.to_vec();
    b.textures_pending = uploaded.iter().any(Option::is_none);
}

/// A bake's culling and buffers for `capacity` instances drawn as `raster` says, with
/// occlusion culling in `occlusion`'s rounds against its depth buffer (of `samples` samples)
/// where given, its lists' room from `list_start` and `needs`.
#[allow(clippy::too_many_arguments)]
fn bake_gpu(
    device: &wgpu::Device,
    pipelines: &CullPipelines,
    cache: &PipelineCache,
    frame: &BakeFrame,
    capacity: u32,
    raster: Raster,
    occlusion: Option<(&wgpu::TextureView, u32)>,
    samples: u32,
    (list_start, needs): (u32, ListNeeds),
) -> Result<BakeGpu, String> {
    use wgpu::util::DeviceExt;
    let draw = &frame.draw;
    let e = |e: skinlet_gpu::GpuError| e.to_string();
    let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
    let init = |label: &str, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let zeros = |label: &str, bytes: u64, usage| init(label, &vec![0u8; bytes.max(16) as usize], usage);
    let joints = draw.mesh.uniform[0] as u64;
    let morphs = draw.mesh.uniform[2] as u64;
    // (Room for the frame before's palettes and weights after this frame's: motion vectors.)
    let palette = zeros("skinlet palette", 2 * 64 * joints * capacity as u64, storage);
    let instance_buffer = zeros("skinlet instances", 80 * capacity as u64, storage);
    let weights = zeros("skinlet morph weights", 2 * 4 * morphs.max(1) * capacity as u64, storage);
    let bits_words = part_words(frame.materials.len()) as u64;
    let part_bits = zeros("skinlet part bits", 2 * 4 * bits_words * capacity as u64, storage);
    let skin_uniform = init("skinlet skin", bytemuck::cast_slice(&draw.mesh.uniform), wgpu::BufferUsages::UNIFORM);
    let words = init("skinlet mesh", bytemuck::cast_slice(&draw.mesh.words), wgpu::BufferUsages::STORAGE);
    // (Each corner's last word: 1 where its part is drawn two-sided.)
    let two_sided = |part: u32| frame.two_sided.get(part as usize) == Some(&true);
    let corner_words: Vec<[u32; 4]> =
        (draw.corners.iter()).map(|&[v, a, p, _]| [v, a, p, two_sided(p) as u32]).collect();
    let corners = init("skinlet corners", bytemuck::cast_slice(&corner_words), wgpu::BufferUsages::STORAGE);
    let attributes = init("skinlet attributes", bytemuck::cast_slice(&draw.attributes), wgpu::BufferUsages::STORAGE);
    let uvs = init("skinlet uvs", bytemuck::cast_slice(&draw.uvs), wgpu::BufferUsages::STORAGE);
    let texture_slots = zeros("skinlet texture slots", 32 * frame.materials.len().max(1) as u64, storage);
    let material_size = StandardMaterialUniform::min_size().get();
    let materials = zeros("skinlet materials", material_size * frame.materials.len().max(1) as u64, storage);
    let bytes = &bytemuck::cast_slice::<u32, u8>(&draw.words)[..draw.len];
    let view = skinlet_runtime::bake_view::BakeView::new(bytes).map_err(|e| e.to_string())?;
    let culler = view.two_sided_culler(&frame.two_sided).map_err(|e| e.to_string())?;
    let meshlets = view.meshlets();
    let vertices = view.vertices().positions.len();
    let (_, draws) = skinlet_gpu::mesh::meshlet_index_buffer(&meshlets, vertices).map_err(e)?;
    let character = GpuCharacter::new(device, &culler, &draw.inverse_bind, &draws).map_err(e)?;
    let survivors = capacity * character.most_drawn();
    let crowd = match occlusion {
        Some((view, rounds)) => {
            let Raster { width, height, subpixel_bits, multisampled, .. } = raster;
            let depth = OcclusionDepth { view, width, height, reversed: true, subpixel_bits, multisampled, rounds };
            CrowdCulling::with_occlusion(
                device,
                pipelines,
                &character,
                &palette,
                &instance_buffer,
                capacity,
                survivors,
                depth,
            )
        }
        None => CrowdCulling::new(device, pipelines, &character, &palette, &instance_buffer, capacity, survivors),
    }
    .map_err(e)?;
    // (The culling's compute passes and skinlet's own depth pass skin with it.)
    let skin_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("skinlet skinning"),
        entries: &layout_entries(wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::VERTEX),
    });
    fn bind(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
        wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
    }
    let skinning = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("skinlet skinning"),
        layout: &skin_layout,
        entries: &[bind(0, &skin_uniform), bind(1, &palette), bind(2, &words), bind(3, &weights)],
    });
    let (margin, relative) = draw.mesh.margins();
    let how = TriangleSkinning { wgsl: CROWD_SKIN_WGSL, layout: &skin_layout, margin, relative };
    let all_triangles = all_triangles(device, capacity, view.triangles().len() as u32);
    let triangles_per_list = list_room(list_start, &needs, None, all_triangles);
    let two_sided_meshlets = view.meshlets_of_parts(&frame.two_sided);
    let culling = TriangleCulling::new(
        device,
        crowd,
        how,
        &meshlets,
        vertices as u32,
        triangles_per_list,
        raster,
        Entries::Corners,
        &two_sided_meshlets,
    )
    .map_err(e)?;
    let params = init(
        "skinlet draw params",
        bytemuck::cast_slice(&[culling.id_bits(), 0, bits_words as u32, capacity]),
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    );
    let draw_layout = cache.get_bind_group_layout(&draw_layout());
    let entries: Vec<wgpu::BindGroupEntry> =
        [&skin_uniform, &palette, &words, &weights, &corners, &attributes, &materials, &params, &uvs, &part_bits]
            .iter()
            .enumerate()
            .map(|(b, buffer)| bind(b as u32, buffer))
            .collect();
    let draw_group = BindGroup::from(device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("skinlet meshlet draw"),
        layout: &draw_layout,
        entries: &entries,
    }));
    let culling_id_bits = culling.id_bits();
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("skinlet meshlet counts"),
        size: 2 * (SurvivorHeader::SIZE + TriangleHeader::SIZE)
            + (MAX_COUNTED_SHADOW_VIEWS + READ_CAMERAS) as u64 * TriangleHeader::SIZE,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let any_two_sided = frame.two_sided.contains(&true);
    let occlusion =
        occlusion.map(|_| occlusion_draw(device, &skin_layout, &corners, &part_bits, samples, any_two_sided));
    Ok(BakeGpu {
        samples,
        two_sided: frame.two_sided.clone(),
        rounds: occlusion.as_ref().map_or(0, |_| culling.crowd().occlusion_rounds()),
        occlusion,
        meshlets: character.meshlets(),
        mesh_triangles: view.triangles().len() as u32,
        readback,
        readback_state: Arc::new(AtomicU8::new(IDLE)),
        texture_slots,
        texture_group: None,
        texture_parts: Vec::new(),
        textures_pending: false,
        triangles: Buffer::from(culling.triangles().clone()),
        culling,
        capacity,
        raster,
        instances: 0,
        palette,
        instance_buffer,
        weights,
        part_bits,
        materials: Buffer::from(materials),
        skinning,
        draw_group,
        id_bits: culling_id_bits,
        corners: draw.corners.len() as u32,
        params,
        unculled: false,
        character,
        skin_layout,
        two_sided_meshlets,
        triangles_per_list,
        all_triangles,
        needs,
        shadows: HashMap::default(),
        cameras: HashMap::default(),
    })
}

/// A view's own culling of the bake `b` (of `draw`): crowd culling of its instances (no
/// occlusion), then their triangles, drawn as `raster` says.
fn view_culling(
    device: &wgpu::Device,
    pipelines: &CullPipelines,
    b: &BakeGpu,
    draw: &BakeDraw,
    raster: Raster,
    room: u32,
) -> Result<TriangleCulling, String> {
    let e = |e: skinlet_gpu::GpuError| e.to_string();
    let bytes = &bytemuck::cast_slice::<u32, u8>(&draw.words)[..draw.len];
    let view = skinlet_runtime::bake_view::BakeView::new(bytes).map_err(|e| e.to_string())?;
    let survivors = b.capacity * b.character.most_drawn();
    let (palette, instances) = (&b.palette, &b.instance_buffer);
    let crowd = CrowdCulling::new(device, pipelines, &b.character, palette, instances, b.capacity, survivors);
    let (margin, relative) = draw.mesh.margins();
    let how = TriangleSkinning { wgsl: CROWD_SKIN_WGSL, layout: &b.skin_layout, margin, relative };
    let vertices = view.vertices().positions.len() as u32;
    let (meshlets, sides) = (view.meshlets(), &b.two_sided_meshlets);
    TriangleCulling::new(device, crowd.map_err(e)?, how, &meshlets, vertices, room, raster, Entries::Corners, sides)
        .map_err(e)
}

/// Every triangle of `capacity` instances of `triangles` each, up to what a list of the
/// storage binding limit holds.
fn all_triangles(device: &wgpu::Device, capacity: u32, triangles: u32) -> u32 {
    let limit = (device.limits().max_storage_buffer_binding_size - 2 * TriangleHeader::SIZE) / 24;
    (capacity as u64 * triangles as u64).min(limit) as u32
}

/// Occlusion culling's depth format (Bevy's main pass depth: reversed, near 1).
const OCCLUSION_DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// skinlet's own depth pass over a bake's triangle lists (`meshlet_occlusion.wgsl`: the
/// crowd skinning in group 1, its `skinning` bind group), with the camera's `samples`;
/// `two_sided`: the bake has parts drawn two-sided (no faces culled, the other parts' back
/// faces discarded).
fn occlusion_draw(
    device: &wgpu::Device,
    skin_layout: &wgpu::BindGroupLayout,
    corners: &wgpu::Buffer,
    part_bits: &wgpu::Buffer,
    samples: u32,
    two_sided: bool,
) -> OcclusionDraw {
    let source = [CROWD_SKIN_WGSL, TRIANGLES_WGSL, include_str!("meshlet_occlusion.wgsl")].concat();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("skinlet occlusion depth"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    };
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("skinlet occlusion depth"),
        entries: &[
            entry(0, wgpu::BufferBindingType::Uniform),
            entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
            entry(2, wgpu::BufferBindingType::Storage { read_only: true }),
        ],
    });
    let uniform = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("skinlet occlusion view"),
        size: 80,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("skinlet occlusion depth"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: corners.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: part_bits.as_entire_binding() },
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("skinlet occlusion depth"),
        bind_group_layouts: &[Some(&layout), Some(skin_layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("skinlet occlusion depth"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vertex"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState { cull_mode: (!two_sided).then_some(wgpu::Face::Back), ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: OCCLUSION_DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::GreaterEqual),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState { count: samples, ..Default::default() },
        fragment: two_sided.then_some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("two_sided_fragment"),
            compilation_options: Default::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    });
    OcclusionDraw { pipeline, uniform, group }
}

/// Before the cameras render: each bake's culling for each camera and shadow view, and the
/// first camera's occlusion culling ([`cull_occluding`]) unless it starts from Bevy's depth.
fn cull(
    mut ctx: RenderContext,
    gpu: Res<MeshletGpu>,
    queue: Res<RenderQueue>,
    views: Query<&ExtractedView, With<ExtractedCamera>>,
    lights: Query<(&ExtractedView, &LightEntity)>,
) {
    let first = views.iter().find(|v| Some(v.retained_view_entity) == gpu.first_camera);
    let Some(camera) = first.and_then(|v| cull_camera(clip_from_world(v), v)) else { return };
    let encoder = ctx.command_encoder();
    for b in gpu.bakes.values().filter(|b| b.instances > 0 && !b.unculled) {
        let (c, skinning, n) = (&b.culling, &b.skinning, b.instances);
        // Each other view's: the other cameras', each shadow view's for the light's view.
        let shadows = lights.iter().map(|(light, kind)| {
            let directional = matches!(kind, LightEntity::Directional { .. });
            (b.shadows.get(&light.retained_view_entity), shadow_clip_from_world(light, directional), light)
        });
        let cameras = views.iter().map(|v| (b.cameras.get(&v.retained_view_entity), clip_from_world(v), v));
        for (culling, clip_from_world, view) in shadows.chain(cameras) {
            let (Some(ViewCulling { culling, .. }), Some(camera)) = (culling, cull_camera(clip_from_world, view))
            else {
                continue;
            };
            if let Err(e) = culling.encode(&queue, encoder, &camera, Tests::Both, n, skinning, None) {
                error!("skinlet meshlets: {e}");
            }
        }
        if !occluding(&gpu, b) {
            match c.encode(&queue, encoder, &camera, Tests::Both, n, skinning, None) {
                Ok(()) => copy_counts(encoder, b),
                Err(e) => error!("skinlet meshlets: {e}"),
            }
        }
    }
    if !gpu.bevy_occluders {
        cull_occluding(encoder, &gpu, &queue, &camera, None);
    }
}

/// Whether a bake's first camera culling is by occlusion ([`cull_occluding`]).
fn occluding(gpu: &MeshletGpu, b: &BakeGpu) -> bool {
    b.occlusion.is_some() && gpu.depth.is_some()
}

/// With Bevy's occlusion culling on the first camera ([`MeshletGpu::bevy_occluders`]), in its
/// `Core3d` schedule between Bevy's early and late prepasses: the first camera's occlusion
/// culling, starting from Bevy's depth of the meshes its early prepass drew (what the frame's
/// final depth can only come nearer to, so what it hides stays hidden).
fn cull_behind_bevy(
    mut ctx: RenderContext,
    gpu: Res<MeshletGpu>,
    queue: Res<RenderQueue>,
    view: ViewQuery<(&ExtractedView, &ViewDepthTexture)>,
) {
    let (view, depth) = view.into_inner();
    if !gpu.bevy_occluders || gpu.first_camera != Some(view.retained_view_entity) {
        return;
    }
    if let Some(camera) = cull_camera(clip_from_world(view), view) {
        cull_occluding(ctx.command_encoder(), &gpu, &queue, &camera, Some(&depth.texture));
    }
    gpu.culled.store(true, Ordering::Release);
}

/// The first camera's occlusion culling of every occluding bake, in rounds that go together:
/// round `r`'s first phase of each bake, then its second phase of each bake, so that every
/// bake's near instances are drawn into the occlusion depth before any bake's farther ones are
/// tested. The depth starts cleared, or as `start` (Bevy's depth, of the same size and
/// samples).
fn cull_occluding(
    encoder: &mut wgpu::CommandEncoder,
    gpu: &MeshletGpu,
    queue: &RenderQueue,
    camera: &CullCamera,
    start: Option<&wgpu::Texture>,
) {
    let Some((texture, depth)) = &gpu.depth else { return };
    let mut occluding: Vec<_> = gpu
        .bakes
        .values()
        .filter(|b| b.instances > 0 && !b.unculled && occluding(gpu, b))
        .filter_map(|b| {
            let draw = b.occlusion.as_ref()?;
            let encoded = b.culling.encode_first(queue, encoder, camera, Tests::Both, b.instances, &b.skinning, None);
            encoded.map_err(|e| error!("skinlet meshlets: {e}")).ok().map(|_| (b, draw))
        })
        .collect();
    let Some(rounds) = occluding.iter().map(|(b, _)| b.rounds).max() else { return };
    let mut load = match start {
        Some(start) if (start.size(), start.sample_count()) == (texture.size(), texture.sample_count()) => {
            encoder.copy_texture_to_texture(start.as_image_copy(), texture.as_image_copy(), texture.size());
            gpu.started_from_bevy.store(true, Ordering::Release);
            wgpu::LoadOp::Load
        }
        _ => wgpu::LoadOp::Clear(0.0),
    };
    // (Round 0's first phases were recorded above.)
    for round in 0..rounds {
        for list in [List::First, List::Second] {
            occluding.retain(|&(b, _)| {
                let (c, skinning) = (&b.culling, &b.skinning);
                let encoded = match list {
                    List::First if round > 0 => c.encode_first_phase(encoder, skinning, round),
                    List::First => Ok(()),
                    List::Second => c.encode_second(encoder, skinning, round),
                };
                encoded.map_err(|e| error!("skinlet meshlets: {e}")).is_ok()
            });
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("skinlet occlusion depth"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: depth,
                    depth_ops: Some(wgpu::Operations {
                        load: std::mem::replace(&mut load, wgpu::LoadOp::Load),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            for &(b, draw) in &occluding {
                pass.set_pipeline(&draw.pipeline);
                pass.set_bind_group(0, &draw.group, &[]);
                pass.set_bind_group(1, &b.skinning, &[]);
                b.culling.draw(&mut pass, list);
            }
        }
    }
    for &(b, _) in &occluding {
        b.culling.encode_whole_lists(encoder);
        copy_counts(encoder, b);
    }
}

/// Copies a bake's counts after its culling, unless the last copy is still being read.
fn copy_counts(encoder: &mut wgpu::CommandEncoder, b: &BakeGpu) {
    if b.readback_state.compare_exchange(IDLE, COPIED, Ordering::AcqRel, Ordering::Relaxed).is_ok() {
        let headers = 2 * SurvivorHeader::SIZE;
        encoder.copy_buffer_to_buffer(b.culling.crowd().survivors(), 0, &b.readback, 0, headers);
        encoder.copy_buffer_to_buffer(b.culling.triangles(), 0, &b.readback, headers, 2 * TriangleHeader::SIZE);
        // Each other view's list header after them, in its slot.
        let at = headers + 2 * TriangleHeader::SIZE;
        for v in b.shadows.values().chain(b.cameras.values()) {
            if let Some(slot) = v.slot {
                let to = at + slot as u64 * TriangleHeader::SIZE;
                encoder.copy_buffer_to_buffer(v.culling.triangles(), 0, &b.readback, to, TriangleHeader::SIZE);
            }
        }
    }
}

/// After the frame's commands are submitted: maps the counts copied this frame; when the GPU
/// is done with them, they go to [`SkinletMeshletStats`].
fn read_back_stats(gpu: Res<MeshletGpu>, stats: Res<SkinletMeshletStats>) {
    for (&id, b) in &gpu.bakes {
        if b.readback_state.compare_exchange(COPIED, MAPPING, Ordering::AcqRel, Ordering::Relaxed).is_err() {
            continue;
        }
        let (buffer, state, stats, needs) =
            (b.readback.clone(), b.readback_state.clone(), stats.clone(), b.needs.clone());
        let (frame, n, meshlets, triangles, rounds) =
            (gpu.frame, b.instances as u64, b.meshlets as u64, b.mesh_triangles as u64, b.rounds);
        let bevy_occluders = gpu.started_from_bevy.load(Ordering::Acquire) && occluding(&gpu, b);
        let room = b.triangles_per_list;
        // The other views whose headers were copied: slot, view, whether a shadow view, room.
        let views: Vec<(usize, RetainedViewEntity, bool, u32)> = (b.shadows.iter().map(|v| (v, true)))
            .chain(b.cameras.iter().map(|v| (v, false)))
            .filter_map(|((&view, v), shadow)| Some((v.slot?, view, shadow, v.culling.capacity())))
            .collect();
        b.readback.slice(..).map_async(wgpu::MapMode::Read, move |mapped| {
            if mapped.is_ok() {
                let (survivors, lists, headers): ([SurvivorHeader; 2], [TriangleHeader; 2], Vec<TriangleHeader>) = {
                    let bytes = buffer.slice(..).get_mapped_range();
                    let (s, t) = bytes.split_at(2 * SurvivorHeader::SIZE as usize);
                    let (t, views) = t.split_at(2 * TriangleHeader::SIZE as usize);
                    let views = views.chunks_exact(TriangleHeader::SIZE as usize);
                    (
                        bytemuck::pod_read_unaligned(s),
                        bytemuck::pod_read_unaligned(t),
                        views.map(bytemuck::pod_read_unaligned).collect(),
                    )
                };
                buffer.unmap();
                // Lists that overflowed need more room.
                let grown = |found: u32| (2 * found as u64).next_power_of_two().min(u32::MAX as u64) as u32;
                if let Ok(mut needs) = needs.lock() {
                    let mut need = |list, found: u32, room: u32| {
                        if found > room {
                            let need = needs.entry(list).or_default();
                            *need = (*need).max(grown(found));
                        }
                    };
                    need(None, lists.iter().map(|l| l.found).max().unwrap_or(0), room);
                    for &(slot, view, _, room) in &views {
                        need(Some(view), headers[slot].found, room);
                    }
                }
                let shadows: Vec<&TriangleHeader> =
                    views.iter().filter(|v| v.2).map(|&(slot, ..)| &headers[slot]).collect();
                // With occlusion culling, the second list's survivors are every meshlet its
                // tests kept, and both lists draw.
                let sum = |f: fn(&TriangleHeader) -> u32| lists.iter().map(|l| f(l) as u64).sum::<u64>();
                let shadow_sum = |f: fn(&TriangleHeader) -> u32| shadows.iter().map(|l| f(l) as u64).sum::<u64>();
                stats.set(
                    id,
                    MeshletStats {
                        frame,
                        culled: true,
                        occlusion_rounds: rounds,
                        bevy_occluders,
                        instances: n as u32,
                        meshlets_total: n * meshlets,
                        meshlets_tested_visible: survivors[(rounds > 0) as usize].found as u64,
                        meshlets_drawn: sum(|l| l.meshlets),
                        triangles_total: n * triangles,
                        triangles_drawn: sum(|l| l.index_count / 3),
                        triangles_dropped: sum(|l| l.found.saturating_sub(l.index_count / 3))
                            + shadow_sum(|l| l.found.saturating_sub(l.index_count / 3)),
                        list_triangles: room,
                        shadow_views: shadows.len() as u32,
                        shadow_triangles_total: shadows.len() as u64 * n * triangles,
                        shadow_triangles_drawn: shadow_sum(|l| l.index_count / 3),
                    },
                );
            }
            state.store(IDLE, Ordering::Release);
        });
    }
}

#[derive(Default, Deref, DerefMut, Resource)]
struct PendingMeshletQueues(PendingQueues);

#[allow(clippy::too_many_arguments)]
fn queue_draws(
    cache: Res<PipelineCache>,
    draw_pipeline: Option<Res<MeshletDrawPipeline>>,
    mut pipelines: ResMut<SpecializedRenderPipelines<MeshletDrawPipeline>>,
    view_keys: Res<ViewKeyCache>,
    mut phases: ResMut<ViewBinnedRenderPhases<Opaque3d>>,
    draw_functions: Res<DrawFunctions<Opaque3d>>,
    views: Query<(&ExtractedView, &RenderVisibleEntities)>,
    dirty: Res<DirtySpecializations>,
    mut pending: ResMut<PendingMeshletQueues>,
    (frames, draws): (Res<MeshletFrames>, Query<&SkinletMeshletDraw>),
    mut queued: Local<HashMap<(RetainedViewEntity, MainEntity), (Entity, bool)>>,
    mut to_queue: Local<Vec<(Entity, MainEntity)>>,
) {
    let Some(draw_pipeline) = draw_pipeline else { return };
    let draw_function = draw_functions.read().id::<DrawMeshletCommands>();
    // Whether a draw's bake has parts drawn two-sided this frame (its pipeline culls no faces).
    let two_sided = |entity: Entity| {
        let frame = draws.get(entity).ok().and_then(|d| frames.0.get(&d.bake));
        frame.is_some_and(|f| f.two_sided.contains(&true))
    };
    queued.retain(|(view, _), _| phases.contains_key(view));
    for (view, visible) in &views {
        let Some(phase) = phases.get_mut(&view.retained_view_entity) else { continue };
        let Some(visible) = visible.get::<SkinletMeshletDraw>() else { continue };
        let view_pending = pending.prepare_for_new_frame(view.retained_view_entity);
        for &main_entity in dirty.iter_to_dequeue(view.retained_view_entity, visible) {
            phase.remove(main_entity);
            queued.remove(&(view.retained_view_entity, main_entity));
        }
        to_queue.clear();
        to_queue.extend(
            (dirty.iter_to_queue(view.retained_view_entity, visible, &view_pending.prev_frame)).map(|(r, m)| (*r, *m)),
        );
        // A draw queued with the other pipeline (its bake's parts changed sides): again.
        for (&(v, main_entity), &(entity, sides)) in &queued {
            if v == view.retained_view_entity
                && sides != two_sided(entity)
                && !to_queue.iter().any(|&(_, m)| m == main_entity)
            {
                to_queue.push((entity, main_entity));
            }
        }
        for &(render_entity, main_entity) in to_queue.iter() {
            let Some(key) = view_keys.get(&view.retained_view_entity) else {
                view_pending.current_frame.insert((render_entity, main_entity));
                continue;
            };
            let sides = two_sided(render_entity);
            let pipeline = pipelines.specialize(&cache, &draw_pipeline, (*key, sides));
            phase.remove(main_entity);
            queued.insert((view.retained_view_entity, main_entity), (render_entity, sides));
            phase.add(
                Opaque3dBatchSetKey {
                    draw_function,
                    pipeline,
                    material_bind_group_index: None,
                    lightmap_slab: None,
                    slabs: MeshSlabs::default(),
                },
                Opaque3dBinKey { asset_id: AssetId::<Mesh>::invalid().untyped() },
                (render_entity, main_entity),
                InputUniformIndex::default(),
                BinnedRenderPhaseType::NonMesh,
            );
        }
    }
}

/// The item's bake, when it has instances this frame, with its group 2 set.
fn drawn_bake<'w>(
    item: Option<&SkinletMeshletDraw>,
    gpu: &'w MeshletGpu,
    pass: &mut TrackedRenderPass<'w>,
) -> Option<&'w BakeGpu> {
    let b = gpu.bakes.get(&item?.bake).filter(|b| b.instances > 0)?;
    pass.set_bind_group(2, &b.draw_group, &[]);
    Some(b)
}

/// Groups 2 and 3 (the textures, where the pipeline has them) and the view's list (both lists
/// with occlusion culling; every corner of every instance unculled).
struct DrawMeshlets;

impl<P: PhaseItem> RenderCommand<P> for DrawMeshlets {
    type Param = SRes<MeshletGpu>;
    type ViewQuery = bevy::ecs::system::lifetimeless::Read<ExtractedView>;
    type ItemQuery = bevy::ecs::system::lifetimeless::Read<SkinletMeshletDraw>;

    fn render<'w>(
        _: &P,
        view: ROQueryItem<'w, '_, Self::ViewQuery>,
        item: Option<ROQueryItem<'w, '_, Self::ItemQuery>>,
        gpu: SystemParamItem<'w, '_, Self::Param>,
        pass: &mut TrackedRenderPass<'w>,
    ) -> RenderCommandResult {
        let gpu = gpu.into_inner();
        let Some(b) = drawn_bake(item, gpu, pass) else { return RenderCommandResult::Skip };
        if let Some(textures) = &b.texture_group {
            pass.set_bind_group(3, textures, &[]);
        }
        if b.unculled {
            // Every corner of every instance: the vertex and instance indices name them.
            pass.draw(0..b.corners, 0..b.instances);
        } else if gpu.first_camera != Some(view.retained_view_entity) {
            // Another camera: its own list.
            let Some(ViewCulling { lists, .. }) = b.cameras.get(&view.retained_view_entity) else {
                return RenderCommandResult::Skip;
            };
            pass.set_index_buffer(lists.slice(2 * TriangleHeader::SIZE..), IndexFormat::Uint32);
            pass.draw_indexed_indirect(lists, 0);
        } else if gpu.bevy_occluders && occluding(gpu, b) && !gpu.culled.load(Ordering::Acquire) {
            // Bevy's early prepass, before the culling that starts from its depth.
            return RenderCommandResult::Skip;
        } else {
            pass.set_index_buffer(b.triangles.slice(2 * TriangleHeader::SIZE..), IndexFormat::Uint32);
            pass.draw_indexed_indirect(&b.triangles, 0);
            if b.rounds > 0 {
                // Occlusion culling's second list (every round's, as the first).
                pass.draw_indexed_indirect(&b.triangles, TriangleHeader::SIZE);
            }
        }
        RenderCommandResult::Success
    }
}

/// The depth-only views' pipeline (shadow views, the camera's prepass): Bevy's prepass view
/// layout (group 0), its empty group 1, skinlet's group 2, and in a camera's prepass the
/// parts' textures (group 3, for normal maps; where the device indexes texture arrays per
/// fragment).
struct MeshletDepthPipeline {
    view: BindGroupLayoutDescriptor,
    view_motion_vectors: BindGroupLayoutDescriptor,
    empty: BindGroupLayoutDescriptor,
    group2: BindGroupLayoutDescriptor,
    group3: Option<BindGroupLayoutDescriptor>,
    shader: Handle<Shader>,
    depth_clip_control: bool,
}

/// The depth draws' shader (made in the main world).
#[derive(Resource)]
struct DepthShader(Handle<Shader>);

/// A depth-only view: a shadow view (`directional`: a directional light's, whose casters in
/// front of the near plane are clamped to it, as Bevy's shadow pipeline does), or a camera's
/// prepass (its mesh pipeline key: the prepass textures it writes and its samples).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum DepthView {
    Shadow { directional: bool },
    Prepass(MeshPipelineKey),
}

impl SpecializedRenderPipeline for MeshletDepthPipeline {
    /// The view, and whether the bake has parts drawn two-sided.
    type Key = (DepthView, bool);

    fn specialize(&self, (key, two_sided): (DepthView, bool)) -> RenderPipelineDescriptor {
        let (directional, view_key) = match key {
            DepthView::Shadow { directional } => (directional, MeshPipelineKey::NONE),
            DepthView::Prepass(view_key) => (false, view_key),
        };
        let emulate = directional && !self.depth_clip_control;
        let normal = view_key.contains(MeshPipelineKey::NORMAL_PREPASS);
        let motion_vectors = view_key.contains(MeshPipelineKey::MOTION_VECTOR_PREPASS);
        let mut shader_defs: Vec<ShaderDefVal> = Vec::new();
        if emulate {
            shader_defs.push("UNCLIPPED_DEPTH_ORTHO_EMULATION".into());
        }
        if normal {
            shader_defs.push("NORMAL_PREPASS".into());
        }
        if motion_vectors {
            shader_defs.push("MOTION_VECTOR_PREPASS".into());
        }
        if normal || motion_vectors || emulate {
            shader_defs.push("DEPTH_FRAGMENT_OUTPUT".into());
        }
        if two_sided {
            shader_defs.push("SKINLET_TWO_SIDED".into());
        }
        // The prepass's targets as Bevy's prepass pipeline has them; skinlet writes the normals
        // and motion vectors (the deferred targets are for Bevy's deferred materials).
        let mut targets = bevy::core_pipeline::prepass::prepass_target_descriptors(
            normal,
            motion_vectors,
            view_key.contains(MeshPipelineKey::DEFERRED_PREPASS),
        );
        for target in targets.iter_mut().skip(2).flatten() {
            target.write_mask = ColorWrites::empty();
        }
        if targets.iter().all(Option::is_none) {
            targets.clear();
        }
        let view = if motion_vectors { &self.view_motion_vectors } else { &self.view };
        let entry_point = if matches!(key, DepthView::Shadow { .. }) { "shadow_vertex" } else { "prepass_vertex" };
        let mut layout = vec![view.clone(), self.empty.clone(), self.group2.clone()];
        if let (DepthView::Prepass(_), Some(group3)) = (key, &self.group3) {
            layout.push(group3.clone());
            shader_defs.push("SKINLET_TEXTURES".into());
        }
        RenderPipelineDescriptor {
            label: Some("skinlet meshlet depth".into()),
            layout,
            vertex: VertexState {
                shader: self.shader.clone(),
                shader_defs: shader_defs.clone(),
                entry_point: Some(entry_point.into()),
                buffers: vec![],
            },
            fragment: (emulate || two_sided || !targets.is_empty()).then(|| FragmentState {
                shader: self.shader.clone(),
                shader_defs,
                entry_point: Some("depth_fragment".into()),
                targets,
            }),
            primitive: PrimitiveState {
                topology: PrimitiveTopology::TriangleList,
                cull_mode: (!two_sided).then_some(Face::Back),
                unclipped_depth: directional && self.depth_clip_control,
                ..default()
            },
            depth_stencil: Some(DepthStencilState {
                format: CORE_3D_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(CompareFunction::GreaterEqual),
                stencil: default(),
                bias: default(),
            }),
            multisample: MultisampleState {
                count: view_key.msaa_samples(),
                mask: !0,
                alpha_to_coverage_enabled: false,
            },
            ..default()
        }
    }
}

impl MeshletDepthPipeline {
    fn new(prepass: &PrepassPipeline, shader: &DepthShader, device: &RenderDevice) -> MeshletDepthPipeline {
        MeshletDepthPipeline {
            view: prepass.view_layout_no_motion_vectors.clone(),
            view_motion_vectors: prepass.view_layout_motion_vectors.clone(),
            empty: prepass.empty_layout.clone(),
            group2: draw_layout(),
            group3: textures_usable(device).then(texture_layout),
            shader: shader.0.clone(),
            depth_clip_control: device.features().contains(wgpu::Features::DEPTH_CLIP_CONTROL),
        }
    }
}

/// The depth draws queued, per (view, draw entity): their pipeline.
type DepthQueued = HashMap<(RetainedViewEntity, MainEntity), CachedRenderPipelineId>;

/// Keeps every bake's depth draw in `view`'s `phase` with the pipeline `pipeline` gives for
/// whether the bake has parts drawn two-sided (the batch set and bin keys from `keys`):
/// removed while its bake draws no instance, added again when its pipeline changed.
#[allow(clippy::too_many_arguments)]
fn queue_depth_draws<P: BinnedPhaseItem>(
    phase: &mut BinnedRenderPhase<P>,
    view: RetainedViewEntity,
    mut pipeline: impl FnMut(bool) -> CachedRenderPipelineId,
    draws: &Query<(Entity, &MainEntity, &SkinletMeshletDraw)>,
    gpu: &MeshletGpu,
    frames: &MeshletFrames,
    queued: &mut DepthQueued,
    keys: impl Fn(CachedRenderPipelineId) -> (P::BatchSetKey, P::BinKey),
) {
    for (entity, &main_entity, draw) in draws {
        let key = (view, main_entity);
        let drawn = gpu.bakes.get(&draw.bake).is_some_and(|b| b.instances > 0);
        if !drawn {
            if queued.remove(&key).is_some() {
                phase.remove(main_entity);
            }
            continue;
        }
        let two_sided = frames.0.get(&draw.bake).is_some_and(|f| f.two_sided.contains(&true));
        let pipeline = pipeline(two_sided);
        if queued.insert(key, pipeline) == Some(pipeline) {
            continue;
        }
        phase.remove(main_entity);
        let (batch_set, bin) = keys(pipeline);
        let (input, phase_type) = (InputUniformIndex::default(), BinnedRenderPhaseType::NonMesh);
        phase.add(batch_set, bin, (entity, main_entity), input, phase_type);
    }
}

/// Puts every bake's shadow draw in every shadow view (lights that cast shadows).
#[allow(clippy::too_many_arguments)]
fn queue_shadows(
    cache: Res<PipelineCache>,
    prepass: Option<Res<PrepassPipeline>>,
    shader: Res<DepthShader>,
    device: Res<RenderDevice>,
    mut depth_pipeline: Local<Option<MeshletDepthPipeline>>,
    mut pipelines: ResMut<SpecializedRenderPipelines<MeshletDepthPipeline>>,
    mut phases: ResMut<ViewBinnedRenderPhases<Shadow>>,
    draw_functions: Res<DrawFunctions<Shadow>>,
    lights: Query<(&ExtractedView, &LightEntity)>,
    draws: Query<(Entity, &MainEntity, &SkinletMeshletDraw)>,
    (gpu, frames): (Res<MeshletGpu>, Res<MeshletFrames>),
    mut queued: Local<DepthQueued>,
) {
    let Some(prepass) = prepass else { return };
    let depth_pipeline = depth_pipeline.get_or_insert_with(|| MeshletDepthPipeline::new(&prepass, &shader, &device));
    let draw_function = draw_functions.read().id::<DrawMeshletShadowCommands>();
    // A view whose phase went away (and may come back empty) has nothing queued.
    queued.retain(|(view, _), _| phases.contains_key(view));
    for (view, light) in &lights {
        let Some(phase) = phases.get_mut(&view.retained_view_entity) else { continue };
        let directional = matches!(light, LightEntity::Directional { .. });
        let key = DepthView::Shadow { directional };
        let pipeline = |two_sided| pipelines.specialize(&cache, depth_pipeline, (key, two_sided));
        let view = view.retained_view_entity;
        queue_depth_draws(phase, view, pipeline, &draws, &gpu, &frames, &mut queued, |pipeline| {
            let slabs = MeshSlabs::default();
            let batch_set = ShadowBatchSetKey { pipeline, draw_function, material_bind_group_index: None, slabs };
            (batch_set, ShadowBinKey { asset_id: AssetId::<Mesh>::invalid().untyped() })
        });
    }
}

/// Puts every bake's prepass draw in every camera's opaque prepass (cameras with a depth or
/// normal prepass): depth, and normals where the camera writes them.
#[allow(clippy::too_many_arguments)]
fn queue_prepass(
    cache: Res<PipelineCache>,
    prepass: Option<Res<PrepassPipeline>>,
    shader: Res<DepthShader>,
    device: Res<RenderDevice>,
    view_keys: Res<ViewKeyCache>,
    mut depth_pipeline: Local<Option<MeshletDepthPipeline>>,
    mut pipelines: ResMut<SpecializedRenderPipelines<MeshletDepthPipeline>>,
    mut phases: ResMut<ViewBinnedRenderPhases<Opaque3dPrepass>>,
    draw_functions: Res<DrawFunctions<Opaque3dPrepass>>,
    views: Query<&ExtractedView, With<ExtractedCamera>>,
    draws: Query<(Entity, &MainEntity, &SkinletMeshletDraw)>,
    (gpu, frames): (Res<MeshletGpu>, Res<MeshletFrames>),
    mut queued: Local<DepthQueued>,
) {
    let Some(prepass) = prepass else { return };
    let depth_pipeline = depth_pipeline.get_or_insert_with(|| MeshletDepthPipeline::new(&prepass, &shader, &device));
    let draw_function = draw_functions.read().id::<DrawMeshletPrepassCommands>();
    // A camera whose prepass went away (and may come back empty) has nothing queued.
    queued.retain(|(view, _), _| phases.contains_key(view));
    for view in &views {
        let Some(phase) = phases.get_mut(&view.retained_view_entity) else { continue };
        let Some(&view_key) = view_keys.get(&view.retained_view_entity) else { continue };
        let key = DepthView::Prepass(view_key);
        let pipeline = |two_sided| pipelines.specialize(&cache, depth_pipeline, (key, two_sided));
        let view = view.retained_view_entity;
        queue_depth_draws(phase, view, pipeline, &draws, &gpu, &frames, &mut queued, |pipeline| {
            let slabs = MeshSlabs::default();
            let batch_set =
                OpaqueNoLightmap3dBatchSetKey { pipeline, draw_function, material_bind_group_index: None, slabs };
            (batch_set, OpaqueNoLightmap3dBinKey { asset_id: AssetId::<Mesh>::invalid().untyped() })
        });
    }
}

/// Group 2 and the bake's shadow draw in a shadow view: the view's culled list, or unculled
/// every corner of every instance.
struct DrawMeshletShadow;

impl<P: PhaseItem> RenderCommand<P> for DrawMeshletShadow {
    type Param = SRes<MeshletGpu>;
    type ViewQuery = bevy::ecs::system::lifetimeless::Read<ExtractedView>;
    type ItemQuery = bevy::ecs::system::lifetimeless::Read<SkinletMeshletDraw>;

    fn render<'w>(
        _: &P,
        view: ROQueryItem<'w, '_, Self::ViewQuery>,
        item: Option<ROQueryItem<'w, '_, Self::ItemQuery>>,
        gpu: SystemParamItem<'w, '_, Self::Param>,
        pass: &mut TrackedRenderPass<'w>,
    ) -> RenderCommandResult {
        let Some(b) = drawn_bake(item, gpu.into_inner(), pass) else { return RenderCommandResult::Skip };
        if b.unculled {
            pass.draw(0..b.corners, 0..b.instances);
        } else {
            let Some(ViewCulling { lists, .. }) = b.shadows.get(&view.retained_view_entity) else {
                return RenderCommandResult::Skip;
            };
            pass.set_index_buffer(lists.slice(2 * TriangleHeader::SIZE..), IndexFormat::Uint32);
            pass.draw_indexed_indirect(lists, 0);
        }
        RenderCommandResult::Success
    }
}

type DrawMeshletShadowCommands =
    (SetItemPipeline, SetPrepassViewBindGroup<0>, SetPrepassViewEmptyBindGroup<1>, DrawMeshletShadow);

type DrawMeshletPrepassCommands =
    (SetItemPipeline, SetPrepassViewBindGroup<0>, SetPrepassViewEmptyBindGroup<1>, DrawMeshlets);

type DrawMeshletCommands =
    (SetItemPipeline, SetMeshViewBindGroup<0>, SetMeshViewBindingArrayBindGroup<1>, DrawMeshlets);
