//! Meshlet culling of a whole crowd on the caller's own wgpu device, recorded into the
//! caller's own command encoder (conservative-bounds paper, section 6), with the per-joint
//! preparation on the GPU too: per frame the CPU writes one small uniform and records one
//! compute pass; it touches no per-instance data.
//!
//! Setup, once:
//! - [`CullPipelines::new`] per device (needs [`wgpu::Features::INDIRECT_FIRST_INSTANCE`]:
//!   each instance's draws carry its index as `first_instance`);
//! - [`GpuCharacter::new`] per character: uploads the culler's meshlets grouped by joint
//!   (`Slot` of `cull_common.wgsl`), its any-pose boxes, each meshlet's index range in the
//!   caller's index buffer, and each joint's bind matrix;
//! - [`CrowdCulling::new`] per crowd, over two buffers the caller owns and writes:
//!   - `palette`: per instance, per joint, the skinning matrix `S_j = global_j ×
//!     inverse_bind_j` as a column-major `mat4x4<f32>` (64 bytes), instance after instance:
//!     the palette a skinning vertex shader reads (`STORAGE` usage);
//!   - `instances`: per instance a [`CullInstance`] (80 bytes: model matrix, [`CullMode`]).
//!
//! Per frame, [`CrowdCulling::encode`] runs, in one compute pass:
//! 1. `prepare.wgsl`, one invocation per (instance, joint): the joint's world matrix
//!    `model × S_j × bind_j` and its record (joint-space planes, eye, margins), as
//!    [`MeshletCuller::prepare`] does on the CPU;
//! 2. `crowd_cull.wgsl::cull_draws`, one invocation per (instance, meshlet): the test of
//!    [`CULL_WGSL`]; each surviving (instance, meshlet) takes the next place in one list of
//!    `DrawIndexedIndirectArgs` ([`CrowdCulling::commands`], one atomic counter, claimed a
//!    workgroup at a time), and per instance the counts (visible, frustum, backface,
//!    occluded) go to [`CrowdCulling::counts`];
//! 3. `crowd_cull.wgsl::finish_draws`, one invocation: the list's header
//!    ([`CrowdCulling::survivors`]) becomes the arguments of one draw, its count clamped to
//!    the list's capacity (a survivor past it is counted, not written, and not drawn: see
//!    [`SurvivorHeader`]), so a frame never draws an entry it did not write.
//!
//! The caller draws the survivors with one call, whatever the crowd's size:
//! - [`CrowdCulling::draw_pulled`]: one `draw_indirect`, one instance per survivor, its
//!   vertex shader pulling the survivor's triangles from the caller's index buffer (read as
//!   storage) with [`SURVIVORS_WGSL`]; any device;
//! - [`CrowdCulling::draw_indexed`]: `multi_draw_indexed_indirect_count` over the list with
//!   the caller's index buffer and an unchanged vertex shader (`first_instance` is the
//!   instance); needs [`wgpu::Features::MULTI_DRAW_INDIRECT_COUNT`].
//!
//! With occlusion culling ([`CrowdCulling::with_occlusion`]), a frame is two phases around the
//! caller's draws: [`CrowdCulling::encode_first`] lists the survivors that were visible last
//! frame ([`List::First`]), the caller draws them into its depth buffer,
//! [`CrowdCulling::encode_second`] builds the depth pyramid of that depth (`pyramid.wgsl`) and
//! lists the survivors whose bounds are not behind it and were not drawn yet
//! ([`List::Second`]), setting every meshlet's visibility bit for the next frame; the caller
//! draws those too. A meshlet with a visible fragment is drawn in one of the two phases
//! whatever the bits say (camera cuts, teleports). Both phases may run in rounds
//! ([`OcclusionDepth::rounds`]), each round over a range of the instances (ordered nearest
//! first by the caller): [`CrowdCulling::encode_first_phase`] and `encode_second` per round,
//! each against a pyramid of the depth drawn so far, the caller drawing each step's survivors
//! before the next. A far character is then tested against the near ones as they are now:
//! what they hide this frame is not drawn for having been visible last frame, and what they
//! no longer hide is drawn before the layers behind it are tested.
//!
//! Cluster LOD ([`GpuCharacter::with_lod`]): the character's meshlets are its full-detail
//! meshlets and its LOD hierarchy's clusters (a bake's `LODC`), each with its own group's and
//! its parent group's error, and each instance has an error threshold
//! ([`CullInstance::lod_threshold`], from `skinlet_runtime::lod_select::LodCamera`): the cull
//! pass tests only the clusters of the instance's cut (own error at most the threshold, the
//! parent's above it: `LodView::cut`'s rule, crack-free with one threshold per instance)
//! before the frustum, backface and occlusion tests, so the survivors are the visible part of
//! the cut.
//!
//! [`crate::triangle_culling`] adds a per-triangle pass over the survivors (with the
//! visibility bits then set from the triangles).
//!
//! Nothing is read back. The visible set is conservative: a meshlet culled here is culled by
//! the same test in exact arithmetic on the same matrices (the GPU's margins cover its f32
//! rounding, `prepare.wgsl`); `tests/crowd_culling.rs` checks every culled meshlet of the
//! crowd scene in f64, and the `bring_your_own` example compares both draws' images with an
//! unculled draw.

use crate::{GpuError, Result};
use glam::{Mat4, Vec4Swizzles};
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::{CullSlot, MeshletCuller, Tests};

/// The per-meshlet culling test as a WGSL module for the caller's own task or compute
/// shader: `CullParams`, `Slot`, `RECORD` and `meshlet_flag(slot, instance)` (0 visible, bit 0
/// outside the frustum, 2 back-facing). The including shader declares, in any group:
/// `var<uniform> cull_params: CullParams` ([`CrowdCulling::params`]), `var<storage, read>
/// joint_records: array<f32>` ([`CrowdCulling::records`], written by [`CrowdCulling::encode`])
/// and `var<storage, read> any_pose_boxes: array<u32>` ([`GpuCharacter::any_pose_boxes`]),
/// and reads its slots from `var<storage, read> slots: array<Slot>` ([`GpuCharacter::slots`]).
pub const CULL_WGSL: &str = include_str!("shaders/cull_common.wgsl");

/// The screen-space occlusion test the meshlet and triangle passes share.
pub(crate) const OCCLUSION_TEST_WGSL: &str =
    concat!(include_str!("shaders/pyramid_layout.wgsl"), include_str!("shaders/occlusion_test.wgsl"));

/// WGSL for a vertex shader drawn by [`CrowdCulling::draw_pulled`]:
/// `survivor_corner(instance_index, vertex_index)` gives the survivor's instance, the place in
/// the caller's index buffer of this corner, and whether the corner is one of the meshlet's
/// (the draw has the largest meshlet's corners; a shader returns a position outside the clip
/// volume, e.g. `vec4(2.0, 2.0, 2.0, 1.0)`, for the others: their triangles are whole, so
/// they are clipped away). The including shader declares `var<storage, read> survivor_draws:
/// array<u32>` ([`CrowdCulling::commands`]) in any group.
pub const SURVIVORS_WGSL: &str = include_str!("shaders/survivors.wgsl");

/// The survivors' header ([`CrowdCulling::survivors`], 32 bytes): the arguments of the pulled
/// draw, then how many survivors the culling found this frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct SurvivorHeader {
    /// The largest meshlet's index count.
    pub vertex_count: u32,
    /// Survivors drawn: found, at most the list's capacity (also the count of the indexed
    /// draws, at [`SurvivorHeader::COUNT_OFFSET`]).
    pub instance_count: u32,
    pub first_vertex: u32,
    pub first_instance: u32,
    /// Survivors found; more than `instance_count` when the list overflowed (those past the
    /// capacity were not drawn: raise the capacity).
    pub found: u32,
    /// The triangle pass's workgroups, one per survivor drawn, in rows of at most 65535
    /// (`dispatch_workgroups_indirect` arguments).
    pub workgroups: [u32; 3],
}

impl SurvivorHeader {
    /// Where the survivors drawn are in a header, in bytes: the count buffer offset of
    /// `multi_draw_indexed_indirect_count`.
    pub const COUNT_OFFSET: u64 = 4;
    /// Bytes per header: the second list's header starts here.
    pub const SIZE: u64 = 32;
}

/// How an instance is culled this frame (the pose guard's answer, when the bounds are the
/// envelope's; see `skinlet_runtime::pose_guard`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u32)]
pub enum CullMode {
    /// By the bounds alone (a pose they hold for).
    #[default]
    Bounds = 0,
    /// By the bounds, and the any-pose boxes on what the bounds keep.
    BoundsAndBoxes = 1,
    /// By the any-pose boxes alone (a pose the bounds do not hold for).
    BoxesOnly = 2,
    /// Not culled (morph weights outside every stored range): every meshlet drawn.
    Keep = 3,
}

