//! Per-triangle culling of crowd culling's survivors (`skinlet_gpu::triangle_culling`), with a
//! skinning function of the test's own (each instance's model matrix on the bind pose): every
//! triangle of the crowd that covers a pixel center in exact (f64) arithmetic, front-facing,
//! is in the list (back-facing too, for meshlets drawn two-sided), and the list culls a good
//! part of the rest; an overflowing list draws what it wrote and a later frame nothing stale;
//! bad arguments are errors.

mod common;
use common::{bake, gpu, read_buffer};
use glam::{DMat4, DVec3, DVec4, Mat4, Vec3};
use skinlet_gpu::Gpu;
use skinlet_gpu::crowd_culling::{CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter};
use skinlet_gpu::triangle_culling::{Entries, Raster, TriangleCulling, TriangleHeader, TriangleSkinning};
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_runtime::bake_view::MeshletView;
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};
use std::collections::HashSet;
use wgpu::util::DeviceExt;

const SKINNING: &str = "
@group(1) @binding(0) var<storage, read> test_models: array<mat4x4<f32>>;
@group(1) @binding(1) var<storage, read> test_positions: array<f32>;
fn skinned_position(instance: u32, vertex: u32) -> vec3<f32> {
    let p = vec3<f32>(test_positions[3u * vertex], test_positions[3u * vertex + 1u], test_positions[3u * vertex + 2u]);
    return (test_models[instance] * vec4<f32>(p, 1.0)).xyz;
}
";

const WIDTH: u32 = 320;
const HEIGHT: u32 = 180;

/// The demo character's crowd (16 instances, every meshlet kept by crowd culling: the triangle
/// pass tests every triangle) with triangle culling over it.
struct Scene {
    gpu: Gpu,
    culling: TriangleCulling,
    /// With `Entries::Corners`, each corner id's mesh vertex.
    corners: Option<Vec<u32>>,
    skinning: wgpu::BindGroup,
    layout: wgpu::BindGroupLayout,
    indices: Vec<u32>,
    positions: Vec<Vec3>,
    models: Vec<DMat4>,
    camera: Camera,
    /// Crowd culling's parts, for more crowds.
    parts: (CullPipelines, GpuCharacter, wgpu::Buffer, wgpu::Buffer),
    baked: skinlet::bake::Baked,
    /// Per triangle of `indices`: whether its meshlet is drawn two-sided.
    two_sided: Vec<bool>,
}

