//! A GPU-driven crowd renderer on `skinlet_gpu::crowd_culling`, as an engine would build one:
//! the crowd's buffers live on the GPU across frames, a frame writes the palette, instances
//! and morph weights, records skinlet's culling pass and draws the survivors with one call.
//!
//! Views of the same frame ([`CrowdView`]): every meshlet of every instance (`draw_indexed`
//! over all instances); the survivors pulled by the vertex shader (one `draw_indirect`); the
//! survivors as indexed draws (`multi_draw_indexed_indirect_count`, where the device has it);
//! two-phase occlusion culling, pulled (the visibility bits kept across frames); either of the
//! two with skinlet's triangle pass after it (`skinlet_gpu::triangle_culling`: one indexed
//! indirect draw per phase of the triangles it keeps); and the ID buffer of the unculled
//! crowd, whose set of (instance, meshlet) pairs with a visible fragment is what no culling
//! can beat (the oracle). All run the same vertex skinning (`crowd_skin.wgsl`) and faceted
//! shading, so a culled image equals every meshlet drawn the same way exactly when culling
//! kept every triangle with a visible fragment (but where two triangles tie in depth: draw
//! order picks the color there, and the ID view finds those pixels).

use crate::render::{COLOR, DEPTH, Image, target_texture};
use glam::{Mat4, Vec3};
use skinlet_gpu::crowd_culling::{
    CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter, List, OcclusionDepth, SURVIVORS_WGSL,
    SurvivorHeader,
};
use skinlet_gpu::crowd_skinning::{CROWD_SKIN_WGSL, CrowdMesh, layout_entries};
use skinlet_gpu::triangle_culling::{
    Entries, Raster, TRIANGLES_WGSL, TriangleCulling, TriangleHeader, TriangleSkinning,
};
use skinlet_gpu::{Gpu, GpuError, Result};
use skinlet_runtime::camera::Camera;
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};

/// What a frame draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrowdView {
    /// Every meshlet of every instance.
    Unculled,
    /// The survivors, pulled: one `draw_indirect`.
    Pulled,
    /// [`CrowdView::Pulled`], each triangle coloured by its cluster's LOD level (white at
    /// full detail; a crowd with LOD, [`GpuCrowd::with_depth_range`]).
    PulledByLevel,
    /// The survivors as indexed draws: one `multi_draw_indexed_indirect_count`.
    Indexed,
    /// Two-phase occlusion culling, the survivors pulled: last frame's visible, then the
    /// newly visible against the depth pyramid of the first (two `draw_indirect`).
    Occluded,
    /// The survivors' triangles kept by the triangle pass: one `draw_indexed_indirect`.
    Triangles,
    /// Two-phase occlusion culling with the triangle pass (the visibility bits from the
    /// triangles): two `draw_indexed_indirect`.
    OccludedTriangles,
    /// The unculled crowd's (instance, meshlet) ids.
    Ids,
}

/// One frame of the crowd: per instance its world-space skinning matrices (`joints` each,
/// instance after instance), how it is culled, its morph weights (the mesh's morph weight
/// count each: none for a mesh without morph targets) and, for a crowd made with
/// LOD ([`GpuCrowd::with_depth_range`]), its LOD threshold (`skinlet_gpu::crowd_culling::CullInstance`:
/// negative for full detail; none: every instance at full detail).
#[derive(Clone, Copy, Debug)]
pub struct CrowdFrame<'a> {
    pub palette: &'a [Mat4],
    pub modes: &'a [CullMode],
    pub weights: &'a [f32],
    pub lod_thresholds: &'a [f32],
    pub camera: &'a Camera,
    pub tests: Tests,
}