/// One instance as `prepare.wgsl` reads it (80 bytes).
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct CullInstance {
    /// Model matrix, column-major.
    pub model: [f32; 16],
    /// A [`CullMode`] as `u32`.
    pub mode: u32,
    /// The error threshold of the instance's LOD cut, in the bake's units (for a character
    /// uploaded with [`GpuCharacter::with_lod`]; `skinlet_runtime::lod_select::LodCamera`
    /// gives it): negative or NaN for full detail.
    pub lod_threshold: f32,
    pub pad: [u32; 2],
}

impl CullInstance {
    /// An instance drawn at full detail.
    pub fn new(model: Mat4, mode: CullMode) -> CullInstance {
        CullInstance { model: model.to_cols_array(), mode: mode as u32, lod_threshold: -1.0, pad: [0; 2] }
    }

    /// An instance drawing its LOD cut at error `threshold` where its mode is
    /// [`CullMode::Bounds`] or [`CullMode::BoundsAndBoxes`] (the LOD errors hold for the poses
    /// the bounds hold for), full detail in the other modes.
    pub fn with_lod(model: Mat4, mode: CullMode, threshold: f32) -> CullInstance {
        CullInstance { lod_threshold: threshold, ..CullInstance::new(model, mode) }
    }
}

/// The most meshlets of one cut (`LodView::cut`'s rule: a full-detail meshlet `i < base` at a
/// threshold below its parent's error, a cluster at one from its own error to below its
/// parent's; full detail, `base`, at a negative threshold): the most intervals of thresholds
/// that overlap, swept in order (a cluster leaving at an error before one entering at it).
fn most_drawn(base: usize, errors: &[[f32; 2]]) -> u32 {
    let mut events: Vec<(f32, i32)> = Vec::with_capacity(2 * errors.len());
    for (i, &[own, parent]) in errors.iter().enumerate() {
        events.push((if i < base { 0.0 } else { own }, 1));
        if parent.is_finite() {
            events.push((parent, -1));
        }
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let (mut now, mut most) = (0i64, base as i64);
    for (_, step) in events {
        now += step as i64;
        most = most.max(now);
    }
    most as u32
}

#[cfg(test)]
mod most_drawn_tests {
    use super::most_drawn;

    #[test]
    fn most_drawn_is_the_largest_cut() {
        let inf = f32::INFINITY;
        // Two meshlets (parent error 1) made into three clusters (1 to 2), made into a root (2).
        let errors = [[0.0, 1.0], [0.0, 1.0], [1.0, 2.0], [1.0, 2.0], [1.0, 2.0], [2.0, inf]];
        assert_eq!(most_drawn(2, &errors), 3);
        // Made into one cluster: full detail is the largest.
        assert_eq!(most_drawn(2, &[[0.0, 1.0], [0.0, 1.0], [1.0, inf]]), 2);
        // Three clusters of error 1 whose parent's error is 1 too are in no cut: leaving and
        // entering at one error never count together.
        let errors = [[0.0, 1.0], [0.0, 1.0], [1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [1.0, inf]];
        assert_eq!(most_drawn(2, &errors), 2);
        // No hierarchy: every meshlet.
        assert_eq!(most_drawn(4, &[[0.0, inf]; 4]), 4);
    }
}

/// The compute pipelines (prepare, cull to draws, finish, depth pyramid) of one device.
pub struct CullPipelines {
    prepare: wgpu::ComputePipeline,
    prepare_layout: wgpu::BindGroupLayout,
    cull: wgpu::ComputePipeline,
    cull_layout: wgpu::BindGroupLayout,
    finish: wgpu::ComputePipeline,
    /// The pyramid's pipeline and layout for a single-sample and a multisampled depth buffer.
    pyramid: [(wgpu::ComputePipeline, wgpu::BindGroupLayout); 2],
}

/// A character's culling data on the GPU (uploaded once).
pub struct GpuCharacter {
    meshlets: u32,
    /// [`GpuCharacter::most_drawn`].
    most_drawn: u32,
    joints: u32,
    /// The largest meshlet's index count.
    corners: u32,
    has_boxes: bool,
    /// Per culling class, where its slots start in `slots_by_class` and how many there are.
    class_ranges: [[u32; 2]; 3],
    slots: wgpu::Buffer,
    slots_by_class: wgpu::Buffer,
    boxes: wgpu::Buffer,
    /// Per meshlet: index count, first index, its own and its parent group's LOD error
    /// (`crowd_cull.wgsl`).
    draws: wgpu::Buffer,
    statics: wgpu::Buffer,
}

/// The depth buffer two-phase occlusion culling reads ([`CrowdCulling::with_occlusion`]): the
/// caller's depth texture (`Depth32Float` or another depth format readable as
/// `texture_depth_2d`, or `texture_depth_multisampled_2d` where `multisampled`, with
/// `TEXTURE_BINDING` usage), its size, and whether its depth range is reversed (near 1, far 0:
/// Bevy's infinite reverse-Z), and the sub-pixel precision of the rasterizer that draws into
/// it ([`subpixel_bits`]). Single-sample, the test takes fragments at pixel centers;
/// multisampled, anywhere in a pixel, against the pixel's farthest sample.
#[derive(Clone, Copy, Debug)]
pub struct OcclusionDepth<'a> {
    pub view: &'a wgpu::TextureView,
    pub width: u32,
    pub height: u32,
    pub reversed: bool,
    pub subpixel_bits: u32,
    pub multisampled: bool,
    /// Rounds of occlusion culling (1 to [`MAX_OCCLUSION_ROUNDS`]): round `r` of `R` culls the
    /// instances `r·n/R .. (r+1)·n/R` of the frame's `n` in both phases, each against a
    /// pyramid of the depth drawn so far (but round 0's first phase, before anything is
    /// drawn), and the caller draws each phase's survivors before the next step. With the
    /// instances ordered nearest first, a far character's meshlets are tested against the
    /// near characters as they are now: what the near ones hide this frame is not drawn
    /// because it was visible last frame, and what they no longer hide is drawn before the
    /// characters behind it are tested (instead of leaving holes that every layer behind
    /// passes).
    pub rounds: u32,
}

/// Most rounds of occlusion culling ([`OcclusionDepth::rounds`]).
pub const MAX_OCCLUSION_ROUNDS: u32 = 64;

/// The sub-pixel precision every Vulkan rasterizer has at least (`subPixelPrecisionBits`):
/// vertices snap to a grid of 1/16 pixel. D3D12 requires 8 bits, as desktop Vulkan drivers
/// and lavapipe have; pass what the device reports where it can tell ([`subpixel_bits`]).
pub const MIN_SUBPIXEL_BITS: u32 = 4;

/// The device's sub-pixel precision where its backend reports it (Vulkan:
/// `VkPhysicalDeviceLimits::subPixelPrecisionBits`), else [`MIN_SUBPIXEL_BITS`].
pub fn subpixel_bits(adapter: &wgpu::Adapter) -> u32 {
    #[cfg(feature = "vulkan")]
    {
        // SAFETY: the hal adapter is only read (its limits), never used to create or
        // destroy anything behind wgpu's back.
        if let Some(vulkan) = unsafe { adapter.as_hal::<wgpu::hal::api::Vulkan>() } {
            return vulkan.physical_device_capabilities().properties().limits.sub_pixel_precision_bits;
        }
    }
    let _ = adapter;
    MIN_SUBPIXEL_BITS
}

/// The vertex snapping of a rasterizer with `bits` of sub-pixel precision, in pixels (the
/// largest distance it may move a vertex); errors above 16 bits.
pub(crate) fn snap(bits: u32, location: &'static str) -> Result<f32> {
    if bits > 16 {
        return Err(invalid(location, format!("{bits} sub-pixel bits (at most 16)")));
    }
    Ok(0.5f32.powi(bits as i32))
}

/// Which survivor list a draw reads: the only one (one-phase culling) or occlusion culling's
/// first (last frame's visible), and occlusion culling's second (the newly visible).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum List {
    First,
    Second,
}

/// One crowd's per-frame buffers and bind groups over the caller's palette and instances.
pub struct CrowdCulling {
    pub(crate) capacity: u32,
    /// Places in each survivor list.
    pub(crate) survivor_capacity: u32,
    pub(crate) meshlets: u32,
    joints: u32,
    corners: u32,
    has_boxes: bool,
    /// The device has `MULTI_DRAW_INDIRECT_COUNT`.
    count_draws: bool,
    /// With occlusion culling: the depth size and range, the pyramid's levels, and the
    /// rounds.
    pub(crate) occlusion: Option<(u32, u32, bool, u32, u32)>,
    /// The occlusion depth's vertex snapping, in pixels.
    snap: f32,
    /// The instances of the frame being recorded (the second phase's dispatch size).
    frame_instances: std::sync::atomic::AtomicU32,
    /// `CullParams` (phases 0 and 1) at 0, `CullCamera` at [`CAMERA_OFFSET`], `CullParams`
    /// (phase 2) at [`SECOND_OFFSET`], `Occlusion` at [`OCCLUSION_OFFSET`].
    pub(crate) uniforms: wgpu::Buffer,
    records: wgpu::Buffer,
    counts: wgpu::Buffer,
    pub(crate) commands: wgpu::Buffer,
    pub(crate) survivors: wgpu::Buffer,
    /// Visibility bits, then the depth pyramid.
    pub(crate) state: wgpu::Buffer,
    prepare: wgpu::BindGroup,
    cull: wgpu::BindGroup,
    /// Per pyramid level (a dynamic offset each) the pyramid pass's bind group.
    pyramid: Option<wgpu::BindGroup>,
    prepare_pipeline: wgpu::ComputePipeline,
    cull_pipeline: wgpu::ComputePipeline,
    finish_pipeline: wgpu::ComputePipeline,
    pyramid_pipeline: wgpu::ComputePipeline,
}

