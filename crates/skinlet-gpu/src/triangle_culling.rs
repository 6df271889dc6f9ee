//! Per-triangle culling of crowd culling's survivors (skinning-with-mesh-shaders thesis, the
//! per-triangle stage after meshlet culling): a compute pass, one workgroup per surviving
//! (instance, meshlet), skins the meshlet's vertices once with the caller's own skinning
//! function and drops the triangles that are certainly outside a side of the view, back-facing, between
//! pixel centers, or (occlusion culling, but for round 0's first phase) behind the depth
//! pyramid; the rest go to one compacted index list, drawn with one `draw_indexed_indirect`
//! per phase and round.
//!
//! Conservative: a triangle dropped here draws no fragment in the caller's draw. The caller's
//! vertex shader skins with the same WGSL function, which the two pipelines may round
//! differently by at most the margin the caller states ([`TriangleSkinning::margin`]); every
//! test widens the corners by it, by the pass's own rounding and by the rasterizer's vertex
//! snapping ([`Raster::subpixel_bits`]). The image then equals the unculled draw's: `skinlet-lab`'s GPU crowd
//! tests check it on every shared character.
//!
//! With two-phase occlusion culling the visibility bits come from the triangles: in the second
//! phase every meshlet the bounds test keeps is tested triangle by triangle against the
//! pyramid, its bit set when a triangle is not behind it, and its triangles listed when the
//! first phase did not draw it. So a meshlet whose box peeks past an occluder but whose
//! triangles do not is not drawn next frame.
//!
//! The index list holds `instance << id_bits | id` ([`TriangleCulling::id_bits`]), the id a
//! mesh vertex or a triangle corner ([`Entries`]): the draw's vertex shader decodes it
//! ([`TRIANGLES_WGSL`]) and skins the vertex for that instance. It needs 32-bit index values (`wgpu::DownlevelFlags::FULL_DRAW_INDEX_UINT32`, every
//! desktop Vulkan, Metal and D3D12 device).

use crate::Result;
use crate::crowd_culling::{
    CrowdCulling, List, OCCLUSION_OFFSET, OCCLUSION_TEST_WGSL, bind, dynamic_uniform, invalid, layout_entry,
    no_occlusion, part, whole,
};
use skinlet_runtime::bake_view::MeshletView;
use skinlet_runtime::camera::Camera;
use skinlet_runtime::meshlet_cull::Tests;

/// WGSL for the draw's vertex shader: `triangle_entry(index, id_bits)` gives the instance
/// and the vertex or corner ([`Entries`]) of an index of the list ([`TriangleCulling::draw`]
/// draws with `@builtin(vertex_index)` equal to it).
pub const TRIANGLES_WGSL: &str = "
fn triangle_entry(index: u32, id_bits: u32) -> vec2<u32> {
    return vec2<u32>(index >> id_bits, index & ((1u << id_bits) - 1u));
}
";

/// The caller's skinning, as the pass runs it.
#[derive(Clone, Copy, Debug)]
pub struct TriangleSkinning<'a> {
    /// WGSL defining `fn skinned_position(instance: u32, vertex: u32) -> vec3<f32>` (world
    /// space) over bindings of `@group(1)` only: the function the draw's vertex shader skins
    /// with.
    pub wgsl: &'a str,
    /// The layout of those bindings (visible to compute shaders); the bind group is given per
    /// frame.
    pub layout: &'a wgpu::BindGroupLayout,
    /// How far apart the draw's skinned positions and the pass's may be, at a position `p`:
    /// `margin + relative × max(|p.x|, |p.y|, |p.z|)` (world units). The same function
    /// compiled into two pipelines rounds differently (fused multiply-adds) by a few ulps of
    /// the skinning's terms, which are about as large as the position plus a character's size:
    /// 2^-16 of a character's size and 2^-16 (a few hundred ulps) are ample.
    pub margin: f32,
    pub relative: f32,
}

