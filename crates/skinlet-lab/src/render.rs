//! Offscreen rendering of a posed character, by each skinning pipeline (thesis fig. 3.2):
//! vertex-shader skinning (the index buffer over bind-pose vertices, skinned as drawn),
//! compute-shader skinning (a compute pass writes skinned vertices, a plain vertex shader
//! draws them) and mesh-shader skinning (one workgroup per meshlet skins its vertices and
//! emits its triangles). All run the same skinning arithmetic on the same triangles in the
//! same order (meshlet order when the mesh has meshlets) and the same fragment shader, so
//! they must give the same image; tests/render.rs checks that pixel for pixel.

use glam::{Mat4, Vec3};
use skinlet_gpu::contours::{ContourExtraction, ContourView, DRAW_ARGS_OFFSET, Extracted, GpuContours};
use skinlet_gpu::crowd_culling::{CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter};
use skinlet_gpu::mesh::{GpuMesh, Pose, entry};
use skinlet_gpu::skinning::{COMMON_WGSL, ComputeSkinning, buffer_entry, mesh_bindings, mesh_entries};
use skinlet_gpu::{Gpu, GpuError, Result};
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::Tests;
use skinlet_runtime::overdraw_orders::Overdraw;

/// How skinned vertices reach the rasterizer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skinning {
    /// In the vertex shader, from bind-pose vertices.
    Vertex,
    /// In a compute pass first, into buffers the vertex shader reads.
    Compute,
    /// In a mesh shader, one workgroup per meshlet (needs mesh shaders and a mesh uploaded
    /// with meshlets).
    Mesh,
    /// In a mesh shader, slim meshlets (one joint set, e.g. from the common-influences
    /// builder) with their joints' matrices in workgroup memory and weight-only vertices
    /// (thesis 3.1.1, "MS-CI"); the others as [`Skinning::Mesh`]. Needs 10 storage buffers
    /// per shader stage.
    MeshSlim,
}

/// An RGBA8 image, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

/// Pipelines for one image size (create once per device and size).
pub struct Renderer {
    pub width: u32,
    pub height: u32,
    compute: ComputeSkinning,
    mesh_layout: wgpu::BindGroupLayout,
    skinned_layout: wgpu::BindGroupLayout,
    camera_layout: wgpu::BindGroupLayout,
    vertex_pipeline: wgpu::RenderPipeline,
    /// Vertex skinning, counting the fragments that pass the depth test (additive red).
    overdraw_pipeline: wgpu::RenderPipeline,
    skinned_pipeline: wgpu::RenderPipeline,
    /// Contour lines (positions, contour edge ids, edge endpoints), hidden then visible.
    lines_layout: wgpu::BindGroupLayout,
    line_pipelines: [wgpu::RenderPipeline; 2],
    /// With mesh shaders: the mesh-shader pipeline.
    mesh_path: Option<MeshPath>,
}

/// The mesh-shader pipeline and its layouts (mesh data and meshlets seen by the mesh stage).
struct MeshPath {
    skin_layout: wgpu::BindGroupLayout,
    meshlet_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    /// Task-shader culling then mesh-shader skinning of the survivors, and its culling data
    /// layout (parameters, slots, joint records, the draw's slot range and instance,
    /// any-pose boxes); the joint records prepared by crowd culling's pipelines.
    cull_layout: wgpu::BindGroupLayout,
    cull_pipelines: CullPipelines,
    /// Compiled with both tests, the frustum test only, none (`CLASS_TESTS` 3, 1, 0).
    culled_pipelines: [wgpu::RenderPipeline; 3],
    /// Every meshlet in its own color (group 3: one RGBA8 word per meshlet).
    color_layout: wgpu::BindGroupLayout,
    colored_pipeline: wgpu::RenderPipeline,
    /// Slim meshlets, where the device has the bindings.
    slim: Option<SlimPath>,
}

/// Slim mesh shading: group 2 with the joint lists, the plain pipeline and the task-culled
/// ones (as `MeshPath::culled_pipelines`).
struct SlimPath {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    culled: [wgpu::RenderPipeline; 3],
}