/// The scene with every third meshlet drawn two-sided where `two_sided`.
fn scene(capacity: Option<u32>, entries: Entries, two_sided: bool) -> Option<Scene> {
    let gpu = gpu()?;
    let device = &gpu.device;
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let character = asset.character().unwrap();
    let baked = bake(&asset, &character);
    let skin = &character.palette;
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let headers = baked.meshlets.headers();
    let meshlets = baked.meshlets.view(&headers);
    let (indices, draws) = skinlet_gpu::mesh::meshlet_index_buffer(&meshlets, baked.mesh.positions.len()).unwrap();
    let pipelines = CullPipelines::new(device).unwrap();
    let character = GpuCharacter::new(device, &culler, &skin.inverse_bind, &draws).unwrap();
    let params = CrowdParams { instances: 16, frames: 1, ..CrowdParams::default() };
    let placed = crowd(&baked.mesh.positions, 1, &params).unwrap();
    let models: Vec<DMat4> = placed.placements.iter().map(|p| p.model).collect();
    let n = models.len() as u32;
    let init = |contents: &[u8]| {
        let usage = wgpu::BufferUsages::STORAGE;
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents, usage })
    };
    let palette: Vec<f32> = (0..n as usize * skin.joints.len()).flat_map(|_| Mat4::IDENTITY.to_cols_array()).collect();
    let instances: Vec<CullInstance> = models.iter().map(|m| CullInstance::new(m.as_mat4(), CullMode::Keep)).collect();
    let (palette, instances) = (init(bytemuck::cast_slice(&palette)), init(bytemuck::cast_slice(&instances)));
    let crowd =
        CrowdCulling::new(device, &pipelines, &character, &palette, &instances, n, n * character.meshlets()).unwrap();
    let entry = |binding| {
        let ty = wgpu::BufferBindingType::Storage { read_only: true };
        skinlet_gpu::skinning::buffer_entry(binding, wgpu::ShaderStages::COMPUTE, ty)
    };
    let layout = device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: None, entries: &[entry(0), entry(1)] });
    let model_floats: Vec<f32> = models.iter().flat_map(|m| m.as_mat4().to_cols_array()).collect();
    let position_floats: Vec<f32> = baked.mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let (model_buffer, position_buffer) =
        (init(bytemuck::cast_slice(&model_floats)), init(bytemuck::cast_slice(&position_floats)));
    let skinning = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: model_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: position_buffer.as_entire_binding() },
        ],
    });
    let how = TriangleSkinning { wgsl: SKINNING, layout: &layout, margin: 0.0, relative: 1.0 / 65536.0 };
    let all = n * indices.len() as u32 / 3;
    let vertices = baked.mesh.positions.len() as u32;
    let raster = Raster {
        width: WIDTH,
        height: HEIGHT,
        subpixel_bits: gpu.subpixel_bits,
        cull_back_faces: true,
        multisampled: false,
    };
    let sides: Vec<bool> = (0..meshlets.len()).map(|m| two_sided && m % 3 == 1).collect();
    let capacity = capacity.unwrap_or(all);
    let culling =
        TriangleCulling::new(device, crowd, how, &meshlets, vertices, capacity, raster, entries, &sides).unwrap();
    let two_sided = draws.iter().zip(&sides).flat_map(|(d, &t)| std::iter::repeat_n(t, d[0] as usize / 3)).collect();
    // Per corner id (MLET's triangle i, corner k at 3·i + k), the mesh vertex.
    let mut corners = vec![u32::MAX; baked.meshlets.triangles.len()];
    for m in &baked.meshlets.meshlets {
        for (t, v) in baked.meshlets.mesh_triangles(m).enumerate() {
            corners[m.triangle_offset as usize + 3 * t..][..3].copy_from_slice(&v);
        }
    }
    let corners = (entries == Entries::Corners).then_some(corners);
    Some(Scene {
        corners,
        culling,
        skinning,
        layout,
        indices,
        positions: baked.mesh.positions.clone(),
        models,
        camera: placed.camera,
        parts: (pipelines, character, palette, instances),
        baked,
        gpu,
        two_sided,
    })
}

/// One frame's list: its header and its triangles as (instance, sorted vertices).
fn cull(s: &Scene, camera: &Camera) -> (TriangleHeader, Vec<(u32, [u32; 3])>) {
    let gpu = &s.gpu;
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let n = s.models.len() as u32;
    s.culling.encode(&gpu.queue, &mut encoder, camera, Tests::Both, n, &s.skinning, None).unwrap();
    gpu.queue.submit([encoder.finish()]);
    let size = 2 * TriangleHeader::SIZE + 24 * s.culling.capacity() as u64;
    let words: Vec<u32> = read_buffer(gpu, s.culling.triangles(), size);
    let header: TriangleHeader = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&words[..8]));
    let bits = s.culling.id_bits();
    let list = words[16..16 + header.index_count as usize]
        .chunks_exact(3)
        .map(|t| {
            let mut v = [t[0], t[1], t[2]].map(|i| i & ((1u32 << bits) - 1));
            if let Some(corners) = &s.corners {
                assert!(v[0] % 3 == 0 && v[1] == v[0] + 1 && v[2] == v[0] + 2, "corners {v:?}: not one triangle's");
                v = v.map(|c| corners[c as usize]);
            }
            v.sort_unstable();
            (t[0] >> bits, v)
        })
        .collect();
    (header, list)
}

