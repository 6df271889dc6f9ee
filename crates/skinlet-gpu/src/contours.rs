//! Contour extraction on the GPU (Tsiapkolis & Bénard 2024, section 4.3): a patch culling
//! compute pass writes the ids of the patches whose spatialized normal cone admits the view,
//! an edge test pass dispatched indirectly (one workgroup per accepted patch) writes the ids
//! of the contour edges, and the count becomes the vertex count of an indirect line draw
//! (skinlet-lab's `Renderer::render_contours`).
//!
//! Guarantee: the extracted set equals skinlet's CPU brute force ([`skinlet_runtime::contour_edges::brute_force`])
//! on the same positions. The patch test is skinlet's f32 cone test, which never rejects a
//! patch holding a contour edge; the edge test is the CPU's f64 test, operation for operation
//! (it needs `SHADER_F64`, which lavapipe and desktop GPUs offer; without it extraction is an
//! error rather than an approximation). tests/contours.rs compares the two on the static
//! scans and on every shared skinned asset skinned on the GPU, perspective and orthographic.
//!
//! Skinned characters: their patches' bounds live in joint spaces ([`skinlet_runtime::contour_patches`]);
//! [`ContourView::skinned`] moves the viewer into each joint's space on the CPU (one vector
//! per joint per frame), as the CPU extractor does.

use crate::mesh::entry;
use crate::skinning::buffer_entry;
use crate::{Gpu, GpuError, Result};
use glam::{DMat4, Vec3};
use skinlet_runtime::camera::Projection;
use skinlet_runtime::contour_edges::Edges;
use skinlet_runtime::contour_patches::{PatchBounds, Patches, SkinnedPatches, ViewF, joint_view};

/// Quads tested every time (outside any patch) are split into groups of this many, so the
/// edge pass spreads them over workgroups.
const ALWAYS_GROUP: usize = 256;
const NONE: u32 = u32::MAX;
/// `State` in contours.wgsl: accepted patches, tested edges, then the line draw's
/// `DrawIndirectArgs` (vertex count, instance count 1, first vertex, first instance).
const STATE_RESET: [u32; 6] = [0, 0, 0, 1, 0, 0];
/// Byte offset of the draw arguments in the state buffer.
pub const DRAW_ARGS_OFFSET: u64 = 8;

/// The three compute pipelines (create once per device).
pub struct ContourExtraction {
    cull: wgpu::ComputePipeline,
    cull_layout: wgpu::BindGroupLayout,
    test: wgpu::ComputePipeline,
    test_layout: wgpu::BindGroupLayout,
    uncullable: wgpu::ComputePipeline,
    uncullable_layout: wgpu::BindGroupLayout,
}

/// A mesh's edges and patches on the GPU, with the buffers one extraction writes.
pub struct GpuContours {
    /// Edge ids: quads `0..Q`, irregular `Q..Q+I`, boundary `Q+I..` (as [`Edges`]).
    pub edges: u32,
    /// One more than the largest vertex index: the positions an extraction needs.
    pub vertices: u32,
    quads_total: u32,
    irregular_count: u32,
    boundary_count: u32,
    group_count: u32,
    patches: u32,
    bound_sets: u32,
    /// One more than the largest joint a patch names (the views a frame must give).
    joints: usize,
    groups: wgpu::Buffer,
    bounds: wgpu::Buffer,
    quads: wgpu::Buffer,
    ids: wgpu::Buffer,
    irregular: wgpu::Buffer,
    faces: wgpu::Buffer,
    /// Both vertices of every edge id (for drawing).
    pub endpoints: wgpu::Buffer,
    accepted: wgpu::Buffer,
    pub state: wgpu::Buffer,
    dispatch: wgpu::Buffer,
    reset: wgpu::Buffer,
    /// Contour edge ids, in no particular order.
    pub contours: wgpu::Buffer,
}

/// The viewer of one extraction: the projection (for the edge test), the bound set, and per
/// joint the viewer in that joint's space (`None`: test all its patches).
#[derive(Clone, Debug, PartialEq)]
pub struct ContourView {
    pub projection: Projection,
    pub bound_set: usize,
    pub joint_views: Vec<Option<ViewF>>,
}

impl ContourView {
    /// A static mesh's view (its patches' bounds are in model space).
    pub fn fixed(projection: Projection) -> ContourView {
        ContourView { projection, bound_set: 0, joint_views: vec![Some(ViewF::new(projection))] }
    }

