//! skinlet's GPU culling inside someone else's renderer: this program opens its own wgpu device,
//! builds its own skinning pipeline, uploads a baked character, records skinlet's culling passes
//! into its own encoder each frame, draws the survivors with one call of its own pipeline
//! (pulled by its vertex shader; and as indexed draws where the device counts them), and
//! compares each image with its own unculled draw of the crowd (where fragments of two
//! meshlets tie in depth, draw order picks the color: such a pixel may be either unculled
//! draw's, the one where the first fragment wins or the one where the last does). Nothing is
//! read back on the drawing path (images and counts are read only to report).
//!
//! `cargo run --release -p skinlet-gpu --example bring_your_own -- --json` prints one line,
//! `{"equal_to_unculled": true, "culled_pct": ..., ...}`; exit status 1 when an image differs.

use glam::Mat4;
use skinlet_gpu::crowd_culling::{
    CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter, List, SURVIVORS_WGSL,
};
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};
use wgpu::util::DeviceExt;

const EXTENT: wgpu::Extent3d = wgpu::Extent3d { width: 320, height: 180, depth_or_array_layers: 1 };
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The renderer's own vertex skinning (morph deltas, then linear blend skinning by the same
/// palette skinlet culls with) and faceted shading.
const SHADER: &str = r#"
struct View { view_proj: mat4x4<f32>, joints: u32, stride: u32, weights: u32, pad: u32 }
struct Instance { model: mat4x4<f32>, mode: u32, p0: u32, p1: u32, p2: u32 }
@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> palette: array<mat4x4<f32>>;
@group(0) @binding(2) var<storage, read> instances: array<Instance>;
@group(0) @binding(3) var<storage, read> positions: array<f32>;
@group(0) @binding(4) var<storage, read> influences: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read> morph_offsets: array<u32>;
@group(0) @binding(6) var<storage, read> morph_deltas: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> morph_weights: array<f32>;
@group(0) @binding(8) var<storage, read> indices: array<u32>;
@group(0) @binding(9) var<storage, read> survivor_draws: array<u32>;
struct Out { @builtin(position) clip: vec4<f32>, @location(0) world: vec3<f32> }
// The survivors pulled: skinlet's one draw has an instance per survivor.
@vertex fn vs_pulled(@builtin(vertex_index) corner: u32, @builtin(instance_index) survivor: u32) -> Out {
    let c = survivor_corner(survivor, corner);
    if !c.live { return Out(vec4<f32>(2.0, 2.0, 2.0, 1.0), vec3<f32>(0.0)); }
    return skinned(indices[c.index], c.instance);
}
@vertex fn vs(@builtin(vertex_index) v: u32, @builtin(instance_index) i: u32) -> Out {
    return skinned(v, i);
}
fn skinned(v: u32, i: u32) -> Out {
    var p = vec3<f32>(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
    for (var d = morph_offsets[v]; d < morph_offsets[v + 1u]; d++) {
        p += morph_deltas[d].xyz * morph_weights[i * view.weights + bitcast<u32>(morph_deltas[d].w)];
    }
    var s = mat4x4<f32>();
    for (var k = v * view.stride; k < (v + 1u) * view.stride; k++) {
        s += palette[i * view.joints + influences[k].x] * bitcast<f32>(influences[k].y);
    }
    let world = (instances[i].model * s * vec4<f32>(p, 1.0)).xyz;
    return Out(view.view_proj * vec4<f32>(world, 1.0), world);
}
@fragment fn fs(in: Out) -> @location(0) vec4<f32> {
    return vec4<f32>(vec3<f32>(0.25 + 0.75 * abs(normalize(cross(dpdx(in.world), dpdy(in.world))).z)), 1.0);
}
"#;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// How a frame's crowd is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Draw {
    Unculled,
    /// Unculled, the last of fragments tied in depth winning.
    UnculledLast,
    Pulled,
    Indexed,
}

fn main() {
    let (equal, line) = run().unwrap_or_else(|e| {
        eprintln!("bring_your_own: {e}");
        std::process::exit(2)
    });
    let json = std::env::args().any(|a| a == "--json");
    println!("{}{line}", if json { "" } else { "skinlet culling in a renderer of its own: " });
    std::process::exit(if equal { 0 } else { 1 });
}