/// Where `CullCamera`, the second phase's `CullParams` (round 0), `Occlusion` and the other
/// rounds' `CullParams` (first and second phase of round 1, of round 2, …) start in the
/// uniform buffer (multiples of the uniform offset alignment WebGPU guarantees).
const CAMERA_OFFSET: usize = 256;
const SECOND_OFFSET: usize = 512;
pub(crate) const OCCLUSION_OFFSET: usize = 768;
const ROUNDS_OFFSET: usize = 1024;
const ROUND_STRIDE: usize = 256;
/// Bytes per (instance, joint) record (`RECORD` floats) and its part for occlusion culling
/// (16 floats, only with it), per draw command; per instance counts.
const RECORD_BYTES: u64 = 40 * 4;
const OCCLUSION_RECORD_BYTES: u64 = 16 * 4;
const COMMAND_BYTES: u64 = 20;
const COUNT_BYTES: u64 = 16;
/// The pyramid's level 0 from a single-sample depth buffer, and from a multisampled one (each
/// pixel's farthest sample).
const LEVEL0: &str = "
@group(0) @binding(1) var depth: texture_depth_2d;
fn level0(p: vec2<i32>) -> f32 { return textureLoad(depth, p, 0); }
";
const LEVEL0_MULTISAMPLED: &str = "
@group(0) @binding(1) var depth: texture_depth_multisampled_2d;
fn level0(p: vec2<i32>) -> f32 {
    var far = textureLoad(depth, p, 0);
    for (var s = 1; s < i32(textureNumSamples(depth)); s++) {
        far = farthest(far, textureLoad(depth, p, s));
    }
    return far;
}
";

/// Bytes per pyramid level's uniform (a dynamic offset).
const LEVEL_STRIDE: u64 = 256;

/// The uniform buffer's contents (prepare.wgsl, crowd_cull.wgsl).
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct Uniforms {
    params: [u32; 8],
    pad: [u32; (CAMERA_OFFSET - 32) / 4],
    planes: [[f32; 4]; 6],
    view: [f32; 4],
    nu: f32,
    omega: f32,
    has_boxes: u32,
    pad2: u32,
    pad3: [u32; (SECOND_OFFSET - CAMERA_OFFSET - 128) / 4],
    second: [u32; 8],
    pad4: [u32; (OCCLUSION_OFFSET - SECOND_OFFSET - 32) / 4],
    view_proj: [f32; 16],
    /// width, height, pyramid base, reversed, levels, 0, 0, 0
    occlusion: [u32; 8],
}

/// The rounds after the first, from [`ROUNDS_OFFSET`]: `CullParams` of each phase.
type RoundParams = [[u32; ROUND_STRIDE / 4]; 2 * (MAX_OCCLUSION_ROUNDS as usize - 1)];

/// Where phase `phase` (1 or 2) of round `round` finds its `CullParams` in the uniforms.
fn round_offset(round: u32, phase: u32) -> u32 {
    match (round, phase) {
        (0, 1) => 0,
        (0, _) => SECOND_OFFSET as u32,
        (r, p) => (ROUNDS_OFFSET + (2 * (r as usize - 1) + p as usize - 1) * ROUND_STRIDE) as u32,
    }
}

pub(crate) fn invalid(location: &'static str, message: String) -> GpuError {
    GpuError::Invalid { location, message }
}

/// The error of an occlusion phase recorded on a crowd made without occlusion culling.
pub(crate) fn no_occlusion() -> GpuError {
    invalid("GPU occlusion culling", "the crowd was made without occlusion culling".into())
}

pub(crate) fn bind(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

pub(crate) fn whole(buffer: &wgpu::Buffer) -> wgpu::BindingResource<'_> {
    buffer.as_entire_binding()
}

pub(crate) fn part(buffer: &wgpu::Buffer, offset: usize, size: usize) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: offset as u64,
        size: std::num::NonZeroU64::new(size as u64),
    })
}

pub(crate) fn layout_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    crate::skinning::buffer_entry(binding, wgpu::ShaderStages::COMPUTE, ty)
}

/// A uniform binding with a dynamic offset.
pub(crate) fn dynamic_uniform(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: None,
        },
        count: None,
    }
}

fn pipeline(
    device: &wgpu::Device,
    label: &str,
    source: String,
    entry: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
    (crate::context::compute_pipeline_with(device, label, source, entry, &layout), layout)
}

/// The pyramid's levels (level 0 the depth buffer's size, each next one half, rounded up, down
/// to 1 × 1) and its size in texels.
fn pyramid_levels(width: u32, height: u32) -> (u32, u64) {
    let (mut w, mut h, mut levels, mut texels) = (width as u64, height as u64, 1, 0);
    loop {
        texels += w * h;
        if w == 1 && h == 1 {
            return (levels, texels);
        }
        (w, h, levels) = (w.div_ceil(2), h.div_ceil(2), levels + 1);
    }
}

impl CullPipelines {
    /// Compiles the passes on `device`. Errors when the device lacks
    /// `INDIRECT_FIRST_INSTANCE` or a pipeline fails validation.
    pub fn new(device: &wgpu::Device) -> Result<CullPipelines> {
        if !device.features().contains(wgpu::Features::INDIRECT_FIRST_INSTANCE) {
            return Err(invalid(
                "GPU crowd culling",
                "the device lacks INDIRECT_FIRST_INSTANCE (request it in the device descriptor)".into(),
            ));
        }
        crate::context::checked(device, "GPU crowd culling pipelines", || {
            use wgpu::BufferBindingType::{Storage, Uniform};
            let (read, write) = (Storage { read_only: true }, Storage { read_only: false });
            let (prepare, prepare_layout) = pipeline(
                device,
                "skinlet prepare",
                include_str!("shaders/prepare.wgsl").into(),
                "prepare",
                &[
                    layout_entry(0, Uniform),
                    layout_entry(1, Uniform),
                    layout_entry(2, read),
                    layout_entry(3, read),
                    layout_entry(4, read),
                    layout_entry(5, write),
                ],
            );
            let source = [CULL_WGSL, OCCLUSION_TEST_WGSL, include_str!("shaders/crowd_cull.wgsl")].concat();
            let (cull, cull_layout) = pipeline(
                device,
                "skinlet cull",
                source.clone(),
                "cull_draws",
                &[
                    dynamic_uniform(0),
                    layout_entry(1, read),
                    layout_entry(2, read),
                    layout_entry(3, write),
                    layout_entry(5, read),
                    layout_entry(6, write),
                    layout_entry(7, read),
                    layout_entry(8, write),
                    layout_entry(9, Uniform),
                    layout_entry(10, write),
                ],
            );
            let finish = crate::context::compute_pipeline_with(
                device,
                "skinlet survivors",
                source,
                "finish_draws",
                &cull_layout,
            );
            // The pyramid of a single-sample depth buffer, and of a multisampled one.
            let pyramid = |multisampled: bool| {
                let depth = wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled,
                    },
                    count: None,
                };
                let level0 = if multisampled { LEVEL0_MULTISAMPLED } else { LEVEL0 };
                let source =
                    [level0, include_str!("shaders/pyramid_layout.wgsl"), include_str!("shaders/pyramid.wgsl")];
                pipeline(
                    device,
                    "skinlet depth pyramid",
                    source.concat(),
                    "reduce",
                    &[dynamic_uniform(0), depth, layout_entry(2, write)],
                )
            };
            CullPipelines {
                prepare,
                prepare_layout,
                cull,
                cull_layout,
                finish,
                pyramid: [pyramid(false), pyramid(true)],
            }
        })
    }
}

impl GpuCharacter {
    /// Uploads `culler`'s meshlets and any-pose boxes, `inverse_bind` (one per joint, the
    /// skin's inverse bind matrices) and `draws` (per meshlet, in the culler's meshlet order:
    /// its index count, whole triangles, and first index in the caller's index buffer). Errors
    /// when the counts disagree, an index count is not a multiple of 3, or an inverse bind
    /// matrix is not finite or not invertible.
    pub fn new(
        device: &wgpu::Device,
        culler: &MeshletCuller,
        inverse_bind: &[Mat4],
        draws: &[[u32; 2]],
    ) -> Result<GpuCharacter> {
        let errors = vec![[0.0, f32::INFINITY]; culler.len()];
        GpuCharacter::with_lod(device, culler, inverse_bind, draws, culler.len(), &errors)
    }