/// What a frame drew.
#[derive(Clone, Debug)]
pub struct CrowdDrawn {
    /// The color image (all but [`CrowdView::Ids`]).
    pub image: Option<Image>,
    /// Per pixel, 0 or the drawn (instance × meshlets + meshlet) + 1 ([`CrowdView::Ids`]).
    pub ids: Option<Vec<u32>>,
    /// Per pixel, 0 or the drawn (instance × triangles + triangle) + 1, the triangle's place
    /// in the mesh's meshlet-order index buffer ([`CrowdView::Ids`]).
    pub triangle_ids: Option<Vec<u32>>,
    /// Per pixel, whether the nearest fragments of two triangles tie in depth there (the
    /// triangle drawn first and the one drawn last differ): where draw order picks the color.
    pub ties: Option<Vec<bool>>,
    /// The survivor lists' headers (culled views: one, two with occlusion culling).
    pub headers: Vec<SurvivorHeader>,
    /// The triangle lists' headers (the triangle views: one, two with occlusion culling).
    pub triangle_headers: Vec<TriangleHeader>,
    /// API draw calls the frame recorded (the ID view draws twice).
    pub draw_calls: u32,
    /// GPU time from the culling pass's start (or the render pass's) to the render pass's
    /// end, where the device has timestamps.
    pub gpu_ms: Option<f64>,
}

/// A triangle the triangle pass listed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrawnTriangle {
    pub instance: u32,
    pub meshlet: u32,
    /// Its place in the mesh's meshlet-order index buffer.
    pub triangle: u32,
    /// Its vertices, sorted.
    pub vertices: [u32; 3],
}

/// A crowd of up to `capacity` instances of one baked character, drawn at one image size.
pub struct GpuCrowd {
    pub width: u32,
    pub height: u32,
    capacity: u32,
    joints: u32,
    morphs: u32,
    meshlets: u32,
    index_count: u32,
    /// Per meshlet its first index (increasing: the index buffer is in meshlet order).
    firsts: Vec<u32>,
    /// Each triangle's meshlet (in index buffer order), and each triangle by its vertex
    /// indices (sorted).
    triangle_meshlets: Vec<u32>,
    triangle_by_vertices: std::collections::HashMap<[u32; 3], u32>,
    palette: wgpu::Buffer,
    instances: wgpu::Buffer,
    weights: wgpu::Buffer,
    view: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// The meshlet culling (`culling.crowd()`) and the triangle pass after it.
    culling: TriangleCulling,
    /// Group 0 (view, indices, survivors) and group 1 (the skinning).
    groups: [wgpu::BindGroup; 2],
    /// Pipelines: indexed, pulled, ids (nearer wins, nearer or equal wins), triangles.
    draws: [wgpu::RenderPipeline; 5],
    color: wgpu::Texture,
    ids: wgpu::Texture,
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    /// Near 1, far 0.
    reversed: bool,
}

const IDS: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// The rounds of [`GpuCrowd::new`]'s occlusion culling.
pub const OCCLUSION_ROUNDS: u32 = 16;

fn invalid(message: String) -> GpuError {
    GpuError::Invalid { location: "GPU crowd", message }
}

impl GpuCrowd {
    /// Uploads `baked`'s mesh, its meshlets' index buffer and `culler` (the bounds the crowd is
    /// culled with: clip or envelope bounds, with any-pose boxes or not) for up to `capacity`
    /// instances, drawn at `width` × `height` with a forward depth range (near 0, far 1).
    pub fn new(
        gpu: &Gpu,
        baked: &skinlet::bake::Baked,
        culler: &MeshletCuller,
        capacity: u32,
        width: u32,
        height: u32,
    ) -> Result<GpuCrowd> {
        GpuCrowd::with_depth_range(gpu, baked, culler, capacity, width, height, false, OCCLUSION_ROUNDS, None)
    }