fn run() -> Result<(bool, String)> {
    // The caller's device, with the feature skinlet's culling needs, indirect draw counts
    // where the adapter has them, and the 9 storage buffers our pulling vertex shader reads.
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let counted = adapter.features() & wgpu::Features::MULTI_DRAW_INDIRECT_COUNT;
    let desc = wgpu::DeviceDescriptor {
        required_features: wgpu::Features::INDIRECT_FIRST_INSTANCE | counted,
        required_limits: wgpu::Limits { max_storage_buffers_per_shader_stage: 9, ..Default::default() },
        ..Default::default()
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&desc))?;

    // A baked character: the demo, baked to bytes and read back as a game reads its file.
    let asset = skinlet_lab::demo::demo_character(&Default::default());
    let clips: Vec<_> = asset.clips.iter().collect();
    let (builder, limits) = (skinlet::meshlet::Builder::SkinAware, skinlet::meshlet::MeshletLimits::NVIDIA);
    let how = skinlet::bounds::refine::Refinement::NONE;
    let (baked, _) = skinlet::bake::bake(&asset, &asset.character()?, &clips, builder, limits, &how, &mut |_| {})?;
    let baked = skinlet::bake::from_bytes(&skinlet::bake::to_bytes(&baked))?;
    let (mesh, skin, joints) = (&baked.mesh, baked.palette(), baked.inverse_bind.len());
    let inf = mesh.influences.as_ref().ok_or("the bake has no skin weights")?;

    // The index buffer in meshlet order, and each meshlet's range in it.
    let (indices, draws) =
        skinlet_gpu::mesh::meshlet_index_buffer(&baked.meshlets.view(&baked.meshlets.headers()), mesh.positions.len())?;

    // The crowd: placements and camera of skinlet's crowd scene, every instance on its clip.
    let params = CrowdParams { instances: 64, frames: 4, ..CrowdParams::default() };
    let scene = crowd(&mesh.positions, clips.len(), &params)?;
    let n = scene.placements.len() as u32;
    let morphs = mesh.morphs.weights.len().max(1);
    let buffer_of = |bytes: &[u8], usage| {
        let contents = [bytes, &[0; 16]].concat(); // never empty
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: &contents, usage })
    };
    let buffer = |bytes: &[u8]| buffer_of(bytes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST);
    let (palette, instances) = (buffer(&vec![0; 64 * joints * n as usize]), buffer(&vec![0; 80 * n as usize]));
    let weights = buffer(&vec![0; 4 * morphs * n as usize]);
    let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let influences: Vec<_> = inf.joints.iter().zip(&inf.weights).map(|(&j, w)| [j as u32, w.to_bits()]).collect();
    let mut offsets = mesh.morphs.offsets.clone();
    offsets.resize(mesh.positions.len() + 1, 0);
    let deltas: Vec<u32> = (mesh.morphs.deltas.iter())
        .flat_map(|d| [d.position.x.to_bits(), d.position.y.to_bits(), d.position.z.to_bits(), d.weight])
        .collect();
    let mut view: Vec<u32> = scene.camera.view_proj.to_cols_array().map(f32::to_bits).to_vec();
    view.extend([joints as u32, inf.stride as u32, morphs as u32, 0]);
    let view = buffer_of(bytemuck::cast_slice(&view), wgpu::BufferUsages::UNIFORM);
    let index_buffer = buffer_of(bytemuck::cast_slice(&indices), wgpu::BufferUsages::INDEX);

    // skinlet: the culler from the bake, its data on our device, a crowd over our buffers.
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, joints)?;
    let pipelines = CullPipelines::new(&device)?;
    let character = GpuCharacter::new(&device, &culler, &baked.inverse_bind, &draws)?;
    // A survivor list with room for every meshlet of every instance: it never overflows.
    let culling =
        CrowdCulling::new(&device, &pipelines, &character, &palette, &instances, n, n * character.meshlets())?;

    // Our own pipelines, vertex shaders fed by index (unculled, and skinlet's indexed draws)
    // and pulling skinlet's survivors: back faces culled by the rasterizer, depth tested.
    let source = wgpu::ShaderSource::Wgsl([SURVIVORS_WGSL, SHADER].concat().into());
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: None, source });
    let options = wgpu::PipelineCompilationOptions::default;
    let targets = [Some(FORMAT.into())];
    let pipeline = |vs: &str, depth_compare| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(vs),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(vs),
                compilation_options: options(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState { cull_mode: Some(wgpu::Face::Back), ..Default::default() },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(depth_compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: options(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let (indexed, pulled) =
        (pipeline("vs", wgpu::CompareFunction::Less), pipeline("vs_pulled", wgpu::CompareFunction::Less));
    let last = pipeline("vs", wgpu::CompareFunction::LessEqual);
    let (positions, influences) = (buffer(bytemuck::cast_slice(&positions)), buffer(bytemuck::cast_slice(&influences)));
    let (offsets, deltas) = (buffer(bytemuck::cast_slice(&offsets)), buffer(bytemuck::cast_slice(&deltas)));
    let storage_indices = buffer(bytemuck::cast_slice(&indices));
    let resources = [
        &view,
        &palette,
        &instances,
        &positions,
        &influences,
        &offsets,
        &deltas,
        &weights,
        &storage_indices,
        culling.commands(),
    ];
    let group = |pipeline: &wgpu::RenderPipeline, bindings: usize| {
        let entries: Vec<_> = (resources[..bindings].iter().enumerate())
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        let layout = &pipeline.get_bind_group_layout(0);
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries: &entries })
    };
    let (indexed_group, pulled_group, last_group) = (group(&indexed, 8), group(&pulled, 10), group(&last, 8));
    let tex = |format| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: EXTENT,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    };
    let depth = tex(wgpu::TextureFormat::Depth32Float);
    // The images: unculled (both ways), survivors pulled, survivors as indexed draws (where
    // counted).
    let draws: Vec<Draw> = [Draw::Unculled, Draw::UnculledLast, Draw::Pulled, Draw::Indexed]
        .into_iter()
        .filter(|&d| d != Draw::Indexed || !counted.is_empty())
        .collect();
    let images: Vec<wgpu::Texture> = draws.iter().map(|_| tex(FORMAT)).collect();

    let (mut poser, mut matrices, mut morph) = (skinlet::pose::Poser::default(), Vec::new(), Vec::new());
    let (mut differing, mut covered, mut drawn) = (0usize, 0usize, 0u64);
    for frame in 0..params.frames {
        // Our animation: palettes and morph weights of each instance's clip at this frame.
        let (mut pal, mut inst, mut w) = (Vec::<f32>::new(), Vec::new(), Vec::<f32>::new());
        for p in &scene.placements {
            let clip = clips.get(p.clip).copied();
            let t = p.time(clip, frame, params.fps);
            poser.skinning_matrices(&asset.skeleton, &skin, clip, t, &mut matrices);
            pal.extend(matrices.iter().flat_map(|&m| Mat4::from(m).to_cols_array()));
            inst.push(CullInstance::new(p.model.as_mat4(), CullMode::Bounds));
            mesh.morphs.weights_at(clip, t, &mut morph);
            morph.resize(morphs, 0.0);
            w.extend(&morph);
        }
        queue.write_buffer(&palette, 0, bytemuck::cast_slice(&pal));
        queue.write_buffer(&instances, 0, bytemuck::cast_slice(&inst));
        queue.write_buffer(&weights, 0, bytemuck::cast_slice(&w));

        // skinlet's passes, then ours: everything, then the survivors each way.
        let mut encoder = device.create_command_encoder(&Default::default());
        culling.encode(&queue, &mut encoder, &scene.camera, Tests::Both, n, None)?;
        for (image, &draw) in images.iter().zip(&draws) {
            let (image, depth) = (image.create_view(&Default::default()), depth.create_view(&Default::default()));
            let store = wgpu::StoreOp::Store;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: None,
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &image,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let (pipeline, group) = match draw {
                Draw::Pulled => (&pulled, &pulled_group),
                Draw::UnculledLast => (&last, &last_group),
                _ => (&indexed, &indexed_group),
            };
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            match draw {
                Draw::Unculled | Draw::UnculledLast => pass.draw_indexed(0..indices.len() as u32, 0, 0..n),
                Draw::Pulled => culling.draw_pulled(&mut pass, List::First),
                Draw::Indexed => culling.draw_indexed(&mut pass, List::First)?,
            }
        }
        // Reporting only: the images and skinlet's counts, copied out and waited for.
        let (usage, image_size) = (wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, 4 * 320 * 180);
        let sizes = std::iter::repeat_n(image_size, images.len()).chain([16 * n as u64]);
        let out: Vec<wgpu::Buffer> = sizes
            .map(|size| {
                device.create_buffer(&wgpu::BufferDescriptor { label: None, size, usage, mapped_at_creation: false })
            })
            .collect();
        for (image, buffer) in images.iter().zip(&out) {
            let layout = wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * 320), rows_per_image: None };
            encoder.copy_texture_to_buffer(image.as_image_copy(), wgpu::TexelCopyBufferInfo { buffer, layout }, EXTENT);
        }
        encoder.copy_buffer_to_buffer(culling.counts(), 0, &out[images.len()], 0, 16 * n as u64);
        queue.submit([encoder.finish()]);
        out.iter().for_each(|b| b.slice(..).map_async(wgpu::MapMode::Read, |_| {}));
        device.poll(wgpu::PollType::Wait { submission_index: None, timeout: None })?;
        let bytes = out.iter().map(|b| Ok(b.slice(..).get_mapped_range().to_vec())).collect::<Result<Vec<_>>>()?;
        for culled in &bytes[2..images.len()] {
            let unculled = bytes[0].chunks(4).zip(bytes[1].chunks(4));
            differing += unculled.zip(culled.chunks(4)).filter(|((first, last), c)| c != first && c != last).count();
        }
        covered += bytes[0].chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        let counts = bytemuck::pod_collect_to_vec::<u8, u32>(&bytes[images.len()]);
        drawn += counts.chunks(4).map(|c| c[0] as u64).sum::<u64>();
    }
    let culled_pct =
        100.0 * (1.0 - drawn as f64 / (params.frames as u64 * n as u64 * character.meshlets() as u64) as f64);
    let equal = differing == 0 && covered > 0;
    let (frames, meshlets, adapter) = (params.frames, character.meshlets(), adapter.get_info().name);
    let ways: Vec<String> = draws[2..].iter().map(|d| format!("{:?}", format!("{d:?}").to_lowercase())).collect();
    let ways = ways.join(", ");
    let line = format!(
        "{{\"equal_to_unculled\": {equal}, \"culled_draws\": [{ways}], \"culled_pct\": {culled_pct:.2}, \"differing_pixels\": {differing}, \
         \"covered_pixels\": {covered}, \"instances\": {n}, \"frames\": {frames}, \"meshlets\": {meshlets}, \"adapter\": {adapter:?}}}"
    );
    Ok((equal, line))
}