    /// [`GpuCharacter::new`] for a character with a cluster LOD hierarchy (a bake's `LODC`,
    /// `skinlet_runtime::bake_view::LodView`): `culler` and `draws` hold its `base` full-detail
    /// meshlets, then its clusters, numbered as `LodView::cluster_errors` numbers them, and
    /// `errors` each one's errors from it (its own group's, 0 at full detail, and its parent
    /// group's, infinite for a root). Each instance then tests only the clusters of its cut at
    /// its [`CullInstance::lod_threshold`] (`LodView::cut`'s rule). Errors also when the counts
    /// disagree, an error is negative or NaN, or a parent's is below its cluster's.
    pub fn with_lod(
        device: &wgpu::Device,
        culler: &MeshletCuller,
        inverse_bind: &[Mat4],
        draws: &[[u32; 2]],
        base: usize,
        errors: &[[f32; 2]],
    ) -> Result<GpuCharacter> {
        let location = "GPU character";
        let (meshlets, joints) = (culler.len(), culler.joints());
        if draws.len() != meshlets || errors.len() != meshlets || base > meshlets {
            return Err(invalid(
                location,
                format!(
                    "{} meshlet draws, {} LOD errors and {base} full-detail meshlets for {meshlets} meshlets",
                    draws.len(),
                    errors.len()
                ),
            ));
        }
        if let Some(i) = errors.iter().position(|&[own, parent]| !(own >= 0.0 && own <= parent)) {
            return Err(invalid(location, format!("meshlet {i}'s LOD errors {:?} (0 ≤ own ≤ parent)", errors[i])));
        }
        // Full detail marked by a negative error of its own (crowd_cull.wgsl).
        let records: Vec<[u32; 4]> = (draws.iter().zip(errors).enumerate())
            .map(|(i, (d, &[own, parent]))| {
                [d[0], d[1], if i < base { -1.0f32 } else { own }.to_bits(), parent.to_bits()]
            })
            .collect();
        if inverse_bind.len() != joints {
            return Err(invalid(location, format!("{} inverse bind matrices for {joints} joints", inverse_bind.len())));
        }
        if let Some(i) = draws.iter().position(|d| d[0] % 3 != 0) {
            return Err(invalid(location, format!("meshlet {i}'s {} indices are not whole triangles", draws[i][0])));
        }
        let mut statics: Vec<f32> = Vec::with_capacity(20 * joints);
        for (j, (m, &extent)) in inverse_bind.iter().zip(culler.joint_extents()).enumerate() {
            let bind = m.inverse();
            if !(m.is_finite() && bind.is_finite() && m.determinant() != 0.0) {
                return Err(invalid(location, format!("joint {j}'s inverse bind matrix is not invertible")));
            }
            statics.extend(bind.to_cols_array());
            statics.extend([extent, 0.0, 0.0, 0.0]);
        }
        if meshlets > u32::MAX as usize / 4 || joints > u32::MAX as usize / 4 {
            return Err(invalid(location, format!("{meshlets} meshlets and {joints} joints")));
        }
        // Slots by culling class (paper section 6): both tests, the frustum test only, none.
        let class = |s: &CullSlot| match (s.frustum_ok, s.sin > 1.0) {
            (false, _) => 2,
            (true, no_cone) => no_cone as usize,
        };
        let slots = culler.slots();
        let mut by_class = slots.clone();
        by_class.sort_by_key(class);
        let mut class_ranges = [[0u32; 2]; 3];
        for s in &slots {
            class_ranges[class(s)][1] += 1;
        }
        class_ranges[1][0] = class_ranges[0][1];
        class_ranges[2][0] = class_ranges[1][0] + class_ranges[1][1];
        let storage = wgpu::BufferUsages::STORAGE;
        let most_drawn = most_drawn(base, errors);
        crate::context::checked(device, location, || GpuCharacter {
            class_ranges,
            meshlets: meshlets as u32,
            most_drawn,
            joints: joints as u32,
            corners: draws.iter().map(|d| d[0]).max().unwrap_or(0),
            has_boxes: !culler.any_pose_boxes().1.is_empty(),
            slots: crate::context::buffer(device, "skinlet cull slots", &pack_slots(&slots), storage),
            slots_by_class: crate::context::buffer(
                device,
                "skinlet cull slots by class",
                &pack_slots(&by_class),
                storage,
            ),
            boxes: crate::context::buffer(device, "skinlet any-pose boxes", &pack_boxes(culler), storage),
            draws: crate::context::buffer(device, "skinlet meshlet draws", &records, storage),
            statics: crate::context::buffer(device, "skinlet joint statics", &statics, storage),
        })
    }

    pub fn meshlets(&self) -> u32 {
        self.meshlets
    }

    /// The most meshlets one instance can draw: every full-detail meshlet, or the largest LOD
    /// cut where that has more. `instances × most_drawn()` places hold every survivor of a
    /// culled list (a hierarchy's clusters all together are never one instance's).
    pub fn most_drawn(&self) -> u32 {
        self.most_drawn
    }

    pub fn joints(&self) -> u32 {
        self.joints
    }

    /// The meshlets as `array<Slot>` of [`CULL_WGSL`] (grouped by joint; `Slot::id` is the
    /// meshlet's index).
    pub fn slots(&self) -> &wgpu::Buffer {
        &self.slots
    }

    /// The same slots ordered by culling class (conservative-bounds paper, section 6: both
    /// tests, the frustum test only, none), for task shaders compiled per class
    /// (`CLASS_TESTS` of [`CULL_WGSL`]: 3, 1, 0), each over its class's range
    /// ([`GpuCharacter::class_ranges`]).
    pub fn slots_by_class(&self) -> &wgpu::Buffer {
        &self.slots_by_class
    }

    /// Per culling class, where its slots start in [`GpuCharacter::slots_by_class`] and how
    /// many there are.
    pub fn class_ranges(&self) -> [[u32; 2]; 3] {
        self.class_ranges
    }

    /// `any_pose_boxes` of [`CULL_WGSL`].
    pub fn any_pose_boxes(&self) -> &wgpu::Buffer {
        &self.boxes
    }
}

impl CrowdCulling {
    /// Buffers and bind groups for up to `capacity` instances of `character` over the
    /// caller's `palette` (at least `capacity × joints` matrices) and `instances` (at least
    /// `capacity` [`CullInstance`]s), both with `STORAGE` usage, and a list of
    /// `survivor_capacity` survivors (`capacity ×` [`GpuCharacter::most_drawn`] never
    /// overflows; a frame's survivors past it are not drawn, [`SurvivorHeader::found`] says how
    /// many there were).
    /// Errors when a buffer is too small or lacks the usage, or the list or the joint records
    /// exceed the device's storage binding limit.
    pub fn new(
        device: &wgpu::Device,
        pipelines: &CullPipelines,
        character: &GpuCharacter,
        palette: &wgpu::Buffer,
        instances: &wgpu::Buffer,
        capacity: u32,
        survivor_capacity: u32,
    ) -> Result<CrowdCulling> {
        Self::build(device, pipelines, character, palette, instances, capacity, survivor_capacity, None)
    }

    /// [`CrowdCulling::new`] with two-phase occlusion culling against `depth`, the depth
    /// buffer the caller draws the crowd into: [`CrowdCulling::encode_first`] and
    /// [`CrowdCulling::encode_second`] (two survivor lists of `survivor_capacity` each, one
    /// visibility bit per instance and meshlet, a depth pyramid of `depth`'s size). Errors
    /// also when `depth` is empty.
    #[allow(clippy::too_many_arguments)]
    pub fn with_occlusion(
        device: &wgpu::Device,
        pipelines: &CullPipelines,
        character: &GpuCharacter,
        palette: &wgpu::Buffer,
        instances: &wgpu::Buffer,
        capacity: u32,
        survivor_capacity: u32,
        depth: OcclusionDepth,
    ) -> Result<CrowdCulling> {
        if depth.width == 0 || depth.height == 0 {
            return Err(invalid("GPU occlusion culling", format!("a {}×{} depth buffer", depth.width, depth.height)));
        }
        if !(1..=MAX_OCCLUSION_ROUNDS).contains(&depth.rounds) {
            return Err(invalid(
                "GPU occlusion culling",
                format!("{} rounds (1 to {MAX_OCCLUSION_ROUNDS})", depth.rounds),
            ));
        }
        Self::build(device, pipelines, character, palette, instances, capacity, survivor_capacity, Some(depth))
    }