    /// [`GpuCrowd::new`] with a reversed depth range where `reversed` (near 1, far 0: Bevy's
    /// infinite reverse-Z; the frames' cameras must project so): depth cleared to 0, nearer
    /// fragments the greater, occlusion culling's pyramid of the nearest; occlusion culling in
    /// `rounds` rounds ([`skinlet_gpu::crowd_culling::OcclusionDepth::rounds`]: the frames'
    /// instances are best ordered nearest first), or none with 0 rounds (the occluded views
    /// then error; one survivor list instead of two: room for more instances).
    ///
    /// Cluster LOD: with `lod_errors` (`LodView::errors`, of the clips or within the pose
    /// envelope: `LodView::envelope`), `culler` holds the mesh's meshlets and then `baked`'s
    /// LOD hierarchy's clusters (as `BakeView::lod_culler` and `lod_envelope_culler` do), and
    /// each instance culls the clusters of its cut at its [`CrowdFrame::lod_thresholds`]; the
    /// unculled and ID views draw full detail. Errors when `culler` holds not the meshlets
    /// (without `lod_errors`), or not meshlets and clusters (with them).
    #[allow(clippy::too_many_arguments)]
    pub fn with_depth_range(
        gpu: &Gpu,
        baked: &skinlet::bake::Baked,
        culler: &MeshletCuller,
        capacity: u32,
        width: u32,
        height: u32,
        reversed: bool,
        rounds: u32,
        lod_errors: Option<&[[f32; 2]]>,
    ) -> Result<GpuCrowd> {
        let mesh = &baked.mesh;
        let base = baked.meshlets.len();
        let clusters = baked.lod.as_ref().map_or(0, |l| l.meshlets.len());
        let all = match (&baked.lod, lod_errors) {
            (_, None) if culler.len() == base => None,
            (Some(hierarchy), Some(_)) if culler.len() == base + clusters => {
                let mut all = baked.meshlets.clone();
                all.append(&hierarchy.meshlets, 0);
                Some(all)
            }
            _ => {
                return Err(invalid(format!(
                    "a culler of {} meshlets for {base} meshlets and {clusters} LOD clusters ({} LOD errors)",
                    culler.len(),
                    lod_errors.map_or(0, |e| e.len())
                )));
            }
        };
        let all = all.as_ref().unwrap_or(&baked.meshlets);
        let headers = all.headers();
        let meshlets = all.view(&headers);
        let (indices, draws) = skinlet_gpu::mesh::meshlet_index_buffer(&meshlets, mesh.positions.len())?;
        // Per triangle, its meshlet's LOD level.
        let level = |m: usize| {
            let cluster = m.checked_sub(base);
            cluster.and_then(|c| baked.lod.as_ref().map(|l| l.groups[l.clusters[c][0] as usize].0)).unwrap_or(0)
        };
        let levels: Vec<u32> = (0..all.len())
            .flat_map(|m| std::iter::repeat_n(level(m), all.meshlets[m].triangle_count as usize))
            .collect();
        // Full detail's indices (the unculled and ID views draw them): the first meshlets'.
        let full_detail = draws.get(base).map_or(indices.len() as u32, |d| d[1]);
        let device = &gpu.device;
        let pipelines = CullPipelines::new(device)?;
        let character = match lod_errors {
            Some(errors) => GpuCharacter::with_lod(device, culler, &baked.inverse_bind, &draws, base, errors)?,
            None => GpuCharacter::new(device, culler, &baked.inverse_bind, &draws)?,
        };
        let (joints, morphs) = (baked.inverse_bind.len() as u32, mesh.morphs.weights.len() as u32);
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let zeros = |bytes: u64| vec![0u8; bytes as usize];
        let cap = capacity as u64;
        let palette = gpu.buffer("crowd palette", &zeros(64 * joints as u64 * cap), storage);
        let instances = gpu.buffer("crowd instances", &zeros(80 * cap), storage);
        // At least one word: a storage binding is never empty (without morph targets no vertex
        // reads it).
        let weights = gpu.buffer("crowd morph weights", &zeros(4 * morphs.max(1) as u64 * cap), storage);
        let view = gpu.buffer("crowd view", &[0u32; 24], wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST);
        let survivors = capacity.saturating_mul(character.most_drawn());
        let texture = |format, usage| target_texture(device, width, height, format, usage);
        let depth = texture(
            DEPTH,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let depth_view = depth.create_view(&Default::default());
        let subpixel_bits = gpu.subpixel_bits;
        let multisampled = false;
        let occlusion =
            OcclusionDepth { view: &depth_view, width, height, reversed, subpixel_bits, multisampled, rounds };
        let culling = match rounds {
            0 => CrowdCulling::new(device, &pipelines, &character, &palette, &instances, capacity, survivors)?,
            _ => CrowdCulling::with_occlusion(
                device, &pipelines, &character, &palette, &instances, capacity, survivors, occlusion,
            )?,
        };
        let commands = culling.commands().clone();
        let packed = CrowdMesh::pack(&mesh.mesh_data(None), joints)?;
        let triangle_meshlets: Vec<u32> =
            (draws.iter().enumerate()).flat_map(|(m, d)| std::iter::repeat_n(m as u32, d[0] as usize / 3)).collect();
        // (A LOD cluster may repeat a full-detail triangle: the first, full detail's, is kept.)
        let mut triangle_by_vertices = std::collections::HashMap::new();
        for (k, t) in indices.chunks_exact(3).enumerate() {
            let mut t = [t[0], t[1], t[2]];
            t.sort_unstable();
            triangle_by_vertices.entry(t).or_insert(k as u32);
        }
        let read = wgpu::BufferUsages::STORAGE;
        let index_buffer = gpu.buffer("crowd indices", &indices, read | wgpu::BufferUsages::INDEX);
        let target = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let source = [SURVIVORS_WGSL, TRIANGLES_WGSL, CROWD_SKIN_WGSL, include_str!("shaders/crowd.wgsl")].concat();
        let (margin, relative) = packed.margins();
        use skinlet_gpu::skinning::buffer_entry;
        use wgpu::BufferBindingType::{Storage, Uniform};
        let uniform = |binding, stages| buffer_entry(binding, stages, Uniform);
        let storage = |binding, stages| buffer_entry(binding, stages, Storage { read_only: true });
        let (built, layouts) = gpu.checked("GPU crowd", || {
            use wgpu::ShaderStages as S;
            let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
                device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
            };
            let draw_layout = layout(
                "crowd draw",
                &[uniform(0, S::VERTEX_FRAGMENT), storage(1, S::VERTEX), storage(2, S::VERTEX), storage(3, S::VERTEX)],
            );
            let skin_layout = layout("crowd skinning", &layout_entries(S::VERTEX_FRAGMENT | S::COMPUTE));
            fn entries<'a>(buffers: &[&'a wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'a>> {
                (buffers.iter().enumerate())
                    .map(|(b, buffer)| wgpu::BindGroupEntry { binding: b as u32, resource: buffer.as_entire_binding() })
                    .collect()
            }
            let groups = [
                gpu.bind_group(
                    "crowd draw",
                    &draw_layout,
                    &entries(&[&view, &index_buffer, &commands, &gpu.buffer("crowd triangle levels", &levels, read)]),
                ),
                gpu.bind_group(
                    "crowd skinning",
                    &skin_layout,
                    &entries(&[
                        &gpu.buffer("crowd skin", &packed.uniform, wgpu::BufferUsages::UNIFORM),
                        &palette,
                        &gpu.buffer("crowd mesh", &packed.words, read),
                        &weights,
                    ]),
                ),
            ];
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("crowd"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("crowd"),
                bind_group_layouts: &[Some(&draw_layout), Some(&skin_layout)],
                immediate_size: 0,
            });
            let make = |vs: &str, fs: &str, format: wgpu::TextureFormat, compare| {
                let targets = [Some(format.into())];
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(vs),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(vs),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState { cull_mode: Some(wgpu::Face::Back), ..Default::default() },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(compare),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(fs),
                        compilation_options: Default::default(),
                        targets: &targets,
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
            use wgpu::CompareFunction::{Greater, GreaterEqual, Less, LessEqual};
            let (nearer, nearer_or_equal) = if reversed { (Greater, GreaterEqual) } else { (Less, LessEqual) };
            let draws = [
                make("vs_indexed", "fs_shaded", COLOR, nearer),
                make("vs_pulled", "fs_shaded", COLOR, nearer),
                make("vs_ids", "fs_ids", IDS, nearer),
                make("vs_ids", "fs_ids", IDS, nearer_or_equal),
                make("vs_triangles", "fs_shaded", COLOR, nearer),
            ];
            ((groups, draws), skin_layout)
        })?;
        let skinning = TriangleSkinning { wgsl: CROWD_SKIN_WGSL, layout: &layouts, margin, relative };
        // As many triangles per list as the crowd has (a list never overflows), or as the
        // device's storage bindings hold.
        let fits = (device.limits().max_storage_buffer_binding_size - 2 * TriangleHeader::SIZE) / 24;
        let all_triangles = (capacity as u64 * indices.len() as u64 / 3).min(fits) as u32;
        let culling = TriangleCulling::new(
            device,
            culling,
            skinning,
            &meshlets,
            mesh.positions.len() as u32,
            all_triangles,
            Raster { width, height, subpixel_bits, cull_back_faces: true, multisampled: false },
            Entries::Vertices,
            &[],
        )?;
        let (groups, pipelines) = built;
        Ok(GpuCrowd {
            width,
            height,
            capacity,
            joints,
            morphs,
            meshlets: character.meshlets(),
            index_count: full_detail,
            firsts: draws.iter().map(|d| d[1]).collect(),
            triangle_by_vertices,
            triangle_meshlets,
            palette: palette.clone(),
            instances: instances.clone(),
            weights: weights.clone(),
            view: view.clone(),
            indices: index_buffer,
            groups,
            draws: pipelines,
            color: texture(COLOR, target),
            ids: texture(IDS, target),
            depth,
            depth_view,
            reversed,
            culling,
        })
    }

    pub fn meshlets(&self) -> u32 {
        self.meshlets
    }

    /// Rounds of occlusion culling's second phase.
    pub fn occlusion_rounds(&self) -> u32 {
        self.culling.crowd().occlusion_rounds()
    }

    /// Triangles per instance.
    pub fn triangles(&self) -> u32 {
        self.index_count / 3
    }

    /// Draws one frame of the first `frame.modes.len()` instances.
    pub fn draw(&self, gpu: &Gpu, frame: &CrowdFrame, view: CrowdView, light: Vec3) -> Result<CrowdDrawn> {
        let n = frame.modes.len() as u32;
        let (joints, morphs) = (self.joints as usize, self.morphs as usize);
        if n > self.capacity || frame.palette.len() != n as usize * joints || frame.weights.len() != n as usize * morphs
        {
            return Err(invalid(format!(
                "{n} instances ({} matrices, {} morph weights) for a crowd of {} instances of {joints} joints and \
                 {morphs} morph weights",
                frame.palette.len(),
                frame.weights.len(),
                self.capacity
            )));
        }
        let queue = &gpu.queue;
        queue.write_buffer(&self.palette, 0, bytemuck::cast_slice(frame.palette));
        let threshold = |i: usize| frame.lod_thresholds.get(i).copied().unwrap_or(-1.0);
        let instances: Vec<CullInstance> = (frame.modes.iter().enumerate())
            .map(|(i, &m)| CullInstance::with_lod(Mat4::IDENTITY, m, threshold(i)))
            .collect();
        queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(&instances));
        if !frame.weights.is_empty() {
            queue.write_buffer(&self.weights, 0, bytemuck::cast_slice(frame.weights));
        }
        let mut uniforms: Vec<u32> = frame.camera.view_proj.to_cols_array().map(f32::to_bits).to_vec();
        uniforms.extend(light.normalize_or_zero().extend(0.0).to_array().map(f32::to_bits));
        uniforms.extend([self.index_count / 3, self.culling.id_bits(), (view == CrowdView::PulledByLevel) as u32, 0]);
        queue.write_buffer(&self.view, 0, bytemuck::cast_slice(&uniforms));
        let device = &gpu.device;
        let (row, height) = ((4 * self.width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT), self.height);
        let bytes = (row * height) as u64;
        // The render passes: (pipeline, what it draws, whether it clears); the ID view draws
        // twice (nearer fragments win, then nearer or equal ones: pixels whose ids differ are
        // depth ties between meshlets), occlusion culling's phases draw into one image.
        let rounds = self.culling.crowd().occlusion_rounds();
        let occluded =
            |p| (0..rounds).flat_map(move |r| [(p, Some(List::First), r == 0), (p, Some(List::Second), false)]);
        let passes: Vec<(usize, Option<List>, bool)> = match view {
            CrowdView::Unculled => vec![(0, None, true)],
            CrowdView::Indexed => vec![(0, Some(List::First), true)],
            CrowdView::Pulled | CrowdView::PulledByLevel => vec![(1, Some(List::First), true)],
            CrowdView::Occluded => occluded(1).collect(),
            CrowdView::Triangles => vec![(4, Some(List::First), true)],
            CrowdView::OccludedTriangles => occluded(4).collect(),
            CrowdView::Ids => vec![(2, None, true), (3, None, true)],
        };
        let triangles = matches!(view, CrowdView::Triangles | CrowdView::OccludedTriangles);
        let (culling, skinning) = (&self.culling, &self.groups[1]);
        let (readbacks, times) = gpu.checked("GPU crowd frame", || -> Result<_> {
            let mut encoder = device.create_command_encoder(&Default::default());
            let queries = gpu.has_timestamps().then(|| {
                device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("crowd frame"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                })
            });
            let start = queries.as_ref().map(|set| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: None,
            });
            let (camera, tests) = (frame.camera, frame.tests);
            match view {
                CrowdView::Pulled | CrowdView::PulledByLevel | CrowdView::Indexed => {
                    culling.crowd().encode(queue, &mut encoder, camera, tests, n, start)?
                }
                CrowdView::Occluded => culling.crowd().encode_first(queue, &mut encoder, camera, tests, n, start)?,
                CrowdView::Triangles => culling.encode(queue, &mut encoder, camera, tests, n, skinning, start)?,
                CrowdView::OccludedTriangles => {
                    culling.encode_first(queue, &mut encoder, camera, tests, n, skinning, start)?
                }
                _ => {
                    encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("crowd frame start"),
                        timestamp_writes: start,
                    });
                }
            }
            let target = if view == CrowdView::Ids { &self.ids } else { &self.color };
            let target_view = target.create_view(&Default::default());
            let mut readbacks = Vec::new();
            for (k, &(p, list, clear)) in passes.iter().enumerate() {
                // Occlusion culling's passes 0, 1, 2, … draw round 0's first and second phase,
                // round 1's, … (round 0's first phase recorded above).
                let round = k as u32 / 2;
                match (list, triangles) {
                    (Some(List::First), false) if round > 0 => {
                        culling.crowd().encode_first_phase(&mut encoder, round)?
                    }
                    (Some(List::First), true) if round > 0 => {
                        culling.encode_first_phase(&mut encoder, skinning, round)?
                    }
                    (Some(List::Second), false) => culling.crowd().encode_second(&mut encoder, round)?,
                    (Some(List::Second), true) => culling.encode_second(&mut encoder, skinning, round)?,
                    _ => {}
                }
                let last = k + 1 == passes.len();
                let (color, depth) = match clear {
                    true => (
                        wgpu::LoadOp::Clear(match view {
                            CrowdView::Ids => wgpu::Color::TRANSPARENT,
                            _ => wgpu::Color { r: 0.08, g: 0.09, b: 0.11, a: 1.0 },
                        }),
                        wgpu::LoadOp::Clear(if self.reversed { 0.0 } else { 1.0 }),
                    ),
                    false => (wgpu::LoadOp::Load, wgpu::LoadOp::Load),
                };
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("crowd"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &target_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations { load: color, store: wgpu::StoreOp::Store },
                    })],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &self.depth_view,
                        depth_ops: Some(wgpu::Operations { load: depth, store: wgpu::StoreOp::Store }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: queries.as_ref().filter(|_| last).map(|set| wgpu::RenderPassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: None,
                        end_of_pass_write_index: Some(1),
                    }),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(&self.draws[p]);
                pass.set_bind_group(0, &self.groups[0], &[]);
                pass.set_bind_group(1, skinning, &[]);
                pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
                match (view, list) {
                    (CrowdView::Ids, _) => pass.draw(0..self.index_count, 0..n),
                    (CrowdView::Indexed, Some(list)) => culling.crowd().draw_indexed(&mut pass, list)?,
                    (_, Some(list)) if triangles => culling.draw(&mut pass, list),
                    (_, Some(list)) => culling.crowd().draw_pulled(&mut pass, list),
                    (_, None) => pass.draw_indexed(0..self.index_count, 0, 0..n),
                }
                drop(pass);
                if view == CrowdView::Ids || last {
                    let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
                    let readback = gpu.buffer("crowd image", &vec![0u8; bytes as usize], usage);
                    encoder.copy_texture_to_buffer(
                        target.as_image_copy(),
                        wgpu::TexelCopyBufferInfo {
                            buffer: &readback,
                            layout: wgpu::TexelCopyBufferLayout {
                                offset: 0,
                                bytes_per_row: Some(row),
                                rows_per_image: None,
                            },
                        },
                        target.size(),
                    );
                    readbacks.push(readback);
                }
            }
            let times = queries.map(|set| {
                let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
                let times = gpu.buffer("crowd frame times", &[0u64; 2], usage);
                encoder.resolve_query_set(&set, 0..2, &times, 0);
                times
            });
            queue.submit([encoder.finish()]);
            Ok((readbacks, times))
        })??;
        let mut images = Vec::new();
        for readback in &readbacks {
            let bytes = gpu.read(readback, bytes)?;
            let rows = bytes.chunks_exact(row as usize).map(|r| r[..4 * self.width as usize].to_vec());
            images.push(rows.flatten().collect::<Vec<u8>>());
        }
        let (mut image, mut ids, mut triangle_ids, mut ties) = (None, None, None, None);
        if let [first, last] = &images[..] {
            let words = |b: &Vec<u8>| bytemuck::pod_collect_to_vec::<u8, u32>(b);
            let (first, last) = (words(first), words(last));
            // Ties between any two triangles (of one meshlet too: faceted shading tells them
            // apart), ids by meshlet.
            ties = Some(first.iter().zip(&last).map(|(a, b)| a != b).collect());
            let triangles = self.index_count / 3;
            let meshlet = |id: u32| match id {
                0 => 0,
                _ => (id - 1) / triangles * self.meshlets + self.triangle_meshlets[((id - 1) % triangles) as usize] + 1,
            };
            ids = Some(first.iter().map(|&id| meshlet(id)).collect());
            triangle_ids = Some(first);
        } else {
            image = Some(Image { width: self.width, height, rgba: images.swap_remove(0) });
        }
        let lists = passes.iter().filter(|p| p.1.is_some()).count().min(2);
        let headers = match lists {
            0 => Vec::new(),
            _ => {
                let words = gpu.read(culling.crowd().survivors(), 2 * SurvivorHeader::SIZE)?;
                let all: Vec<SurvivorHeader> = bytemuck::pod_collect_to_vec(&words);
                all[..lists].to_vec()
            }
        };
        let triangle_headers = match triangles {
            false => Vec::new(),
            true => {
                let words = gpu.read(culling.triangles(), 2 * TriangleHeader::SIZE)?;
                let all: Vec<TriangleHeader> = bytemuck::pod_collect_to_vec(&words);
                all[..lists].to_vec()
            }
        };
        let gpu_ms = match times {
            Some(times) => {
                let t = bytemuck::pod_collect_to_vec::<u8, u64>(&gpu.read(&times, 16)?);
                Some(t[1].saturating_sub(t[0]) as f64 * gpu.queue.get_timestamp_period() as f64 / 1e6)
            }
            None => None,
        };
        Ok(CrowdDrawn {
            image,
            ids,
            triangle_ids,
            ties,
            headers,
            triangle_headers,
            draw_calls: passes.len() as u32,
            gpu_ms,
        })
    }

    /// The depth buffer the last frame left, rows top to bottom.
    pub fn depth(&self, gpu: &Gpu) -> Result<Vec<f32>> {
        let row = (4 * self.width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let bytes = (row * self.height) as u64;
        let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let readback = gpu.buffer("crowd depth", &vec![0u8; bytes as usize], usage);
        gpu.checked("GPU crowd depth", || {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo { aspect: wgpu::TextureAspect::DepthOnly, ..self.depth.as_image_copy() },
                wgpu::TexelCopyBufferInfo {
                    buffer: &readback,
                    layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None },
                },
                self.depth.size(),
            );
            gpu.queue.submit([encoder.finish()]);
        })?;
        let bytes = gpu.read(&readback, bytes)?;
        let rows = bytes
            .chunks_exact(row as usize)
            .map(|r| bytemuck::pod_collect_to_vec::<u8, f32>(&r[..4 * self.width as usize]));
        Ok(rows.flatten().collect())
    }

    /// The survivors of the last culled frame as (instance, meshlet) pairs: the first list's,
    /// then (occlusion culling) the second's.
    pub fn survivors(&self, gpu: &Gpu) -> Result<Vec<[u32; 2]>> {
        let crowd = self.culling.crowd();
        let lists = if crowd.occlusion_rounds() > 0 { 2 } else { 1 };
        let words = gpu.read(crowd.survivors(), lists * SurvivorHeader::SIZE)?;
        let headers: Vec<SurvivorHeader> = bytemuck::pod_collect_to_vec(&words);
        let places = crowd.survivor_capacity() as u64;
        let all = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(crowd.commands(), lists * 20 * places)?);
        let meshlet = |first: u32| self.firsts.binary_search(&first).unwrap_or(usize::MAX) as u32;
        let mut out = Vec::new();
        // Every round's survivors (the second list's header counts its last round).
        for (k, h) in headers.iter().enumerate() {
            let list = &all[5 * (k as u64 * places) as usize..];
            out.extend(list.chunks_exact(5).take(h.found.min(places as u32) as usize).map(|c| [c[4], meshlet(c[2])]));
        }
        Ok(out)
    }

    /// The triangles the last frame of a triangle view drew (both lists'), each with its
    /// instance and its meshlet (found by its vertices). Errors when a listed triangle is none
    /// of the mesh's.
    pub fn drawn_triangles(&self, gpu: &Gpu) -> Result<Vec<DrawnTriangle>> {
        let culling = &self.culling;
        let words = gpu.read(culling.triangles(), 2 * TriangleHeader::SIZE)?;
        let headers: Vec<TriangleHeader> = bytemuck::pod_collect_to_vec(&words);
        let size = 2 * TriangleHeader::SIZE + 2 * 12 * culling.capacity() as u64;
        let all = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(culling.triangles(), size)?);
        let (bits, mut out) = (culling.id_bits(), Vec::new());
        for (k, h) in headers.iter().enumerate() {
            let start = 16 + 3 * k * culling.capacity() as usize;
            for t in all[start..start + 3 * h.found.min(culling.capacity()) as usize].chunks_exact(3) {
                let mut vertices = [t[0], t[1], t[2]].map(|i| i & ((1u64 << bits) - 1) as u32);
                vertices.sort_unstable();
                let &triangle = self.triangle_by_vertices.get(&vertices).ok_or_else(|| {
                    invalid(format!("list {k} holds a triangle {t:?} of no meshlet (vertices {vertices:?})"))
                })?;
                let meshlet = self.triangle_meshlets[triangle as usize];
                out.push(DrawnTriangle { instance: t[0] >> bits, meshlet, triangle, vertices });
            }
        }
        Ok(out)
    }
}