/// Whether triangle `t` of instance `i` covers a pixel center, front-facing (either facing
/// where `two_sided`), in f64: the center at least 0.02 pixel inside each edge (rasterizers
/// snap vertices to 1/256 pixel or finer; the f32 corners are within 1e-4 pixel here), every
/// corner in front of the eye.
fn covers_a_pixel_center(s: &Scene, i: usize, t: &[u32], two_sided: bool) -> bool {
    let view_proj = s.camera.view_proj.as_dmat4();
    let size = DVec3::new(WIDTH as f64, HEIGHT as f64, 1.0);
    let mut corners = [DVec3::ZERO; 3];
    for (k, &v) in t.iter().enumerate() {
        let world = s.models[i] * s.positions[v as usize].as_dvec3().extend(1.0);
        let clip: DVec4 = view_proj * world;
        if clip.w <= 1e-9 {
            return false;
        }
        // Pixels, y up.
        corners[k] = (clip.truncate() / clip.w * 0.5 + 0.5) * size;
    }
    let [a, mut b, mut c] = corners;
    let area = (b - a).x * (c - a).y - (b - a).y * (c - a).x;
    if area < 0.0 && two_sided {
        std::mem::swap(&mut b, &mut c);
    } else if area <= 0.0 {
        return false;
    }
    let inside = |p: DVec3| {
        [(a, b), (b, c), (c, a)].iter().all(|&(u, w)| {
            let e = w - u;
            (e.x * (p.y - u.y) - e.y * (p.x - u.x)) / e.truncate().length() > 0.02
        })
    };
    let lo = a.min(b).min(c).max(DVec3::ZERO);
    let hi = a.max(b).max(c).min(size - 1e-9);
    let (mut x, y0) = (lo.x.floor(), lo.y.floor());
    while x <= hi.x {
        let mut y = y0;
        while y <= hi.y {
            if inside(DVec3::new(x + 0.5, y + 0.5, 0.0)) {
                return true;
            }
            y += 1.0;
        }
        x += 1.0;
    }
    false
}

#[test]
fn every_triangle_covering_a_pixel_center_is_kept() {
    every_visible_triangle_is_kept(false);
}

#[test]
fn two_sided_meshlets_keep_their_back_faces() {
    every_visible_triangle_is_kept(true);
}

fn every_visible_triangle_is_kept(two_sided: bool) {
    let Some(s) = scene(None, Entries::Vertices, two_sided) else { return };
    let (header, list) = cull(&s, &s.camera);
    assert_eq!(3 * header.found, header.index_count, "the list overflowed");
    let kept: HashSet<(u32, [u32; 3])> = list.iter().copied().collect();
    assert_eq!(kept.len(), list.len(), "a triangle listed twice");
    let triangles: HashSet<[u32; 3]> = s
        .indices
        .chunks_exact(3)
        .map(|t| {
            let mut v = [t[0], t[1], t[2]];
            v.sort_unstable();
            v
        })
        .collect();
    assert!(kept.iter().all(|(i, t)| (*i as usize) < s.models.len() && triangles.contains(t)), "a stranger listed");
    let (mut required, mut all, mut back) = (0, 0, 0);
    for i in 0..s.models.len() {
        for (t, &two_sided) in s.indices.chunks_exact(3).zip(&s.two_sided) {
            all += 1;
            if covers_a_pixel_center(&s, i, t, two_sided) {
                required += 1;
                back += !covers_a_pixel_center(&s, i, t, false) as usize;
                let mut v = [t[0], t[1], t[2]];
                v.sort_unstable();
                assert!(kept.contains(&(i as u32, v)), "instance {i}'s triangle {t:?} covers a pixel center: culled");
            }
        }
    }
    eprintln!("{all} triangles: {} kept, {required} cover a pixel center ({back} back-facing)", list.len());
    assert!(required > 100, "too few visible triangles for a test");
    assert_eq!(back > 100, two_sided, "{back} back-facing triangles of two-sided meshlets cover a pixel center");
    assert!(2 * list.len() < all, "the pass culled less than half the crowd's triangles");
}