    #[allow(clippy::too_many_arguments)]
    fn build(
        device: &wgpu::Device,
        pipelines: &CullPipelines,
        character: &GpuCharacter,
        palette: &wgpu::Buffer,
        instances: &wgpu::Buffer,
        capacity: u32,
        survivor_capacity: u32,
        depth: Option<OcclusionDepth>,
    ) -> Result<CrowdCulling> {
        let location = "GPU crowd culling";
        // Multisampled: samples anywhere in a pixel, as if its center could move half a pixel.
        let snap = match depth {
            Some(d) => snap(d.subpixel_bits, location)? + if d.multisampled { 0.5 } else { 0.0 },
            None => 1.0,
        };
        let cap = capacity as u64;
        let (joints, meshlets) = (character.joints as u64, character.meshlets as u64);
        let need = |buffer: &wgpu::Buffer, name: &str, bytes: u64| {
            if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
                return Err(invalid(location, format!("the {name} buffer lacks STORAGE usage")));
            }
            if buffer.size() < bytes {
                return Err(invalid(
                    location,
                    format!("the {name} buffer holds {} bytes; {capacity} instances need {bytes}", buffer.size()),
                ));
            }
            Ok(())
        };
        need(palette, "palette", cap * joints * 64)?;
        need(instances, "instances", cap * std::mem::size_of::<CullInstance>() as u64)?;
        let limit = device.limits().max_storage_buffer_binding_size;
        let lists = if depth.is_some() { 2 } else { 1 };
        let (levels, texels) = depth.map_or((0, 0), |d| pyramid_levels(d.width, d.height));
        let state_size = (cap * meshlets + texels) * 4;
        // The joints' records, each instance's LOD threshold, the records' occlusion part.
        let occlusion_bytes = if depth.is_some() { OCCLUSION_RECORD_BYTES } else { 0 };
        let records_size = cap * joints * (RECORD_BYTES + occlusion_bytes) + cap * 4;
        let commands_size = lists * survivor_capacity as u64 * COMMAND_BYTES;
        if records_size.max(commands_size).max(state_size).max(cap * COUNT_BYTES) > limit
            || cap * meshlets.max(joints) > u32::MAX as u64 / 2
            || (cap * meshlets + texels) > u32::MAX as u64 / 2
        {
            return Err(invalid(
                location,
                format!(
                    "{capacity} instances of {meshlets} meshlets and {joints} joints, {survivor_capacity} survivors, \
                     a {texels}-texel depth pyramid exceed the device's {limit}-byte storage bindings"
                ),
            ));
        }
        let size = |bytes: u64| bytes.max(16);
        let make = |label: &str, bytes: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size(bytes),
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        crate::context::checked(device, location, || {
            let rounds = depth.map_or(1, |d| d.rounds) as usize;
            let uniforms_size = ROUNDS_OFFSET + 2 * (rounds - 1) * ROUND_STRIDE;
            let uniforms = make("skinlet cull uniforms", uniforms_size as u64, U::UNIFORM | U::COPY_DST);
            let records = make("skinlet joint records", records_size, U::STORAGE);
            let counts = make("skinlet cull counts", cap * COUNT_BYTES, U::STORAGE | U::COPY_SRC | U::COPY_DST);
            let commands = make("skinlet draw commands", commands_size, U::STORAGE | U::INDIRECT | U::COPY_SRC);
            let survivors = make(
                "skinlet survivors",
                2 * std::mem::size_of::<SurvivorHeader>() as u64,
                U::STORAGE | U::INDIRECT | U::COPY_SRC | U::COPY_DST,
            );
            let state = make("skinlet occlusion state", state_size, U::STORAGE | U::COPY_DST);
            let params_size = 32;
            let prepare = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("skinlet prepare"),
                layout: &pipelines.prepare_layout,
                entries: &[
                    bind(0, part(&uniforms, 0, params_size)),
                    bind(1, part(&uniforms, CAMERA_OFFSET, 128)),
                    bind(2, whole(palette)),
                    bind(3, whole(instances)),
                    bind(4, whole(&character.statics)),
                    bind(5, whole(&records)),
                ],
            });
            let cull = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("skinlet cull"),
                layout: &pipelines.cull_layout,
                entries: &[
                    bind(0, part(&uniforms, 0, params_size)),
                    bind(1, whole(&character.slots)),
                    bind(2, whole(&records)),
                    bind(3, whole(&counts)),
                    bind(5, whole(&character.draws)),
                    bind(6, whole(&commands)),
                    bind(7, whole(&character.boxes)),
                    bind(8, whole(&survivors)),
                    bind(9, part(&uniforms, OCCLUSION_OFFSET, 96)),
                    bind(10, whole(&state)),
                ],
            });
            let pyramid = depth.map(|d| {
                // Per level: width, height, pyramid base, reversed, level.
                let words: Vec<u32> = (0..levels)
                    .flat_map(|level| {
                        let mut w = [0u32; LEVEL_STRIDE as usize / 4];
                        w[..5].copy_from_slice(&[d.width, d.height, (cap * meshlets) as u32, d.reversed as u32, level]);
                        w
                    })
                    .collect();
                let level_uniforms = crate::context::buffer(device, "skinlet pyramid levels", &words, U::UNIFORM);
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("skinlet depth pyramid"),
                    layout: &pipelines.pyramid[d.multisampled as usize].1,
                    entries: &[
                        bind(0, part(&level_uniforms, 0, 32)),
                        bind(1, wgpu::BindingResource::TextureView(d.view)),
                        bind(2, whole(&state)),
                    ],
                })
            });
            CrowdCulling {
                capacity,
                survivor_capacity,
                meshlets: character.meshlets,
                joints: character.joints,
                corners: character.corners,
                has_boxes: character.has_boxes,
                count_draws: device.features().contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
                occlusion: depth.map(|d| (d.width, d.height, d.reversed, levels, d.rounds)),
                snap,
                frame_instances: std::sync::atomic::AtomicU32::new(0),
                uniforms,
                records,
                counts,
                commands,
                survivors,
                state,
                prepare,
                cull,
                pyramid,
                prepare_pipeline: pipelines.prepare.clone(),
                cull_pipeline: pipelines.cull.clone(),
                finish_pipeline: pipelines.finish.clone(),
                pyramid_pipeline: pipelines.pyramid[depth.is_some_and(|d| d.multisampled) as usize].0.clone(),
            }
        })
    }

    /// One-phase culling (frustum, backface, any-pose boxes; no occlusion): writes this
    /// frame's camera and instance count (`queue.write_buffer`, under 1 KB) and records the
    /// passes for the first `instances` instances into `encoder` (the counts and the survivors'
    /// headers are cleared first): the survivors go to [`List::First`]. `timestamps`, if given,
    /// are written at the pass's start and end. The caller's palette and instances must hold
    /// this frame's values when the commands run. Allocates nothing itself. Errors when
    /// `instances` exceeds the capacity.
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<()> {
        self.encode_phase(queue, encoder, camera, tests, instances, timestamps, 0, false)?;
        Ok(())
    }

    /// Only the per-joint preparation of [`CrowdCulling::encode`] (the counts and survivor
    /// lists are cleared, not written), with the same inputs: [`CrowdCulling::records`] and
    /// [`CrowdCulling::params`] then hold what `meshlet_flag` of [`CULL_WGSL`] reads, for the
    /// caller's own task or compute shader. Allocates nothing itself.
    pub fn encode_prepare(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
    ) -> Result<()> {
        let mut pass = self.begin(queue, encoder, camera, tests, instances, None, 0, false)?;
        self.prepare_pass(&mut pass, instances);
        Ok(())
    }

    /// Occlusion culling's first phase of round 0 ([`OcclusionDepth::rounds`]): as
    /// [`CrowdCulling::encode`], the survivors of the round's instances that were visible last
    /// frame (by the second phase's bits) to [`List::First`]. The caller draws them into the
    /// depth buffer given at construction, then records [`CrowdCulling::encode_second`] for
    /// round 0, draws, and for each later round [`CrowdCulling::encode_first_phase`] and
    /// `encode_second`, drawing after each. Errors also without occlusion culling.
    pub fn encode_first(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<()> {
        if self.occlusion.is_none() {
            return Err(no_occlusion());
        }
        self.encode_phase(queue, encoder, camera, tests, instances, timestamps, 1, false)?;
        Ok(())
    }

    /// The first phase of round `round` (1 or later: [`CrowdCulling::encode_first`] records
    /// round 0's): the depth pyramid of what is drawn so far, then the round's instances'
    /// survivors that were visible last frame and are not behind the pyramid (their bounding
    /// spheres; any-pose boxes as in the second phase) to [`List::First`] (this round's
    /// only). Allocates nothing. Errors without occlusion culling or for a round out of range.
    pub fn encode_first_phase(&self, encoder: &mut wgpu::CommandEncoder, round: u32) -> Result<()> {
        if round == 0 {
            return Err(invalid("GPU occlusion culling", "round 0's first phase is encode_first's".into()));
        }
        self.encode_round(encoder, round, 1)?;
        Ok(())
    }

    /// The second phase of round `round` ([`OcclusionDepth::rounds`]; the caller records the
    /// rounds in order, each phase drawn into the depth buffer before the next step): the
    /// depth pyramid of what is drawn so far, then every meshlet of the round's instances that
    /// the first phase did not draw tested again with its bounding sphere (its any-pose boxes,
    /// for an instance culled by the boxes alone) against the pyramid; the newly visible to
    /// [`List::Second`] (this round's survivors only), and every meshlet's visibility bit set
    /// for the next frame. Allocates nothing. Errors without occlusion culling or for a round
    /// past the last.
    pub fn encode_second(&self, encoder: &mut wgpu::CommandEncoder, round: u32) -> Result<()> {
        self.encode_round(encoder, round, 2)?;
        Ok(())
    }

    /// Occlusion culling's rounds ([`OcclusionDepth::rounds`]; 0 without occlusion culling).
    pub fn occlusion_rounds(&self) -> u32 {
        self.occlusion.map_or(0, |o| o.4)
    }

    /// Phase `phase` (1 or 2) of round `round` after the pyramid of the depth drawn so far,
    /// its last pass left open (for the triangle pass).
    pub(crate) fn encode_round<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        round: u32,
        phase: u32,
    ) -> Result<wgpu::ComputePass<'e>> {
        let rounds = self.occlusion_rounds();
        if round >= rounds {
            return Err(match rounds {
                0 => no_occlusion(),
                _ => invalid("GPU occlusion culling", format!("round {round} of {rounds}")),
            });
        }
        let (Some((width, height, _, levels, _)), Some(pyramid)) = (self.occlusion, &self.pyramid) else {
            return Err(no_occlusion());
        };
        // Each level in its own pass: the next one reads what this one wrote.
        for level in 0..levels {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("skinlet depth pyramid"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pyramid_pipeline);
            pass.set_bind_group(0, pyramid, &[level * LEVEL_STRIDE as u32]);
            let (w, h) = (width.div_ceil(1 << level).max(1), height.div_ceil(1 << level).max(1));
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("skinlet occlusion culling"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.cull_pipeline);
        pass.set_bind_group(0, &self.cull, &[round_offset(round, phase)]);
        dispatch(&mut pass, self.round_instances(round) * self.meshlets);
        pass.set_pipeline(&self.finish_pipeline);
        pass.dispatch_workgroups(1, 1, 1);
        Ok(pass)
    }

    /// How many instances occlusion culling's round `round` culls in the frame the last
    /// `encode*` began (crowd_cull.wgsl's ranges).
    fn round_instances(&self, round: u32) -> u32 {
        let n = self.frame_instances.load(std::sync::atomic::Ordering::Relaxed) as u64;
        let rounds = self.occlusion_rounds().max(1) as u64;
        let first = |r: u32| r as u64 * n / rounds;
        (first(round + 1) - first(round)) as u32
    }

    /// Phase `phase`'s culling, its pass left open; `triangles`: the triangle pass follows
    /// (`crowd_cull.wgsl`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn encode_phase<'e>(
        &self,
        queue: &wgpu::Queue,
        encoder: &'e mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
        phase: u32,
        triangles: bool,
    ) -> Result<wgpu::ComputePass<'e>> {
        let mut pass = self.begin(queue, encoder, camera, tests, instances, timestamps, phase, triangles)?;
        self.prepare_pass(&mut pass, instances);
        pass.set_pipeline(&self.cull_pipeline);
        pass.set_bind_group(0, &self.cull, &[0]);
        // Phase 1: round 0's instances.
        let culled = if phase == 1 { self.round_instances(0) } else { instances };
        dispatch(&mut pass, culled * self.meshlets);
        pass.set_pipeline(&self.finish_pipeline);
        pass.dispatch_workgroups(1, 1, 1);
        Ok(pass)
    }

    fn prepare_pass(&self, pass: &mut wgpu::ComputePass<'_>, instances: u32) {
        pass.set_pipeline(&self.prepare_pipeline);
        pass.set_bind_group(0, &self.prepare, &[]);
        dispatch(pass, instances * self.joints);
    }

    /// Writes this frame's uniforms, clears the counts and headers, and opens the culling
    /// pass.
    #[allow(clippy::too_many_arguments)]
    fn begin<'e>(
        &self,
        queue: &wgpu::Queue,
        encoder: &'e mut wgpu::CommandEncoder,
        camera: &Camera,
        tests: Tests,
        instances: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
        phase: u32,
        triangles: bool,
    ) -> Result<wgpu::ComputePass<'e>> {
        if instances > self.capacity {
            return Err(invalid(
                "GPU crowd culling",
                format!("{instances} instances for a crowd of capacity {}", self.capacity),
            ));
        }
        let (view, orthographic) = match camera.projection {
            Projection::Perspective { eye } => (eye.extend(0.0), false),
            Projection::Orthographic { dir } => (dir.extend(0.0), true),
        };
        let planes = &camera.planes;
        let (width, height, reversed, levels, rounds) = self.occlusion.unwrap_or_default();
        // The round (and the rounds) in the padding word.
        let params = |phase, round: usize| {
            let f = flags(tests, orthographic) | (triangles as u32) << 3;
            let round = round as u32 | rounds << 8;
            [self.meshlets, self.joints, instances, f, round, self.survivor_capacity, self.corners, phase]
        };
        let uniforms = Uniforms {
            params: params(phase, 0),
            pad: [0; (CAMERA_OFFSET - 32) / 4],
            planes: planes.map(|p| p.to_array()),
            view: view.to_array(),
            nu: planes.iter().map(|p| p.xyz().abs().max_element()).fold(0.0, f32::max),
            omega: planes.iter().map(|p| p.w.abs()).fold(0.0, f32::max),
            has_boxes: self.has_boxes as u32,
            pad2: 0,
            pad3: [0; (SECOND_OFFSET - CAMERA_OFFSET - 128) / 4],
            second: params(2, 0),
            pad4: [0; (OCCLUSION_OFFSET - SECOND_OFFSET - 32) / 4],
            view_proj: camera.view_proj.to_cols_array(),
            occlusion: [
                width,
                height,
                self.capacity * self.meshlets,
                reversed as u32,
                levels,
                self.snap.to_bits(),
                0,
                0,
            ],
        };
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        if rounds > 1 {
            let mut round_params: RoundParams = [[0; ROUND_STRIDE / 4]; 2 * (MAX_OCCLUSION_ROUNDS as usize - 1)];
            for (k, block) in round_params.iter_mut().take(2 * (rounds as usize - 1)).enumerate() {
                block[..8].copy_from_slice(&params(1 + k as u32 % 2, 1 + k / 2));
            }
            let used = bytemuck::cast_slice(&round_params[..2 * (rounds as usize - 1)]);
            queue.write_buffer(&self.uniforms, ROUNDS_OFFSET as u64, used);
        }
        self.frame_instances.store(instances, std::sync::atomic::Ordering::Relaxed);
        encoder.clear_buffer(&self.counts, 0, None);
        encoder.clear_buffer(&self.survivors, 0, None);
        Ok(encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("skinlet crowd culling"),
            timestamp_writes: timestamps,
        }))
    }

    /// Where `list`'s header starts in [`CrowdCulling::survivors`], and its first entry in
    /// [`CrowdCulling::commands`].
    fn list_offsets(&self, list: List) -> (u64, u64) {
        match list {
            List::First => (0, 0),
            List::Second => (SurvivorHeader::SIZE, self.survivor_capacity as u64 * COMMAND_BYTES),
        }
    }

    /// Draws `list`'s survivors with one `draw_indirect` of its header: the pipeline's vertex
    /// shader pulls its vertices with [`SURVIVORS_WGSL`] (the second list's instances start
    /// past the first's places, so the same shader and bindings draw both).
    pub fn draw_pulled(&self, pass: &mut wgpu::RenderPass<'_>, list: List) {
        pass.draw_indirect(&self.survivors, self.list_offsets(list).0);
    }

    /// Draws `list`'s survivors with `multi_draw_indexed_indirect_count` (the pipeline's
    /// index buffer set, `first_instance` the instance). Errors when the device lacks
    /// [`wgpu::Features::MULTI_DRAW_INDIRECT_COUNT`].
    pub fn draw_indexed(&self, pass: &mut wgpu::RenderPass<'_>, list: List) -> Result<()> {
        if !self.count_draws {
            return Err(invalid(
                "GPU crowd culling",
                "indexed draws of the survivors need MULTI_DRAW_INDIRECT_COUNT (or draw them pulled)".into(),
            ));
        }
        let (header, first) = self.list_offsets(list);
        let count = header + SurvivorHeader::COUNT_OFFSET;
        pass.multi_draw_indexed_indirect_count(&self.commands, first, &self.survivors, count, self.survivor_capacity);
        Ok(())
    }

    /// The survivors: per survivor a `DrawIndexedIndirectArgs` (index count, instance count
    /// 1, first index, base vertex 0, first instance = the instance's index), as many as the
    /// list's header's `instance_count`, in no particular order; the second list (occlusion
    /// culling) from place `survivor_capacity`. `INDIRECT`, `STORAGE` and `COPY_SRC` usage.
    pub fn commands(&self) -> &wgpu::Buffer {
        &self.commands
    }

    /// The lists' headers, two [`SurvivorHeader`]s (`INDIRECT`, `STORAGE`, `COPY_SRC`).
    pub fn survivors(&self) -> &wgpu::Buffer {
        &self.survivors
    }

    /// Places in each survivor list.
    pub fn survivor_capacity(&self) -> u32 {
        self.survivor_capacity
    }

    /// Per instance four `u32`: meshlets visible, culled by the frustum, culled as
    /// back-facing only, occluded (after the second phase; 0 without occlusion culling)
    /// (`COPY_SRC`: an optional readback).
    pub fn counts(&self) -> &wgpu::Buffer {
        &self.counts
    }

    /// The joint records `prepare.wgsl` writes (`joint_records` of [`CULL_WGSL`]).
    pub fn records(&self) -> &wgpu::Buffer {
        &self.records
    }

    /// `cull_params` of [`CULL_WGSL`]: a uniform binding of the first 32 bytes.
    pub fn params(&self) -> wgpu::BufferBinding<'_> {
        wgpu::BufferBinding { buffer: &self.uniforms, offset: 0, size: std::num::NonZeroU64::new(32) }
    }
}