    /// A skinned character's view for joints at inverse global matrices `joint_inverses`
    /// (one per skin joint), posed by clip `at.0` at time `at.1` when given (that window's
    /// bounds; otherwise the bounds over every clip) — what [`SkinnedPatches::extract_prepared`]
    /// uses.
    pub fn skinned(
        patches: &SkinnedPatches,
        joint_inverses: &[DMat4],
        at: Option<(usize, f32)>,
        projection: Projection,
    ) -> ContourView {
        let joints = patches.joints.iter().map(|&j| j as usize + 1).max().unwrap_or(0);
        let joint_views =
            (0..joints).map(|j| joint_view(joint_inverses.get(j).unwrap_or(&DMat4::NAN), projection)).collect();
        ContourView { projection, bound_set: patches.bound_set(at), joint_views }
    }
}

/// What one extraction found and did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Extracted {
    /// Contour edge ids, ascending.
    pub edges: Vec<u32>,
    /// Patch groups accepted by the cone test (quads outside patches count as accepted
    /// groups of up to 256).
    pub accepted_groups: u32,
    /// Edges tested (accepted quads and irregular edges), as the CPU's `Tested::edges`.
    pub tested: u32,
}

impl ContourExtraction {
    /// Errors when the device lacks `SHADER_F64` (the edge test is the CPU's f64 test).
    pub fn new(gpu: &Gpu) -> Result<ContourExtraction> {
        if !gpu.features.contains(wgpu::Features::SHADER_F64) {
            return Err(GpuError::Invalid {
                location: "GPU contours",
                message: "the device has no 64-bit floats in shaders (SHADER_F64), which the exact edge test needs"
                    .into(),
            });
        }
        let stage = wgpu::ShaderStages::COMPUTE;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        let source = || include_str!("shaders/contours.wgsl").to_string();
        gpu.checked("contour pipelines", || {
            let cull_entries: Vec<_> = (0..=6)
                .map(|b| buffer_entry(b, stage, [uniform, read, read, read, write, write, write][b as usize]))
                .collect();
            let (cull, cull_layout) = gpu.compute_pipeline("patch culling", source(), "cull_patches", &cull_entries);
            let entries = |bindings: &[(u32, wgpu::BufferBindingType)]| -> Vec<wgpu::BindGroupLayoutEntry> {
                bindings.iter().map(|&(b, ty)| buffer_entry(b, stage, ty)).collect()
            };
            let test_entries = entries(&[
                (0, uniform),
                (1, read),
                (4, write),
                (5, write),
                (7, read),
                (8, read),
                (9, read),
                (12, write),
            ]);
            let (test, test_layout) = gpu.compute_pipeline("edge test", source(), "test_edges", &test_entries);
            let uncullable_entries =
                entries(&[(0, uniform), (5, write), (7, read), (10, read), (11, read), (12, write)]);
            let (uncullable, uncullable_layout) =
                gpu.compute_pipeline("uncullable edges", source(), "test_uncullable", &uncullable_entries);
            ContourExtraction { cull, cull_layout, test, test_layout, uncullable, uncullable_layout }
        })
    }

