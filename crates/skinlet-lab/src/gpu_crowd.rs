//! A GPU-driven crowd renderer on `skinlet_gpu::crowd_culling`, as an engine would build one:
//! the crowd's buffers live on the GPU across frames, a frame writes the palette, instances
//! and morph weights, records skinlet's culling pass and draws the survivors with one call.
//!
//! Views of the same frame ([`CrowdView`]): every meshlet of every instance (`draw_indexed`
//! over all instances); the survivors pulled by the vertex shader (one `draw_indirect`); the
//! survivors as indexed draws (`multi_draw_indexed_indirect_count`, where the device has it);
//! two-phase occlusion culling, pulled (the visibility bits kept across frames); and the ID
//! buffer of the unculled crowd, whose set of (instance, meshlet) pairs with a visible
//! fragment is what no culling can beat (the oracle). All run the same vertex skinning and
//! faceted shading, so a culled image equals every meshlet drawn the same way exactly when
//! culling kept every meshlet with a visible fragment (but where two meshlets tie in depth:
//! draw order picks the color there, and the ID view finds those pixels).

use crate::render::{COLOR, DEPTH, Image, target_texture};
use glam::{Mat4, Vec3};
use skinlet_gpu::crowd_culling::{
    CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter, List, OcclusionDepth, SURVIVORS_WGSL,
    SurvivorHeader,
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
    /// The survivors as indexed draws: one `multi_draw_indexed_indirect_count`.
    Indexed,
    /// Two-phase occlusion culling, the survivors pulled: last frame's visible, then the
    /// newly visible against the depth pyramid of the first (two `draw_indirect`).
    Occluded,
    /// The unculled crowd's (instance, meshlet) ids.
    Ids,
}

/// One frame of the crowd: per instance its world-space skinning matrices (`joints` each,
/// instance after instance), how it is culled, and its morph weights (the mesh's morph weight
/// count each: none for a mesh without morph targets).
#[derive(Clone, Copy, Debug)]
pub struct CrowdFrame<'a> {
    pub palette: &'a [Mat4],
    pub modes: &'a [CullMode],
    pub weights: &'a [f32],
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
    /// Per pixel, whether the nearest fragments of two meshlets tie in depth there (the
    /// meshlet drawn first and the one drawn last differ): where draw order picks the color.
    pub ties: Option<Vec<bool>>,
    /// The survivor lists' headers (culled views: one, two with occlusion culling).
    pub headers: Vec<SurvivorHeader>,
    /// API draw calls the frame recorded (the ID view draws twice).
    pub draw_calls: u32,
    /// GPU time from the culling pass's start (or the render pass's) to the render pass's
    /// end, where the device has timestamps.
    pub gpu_ms: Option<f64>,
}

/// A crowd of up to `capacity` instances of one baked character, drawn at one image size.
pub struct GpuCrowd {
    pub width: u32,
    pub height: u32,
    capacity: u32,
    joints: u32,
    morphs: u32,
    stride: u32,
    meshlets: u32,
    index_count: u32,
    /// Per meshlet its first index (increasing: the index buffer is in meshlet order).
    firsts: Vec<u32>,
    palette: wgpu::Buffer,
    instances: wgpu::Buffer,
    weights: wgpu::Buffer,
    view: wgpu::Buffer,
    indices: wgpu::Buffer,
    culling: CrowdCulling,
    /// Pipelines and their bind groups: indexed, pulled, ids (nearer wins, nearer or equal
    /// wins).
    draws: [(wgpu::RenderPipeline, wgpu::BindGroup); 4],
    color: wgpu::Texture,
    ids: wgpu::Texture,
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    /// Near 1, far 0.
    reversed: bool,
}