/// `total` invocations of a 64-wide entry point: index = y × 65535 × 64 + x (crowd_cull.wgsl,
/// prepare.wgsl dispatch a 2D grid past 65535 groups).
fn dispatch(pass: &mut wgpu::ComputePass, total: u32) {
    let groups = total.div_ceil(64);
    if groups > 0 {
        pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
    }
}

/// Slots as `Slot` in cull_common.wgsl (12 words each).
fn pack_slots(slots: &[CullSlot]) -> Vec<u32> {
    slots
        .iter()
        .flat_map(|s| {
            [
                s.center.x.to_bits(),
                s.center.y.to_bits(),
                s.center.z.to_bits(),
                s.radius.to_bits(),
                s.axis.x.to_bits(),
                s.axis.y.to_bits(),
                s.axis.z.to_bits(),
                s.sin.to_bits(),
                s.frustum_ok as u32,
                s.joint,
                s.id,
                0,
            ]
        })
        .collect()
}

/// The culler's any-pose boxes as `any_pose_boxes` in cull_common.wgsl: per meshlet
/// (original index) the first word of its boxes and, after the last, the end; then the
/// boxes, 8 words each. One zero word without boxes (frames then never test them).
fn pack_boxes(culler: &MeshletCuller) -> Vec<u32> {
    let (offsets, boxes) = culler.any_pose_boxes();
    if boxes.is_empty() {
        return vec![0];
    }
    let start = offsets.len() as u32;
    let mut out: Vec<u32> = offsets.iter().map(|&o| start + 8 * o).collect();
    for b in boxes {
        out.push(b.joint);
        out.extend(b.center.iter().chain(&b.half).map(|f| f.to_bits()));
        out.push(b.magnitude.to_bits());
    }
    out
}