/// What a draw runs.
#[derive(Clone, Copy)]
enum Draw<'a> {
    Plain(Skinning),
    /// Culled in task shaders, then skinned and drawn.
    Culled(TaskCulling<'a>, Skinning),
    Colored(&'a [[u8; 4]]),
    Contours(&'a ContourExtraction, &'a GpuContours, &'a ContourView),
    Overdraw,
}

/// One character of a crowd draw ([`Renderer::render_crowd`]).
#[derive(Clone, Copy, Debug)]
pub struct PosedInstance<'a> {
    /// Skinning matrices, into the space of the camera's `view_proj` (world), and morph weights.
    pub pose: Pose<'a>,
    /// For culled drawing: how the instance is culled (the pose guard's answer).
    pub cull: Option<CullMode>,
}

/// Task-shader culling of a draw: `character`'s meshlets (uploaded by `GpuCharacter::new` from
/// the culler of the mesh's meshlets), the joint records prepared on the GPU by crowd culling
/// for `camera` and `tests`, and optionally per-triangle culling in the mesh shader from
/// `triangles` (the camera's projection).
#[derive(Clone, Copy)]
pub struct TaskCulling<'a> {
    pub character: &'a GpuCharacter,
    pub camera: &'a Camera,
    pub tests: Tests,
    pub culling: Culling,
    pub triangles: Option<Projection>,
}

/// Where meshlets are culled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Culling {
    /// In a task shader before mesh-shader skinning, one pipeline reading each meshlet's
    /// class from its flags.
    Task,
    /// In task shaders, three pipelines by culling class (paper section 6): compiled with
    /// both tests, the frustum test only, and none, each over its class's meshlets.
    TaskByClass,
}

/// How a crowd is drawn.
#[derive(Clone, Copy)]
pub enum CrowdDraw<'a> {
    Plain(Skinning),
    /// Meshlets culled in task shaders, then skinned by `Mesh` or `MeshSlim` skinning
    /// (vertex skinning is culled by `crate::gpu_crowd`).
    Culled(TaskCulling<'a>, Skinning),
}

/// What a draw produced and measured.
#[derive(Clone, Debug)]
pub struct Drawn {
    pub image: Image,
    /// Culled drawing: the triangles drawn, over all instances.
    pub triangles: Option<u32>,
    /// Culled drawing: the meshlets drawn, over all instances.
    pub meshlets: Option<u32>,
    /// GPU time from the first pass's start to the render pass's end, where the device has
    /// timestamp queries (milliseconds).
    pub gpu_ms: Option<f64>,
}