/// How the draw rasterizes: its viewport (the occlusion depth's size where the crowd has
/// one), the rasterizer's sub-pixel precision
/// ([`crate::crowd_culling::subpixel_bits`]), whether it culls back faces
/// (`wgpu::Face::Back`, counter-clockwise front), and whether it is multisampled (then a
/// triangle is kept when it may cover any point of a pixel, not only its center).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Raster {
    pub width: u32,
    pub height: u32,
    pub subpixel_bits: u32,
    pub cull_back_faces: bool,
    pub multisampled: bool,
}

/// What the list's indices name besides the instance ([`TriangleCulling::id_bits`] low bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entries {
    /// The mesh vertex: a draw of the bake's vertices alone (positions, normals, skin).
    Vertices,
    /// The corner: `3·i + k` for corner `k` of the triangle at MLET triangle byte `3·i`, for a
    /// draw that looks up each corner's own attributes (the bake's `SRCT` section names its
    /// source vertex, welded away in the bake's vertices).
    Corners,
}

/// A triangle list's header in [`TriangleCulling::triangles`] (32 bytes; list A's at 0, B's at
/// 32): the indexed draw's arguments, then what the pass found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct TriangleHeader {
    /// 3 × the triangles listed (at most the list's capacity).
    pub index_count: u32,
    pub instance_count: u32,
    pub first_index: u32,
    pub base_vertex: u32,
    pub first_instance: u32,
    /// Triangles kept; more than `index_count / 3` when the list overflowed (those past the
    /// capacity are not drawn: raise it).
    pub found: u32,
    /// Meshlets with a triangle kept (listed).
    pub meshlets: u32,
    pub pad: u32,
}

impl TriangleHeader {
    /// Bytes per header; the indices start after two.
    pub const SIZE: u64 = 32;
}

/// Crowd culling followed by the triangle pass.
pub struct TriangleCulling {
    crowd: CrowdCulling,
    /// Triangles per list.
    capacity: u32,
    id_bits: u32,
    /// `TriangleParams` for phase 0 and round 0's phase 1 at 0, phase 2 at 256, a later
    /// round's phase 1 (tested against the pyramid) at 512.
    pub(crate) uniforms: wgpu::Buffer,
    params: [u32; 12],
    pub(crate) triangles: wgpu::Buffer,
    pub(crate) group: wgpu::BindGroup,
    pub(crate) cull: wgpu::ComputePipeline,
    pub(crate) finish: wgpu::ComputePipeline,
    whole: wgpu::ComputePipeline,
}

const SECOND: u64 = 256;
const FIRST_TESTED: u64 = 512;

/// Most vertices a meshlet may have (the pass skins them into workgroup memory).
pub const MAX_MESHLET_VERTICES: usize = 128;

/// The meshlets as `meshlet_words` of triangle_cull.wgsl: per meshlet where its vertices
/// start, their count (bit 31 set where `two_sided` says so), where its triangles start, their
/// count (words of this array); the
/// vertices; from the returned base, the triangles, one word each (local indices in the low
/// three bytes), the one at MLET triangle byte `3·i` at word `base + i`.
fn pack_meshlets(m: &MeshletView, two_sided: &[bool]) -> (Vec<u32>, u32) {
    let mut words = vec![0u32; 4 * m.len()];
    for i in 0..m.len() {
        let (first, (vertices, _)) = (words.len() as u32, m.counts(i));
        let sides = (two_sided.get(i) == Some(&true)) as u32;
        words[4 * i..4 * i + 2].copy_from_slice(&[first, vertices as u32 | sides << 31]);
        words.extend(m.vertices_of(i));
    }
    let base = words.len();
    words.resize(base + m.triangles.len() / 3, 0);
    for i in 0..m.len() {
        let (h, triangles) = (m.headers[i], m.counts(i).1);
        let first = base + h[1] as usize / 3;
        words[4 * i + 2..4 * i + 4].copy_from_slice(&[first as u32, triangles as u32]);
        let local = &m.triangles[h[1] as usize..h[1] as usize + 3 * triangles];
        let packed = local.chunks_exact(3).map(|t| t[0] as u32 | (t[1] as u32) << 8 | (t[2] as u32) << 16);
        words.splice(first..first + triangles, packed);
    }
    (words, base as u32)
}