/// `CullParams::flags`: bit 0 frustum, bit 1 backface, bit 2 orthographic.
fn flags(tests: Tests, orthographic: bool) -> u32 {
    (tests != Tests::Backface) as u32 | ((tests != Tests::Frustum) as u32) << 1 | (orthographic as u32) << 2
}

#[cfg(test)]
mod tests {
    //! A frame of GPU crowd culling costs the CPU no allocation of skinlet's own: after setup,
    //! `encode`, `encode_prepare`, occlusion culling's `encode_first` and `encode_second` (every
    //! round), and `TriangleCulling`'s, allocate exactly as often as their own wgpu calls made
    //! by hand on the same pipelines, bind groups and buffers (wgpu's command recording; the
    //! fewest of a few calls on each side), whatever the instance count. Allocations are
    //! counted per thread (wgpu records on the calling thread).
    use super::*;
    use glam::Vec3;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    struct Counting;

    thread_local! {
        static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    }

    // SAFETY: forwards to the system allocator, counting this thread's allocating calls (a
    // const-initialized thread local: counting never allocates).
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            let _ = ALLOCATIONS.try_with(|a| a.set(a.get() + 1));
            // SAFETY: the caller's promises hold for System too.
            unsafe { System.alloc(layout) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            // SAFETY: `ptr` came from `alloc` above, that is from System.
            unsafe { System.dealloc(ptr, layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            let _ = ALLOCATIONS.try_with(|a| a.set(a.get() + 1));
            // SAFETY: as for `alloc` and `dealloc`.
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }

    #[global_allocator]
    static GLOBAL: Counting = Counting;

    /// This thread's allocations while `record` records into a fresh encoder (submitted and
    /// waited for afterwards).
    fn counted(gpu: &crate::Gpu, record: impl Fn(&mut wgpu::CommandEncoder)) -> usize {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let before = ALLOCATIONS.with(Cell::get);
        record(&mut encoder);
        let during = ALLOCATIONS.with(Cell::get) - before;
        gpu.queue.submit([encoder.finish()]);
        gpu.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).unwrap();
        during
    }

    /// A device on any adapter, as a caller's would be (skinlet-lab's headless device is
    /// another copy of this crate, so a unit test makes its own).
    fn test_gpu() -> Option<crate::Gpu> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let adapter = match pollster::block_on(instance.request_adapter(&Default::default())) {
            Ok(adapter) => adapter,
            Err(e) if std::env::var("SKINLET_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("{e}"),
            Err(e) => {
                eprintln!("skipping: {e}");
                return None;
            }
        };
        let desc = wgpu::DeviceDescriptor {
            required_features: adapter.features() & wgpu::Features::INDIRECT_FIRST_INSTANCE,
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc)).unwrap();
        Some(crate::Gpu::from_device(device, queue, adapter.get_info()))
    }

    /// A small character (12 joints, 4 meshlets each, a triangle of 3 vertices each): its
    /// pipelines, its upload, and palette and instances buffers for `capacity` instances.
    fn small_character(
        device: &wgpu::Device,
        capacity: u32,
    ) -> (CullPipelines, GpuCharacter, wgpu::Buffer, wgpu::Buffer) {
        let joints = 12;
        let bounds: Vec<_> = (0..4 * joints)
            .map(|i| skinlet_runtime::meshlet_bounds::MeshletBounds {
                joint: (i / 4) as u16,
                center: Vec3::new(0.1 * i as f32, 0.0, 0.0),
                radius: 0.2,
                rest_radius: 0.2,
                cone_axis: Vec3::Z,
                cone_angle: 0.7,
                rest_cone_angle: 0.7,
            })
            .collect();
        let classes = vec![skinlet_runtime::meshlet_bounds::Class::Both; bounds.len()];
        let culler = MeshletCuller::new(&bounds, &classes, joints).unwrap();
        let draws: Vec<[u32; 2]> = (0..bounds.len() as u32).map(|i| [3, 3 * i]).collect();
        let pipelines = CullPipelines::new(device).unwrap();
        let character = GpuCharacter::new(device, &culler, &vec![Mat4::IDENTITY; joints], &draws).unwrap();
        let storage = |size: u64| {
            let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
            device.create_buffer(&wgpu::BufferDescriptor { label: None, size, usage, mapped_at_creation: false })
        };
        let (palette, instances) = (storage(64 * joints as u64 * capacity as u64), storage(80 * capacity as u64));
        (pipelines, character, palette, instances)
    }

    /// What a frame records into an encoder.
    type Recording<'a> = Box<dyn Fn(&mut wgpu::CommandEncoder) + 'a>;