pub(crate) const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub(crate) const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A `width` × `height` 2D render target of one mip level and one sample.
pub(crate) fn target_texture(
    device: &wgpu::Device,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

impl Renderer {
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Result<Renderer> {
        if !(1..=8192).contains(&width) || !(1..=8192).contains(&height) {
            return Err(GpuError::Invalid { location: "renderer", message: format!("image size {width}×{height}") });
        }
        let compute = ComputeSkinning::new(gpu)?;
        let mut cull_pipelines = gpu.has_mesh_shaders().then(|| CullPipelines::new(&gpu.device)).transpose()?;
        gpu.checked("render pipelines", || {
            let device = &gpu.device;
            let vertex = wgpu::ShaderStages::VERTEX;
            let layout = |label: &str, entries: &[wgpu::BindGroupLayoutEntry]| {
                device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
            };
            let mesh_layout = layout("mesh", &mesh_entries(vertex));
            let skinned_layout =
                layout("skinned", &[buffer_entry(0, vertex, wgpu::BufferBindingType::Storage { read_only: true })]);
            let mesh_stage =
                if gpu.has_mesh_shaders() { wgpu::ShaderStages::MESH } else { wgpu::ShaderStages::empty() };
            let camera_layout = layout(
                "camera",
                &[buffer_entry(
                    0,
                    vertex | mesh_stage | wgpu::ShaderStages::FRAGMENT,
                    wgpu::BufferBindingType::Uniform,
                )],
            );
            let depth_stencil = || wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            };
            let targets = [Some(wgpu::ColorTargetState::from(COLOR))];
            let draw = include_str!("shaders/draw.wgsl");
            let pipeline = |label: &str,
                            sources: &[&str],
                            group0: &wgpu::BindGroupLayout,
                            (entry, targets): (&str, &[Option<wgpu::ColorTargetState>])| {
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(label),
                    source: wgpu::ShaderSource::Wgsl(sources.concat().into()),
                });
                let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &[Some(group0), Some(&camera_layout)],
                    immediate_size: 0,
                });
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vertex"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: primitive(),
                    depth_stencil: Some(depth_stencil()),
                    multisample: Default::default(),
                    fragment: fragment(&module, entry, targets),
                    multiview_mask: None,
                    cache: None,
                })
            };
            let shade = ("shade", &targets[..]);
            let mesh_path = cull_pipelines.take().map(|cull_pipelines| {
                let stage = wgpu::ShaderStages::MESH;
                let read = wgpu::BufferBindingType::Storage { read_only: true };
                let skin_layout = layout("mesh-shader mesh", &mesh_entries(stage));
                let meshlet_layout =
                    layout("meshlets", &(0..3).map(|b| buffer_entry(b, stage, read)).collect::<Vec<_>>());
                let cull_layout = layout(
                    "task culling",
                    &[
                        buffer_entry(0, wgpu::ShaderStages::TASK, wgpu::BufferBindingType::Uniform),
                        buffer_entry(1, wgpu::ShaderStages::TASK, read),
                        buffer_entry(2, wgpu::ShaderStages::TASK, read),
                        buffer_entry(3, wgpu::ShaderStages::TASK, wgpu::BufferBindingType::Uniform),
                        buffer_entry(
                            4,
                            stage | wgpu::ShaderStages::TASK,
                            wgpu::BufferBindingType::Storage { read_only: false },
                        ),
                        buffer_entry(5, stage, wgpu::BufferBindingType::Uniform),
                        buffer_entry(6, wgpu::ShaderStages::TASK, read),
                    ],
                );
                // Survivors compacted by subgroup operations where the device has them.
                let ballot = gpu.has_subgroups();
                let source = [
                    "enable wgpu_mesh_shader;\n",
                    COMMON_WGSL,
                    draw,
                    include_str!("shaders/mesh_skin.wgsl"),
                    skinlet_gpu::crowd_culling::CULL_WGSL,
                    include_str!("shaders/task_cull.wgsl"),
                    include_str!("shaders/slim_skin.wgsl"),
                    if ballot { include_str!("shaders/task_ballot.wgsl") } else { "" },
                ]
                .concat();
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("mesh skinning"),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                });
                let mesh_pipeline = |groups: &[Option<&wgpu::BindGroupLayout>],
                                     task: Option<(&str, &[(&str, f64)])>,
                                     mesh: &str| {
                    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(mesh),
                        bind_group_layouts: groups,
                        immediate_size: 0,
                    });
                    device.create_mesh_pipeline(&wgpu::MeshPipelineDescriptor {
                        label: Some(mesh),
                        layout: Some(&layout),
                        task: task.map(|(entry, constants)| wgpu::TaskState {
                            module: &module,
                            entry_point: Some(entry),
                            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
                        }),
                        mesh: wgpu::MeshState {
                            module: &module,
                            entry_point: Some(mesh),
                            compilation_options: Default::default(),
                        },
                        primitive: primitive(),
                        depth_stencil: Some(depth_stencil()),
                        multisample: Default::default(),
                        fragment: fragment(&module, "shade_colored", &targets),
                        multiview: None,
                        cache: None,
                    })
                };
                let three = [Some(&skin_layout), Some(&camera_layout), Some(&meshlet_layout)];
                let pipeline = mesh_pipeline(&three, None, "mesh");
                let four = [Some(&skin_layout), Some(&camera_layout), Some(&meshlet_layout), Some(&cull_layout)];
                let task = if ballot { "task_ballot" } else { "task" };
                let culled_pipelines = [3.0, 1.0, 0.0]
                    .map(|tests| mesh_pipeline(&four, Some((task, &[("CLASS_TESTS", tests)])), "culled_mesh"));
                let color_layout = layout("meshlet colors", &[buffer_entry(3, stage, read)]);
                let colored = [Some(&skin_layout), Some(&camera_layout), Some(&meshlet_layout), Some(&color_layout)];
                let colored_pipeline = mesh_pipeline(&colored, None, "colored_mesh");
                // The task-culled slim pipelines bind 10 storage buffers to the mesh stage.
                let slim = (gpu.device.limits().max_storage_buffers_per_shader_stage >= 10).then(|| {
                    let layout =
                        layout("slim meshlets", &(0..4).map(|b| buffer_entry(b, stage, read)).collect::<Vec<_>>());
                    let groups = [Some(&skin_layout), Some(&camera_layout), Some(&layout)];
                    let pipeline = mesh_pipeline(&groups, None, "slim_mesh");
                    let four = [Some(&skin_layout), Some(&camera_layout), Some(&layout), Some(&cull_layout)];
                    let culled = [3.0, 1.0, 0.0]
                        .map(|tests| mesh_pipeline(&four, Some((task, &[("CLASS_TESTS", tests)])), "culled_slim_mesh"));
                    SlimPath { layout, pipeline, culled }
                });
                MeshPath {
                    skin_layout,
                    meshlet_layout,
                    pipeline,
                    cull_layout,
                    cull_pipelines,
                    culled_pipelines,
                    color_layout,
                    colored_pipeline,
                    slim,
                }
            });
            let vertex_source = [COMMON_WGSL, draw, include_str!("shaders/vertex_skin.wgsl")];
            let vertex_pipeline = pipeline("vertex skinning", &vertex_source, &mesh_layout, shade);
            let add = wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::One,
                operation: wgpu::BlendOperation::Add,
            };
            let counting = [Some(wgpu::ColorTargetState {
                blend: Some(wgpu::BlendState { color: add, alpha: add }),
                ..wgpu::ColorTargetState::from(COLOR)
            })];
            let overdraw_pipeline =
                pipeline("overdraw", &vertex_source, &mesh_layout, ("count_fragment", &counting[..]));
            let skinned_pipeline =
                pipeline("skinned draw", &[draw, include_str!("shaders/skinned.wgsl")], &skinned_layout, shade);
            let read = wgpu::BufferBindingType::Storage { read_only: true };
            let lines_layout =
                layout("contour lines", &(0..3).map(|b| buffer_entry(b, vertex, read)).collect::<Vec<_>>());
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("contour lines"),
                source: wgpu::ShaderSource::Wgsl([draw, include_str!("shaders/contour_lines.wgsl")].concat().into()),
            });
            let lines_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("contour lines"),
                bind_group_layouts: &[Some(&lines_layout), Some(&camera_layout)],
                immediate_size: 0,
            });
            let line_pipeline = |fragment_entry: &str, compare| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(fragment_entry),
                    layout: Some(&lines_pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("line_vertex"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::LineList,
                        ..Default::default()
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        depth_write_enabled: Some(false),
                        depth_compare: Some(compare),
                        ..depth_stencil()
                    }),
                    multisample: Default::default(),
                    fragment: fragment(&module, fragment_entry, &targets),
                    multiview_mask: None,
                    cache: None,
                })
            };
            let line_pipelines = [
                line_pipeline("hidden_line", wgpu::CompareFunction::Greater),
                line_pipeline("visible_line", wgpu::CompareFunction::LessEqual),
            ];
            Renderer {
                width,
                height,
                compute,
                mesh_layout,
                skinned_layout,
                camera_layout,
                vertex_pipeline,
                overdraw_pipeline,
                skinned_pipeline,
                lines_layout,
                line_pipelines,
                mesh_path,
            }
        })
    }

    /// Renders `mesh` in `pose` (skinning matrices, and morph weights for a mesh with morph
    /// targets) through `view_proj` (wgpu's clip space: depth 0 to 1), lit from `light` (a
    /// direction), by the given pipeline.
    pub fn render<'a>(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        pose: impl Into<Pose<'a>>,
        view_proj: Mat4,
        light: Vec3,
        skinning: Skinning,
    ) -> Result<Image> {
        let one = [PosedInstance { pose: pose.into(), cull: None }];
        self.draw(gpu, mesh, &one, view_proj, light, Draw::Plain(skinning)).map(|d| d.image)
    }

    /// Draws `mesh` (uploaded with meshlets) with its meshlets culled first (paper section 6)
    /// by `cull`, the instance culled in `mode`, through `cull.camera`: crowd culling prepares
    /// the joint records on the GPU, a task shader tests each meshlet and launches mesh-shader
    /// skinning of the survivors only; with `cull.triangles` the mesh shader also culls
    /// back-facing and edge-on triangles (thesis 5.1.3). Culling is conservative, so the image
    /// is the unculled one. Needs mesh shaders ([`crate::gpu_crowd`] culls vertex skinning on
    /// any device).
    ///
    /// Also returns how many triangles and meshlets were drawn.
    pub fn render_culled<'a>(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        pose: impl Into<Pose<'a>>,
        light: Vec3,
        cull: TaskCulling,
        mode: CullMode,
    ) -> Result<(Image, u32, u32)> {
        let one = [PosedInstance { pose: pose.into(), cull: Some(mode) }];
        let d = self.draw(gpu, mesh, &one, cull.camera.view_proj, light, Draw::Culled(cull, Skinning::Mesh))?;
        Ok((d.image, d.triangles.unwrap_or(0), d.meshlets.unwrap_or(0)))
    }

    /// Draws many instances of `mesh` in one render pass, each with its own skinning matrices
    /// (and culling mode): the crowd scene of `skinlet gpu-bench`. Also returns the GPU time
    /// where the device has timestamp queries.
    pub fn render_crowd(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        instances: &[PosedInstance],
        view_proj: Mat4,
        light: Vec3,
        how: CrowdDraw,
    ) -> Result<Drawn> {
        let draw = match how {
            CrowdDraw::Plain(skinning) => Draw::Plain(skinning),
            CrowdDraw::Culled(cull, skinning) => Draw::Culled(cull, skinning),
        };
        self.draw(gpu, mesh, instances, view_proj, light, draw)
    }

    /// Like [`Renderer::render`] with mesh-shader skinning, every meshlet shaded in its own
    /// color (`colors[i]`, RGBA8, for meshlet `i`): pictures of meshlets, classes or culling.
    #[allow(clippy::too_many_arguments)]
    pub fn render_colored<'a>(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        pose: impl Into<Pose<'a>>,
        view_proj: Mat4,
        light: Vec3,
        colors: &[[u8; 4]],
    ) -> Result<Image> {
        let one = [PosedInstance { pose: pose.into(), cull: None }];
        self.draw(gpu, mesh, &one, view_proj, light, Draw::Colored(colors)).map(|d| d.image)
    }

    /// Like [`Renderer::render`] with compute skinning, then the contour edges of the
    /// skinned positions seen by `view` extracted on the GPU ([`ContourExtraction`]) and drawn
    /// as lines by an indirect draw: visible ones bright, hidden ones dim. `contours` must be
    /// built over `mesh`'s vertices. Also returns what the extraction found.
    #[allow(clippy::too_many_arguments)]
    pub fn render_contours<'a>(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        pose: impl Into<Pose<'a>>,
        view_proj: Mat4,
        light: Vec3,
        extraction: &ContourExtraction,
        contours: &GpuContours,
        view: &ContourView,
    ) -> Result<(Image, Extracted)> {
        if contours.vertices > mesh.vertices {
            return Err(GpuError::Invalid {
                location: "render",
                message: format!("contours over {} vertices, the mesh has {}", contours.vertices, mesh.vertices),
            });
        }
        let one = [PosedInstance { pose: pose.into(), cull: None }];
        let d = self.draw(gpu, mesh, &one, view_proj, light, Draw::Contours(extraction, contours, view))?;
        Ok((d.image, contours.read(gpu)?))
    }

    /// Overdraw of `mesh` in `pose`, its triangles in the order of its index buffer
    /// (upload the mesh with the triangles in the order to measure): per pixel (rows top to
    /// bottom) the fragments that passed the depth test ("less", back faces culled; at most
    /// 255), and their total over the pixels covered — the OVR of skinlet's CPU rasterizer
    /// (`skinlet::overdraw::measure::Raster`), measured by the GPU's.
    pub fn render_overdraw<'a>(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        pose: impl Into<Pose<'a>>,
        view_proj: Mat4,
    ) -> Result<(Vec<u32>, Overdraw)> {
        let one = [PosedInstance { pose: pose.into(), cull: None }];
        let d = self.draw(gpu, mesh, &one, view_proj, Vec3::ZERO, Draw::Overdraw)?;
        let counts: Vec<u32> = d.image.rgba.chunks_exact(4).map(|p| p[0] as u32).collect();
        let covered = counts.iter().filter(|&&n| n > 0).count() as u64;
        let shaded = counts.iter().map(|&n| n as u64).sum();
        Ok((counts, Overdraw { shaded, covered }))
    }

    fn draw(
        &self,
        gpu: &Gpu,
        mesh: &GpuMesh,
        instances: &[PosedInstance],
        view_proj: Mat4,
        light: Vec3,
        draw: Draw,
    ) -> Result<Drawn> {
        let invalid = |message: &str| GpuError::Invalid { location: "render", message: message.into() };
        let mesh_draw = match (draw, &self.mesh_path, &mesh.meshlets) {
            (Draw::Plain(Skinning::Vertex | Skinning::Compute) | Draw::Contours(..) | Draw::Overdraw, _, _) => None,
            (Draw::Culled(..), _, None) => return Err(invalid("culled drawing needs a mesh uploaded with meshlets")),
            (Draw::Culled(.., Skinning::Vertex | Skinning::Compute), ..) => {
                return Err(invalid("task culling goes with mesh-shader skinning (gpu_crowd culls vertex skinning)"));
            }
            (_, None, _) => return Err(invalid("the device has no mesh shaders")),
            (_, _, None) => return Err(invalid("mesh-shader skinning needs a mesh uploaded with meshlets")),
            (_, Some(path), Some(meshlets)) => Some((path, meshlets)),
        };
        let meshlet_count = mesh.meshlets.as_ref().map_or(0, |m| m.count as usize);
        match draw {
            Draw::Culled(cull, _)
                if cull.character.meshlets() as usize != meshlet_count
                    || instances.iter().any(|i| i.cull.is_none()) =>
            {
                return Err(invalid("the culled character must be the mesh's meshlets, every instance culled"));
            }
            Draw::Colored(colors) if colors.len() != meshlet_count => return Err(invalid("one color per meshlet")),
            Draw::Contours(..) if instances.len() != 1 => return Err(invalid("contours of one instance at a time")),
            _ => {}
        }
        let matrices: Vec<wgpu::Buffer> =
            instances.iter().map(|i| mesh.pose_buffer(gpu, i.pose)).collect::<Result<_>>()?;
        let (width, height) = (self.width, self.height);
        let row = (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let timestamps = gpu.has_timestamps();
        let (readback, counter, times) = gpu.checked("render", || -> Result<_> {
            let device = &gpu.device;
            let storage = wgpu::BufferUsages::STORAGE;
            let uniform = wgpu::BufferUsages::UNIFORM;
            let mut camera = view_proj.to_cols_array().to_vec();
            camera.extend(light.normalize_or_zero().extend(0.0).to_array());
            let camera = gpu.buffer("camera", &camera, wgpu::BufferUsages::UNIFORM);
            let camera = gpu.bind_group("camera", &self.camera_layout, &[entry(0, &camera)]);
            let texture = |format, usage| target_texture(device, width, height, format, usage);
            let color = texture(COLOR, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
            let depth = texture(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT);
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            // GPU time: from an empty pass opening the frame to the end of the render pass.
            let queries = timestamps.then(|| {
                let set = device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("frame time"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                });
                encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("frame start"),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: &set,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: None,
                    }),
                });
                set
            });
            // Task culling: every instance's joint records prepared on the GPU by crowd culling.
            let culling = match (draw, mesh_draw) {
                (Draw::Culled(cull, _), Some((path, _))) => {
                    let palette: Vec<Mat4> =
                        instances.iter().flat_map(|i| i.pose.matrices.iter().map(|&m| Mat4::from(m))).collect();
                    let modes: Vec<CullInstance> = (instances.iter())
                        .map(|i| CullInstance::new(Mat4::IDENTITY, i.cull.unwrap_or(CullMode::Keep)))
                        .collect();
                    let palette = gpu.buffer("culled palette", &palette, storage);
                    let modes = gpu.buffer("culled instances", &modes, storage);
                    let n = instances.len() as u32;
                    let culling =
                        CrowdCulling::new(device, &path.cull_pipelines, cull.character, &palette, &modes, n, 0)?;
                    culling.encode_prepare(&gpu.queue, &mut encoder, cull.camera, cull.tests, n)?;
                    Some(culling)
                }
                _ => None,
            };
            let mut per_instance: Vec<InstanceDraw> = Vec::new();
            // Shared: group 2 (meshlets) and group 3 (colors) of the mesh-shader pipelines.
            let mut shared = Vec::new();
            let mut counter = None;
            let mut lines = None;
            let pipeline = match mesh_draw {
                Some((path, meshlets)) => {
                    let slim = match draw {
                        Draw::Plain(Skinning::MeshSlim) | Draw::Culled(_, Skinning::MeshSlim) => match &path.slim {
                            Some(slim) => Some(slim),
                            None => return Err(invalid("slim mesh shading needs 10 storage buffers per shader stage")),
                        },
                        _ => None,
                    };
                    let mut meshlet_entries =
                        vec![entry(0, &meshlets.meshlets), entry(1, &meshlets.vertices), entry(2, &meshlets.triangles)];
                    if slim.is_some() {
                        meshlet_entries.push(entry(3, &meshlets.joint_lists));
                    }
                    let meshlet_layout = slim.map_or(&path.meshlet_layout, |slim| &slim.layout);
                    shared.push(gpu.bind_group("meshlets", meshlet_layout, &meshlet_entries));
                    // Task-culled draws set their own pipelines (by class).
                    let culled_pipelines = slim.map_or(&path.culled_pipelines, |slim| &slim.culled);
                    let pipeline = match draw {
                        Draw::Plain(Skinning::MeshSlim) => &slim.expect("slim is set for slim draws").pipeline,
                        Draw::Colored(colors) => {
                            let words: Vec<u32> = colors.iter().map(|c| u32::from_le_bytes(*c)).collect();
                            let colors = gpu.buffer("meshlet colors", &words, storage);
                            shared.push(gpu.bind_group("meshlet colors", &path.color_layout, &[entry(3, &colors)]));
                            &path.colored_pipeline
                        }
                        Draw::Culled(..) => &culled_pipelines[0],
                        _ => &path.pipeline,
                    };
                    let triangle_cull = match draw {
                        Draw::Culled(TaskCulling { triangles, .. }, _) => {
                            counter =
                                Some(gpu.buffer("drawn triangles", &[0u32; 4], storage | wgpu::BufferUsages::COPY_SRC));
                            Some(gpu.buffer(
                                "triangle culling",
                                &triangle_cull_words(triangles),
                                wgpu::BufferUsages::UNIFORM,
                            ))
                        }
                        _ => None,
                    };
                    for (k, m) in matrices.iter().enumerate() {
                        let group0 = gpu.bind_group("mesh-shader mesh", &path.skin_layout, &mesh_bindings(mesh, m));
                        // Task draws: (pipeline, group 3, task workgroups) per slot range.
                        let mut tasks = Vec::new();
                        if let (Draw::Culled(cull, _), Some(culling), Some(triangle_cull), Some(counter)) =
                            (draw, &culling, &triangle_cull, &counter)
                        {
                            // All slots with the pipeline reading each one's class, or each
                            // class's range with its own pipeline.
                            let (slots, ranges) = match cull.culling {
                                Culling::TaskByClass => {
                                    (cull.character.slots_by_class(), cull.character.class_ranges())
                                }
                                Culling::Task => {
                                    (cull.character.slots(), [[0, cull.character.meshlets()], [0; 2], [0; 2]])
                                }
                            };
                            for (class, &[first, count]) in ranges.iter().enumerate().filter(|(_, r)| r[1] > 0) {
                                let range = gpu.buffer("task range", &[first, count, k as u32, 0], uniform);
                                let entries = [
                                    wgpu::BindGroupEntry {
                                        binding: 0,
                                        resource: wgpu::BindingResource::Buffer(culling.params()),
                                    },
                                    entry(1, slots),
                                    entry(2, culling.records()),
                                    entry(3, &range),
                                    entry(4, counter),
                                    entry(5, triangle_cull),
                                    entry(6, cull.character.any_pose_boxes()),
                                ];
                                let group3 = gpu.bind_group("task culling", &path.cull_layout, &entries);
                                // One task workgroup per 32 slots (task_cull.wgsl).
                                tasks.push((&culled_pipelines[class], group3, count.div_ceil(32)));
                            }
                        }
                        per_instance.push(InstanceDraw { group0, tasks });
                    }
                    pipeline
                }
                None if matches!(draw, Draw::Plain(Skinning::Vertex) | Draw::Overdraw) => {
                    for m in &matrices {
                        let group0 = gpu.bind_group("mesh", &self.mesh_layout, &mesh_bindings(mesh, m));
                        per_instance.push(InstanceDraw { group0, tasks: Vec::new() });
                    }
                    if matches!(draw, Draw::Overdraw) { &self.overdraw_pipeline } else { &self.vertex_pipeline }
                }
                None => {
                    for (k, m) in matrices.iter().enumerate() {
                        // The first instance skins into the mesh's buffers, the others into their own.
                        let out = (k > 0).then(|| {
                            let bytes = |n: u32| vec![0f32; 3 * n as usize];
                            let usage = storage | wgpu::BufferUsages::COPY_SRC;
                            let normals = if mesh.has_normals { mesh.vertices } else { 0 };
                            [
                                gpu.buffer("skinned positions", &bytes(mesh.vertices), usage),
                                gpu.buffer("skinned normals", &bytes(normals), usage),
                            ]
                        });
                        let [positions, normals] = match &out {
                            Some([p, n]) => [p, n],
                            None => [&mesh.out_positions, &mesh.out_normals],
                        };
                        self.compute.encode_into(gpu, &mut encoder, mesh, m, positions, normals);
                        let group0 = gpu.bind_group("skinned", &self.skinned_layout, &[entry(0, positions)]);
                        per_instance.push(InstanceDraw { group0, tasks: Vec::new() });
                    }
                    if let Draw::Contours(extraction, contours, view) = draw {
                        extraction.encode(gpu, &mut encoder, contours, &mesh.out_positions, view)?;
                        let entries = [
                            entry(0, &mesh.out_positions),
                            entry(1, &contours.contours),
                            entry(2, &contours.endpoints),
                        ];
                        lines = Some((contours, gpu.bind_group("contour lines", &self.lines_layout, &entries)));
                    }
                    &self.skinned_pipeline
                }
            };
            {
                let color_view = color.create_view(&Default::default());
                let depth_view = depth.create_view(&Default::default());
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("draw"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &color_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(match draw {
                                Draw::Overdraw => wgpu::Color::TRANSPARENT,
                                _ => wgpu::Color { r: 0.08, g: 0.09, b: 0.11, a: 1.0 },
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &depth_view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: queries.as_ref().map(|set| wgpu::RenderPassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: None,
                        end_of_pass_write_index: Some(1),
                    }),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(pipeline);
                pass.set_bind_group(1, &camera, &[]);
                for (i, group) in shared.iter().enumerate() {
                    pass.set_bind_group(2 + i as u32, group, &[]);
                }
                for InstanceDraw { group0, tasks } in &per_instance {
                    pass.set_bind_group(0, group0, &[]);
                    for (pipeline, group3, workgroups) in tasks {
                        pass.set_pipeline(pipeline);
                        pass.set_bind_group(3, group3, &[]);
                        pass.draw_mesh_tasks(*workgroups, 1, 1);
                    }
                    match mesh_draw {
                        Some(_) if matches!(draw, Draw::Culled(..)) => {}
                        Some(_) => {
                            // Meshlet id = y × 1024 + x (mesh_skin.wgsl).
                            let n = meshlet_count as u32;
                            pass.draw_mesh_tasks(n.min(1024), n.div_ceil(1024), 1);
                        }
                        None => {
                            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
                            pass.draw_indexed(0..mesh.index_count, 0, 0..1);
                        }
                    }
                }
                if let Some((contours, group)) = &lines {
                    pass.set_bind_group(0, group, &[]);
                    for pipeline in &self.line_pipelines {
                        pass.set_pipeline(pipeline);
                        pass.draw_indirect(&contours.state, DRAW_ARGS_OFFSET);
                    }
                }
            }
            let readback = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("image"),
                size: (row * height) as u64,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: &color,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            );
            let times = queries.map(|set| {
                let times = gpu.buffer(
                    "frame times",
                    &[0u64; 2],
                    wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                );
                encoder.resolve_query_set(&set, 0..2, &times, 0);
                times
            });
            gpu.queue.submit([encoder.finish()]);
            Ok((readback, counter, times))
        })??;
        let bytes = gpu.read(&readback, (row * height) as u64)?;
        let rgba = bytes.chunks_exact(row as usize).flat_map(|r| &r[..4 * width as usize]).copied().collect();
        let (triangles, meshlets) = match counter {
            Some(counter) => {
                let words = bytemuck::pod_collect_to_vec::<u8, u32>(&gpu.read(&counter, 8)?);
                (Some(words[0]), Some(words[1]))
            }
            None => (None, None),
        };
        let gpu_ms = match times {
            Some(times) => {
                let t = bytemuck::pod_collect_to_vec::<u8, u64>(&gpu.read(&times, 16)?);
                Some(t[1].saturating_sub(t[0]) as f64 * gpu.queue.get_timestamp_period() as f64 / 1e6)
            }
            None => None,
        };
        Ok(Drawn { image: Image { width, height, rgba }, triangles, meshlets, gpu_ms })
    }
}