    /// Records one extraction of `contours` over `positions` (3 f32 per vertex, e.g.
    /// `GpuMesh::out_positions` after compute skinning) seen by `view` into `encoder`.
    pub fn encode(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        c: &GpuContours,
        positions: &wgpu::Buffer,
        view: &ContourView,
    ) -> Result<()> {
        let invalid = |message: String| GpuError::Invalid { location: "GPU contours", message };
        if view.bound_set >= c.bound_sets as usize {
            return Err(invalid(format!("bound set {} of {}", view.bound_set, c.bound_sets)));
        }
        if view.joint_views.len() < c.joints {
            return Err(invalid(format!("{} joint views for patches of {} joints", view.joint_views.len(), c.joints)));
        }
        if positions.size() < 12 * c.vertices as u64 {
            return Err(invalid(format!("{} bytes of positions for {} vertices", positions.size(), c.vertices)));
        }
        let (viewer, ortho) = match view.projection {
            Projection::Perspective { eye } => (eye, 0.0),
            Projection::Orthographic { dir } => (-dir, 1.0),
        };
        if !viewer.is_finite() {
            return Err(invalid(format!("the viewer {viewer} is not finite")));
        }
        let mut frame: Vec<u32> = viewer.extend(ortho).to_array().map(f32::to_bits).to_vec();
        frame.extend([
            c.group_count,
            view.bound_set as u32 * c.patches,
            c.irregular_count,
            c.boundary_count,
            c.quads_total,
            0,
            0,
            0,
        ]);
        let views: Vec<[f32; 4]> = view
            .joint_views
            .iter()
            .map(|v| match v {
                Some(ViewF::Eye(e)) => e.extend(0.0).to_array(),
                Some(ViewF::Dir(d)) => d.extend(1.0).to_array(),
                None => [0.0, 0.0, 0.0, 2.0],
            })
            .collect();
        let frame = gpu.buffer("contour frame", &frame, wgpu::BufferUsages::UNIFORM);
        let views = gpu.buffer("joint views", &views, wgpu::BufferUsages::STORAGE);
        encoder.copy_buffer_to_buffer(&c.reset, 0, &c.state, 0, 24);
        encoder.copy_buffer_to_buffer(&c.reset, 24, &c.dispatch, 0, 12);
        let cull = gpu.bind_group(
            "patch culling",
            &self.cull_layout,
            &[
                entry(0, &frame),
                entry(1, &c.groups),
                entry(2, &c.bounds),
                entry(3, &views),
                entry(4, &c.accepted),
                entry(5, &c.state),
                entry(6, &c.dispatch),
            ],
        );
        let test = gpu.bind_group(
            "edge test",
            &self.test_layout,
            &[
                entry(0, &frame),
                entry(1, &c.groups),
                entry(4, &c.accepted),
                entry(5, &c.state),
                entry(7, positions),
                entry(8, &c.quads),
                entry(9, &c.ids),
                entry(12, &c.contours),
            ],
        );
        let uncullable = gpu.bind_group(
            "uncullable edges",
            &self.uncullable_layout,
            &[
                entry(0, &frame),
                entry(5, &c.state),
                entry(7, positions),
                entry(10, &c.irregular),
                entry(11, &c.faces),
                entry(12, &c.contours),
            ],
        );
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("contours"), timestamp_writes: None });
        pass.set_pipeline(&self.cull);
        pass.set_bind_group(0, &cull, &[]);
        pass.dispatch_workgroups(c.group_count.div_ceil(64).max(1), 1, 1);
        pass.set_pipeline(&self.test);
        pass.set_bind_group(0, &test, &[]);
        pass.dispatch_workgroups_indirect(&c.dispatch, 0);
        let rest = c.irregular_count + c.boundary_count;
        if rest > 0 {
            pass.set_pipeline(&self.uncullable);
            pass.set_bind_group(0, &uncullable, &[]);
            pass.dispatch_workgroups(rest.div_ceil(64), 1, 1);
        }
        Ok(())
    }

    /// Extracts the contour edges of `contours` over `positions` (3 f32 per vertex, e.g.
    /// `GpuMesh::out_positions` after [`crate::skinning::ComputeSkinning::skin`]) for `view`
    /// and reads them back.
    pub fn extract(
        &self,
        gpu: &Gpu,
        c: &GpuContours,
        positions: &wgpu::Buffer,
        view: &ContourView,
    ) -> Result<Extracted> {
        gpu.checked("contour extraction", || -> Result<()> {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            self.encode(gpu, &mut encoder, c, positions, view)?;
            gpu.queue.submit([encoder.finish()]);
            Ok(())
        })??;
        c.read(gpu)
    }
}

impl GpuContours {
    /// A static mesh's edges and patches (built over the same vertices).
    pub fn new(gpu: &Gpu, edges: &Edges, patches: &Patches) -> Result<GpuContours> {
        GpuContours::upload(gpu, edges, patches, None, &[&patches.bounds])
    }

    /// A skinned character's edges and patches, every bound set (all clips, then each window).
    pub fn skinned(gpu: &Gpu, edges: &Edges, patches: &SkinnedPatches) -> Result<GpuContours> {
        let sets: Vec<&[PatchBounds]> = (0..patches.bound_sets()).map(|s| patches.bound_set_bounds(s)).collect();
        GpuContours::upload(gpu, edges, &patches.patches, Some(&patches.joints), &sets)
    }