#[test]
fn an_overflowing_triangle_list_draws_what_it_wrote_and_a_later_frame_nothing_stale() {
    let Some(whole_scene) = scene(None, Entries::Vertices, false) else { return };
    let (whole, all) = cull(&whole_scene, &whole_scene.camera);
    let found = whole.found;
    let all: HashSet<_> = all.into_iter().collect();
    for capacity in [1, found / 2, found - 1] {
        let s = scene(Some(capacity), Entries::Vertices, false).unwrap();
        let (header, part) = cull(&s, &s.camera);
        assert_eq!((header.found, header.index_count), (found, 3 * capacity), "capacity {capacity}");
        assert!(part.iter().all(|t| all.contains(t)), "capacity {capacity}: a triangle listed that was culled");
        // A camera facing away: nothing found, nothing drawn (the first frame's entries are
        // still in the list).
        let Projection::Perspective { eye } = s.camera.projection else { unreachable!() };
        let target = s.camera.planes[0].truncate();
        let away = Camera::perspective(eye, eye + (eye - target).normalize(), Vec3::Y, 0.5, 1.5, 0.1, 0.2).unwrap();
        let (header, _) = cull(&s, &away);
        assert_eq!((header.found, header.index_count), (0, 0));
    }
}

#[test]
fn corner_lists_name_the_triangles_vertex_lists_do() {
    let (Some(by_vertex), Some(by_corner)) =
        (scene(None, Entries::Vertices, false), scene(None, Entries::Corners, false))
    else {
        return;
    };
    let (a, mut vertex_list) = cull(&by_vertex, &by_vertex.camera);
    let (b, mut corner_list) = cull(&by_corner, &by_vertex.camera);
    assert_eq!(a, b);
    assert!(!vertex_list.is_empty());
    vertex_list.sort_unstable();
    corner_list.sort_unstable();
    assert_eq!(vertex_list, corner_list);
}

#[test]
fn triangle_culling_refuses_bad_arguments() {
    let Some(s) = scene(None, Entries::Vertices, false) else { return };
    let device = &s.gpu.device;
    let (pipelines, character, palette, instances) = &s.parts;
    let crowd = || CrowdCulling::new(device, pipelines, character, palette, instances, 16, 16).unwrap();
    let skinning = TriangleSkinning { wgsl: SKINNING, layout: &s.layout, margin: 0.0, relative: 0.0 };
    let headers = s.baked.meshlets.headers();
    let meshlets = s.baked.meshlets.view(&headers);
    let vertices = s.positions.len() as u32;
    let make = |skinning: TriangleSkinning, meshlets: &MeshletView, vertices: u32, raster: Raster| {
        TriangleCulling::new(device, crowd(), skinning, meshlets, vertices, 64, raster, Entries::Vertices, &[])
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let size = Raster { width: WIDTH, height: HEIGHT, subpixel_bits: 8, cull_back_faces: true, multisampled: false };
    assert_eq!(make(skinning, &meshlets, vertices, size), "");
    let fewer = MeshletView { headers: &headers[1..], ..meshlets };
    assert!(make(skinning, &fewer, vertices, size).contains("meshlets for a crowd of"));
    assert!(make(skinning, &meshlets, 0, size).contains("0 vertices"));
    assert!(make(skinning, &meshlets, 10, size).contains("past"));
    assert!(make(skinning, &meshlets, vertices, Raster { width: 0, ..size }).contains("drawn at 0×"));
    assert!(make(skinning, &meshlets, vertices, Raster { subpixel_bits: 17, ..size }).contains("17 sub-pixel bits"));
    assert!(make(skinning, &meshlets, 1 << 31, size).contains("32-bit indices"));
    let sides =
        TriangleCulling::new(device, crowd(), skinning, &meshlets, vertices, 64, size, Entries::Vertices, &[true]);
    assert!(sides.err().unwrap().to_string().contains("1 two-sided flags for"));
    let nan = TriangleSkinning { margin: f32::NAN, ..skinning };
    assert!(make(nan, &meshlets, vertices, size).contains("margins"));
    let broken =
        TriangleSkinning { wgsl: "fn skinned_position(i: u32, v: u32) -> vec3<f32> { return q; }", ..skinning };
    assert!(!make(broken, &meshlets, vertices, size).is_empty(), "a skinning function that does not compile");
}