/// One instance's part of a draw: its bind group 0 and its task-shader draws (pipeline,
/// group 3, task workgroups).
struct InstanceDraw<'p> {
    group0: wgpu::BindGroup,
    tasks: Vec<(&'p wgpu::RenderPipeline, wgpu::BindGroup, u32)>,
}

/// `TriangleCull` in task_cull.wgsl: the eye or view direction, and the mode.
fn triangle_cull_words(triangles: Option<Projection>) -> Vec<u32> {
    let (view, mode) = match triangles {
        None => (Vec3::ZERO, 0),
        Some(Projection::Perspective { eye }) => (eye, 1),
        Some(Projection::Orthographic { dir }) => (dir, 2),
    };
    view.extend(0.0).to_array().iter().map(|f| f.to_bits()).chain([mode, 0, 0, 0]).collect()
}

/// The shared primitive state: triangle lists, counter-clockwise front faces (glTF's), back
/// faces culled (so a meshlet culled as back-facing would have drawn nothing).
fn primitive() -> wgpu::PrimitiveState {
    wgpu::PrimitiveState { cull_mode: Some(wgpu::Face::Back), ..Default::default() }
}

/// The fragment stage: `entry` (`shade` in draw.wgsl, or `shade_colored` in mesh_skin.wgsl),
/// one RGBA8 target.
fn fragment<'a>(
    module: &'a wgpu::ShaderModule,
    entry: &'a str,
    targets: &'a [Option<wgpu::ColorTargetState>],
) -> Option<wgpu::FragmentState<'a>> {
    Some(wgpu::FragmentState { module, entry_point: Some(entry), compilation_options: Default::default(), targets })
}

/// A perspective camera that frames points `p` from direction `dir` (toward the eye), with a
/// 40° vertical field of view and a square image, `zoom` times closer than a fit (1: the
/// whole of `p` in view). Its `view_proj` is in wgpu's clip space (depth 0 to 1). Errors on
/// points that are not finite.
pub fn framing(points: &[Vec3], dir: Vec3, zoom: f32) -> Result<Camera> {
    let (lo, hi) = points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
    let (center, radius) =
        if lo.x <= hi.x { ((lo + hi) / 2.0, ((hi - lo).length() / 2.0).max(1e-6)) } else { (Vec3::ZERO, 1.0) };
    let fov = 40f32.to_radians();
    let distance = radius / (fov / 2.0).sin() * 1.05 / zoom.max(1e-3);
    let dir = dir.try_normalize().unwrap_or(Vec3::Z);
    let up = if dir.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
    let near = (distance - radius).max(distance * 1e-3) * 0.5;
    Camera::perspective(center + dir * distance, center, up, fov, 1.0, near, distance + radius * 2.0)
        .map_err(|e| GpuError::Invalid { location: "framing", message: e.to_string() })
}