    fn upload(
        gpu: &Gpu,
        edges: &Edges,
        p: &Patches,
        joints: Option<&[u16]>,
        sets: &[&[PatchBounds]],
    ) -> Result<GpuContours> {
        let invalid = |message: String| GpuError::Invalid { location: "GPU contours", message };
        let n = p.len();
        if p.ranges.len() != n || joints.is_some_and(|j| j.len() != n) || sets.iter().any(|s| s.len() != n) {
            return Err(invalid(format!("{n} patches but ranges, joints or bounds of another length")));
        }
        if p.quads.len() != p.order.len() || p.order.len() != edges.quads.len() {
            return Err(invalid(format!(
                "the patches hold {} quads, the edges {}: built from other edges",
                p.order.len(),
                edges.quads.len()
            )));
        }
        if edges.len() > (u32::MAX / 2) as usize {
            return Err(invalid(format!("{} edges", edges.len())));
        }
        let mut groups: Vec<[u32; 4]> = p
            .ranges
            .iter()
            .enumerate()
            .map(|(i, r)| [r[0], r[1], joints.map_or(0, |j| j[i] as u32), i as u32])
            .collect();
        if let Some((i, r)) = p.ranges.iter().enumerate().find(|(_, r)| r[0] as usize + r[1] as usize > p.always_from) {
            return Err(invalid(format!("patch {i} covers quads {r:?} past the patched ones")));
        }
        if let Some(&id) = p.order.iter().find(|&&id| id as usize >= edges.quads.len()) {
            return Err(invalid(format!("quad {id} is past the {} quads of the edges", edges.quads.len())));
        }
        for start in (p.always_from..p.order.len()).step_by(ALWAYS_GROUP) {
            let count = ALWAYS_GROUP.min(p.order.len() - start);
            groups.push([start as u32, count as u32, NONE, NONE]);
        }
        let bounds: Vec<[f32; 12]> = sets
            .iter()
            .flat_map(|s| s.iter())
            .map(|b| {
                let [cx, cy, cz] = b.center.to_array();
                let [ax, ay, az] = b.axis.to_array();
                [cx, cy, cz, b.radius, ax, ay, az, b.sin_angle, b.cos_angle, 0.0, 0.0, 0.0]
            })
            .collect();
        let vertices = (p.quads.iter().flatten())
            .chain(edges.boundary.iter().flatten())
            .chain(edges.irregular.iter().flat_map(|e| e.faces.iter().flatten()))
            .map(|&v| v + 1)
            .max()
            .unwrap_or(0);
        let mut irregular = Vec::with_capacity(edges.irregular.len());
        let mut faces: Vec<u32> = Vec::new();
        for e in &edges.irregular {
            irregular.push([(faces.len() / 3) as u32, e.faces.len() as u32, e.edge[0], 0]);
            faces.extend(e.faces.iter().flatten());
        }
        let endpoints: Vec<[u32; 2]> = (0..edges.len() as u32).map(|id| edges.endpoints(id)).collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let mut reset = STATE_RESET.to_vec();
        reset.extend([0, 1, 1]);
        gpu.checked("GPU contours upload", || GpuContours {
            edges: edges.len() as u32,
            vertices,
            quads_total: edges.quads.len() as u32,
            irregular_count: edges.irregular.len() as u32,
            boundary_count: edges.boundary.len() as u32,
            group_count: groups.len() as u32,
            patches: n as u32,
            bound_sets: sets.len() as u32,
            joints: joints.map_or(1, |j| j.iter().map(|&j| j as usize + 1).max().unwrap_or(0)),
            groups: gpu.buffer("patch groups", &groups, storage),
            bounds: gpu.buffer("patch bounds", &bounds, storage),
            quads: gpu.buffer("quads", &p.quads, storage),
            ids: gpu.buffer("quad ids", &p.order, storage),
            irregular: gpu.buffer("irregular edges", &irregular, storage),
            faces: gpu.buffer("irregular faces", &faces, storage),
            endpoints: gpu.buffer("edge endpoints", &endpoints, storage),
            accepted: gpu.buffer("accepted patches", &vec![0u32; groups.len()], storage),
            state: gpu.buffer("contour state", &STATE_RESET, storage | copy | wgpu::BufferUsages::INDIRECT),
            dispatch: gpu.buffer("edge dispatch", &[0u32, 1, 1], storage | copy | wgpu::BufferUsages::INDIRECT),
            reset: gpu.buffer("contour reset", &reset, copy),
            contours: gpu.buffer("contour edges", &vec![0u32; edges.len()], storage | copy),
        })
    }

    /// Reads back what the last extraction found.
    pub fn read(&self, gpu: &Gpu) -> Result<Extracted> {
        let state = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(&self.state, 24)?);
        let count = state[2] / 2;
        if count > self.edges {
            return Err(GpuError::Gpu {
                location: "GPU contours",
                message: format!("{count} contour edges of {}", self.edges),
            });
        }
        let mut edges = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(&self.contours, 4 * count.max(1) as u64)?);
        edges.truncate(count as usize);
        edges.sort_unstable();
        Ok(Extracted { edges, accepted_groups: state[0], tested: state[1] })
    }
}

/// Uploads static positions (3 f32 per vertex) for [`ContourExtraction::extract`].
pub fn positions_buffer(gpu: &Gpu, positions: &[Vec3]) -> wgpu::Buffer {
    crate::mesh::vec3_buffer(gpu, "positions", positions)
}
