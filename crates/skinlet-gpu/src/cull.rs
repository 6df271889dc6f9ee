//! Per-meshlet culling on the GPU (conservative-bounds paper, section 6), as a compute pass:
//! the path for adapters without mesh shaders, and the per-meshlet test a task shader runs.
//!
//! The per-joint values of each instance come from the CPU (the culler's `prepare`
//! methods: joint-space planes, the eye in joint space, the group tests, whether the
//! any-pose boxes are tested), and `shaders/cull.wgsl` runs [`MeshletCuller::cull`]'s
//! per-meshlet loop operation for operation, any-pose boxes included, one invocation per
//! (instance, meshlet), so the visible set is the CPU's exactly (tests/cull.rs, on the crowd
//! scene; skinlet-lab's tests/render.rs, on game poses). Survivors are compacted per instance with an
//! atomic counter (their order varies; the set does not).

use crate::mesh::entry;
use crate::skinning::buffer_entry;
use crate::{Gpu, GpuError, Result};
use skinlet_runtime::meshlet_cull::{CullCounts, CullSlot, JointFrame, MeshletCuller, Tests};

/// Floats per joint record in `cull.wgsl`.
const RECORD: usize = 40;

pub struct ComputeCulling {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// What the culling passes read: parameters, slots, joint records, any-pose boxes (see
/// cull_common.wgsl).
pub struct CullInput {
    /// `CullParams`: slots, joints, instances, test flags, first slot, padding.
    pub params: [u32; 8],
    pub slots: Vec<u32>,
    pub records: Vec<f32>,
    pub boxes: Vec<u32>,
    /// Slot ranges (first, count) of the task pipelines compiled with both tests, the
    /// frustum test only and none (paper section 6's classes); all slots in the first
    /// unless packed by class.
    pub ranges: [(u32, u32); 3],
}

impl CullInput {
    /// The culler's slots in its order, every one in the first range.
    pub fn new(culler: &MeshletCuller, frames: &[JointFrame]) -> CullInput {
        CullInput::packed(culler, frames, false)
    }

    /// The slots sorted by culling class: both tests (usable cone), frustum only, none.
    pub fn by_class(culler: &MeshletCuller, frames: &[JointFrame]) -> CullInput {
        CullInput::packed(culler, frames, true)
    }

    fn packed(culler: &MeshletCuller, frames: &[JointFrame], by_class: bool) -> CullInput {
        let flags = frames.first().map_or(0, test_flags);
        let class = |s: &CullSlot| {
            if !by_class {
                0
            } else if !s.frustum_ok {
                2
            } else {
                (s.sin > 1.0) as usize
            }
        };
        let mut slots: Vec<CullSlot> = culler.slots();
        slots.sort_by_key(class);
        let mut ranges = [(0u32, 0u32); 3];
        for (k, range) in ranges.iter_mut().enumerate() {
            let first = slots.iter().take_while(|s| class(s) < k).count() as u32;
            *range = (first, slots.iter().filter(|s| class(s) == k).count() as u32);
        }
        CullInput {
            params: [culler.len() as u32, culler.joints() as u32, frames.len() as u32, flags, 0, 0, 0, 0],
            slots: pack_slots(&slots),
            records: pack_records(frames),
            boxes: pack_boxes(culler),
            ranges,
        }
    }

    /// The parameters (all slots), slots, joint records and any-pose boxes (bind group
    /// entries 0, 1, 2 and, in cull.wgsl 7, in task_cull.wgsl 6).
    pub fn buffers(&self, gpu: &Gpu) -> [wgpu::Buffer; 4] {
        let storage = wgpu::BufferUsages::STORAGE;
        [
            gpu.buffer("culling params", &self.params, wgpu::BufferUsages::UNIFORM),
            gpu.buffer("cull slots", &self.slots, storage),
            gpu.buffer("joint records", &self.records, storage),
            gpu.buffer("any-pose boxes", &self.boxes, storage),
        ]
    }

    /// The parameters of range `k` (one instance).
    pub fn range_params(&self, gpu: &Gpu, k: usize) -> wgpu::Buffer {
        let (first, count) = self.ranges[k];
        let mut params = self.params;
        (params[0], params[4]) = (count, first);
        gpu.buffer("culling params", &params, wgpu::BufferUsages::UNIFORM)
    }
}

impl ComputeCulling {
    pub fn new(gpu: &Gpu) -> Result<ComputeCulling> {
        gpu.checked("culling pipeline", || {
            let stage = wgpu::ShaderStages::COMPUTE;
            let read = wgpu::BufferBindingType::Storage { read_only: true };
            let write = wgpu::BufferBindingType::Storage { read_only: false };
            let source = [include_str!("shaders/cull_common.wgsl"), include_str!("shaders/cull.wgsl")].concat();
            let (pipeline, layout) = gpu.compute_pipeline(
                "culling",
                source,
                "cull",
                &[
                    buffer_entry(0, stage, wgpu::BufferBindingType::Uniform),
                    buffer_entry(1, stage, read),
                    buffer_entry(2, stage, read),
                    buffer_entry(3, stage, write),
                    buffer_entry(4, stage, write),
                    buffer_entry(7, stage, read),
                ],
            );
            ComputeCulling { pipeline, layout }
        })
    }