const IDS: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

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
        GpuCrowd::with_depth_range(gpu, baked, culler, capacity, width, height, false)
    }

    /// [`GpuCrowd::new`] with a reversed depth range where `reversed` (near 1, far 0: Bevy's
    /// infinite reverse-Z; the frames' cameras must project so): depth cleared to 0, nearer
    /// fragments the greater, occlusion culling's pyramid of the nearest.
    #[allow(clippy::too_many_arguments)]
    pub fn with_depth_range(
        gpu: &Gpu,
        baked: &skinlet::bake::Baked,
        culler: &MeshletCuller,
        capacity: u32,
        width: u32,
        height: u32,
        reversed: bool,
    ) -> Result<GpuCrowd> {
        let mesh = &baked.mesh;
        let inf = mesh.influences.as_ref().ok_or_else(|| invalid("the bake has no skin weights".into()))?;
        let (indices, draws) = skinlet_gpu::mesh::meshlet_index_buffer(
            &baked.meshlets.view(&baked.meshlets.headers()),
            mesh.positions.len(),
        )?;
        let device = &gpu.device;
        let pipelines = CullPipelines::new(device)?;
        let character = GpuCharacter::new(device, culler, &baked.inverse_bind, &draws)?;
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
        let survivors = capacity.saturating_mul(character.meshlets());
        let texture = |format, usage| target_texture(device, width, height, format, usage);
        let depth = texture(
            DEPTH,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let depth_view = depth.create_view(&Default::default());
        let occlusion = OcclusionDepth { view: &depth_view, width, height, reversed };
        let culling = CrowdCulling::with_occlusion(
            device, &pipelines, &character, &palette, &instances, capacity, survivors, occlusion,
        )?;
        let commands = culling.commands().clone();
        let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
        let influences: Vec<[u32; 2]> =
            inf.joints.iter().zip(&inf.weights).map(|(&j, w)| [j as u32, w.to_bits()]).collect();
        let mut offsets = mesh.morphs.offsets.clone();
        offsets.resize(mesh.positions.len() + 1, 0);
        let deltas: Vec<u32> = (mesh.morphs.deltas.iter())
            .flat_map(|d| [d.position.x.to_bits(), d.position.y.to_bits(), d.position.z.to_bits(), d.weight])
            .collect();
        let triangle_meshlets: Vec<u32> =
            (draws.iter().enumerate()).flat_map(|(m, d)| std::iter::repeat_n(m as u32, d[0] as usize / 3)).collect();
        let read = wgpu::BufferUsages::STORAGE;
        let buffers = [
            &view,
            &palette,
            &gpu.buffer("crowd positions", &positions, read),
            &gpu.buffer("crowd influences", &influences, read),
            &gpu.buffer("crowd morph offsets", &offsets, read),
            &gpu.buffer("crowd morph deltas", &deltas, read),
            &weights,
            &gpu.buffer("crowd indices", &indices, read | wgpu::BufferUsages::INDEX),
            &commands,
            &gpu.buffer("crowd triangle meshlets", &triangle_meshlets, read),
        ];
        let index_buffer = buffers[7].clone();
        let target = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let source = [SURVIVORS_WGSL, include_str!("shaders/crowd.wgsl")].concat();
        gpu.checked("GPU crowd", || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("crowd"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            let make = |vs: &str, fs: &str, format: wgpu::TextureFormat, compare, bindings: &[u32]| {
                let targets = [Some(format.into())];
                let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(vs),
                    layout: None,
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
                });
                let entries: Vec<wgpu::BindGroupEntry> = (bindings.iter())
                    .map(|&b| wgpu::BindGroupEntry { binding: b, resource: buffers[b as usize].as_entire_binding() })
                    .collect();
                let layout = pipeline.get_bind_group_layout(0);
                let group = gpu.bind_group(vs, &layout, &entries);
                (pipeline, group)
            };
            let skinning = [0, 1, 2, 3, 4, 5, 6];
            let ids = [&skinning[..], &[7, 9]].concat();
            use wgpu::CompareFunction::{Greater, GreaterEqual, Less, LessEqual};
            let (nearer, nearer_or_equal) = if reversed { (Greater, GreaterEqual) } else { (Less, LessEqual) };
            GpuCrowd {
                width,
                height,
                capacity,
                joints,
                morphs,
                stride: inf.stride as u32,
                meshlets: character.meshlets(),
                index_count: indices.len() as u32,
                firsts: draws.iter().map(|d| d[1]).collect(),
                palette: palette.clone(),
                instances: instances.clone(),
                weights: weights.clone(),
                view: view.clone(),
                indices: index_buffer,
                draws: [
                    make("vs_indexed", "fs_shaded", COLOR, nearer, &skinning),
                    make("vs_pulled", "fs_shaded", COLOR, nearer, &[&skinning[..], &[7, 8]].concat()),
                    make("vs_ids", "fs_ids", IDS, nearer, &ids),
                    make("vs_ids", "fs_ids", IDS, nearer_or_equal, &ids),
                ],
                color: texture(COLOR, target),
                ids: texture(IDS, target),
                depth,
                depth_view,
                reversed,
                culling,
            }
        })
    }

    pub fn meshlets(&self) -> u32 {
        self.meshlets
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
        let instances: Vec<CullInstance> = frame.modes.iter().map(|&m| CullInstance::new(Mat4::IDENTITY, m)).collect();
        queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(&instances));
        if !frame.weights.is_empty() {
            queue.write_buffer(&self.weights, 0, bytemuck::cast_slice(frame.weights));
        }
        let mut uniforms: Vec<u32> = frame.camera.view_proj.to_cols_array().map(f32::to_bits).to_vec();
        uniforms.extend(light.normalize_or_zero().extend(0.0).to_array().map(f32::to_bits));
        uniforms.extend([self.joints, self.stride, self.morphs, self.meshlets]);
        queue.write_buffer(&self.view, 0, bytemuck::cast_slice(&uniforms));
        let device = &gpu.device;
        let (row, height) = ((4 * self.width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT), self.height);
        let bytes = (row * height) as u64;
        // The render passes: (pipeline, what it draws, whether it clears); the ID view draws
        // twice (nearer fragments win, then nearer or equal ones: pixels whose ids differ are
        // depth ties between meshlets), occlusion culling's phases draw into one image.
        let passes: &[(usize, Option<List>, bool)] = match view {
            CrowdView::Unculled => &[(0, None, true)],
            CrowdView::Indexed => &[(0, Some(List::First), true)],
            CrowdView::Pulled => &[(1, Some(List::First), true)],
            CrowdView::Occluded => &[(1, Some(List::First), true), (1, Some(List::Second), false)],
            CrowdView::Ids => &[(2, None, true), (3, None, true)],
        };
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
            match view {
                CrowdView::Pulled | CrowdView::Indexed => {
                    self.culling.encode(queue, &mut encoder, frame.camera, frame.tests, n, start)?
                }
                CrowdView::Occluded => {
                    self.culling.encode_first(queue, &mut encoder, frame.camera, frame.tests, n, start)?
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
                if list == Some(List::Second) {
                    self.culling.encode_second(&mut encoder)?;
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
                let (pipeline, group) = &self.draws[p];
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
                match (view, list) {
                    (CrowdView::Ids, _) => pass.draw(0..self.index_count, 0..n),
                    (CrowdView::Indexed, Some(list)) => self.culling.draw_indexed(&mut pass, list)?,
                    (_, Some(list)) => self.culling.draw_pulled(&mut pass, list),
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
        let (mut image, mut ids, mut ties) = (None, None, None);
        if let [first, last] = &images[..] {
            let words = |b: &Vec<u8>| bytemuck::pod_collect_to_vec::<u8, u32>(b);
            let (first, last) = (words(first), words(last));
            ties = Some(first.iter().zip(&last).map(|(a, b)| a != b).collect());
            ids = Some(first);
        } else {
            image = Some(Image { width: self.width, height, rgba: images.swap_remove(0) });
        }
        let lists = passes.iter().filter(|p| p.1.is_some()).count();
        let headers = match lists {
            0 => Vec::new(),
            _ => {
                let words = gpu.read(self.culling.survivors(), 2 * SurvivorHeader::SIZE)?;
                let all: Vec<SurvivorHeader> = bytemuck::pod_collect_to_vec(&words);
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
        Ok(CrowdDrawn { image, ids, ties, headers, draw_calls: passes.len() as u32, gpu_ms })
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
        let words = gpu.read(self.culling.survivors(), 2 * SurvivorHeader::SIZE)?;
        let headers: Vec<SurvivorHeader> = bytemuck::pod_collect_to_vec(&words);
        let places = self.culling.survivor_capacity() as u64;
        let all = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(self.culling.commands(), 40 * places)?);
        let meshlet = |first: u32| self.firsts.binary_search(&first).unwrap_or(usize::MAX) as u32;
        let mut out = Vec::new();
        for (k, h) in headers.iter().enumerate() {
            let list = &all[5 * (k as u64 * places) as usize..];
            out.extend(list.chunks_exact(5).take(h.instance_count as usize).map(|c| [c[4], meshlet(c[2])]));
        }
        Ok(out)
    }
}