    /// Asserts that `ours` allocates as often as `hand` (the same wgpu calls made by hand) for
    /// every instance count, the fewest of a few calls each: an allocation of skinlet's own
    /// would come with every call (wgpu's bookkeeping grows a vector now and then, on either
    /// side).
    fn same_allocations<'a>(
        gpu: &crate::Gpu,
        capacity: u32,
        what: &str,
        ours: &dyn Fn(u32) -> Recording<'a>,
        hand: &dyn Fn(u32) -> Recording<'a>,
    ) {
        for _ in 0..3 {
            counted(gpu, hand(capacity));
            counted(gpu, ours(capacity));
        }
        let mut seen = Vec::new();
        // (At least 3 instances: every round of a 3-round second phase has one; a round without
        // any records no dispatch, here as by hand.)
        for frame in 0..12 {
            let n = [3, 17, 250, capacity][frame % 4];
            let fewest = |record: &dyn Fn() -> usize| (0..4).map(|_| record()).min().unwrap();
            let by_hand = fewest(&|| counted(gpu, hand(n)));
            seen.push((n, by_hand, fewest(&|| counted(gpu, ours(n)))));
        }
        for &(n, by_hand, ours) in &seen {
            assert_eq!(ours, by_hand, "{what}, {n} instances: {ours} allocations, its wgpu calls by hand {by_hand}");
        }
        let counts: std::collections::BTreeSet<usize> = seen.iter().map(|s| s.2).collect();
        assert_eq!(counts.len(), 1, "{what}: allocations vary with the instance count: {seen:?}");
    }

    #[test]
    fn encode_allocates_only_what_its_wgpu_calls_allocate() {
        let Some(gpu) = test_gpu() else { return };
        let device = &gpu.device;
        let capacity = 1000u32;
        let (pipelines, character, palette, instances) = small_character(device, capacity);
        let survivors = capacity * character.meshlets();
        let crowd =
            CrowdCulling::new(device, &pipelines, &character, &palette, &instances, capacity, survivors).unwrap();
        let camera = test_camera();
        for prepare_only in [false, true] {
            let (crowd, camera, queue) = (&crowd, &camera, &gpu.queue);
            let ours = |n: u32| -> Recording<'_> {
                Box::new(move |encoder| match prepare_only {
                    true => crowd.encode_prepare(queue, encoder, camera, Tests::Both, n).unwrap(),
                    false => crowd.encode(queue, encoder, camera, Tests::Both, n, None).unwrap(),
                })
            };
            let hand = |n: u32| -> Recording<'_> {
                Box::new(move |encoder| drop(by_hand(crowd, queue, encoder, n, prepare_only)))
            };
            same_allocations(&gpu, capacity, &format!("prepare only {prepare_only}"), &ours, &hand);
        }
    }

    fn test_camera() -> Camera {
        Camera::perspective(Vec3::new(0.0, 1.0, 6.0), Vec3::ZERO, Vec3::Y, 1.0, 1.5, 0.1, 100.0).unwrap()
    }

    /// The wgpu calls of `encode` (`encode_prepare` where `prepare_only`; `encode_first` with
    /// occlusion culling) with the same arguments, made here; the pass left open.
    fn by_hand<'e>(
        crowd: &CrowdCulling,
        queue: &wgpu::Queue,
        encoder: &'e mut wgpu::CommandEncoder,
        n: u32,
        prepare_only: bool,
    ) -> wgpu::ComputePass<'e> {
        queue.write_buffer(&crowd.uniforms, 0, &[0; std::mem::size_of::<Uniforms>()]);
        let rounds = crowd.occlusion_rounds() as usize;
        if rounds > 1 {
            let bytes = [0; std::mem::size_of::<RoundParams>()];
            queue.write_buffer(&crowd.uniforms, ROUNDS_OFFSET as u64, &bytes[..2 * (rounds - 1) * ROUND_STRIDE]);
        }
        encoder.clear_buffer(&crowd.counts, 0, None);
        encoder.clear_buffer(&crowd.survivors, 0, None);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("skinlet crowd culling"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&crowd.prepare_pipeline);
        pass.set_bind_group(0, &crowd.prepare, &[]);
        dispatch(&mut pass, n * crowd.joints);
        if !prepare_only {
            pass.set_pipeline(&crowd.cull_pipeline);
            pass.set_bind_group(0, &crowd.cull, &[0]);
            // (Occlusion culling's first phase: round 0's instances.)
            dispatch(&mut pass, n / rounds.max(1) as u32 * crowd.meshlets);
            pass.set_pipeline(&crowd.finish_pipeline);
            pass.dispatch_workgroups(1, 1, 1);
        }
        pass
    }

    /// The wgpu calls of phase `phase` of round `round` of `rounds` (pyramid, tests), made
    /// here; the pass left open.
    fn round_by_hand<'e>(
        crowd: &CrowdCulling,
        encoder: &'e mut wgpu::CommandEncoder,
        n: u32,
        (round, phase): (u32, u32),
        rounds: u32,
    ) -> wgpu::ComputePass<'e> {
        let (width, height, _, levels, _) = crowd.occlusion.unwrap();
        for level in 0..levels {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("skinlet depth pyramid"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&crowd.pyramid_pipeline);
            pass.set_bind_group(0, crowd.pyramid.as_ref().unwrap(), &[level * LEVEL_STRIDE as u32]);
            let (w, h) = (width.div_ceil(1 << level).max(1), height.div_ceil(1 << level).max(1));
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("skinlet occlusion culling"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&crowd.cull_pipeline);
        pass.set_bind_group(0, &crowd.cull, &[round_offset(round, phase)]);
        let first = |r: u32| (r as u64 * n as u64 / rounds as u64) as u32;
        dispatch(&mut pass, (first(round + 1) - first(round)) * crowd.meshlets);
        pass.set_pipeline(&crowd.finish_pipeline);
        pass.dispatch_workgroups(1, 1, 1);
        pass
    }

    #[test]
    fn occlusion_and_triangle_culling_allocate_only_what_their_wgpu_calls_allocate() {
        // Occlusion culling's phases in every round (3 rounds), without and with the triangle
        // pass.
        use crate::triangle_culling::{Entries, Raster, TriangleCulling, TriangleSkinning};
        let Some(gpu) = test_gpu() else { return };
        let (device, queue) = (&gpu.device, &gpu.queue);
        let capacity = 1000u32;
        let (pipelines, character, palette, instances) = small_character(device, capacity);
        let survivors = capacity * character.meshlets();
        let (width, height, rounds) = (64, 36, 3);
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Depth32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let view = depth.create_view(&Default::default());
        let occlusion = || OcclusionDepth {
            view: &view,
            width,
            height,
            reversed: false,
            subpixel_bits: 8,
            multisampled: false,
            rounds,
        };
        let occluding = |crowd_capacity| {
            CrowdCulling::with_occlusion(
                device,
                &pipelines,
                &character,
                &palette,
                &instances,
                crowd_capacity,
                survivors,
                occlusion(),
            )
            .unwrap()
        };
        let crowd = occluding(capacity);
        // The triangle pass's skinning: the bind pose (one storage binding of positions).
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: None,
            entries: &[layout_entry(0, wgpu::BufferBindingType::Storage { read_only: true })],
        });
        let positions = crate::context::buffer(device, "positions", &[0f32; 4 * 144], wgpu::BufferUsages::STORAGE);
        let skinning = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &[bind(0, whole(&positions))],
        });
        let wgsl = "@group(1) @binding(0) var<storage, read> test_positions: array<vec4<f32>>;
            fn skinned_position(instance: u32, vertex: u32) -> vec3<f32> { return test_positions[vertex].xyz; }";
        let headers: Vec<[u32; 4]> = (0..48).map(|i| [3 * i, 3 * i, 0, 3 | 1 << 9]).collect();
        let (vertices, triangles): (Vec<u32>, Vec<u8>) = ((0..144).collect(), [0, 1, 2].repeat(48));
        let meshlets = skinlet_runtime::bake_view::MeshletView {
            headers: &headers,
            vertices: &vertices,
            triangles: &triangles,
            joints: &[],
        };
        let triangle_culling = TriangleCulling::new(
            device,
            occluding(capacity),
            TriangleSkinning { wgsl, layout: &layout, margin: 0.0, relative: 0.0 },
            &meshlets,
            144,
            1000,
            Raster { width, height, subpixel_bits: 8, cull_back_faces: true, multisampled: false },
            Entries::Vertices,
            &[],
        )
        .unwrap();
        let camera = test_camera();
        let camera = &camera;
        // What the triangle pass adds to a phase: its calls, made here.
        // Its uniform block by phase: 0 (round 0's first), 512 (a later round's first), 256.
        let triangle_pass = |pass: &mut wgpu::ComputePass<'_>, offset: u32| {
            let header = if offset == 256 { SurvivorHeader::SIZE } else { 0 };
            pass.set_pipeline(&triangle_culling.cull);
            pass.set_bind_group(0, &triangle_culling.group, &[offset]);
            pass.set_bind_group(1, &skinning, &[]);
            pass.dispatch_workgroups_indirect(&triangle_culling.crowd().survivors, header + 20);
            pass.set_pipeline(&triangle_culling.finish);
            pass.dispatch_workgroups(1, 1, 1);
        };
        let (crowd, triangle_culling, skinning) = (&crowd, &triangle_culling, &skinning);
        for triangles in [false, true] {
            let what = format!("occlusion culling, triangle pass {triangles}");
            let culling = if triangles { triangle_culling.crowd() } else { crowd };
            let ours = |n: u32| -> Recording<'_> {
                Box::new(move |encoder| {
                    if triangles {
                        let t = triangle_culling;
                        t.encode_first(queue, encoder, camera, Tests::Both, n, skinning, None).unwrap();
                        t.encode_second(encoder, skinning, 0).unwrap();
                        for r in 1..rounds {
                            t.encode_first_phase(encoder, skinning, r).unwrap();
                            t.encode_second(encoder, skinning, r).unwrap();
                        }
                    } else {
                        crowd.encode_first(queue, encoder, camera, Tests::Both, n, None).unwrap();
                        crowd.encode_second(encoder, 0).unwrap();
                        for r in 1..rounds {
                            crowd.encode_first_phase(encoder, r).unwrap();
                            crowd.encode_second(encoder, r).unwrap();
                        }
                    }
                })
            };
            let hand = |n: u32| -> Recording<'_> {
                Box::new(move |encoder| {
                    if triangles {
                        for offset in [0, 256, 512] {
                            queue.write_buffer(&triangle_culling.uniforms, offset, &[0; 48]);
                        }
                        encoder.clear_buffer(&triangle_culling.triangles, 0, Some(64));
                    }
                    let mut pass = by_hand(culling, queue, encoder, n, false);
                    if triangles {
                        triangle_pass(&mut pass, 0);
                    }
                    drop(pass);
                    for (r, phase) in (0..rounds).flat_map(|r| [(r, 1), (r, 2)]).skip(1) {
                        let mut pass = round_by_hand(culling, encoder, n, (r, phase), rounds);
                        if triangles {
                            triangle_pass(&mut pass, if phase == 2 { 256 } else { 512 });
                        }
                    }
                })
            };
            same_allocations(&gpu, capacity, &what, &ours, &hand);
        }
    }
}