    /// Culls every meshlet of `culler` for each instance's prepared `frames` (all with the
    /// same tests and projection) and returns, per instance, the visible meshlets' original
    /// indices (in no particular order) and the counts.
    pub fn cull(
        &self,
        gpu: &Gpu,
        culler: &MeshletCuller,
        frames: &[JointFrame],
    ) -> Result<Vec<(Vec<u32>, CullCounts)>> {
        let invalid = |message: String| GpuError::Invalid { location: "GPU culling", message };
        let Some(first) = frames.first() else { return Ok(Vec::new()) };
        let joints = culler.joints();
        if frames
            .iter()
            .any(|f| f.joints() != joints || f.tests() != first.tests() || f.orthographic() != first.orthographic())
        {
            return Err(invalid(format!(
                "every frame must be prepared for the culler's {joints} joints with the same tests and projection"
            )));
        }
        let slots = culler.len();
        let total = slots * frames.len();
        if total == 0 {
            return Ok(frames.iter().map(|_| (Vec::new(), CullCounts::default())).collect());
        }
        if total > u32::MAX as usize / 2 {
            return Err(invalid(format!("{total} (instance, meshlet) pairs in one call")));
        }
        let input = CullInput::new(culler, frames);
        let counts_size = (12 * frames.len()) as u64;
        let visible_size = (4 * total) as u64;
        let (counts, visible) = gpu.checked("GPU culling", || {
            let out = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
            let [params, slot_buffer, record_buffer, boxes] = input.buffers(gpu);
            let counts = gpu.buffer("cull counts", &vec![0u32; 3 * frames.len()], out);
            let visible = gpu.buffer("visible meshlets", &vec![0u32; total], out);
            let bind = gpu.bind_group(
                "culling",
                &self.layout,
                &[
                    entry(0, &params),
                    entry(1, &slot_buffer),
                    entry(2, &record_buffer),
                    entry(3, &counts),
                    entry(4, &visible),
                    entry(7, &boxes),
                ],
            );
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind, &[]);
                dispatch(&mut pass, total as u32);
            }
            gpu.queue.submit([encoder.finish()]);
            (counts, visible)
        })?;
        let counts = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(&counts, counts_size)?);
        let visible = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(&visible, visible_size)?);
        Ok((0..frames.len())
            .map(|i| {
                let (n, frustum, backface) =
                    (counts[3 * i] as usize, counts[3 * i + 1] as usize, counts[3 * i + 2] as usize);
                let ids = visible[i * slots..i * slots + n.min(slots)].to_vec();
                (ids, CullCounts { meshlets: slots, visible: n, frustum, backface })
            })
            .collect())
    }
}

/// `total` invocations of a 64-wide entry point: index = y × 65535 × 64 + x (cull.wgsl,
/// prepare.wgsl dispatch a 2D grid past 65535 groups).
pub(crate) fn dispatch(pass: &mut wgpu::ComputePass, total: u32) {
    let groups = total.div_ceil(64);
    if groups > 0 {
        pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
    }
}

/// Slots as `Slot` in cull_common.wgsl (12 words each).
pub(crate) fn pack_slots(slots: &[CullSlot]) -> Vec<u32> {
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

/// Every frame's joint records, instance after instance (`RECORD` floats per joint).
pub(crate) fn pack_records(frames: &[JointFrame]) -> Vec<f32> {
    let mut out = Vec::with_capacity(frames.first().map_or(0, |f| frames.len() * f.joints() * RECORD));
    for f in frames {
        for r in f.records() {
            out.extend(r.planes.iter().flatten());
            out.extend(r.len);
            out.push(r.margin);
            out.extend(r.view.to_array());
            out.extend([r.sign, r.backface_margin, f32::from_bits(r.group)]);
            out.extend(r.box_margin);
            out.push(r.any_pose as u32 as f32);
        }
    }
    out
}

/// The culler's any-pose boxes as `any_pose_boxes` in cull_common.wgsl: per meshlet
/// (original index) the first word of its boxes and, after the last, the end; then the
/// boxes, 8 words each. One zero word without boxes (frames then never test them).
pub(crate) fn pack_boxes(culler: &MeshletCuller) -> Vec<u32> {
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

/// `CullParams::flags` for a prepared frame.
pub(crate) fn test_flags(frame: &JointFrame) -> u32 {
    flags(frame.tests(), frame.orthographic())
}

/// `CullParams::flags`: bit 0 frustum, bit 1 backface, bit 2 orthographic.
pub(crate) fn flags(tests: Tests, orthographic: bool) -> u32 {
    (tests != Tests::Backface) as u32 | ((tests != Tests::Frustum) as u32) << 1 | (orthographic as u32) << 2
}