impl TriangleCulling {
    /// The triangle pass after `crowd` (which it takes over: [`TriangleCulling::crowd`]), for
    /// a mesh of `vertices` vertices and its `meshlets` (the culler's, in its order; at most
    /// [`MAX_MESHLET_VERTICES`] vertices each), skinned by `skinning`, drawn as `raster` says;
    /// the lists name `entries`. Each list holds `capacity` triangles. `two_sided`, per
    /// meshlet (empty: none): the draw shows its back faces (a double-sided material), so
    /// its triangles are not tested for facing even where `raster` culls back faces (the
    /// draw then culls the other meshlets' back faces itself, e.g. discarding back-facing
    /// fragments, and their crowd culling keeps its cones; the double-sided meshlets' culler
    /// classes must be frustum-only). Errors when an argument is out of range, the meshlets
    /// are not the crowd's or fail their check, `two_sided` is neither empty nor one per
    /// meshlet, the encoded indices would not fit 32 bits, or the pipeline fails validation
    /// (e.g. the skinning WGSL or its layout).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &wgpu::Device,
        crowd: CrowdCulling,
        skinning: TriangleSkinning,
        meshlets: &MeshletView,
        vertices: u32,
        capacity: u32,
        raster: Raster,
        entries: Entries,
        two_sided: &[bool],
    ) -> Result<TriangleCulling> {
        let location = "GPU triangle culling";
        let Raster { width, height, subpixel_bits, cull_back_faces, multisampled } = raster;
        // Multisampled: samples anywhere in a pixel, as if its center could move half a pixel.
        let snap = crate::crowd_culling::snap(subpixel_bits, location)? + if multisampled { 0.5 } else { 0.0 };
        if vertices == 0 || width == 0 || height == 0 {
            return Err(invalid(location, format!("{vertices} vertices drawn at {width}×{height}")));
        }
        if meshlets.len() != crowd.meshlets as usize {
            return Err(invalid(location, format!("{} meshlets for a crowd of {}", meshlets.len(), crowd.meshlets)));
        }
        meshlets
            .check(vertices as usize, [MAX_MESHLET_VERTICES, usize::MAX])
            .map_err(|e| invalid(location, e.to_string()))?;
        if !two_sided.is_empty() && two_sided.len() != meshlets.len() {
            return Err(invalid(
                location,
                format!("{} two-sided flags for {} meshlets", two_sided.len(), meshlets.len()),
            ));
        }
        let (words, triangle_base) = pack_meshlets(meshlets, two_sided);
        if let Some((w, h, ..)) = crowd.occlusion
            && (w, h) != (width, height)
        {
            return Err(invalid(location, format!("drawn at {width}×{height}, occlusion depth {w}×{h}")));
        }
        if ![skinning.margin, skinning.relative].iter().all(|m| m.is_finite() && *m >= 0.0) {
            let (m, r) = (skinning.margin, skinning.relative);
            return Err(invalid(location, format!("skinning margins of {m} and {r} (relative)")));
        }
        let ids = match entries {
            Entries::Vertices => vertices as u64,
            Entries::Corners => meshlets.triangles.len() as u64 / 3 * 3,
        };
        let id_bits = u64::BITS - ids.saturating_sub(1).leading_zeros();
        if (crowd.capacity as u64) << id_bits > 1 << 32 {
            return Err(invalid(
                location,
                format!("{} instances of {ids} {entries:?} ids do not fit 32-bit indices", crowd.capacity),
            ));
        }
        let bytes = 2 * TriangleHeader::SIZE + 2 * 3 * 4 * capacity as u64;
        if bytes > device.limits().max_storage_buffer_binding_size {
            return Err(invalid(location, format!("{capacity} triangles per list exceed the storage binding limit")));
        }
        let params = [
            0,
            capacity,
            id_bits,
            cull_back_faces as u32 | ((entries == Entries::Corners) as u32) << 1,
            width,
            height,
            crowd.survivor_capacity,
            crowd.meshlets,
            skinning.margin.to_bits(),
            skinning.relative.to_bits(),
            snap.to_bits(),
            triangle_base,
        ];
        crate::context::checked(device, location, || {
            use wgpu::BufferBindingType::{Storage, Uniform};
            use wgpu::BufferUsages as U;
            let (read, write) = (Storage { read_only: true }, Storage { read_only: false });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(location),
                entries: &[
                    dynamic_uniform(0),
                    layout_entry(1, Uniform),
                    layout_entry(2, read),
                    layout_entry(3, read),
                    layout_entry(4, write),
                    layout_entry(5, read),
                    layout_entry(6, write),
                ],
            });
            let source = [OCCLUSION_TEST_WGSL, skinning.wgsl, include_str!("shaders/triangle_cull.wgsl")].concat();
            let layouts = [Some(&layout), Some(skinning.layout)];
            let pipeline =
                |entry| crate::context::compute_pipeline_layouts(device, location, source.clone(), entry, &layouts);
            let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("skinlet triangle params"),
                size: FIRST_TESTED + 48,
                usage: U::UNIFORM | U::COPY_DST,
                mapped_at_creation: false,
            });
            let triangles = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("skinlet triangles"),
                size: bytes,
                usage: U::STORAGE | U::INDEX | U::INDIRECT | U::COPY_SRC | U::COPY_DST,
                mapped_at_creation: false,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(location),
                layout: &layout,
                entries: &[
                    bind(0, part(&uniforms, 0, 48)),
                    bind(1, part(&crowd.uniforms, OCCLUSION_OFFSET, 96)),
                    bind(2, whole(&crowd.commands)),
                    bind(3, whole(&crowd.survivors)),
                    bind(4, whole(&crowd.state)),
                    bind(5, whole(&crate::context::buffer(device, "skinlet triangle meshlets", &words, U::STORAGE))),
                    bind(6, whole(&triangles)),
                ],
            });
            TriangleCulling {
                cull: pipeline("cull_triangles"),
                finish: pipeline("finish_triangles"),
                // (Group 0 only: the caller's skinning is not bound then.)
                whole: crate::context::compute_pipeline_layouts(
                    device,
                    location,
                    source.clone(),
                    "whole_lists",
                    &[Some(&layout)],
                ),
                crowd,
                capacity,
                id_bits,
                uniforms,
                params,
                triangles,
                group,
            }
        })
    }

    /// One-phase culling (no occlusion): [`CrowdCulling::encode`]'s meshlet tests, then the
    /// triangle pass over their survivors with the caller's `skinning` bind group (its
    /// palette and instances holding this frame's values), in one compute pass; the triangles
    /// to [`List::First`]. Allocates nothing itself. Errors when `instances` exceeds the
    /// crowd's capacity.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        skinning: &wgpu::BindGroup,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<()> {
        self.encode_phase(queue, encoder, camera, tests, instances, skinning, timestamps, 0)
    }

    /// Occlusion culling's first phase of round 0: the survivors visible last frame (by
    /// their triangles), their triangles to [`List::First`]; the caller draws them into the
    /// depth buffer, then records [`TriangleCulling::encode_second`] for round 0, and for each
    /// later round [`TriangleCulling::encode_first_phase`] and `encode_second`, drawing after
    /// each (as [`CrowdCulling::encode_first`]). Errors also without occlusion culling.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_first(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        skinning: &wgpu::BindGroup,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<()> {
        if self.crowd.occlusion.is_none() {
            return Err(no_occlusion());
        }
        self.encode_phase(queue, encoder, camera, tests, instances, skinning, timestamps, 1)
    }

    /// The first phase of round `round` (1 or later): [`CrowdCulling::encode_first_phase`]'s
    /// pyramid and meshlet tests, then the survivors' triangles not behind the pyramid to
    /// [`List::First`] (this round's only). Errors without occlusion culling or for a round
    /// out of range.
    pub fn encode_first_phase(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        skinning: &wgpu::BindGroup,
        round: u32,
    ) -> Result<()> {
        if round == 0 {
            return Err(invalid("GPU triangle culling", "round 0's first phase is encode_first's".into()));
        }
        let mut pass = self.crowd.encode_round(encoder, round, 1)?;
        self.triangle_pass(&mut pass, skinning, FIRST_TESTED as u32, List::First);
        Ok(())
    }

    /// The second phase of round `round`: [`CrowdCulling::encode_second`]'s pyramid and
    /// meshlet tests, then every survivor's triangles against the pyramid: its visibility bit
    /// from them, and where the first phase did not draw it, its triangles not behind the
    /// pyramid to [`List::Second`] (this round's only). Errors without occlusion culling or
    /// for a round past the last.
    pub fn encode_second(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        skinning: &wgpu::BindGroup,
        round: u32,
    ) -> Result<()> {
        let mut pass = self.crowd.encode_round(encoder, round, 2)?;
        self.triangle_pass(&mut pass, skinning, SECOND as u32, List::Second);
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn encode_phase(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        skinning: &wgpu::BindGroup,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
        phase: u32,
    ) -> Result<()> {
        // (Flags bit 2: tested against the pyramid.)
        for (offset, phase, tested) in [(0, phase, 0), (SECOND, 2, 0), (FIRST_TESTED, 1, 4)] {
            let mut params = self.params;
            (params[0], params[3]) = (phase, params[3] | tested);
            queue.write_buffer(&self.uniforms, offset, bytemuck::cast_slice(&params));
        }
        encoder.clear_buffer(&self.triangles, 0, Some(2 * TriangleHeader::SIZE));
        let mut pass = self.crowd.encode_phase(queue, encoder, camera, tests, instances, timestamps, phase, true)?;
        self.triangle_pass(&mut pass, skinning, 0, List::First);
        Ok(())
    }

    /// After occlusion culling's last round: each list's header becomes the draw of its
    /// triangles of every round, so that a later pass (the shaded pass after a depth pass that
    /// drew the rounds) draws the frame's survivors with one draw per list. Allocates nothing.
    pub fn encode_whole_lists(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("skinlet whole triangle lists"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.whole);
        pass.set_bind_group(0, &self.group, &[0]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// The triangle pass over `list`'s survivors with the `TriangleParams` at `offset`.
    fn triangle_pass(&self, pass: &mut wgpu::ComputePass<'_>, skinning: &wgpu::BindGroup, offset: u32, list: List) {
        let header = match list {
            List::First => 0,
            List::Second => crate::crowd_culling::SurvivorHeader::SIZE,
        };
        pass.set_pipeline(&self.cull);
        pass.set_bind_group(0, &self.group, &[offset]);
        pass.set_bind_group(1, skinning, &[]);
        pass.dispatch_workgroups_indirect(&self.crowd.survivors, header + 20);
        pass.set_pipeline(&self.finish);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// Draws `list`'s triangles: sets the index buffer (the list, `Uint32`) and records one
    /// `draw_indexed_indirect` (base vertex 0, instance 0: the vertex shader decodes
    /// `vertex_index` with [`TRIANGLES_WGSL`]).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, list: List) {
        let header = match list {
            List::First => 0,
            List::Second => TriangleHeader::SIZE,
        };
        pass.set_index_buffer(self.triangles.slice(2 * TriangleHeader::SIZE..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed_indirect(&self.triangles, header);
    }

    /// The meshlet culling the pass follows (its lists, counts and occlusion state are this
    /// culling's; its own encode and draw functions draw meshlets as before, sharing the
    /// visibility bits).
    pub fn crowd(&self) -> &CrowdCulling {
        &self.crowd
    }

    /// Bits of an index that hold the vertex or corner ([`Entries`]).
    pub fn id_bits(&self) -> u32 {
        self.id_bits
    }

    /// Triangles each list holds.
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Two [`TriangleHeader`]s, then list A's indices (3 per triangle), then list B's from
    /// index 3 × capacity (`INDEX`, `INDIRECT`, `STORAGE`, `COPY_SRC`).
    pub fn triangles(&self) -> &wgpu::Buffer {
        &self.triangles
    }
}
