//! Crowd culling on the caller's device (`skinlet_gpu::crowd_culling`), joint preparation
//! on the GPU: every meshlet it culls is culled by the same tests in exact (f64) arithmetic
//! on the same matrices, on the crowd scene of every shared asset and the demo (perspective
//! and orthographic, each culling pipeline, instances in every mode) and on random joint
//! matrices (shear, negative and near-zero scale, non-finite entries); it culls about what
//! the CPU culler culls, and its draw commands say what it culled.

mod common;
use common::{assets, bake, boxed_culler, gpu, read_buffer};
use glam::{Affine3A, DMat4, DVec3, DVec4, Mat4, Vec3, Vec4};
use skinlet::clip::Clip;
use skinlet::pose::Poser;
use skinlet_gpu::Gpu;
use skinlet_gpu::crowd_culling::{CrowdCulling, CullInstance, CullMode, CullPipelines, GpuCharacter, SurvivorHeader};
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::{CullSlot, JointFrame, MeshletCuller, Tests, joints_from_skinning};
use wgpu::util::DeviceExt;

const MODES: [CullMode; 4] = [CullMode::Bounds, CullMode::BoundsAndBoxes, CullMode::BoxesOnly, CullMode::Keep];

/// Whether the tests cull meshlet `s` of an instance whose joint `j` has world matrix
/// `world[j]` (f64), in exact arithmetic: the sphere beyond a plane moved into joint space,
/// the cone facing away from the eye (or direction) moved into joint space, every any-pose box
/// beyond one and the same plane.
fn culled_exactly(
    culler: &MeshletCuller,
    s: &CullSlot,
    world: &[DMat4],
    camera: &Camera,
    tests: Tests,
    mode: CullMode,
) -> bool {
    let planes: Vec<DVec4> = camera.planes.iter().map(|p| p.as_dvec4()).collect();
    let moved = |g: &DMat4, p: &DVec4| {
        let n = p.truncate();
        let nj = DVec3::new(g.x_axis.truncate().dot(n), g.y_axis.truncate().dot(n), g.z_axis.truncate().dot(n));
        (nj, g.w_axis.truncate().dot(n) + p.w)
    };
    let (do_frustum, do_back) = (tests != Tests::Backface, tests != Tests::Frustum);
    let g = &world[s.joint as usize];
    // A joint matrix that is not finite culls nothing (its meshlets' bounds, its boxes).
    let bounds = matches!(mode, CullMode::Bounds | CullMode::BoundsAndBoxes) && g.is_finite();
    let frustum = bounds
        && do_frustum
        && s.frustum_ok
        && planes.iter().any(|p| {
            let (nj, wj) = moved(g, p);
            nj.dot(s.center.as_dvec3()) + wj + s.radius as f64 * nj.length() < 0.0
        });
    let det = g.determinant();
    let back = bounds && do_back && s.sin <= 1.0 && det != 0.0 && {
        let (inv, axis, sin) = (g.inverse(), s.axis.as_dvec3(), s.sin as f64);
        match camera.projection {
            Projection::Perspective { eye } => {
                let d = s.center.as_dvec3() - inv.transform_point3(eye.as_dvec3());
                det.signum() * d.dot(axis) - s.radius as f64 * (1.0 + sin) >= d.length() * sin
            }
            Projection::Orthographic { dir } => {
                let v = inv.transform_vector3(dir.as_dvec3()).normalize();
                det.signum() * v.dot(axis) >= sin
            }
        }
    };
    let (offsets, boxes) = culler.any_pose_boxes();
    let boxed = matches!(mode, CullMode::BoundsAndBoxes | CullMode::BoxesOnly) && do_frustum && !boxes.is_empty() && {
        let mine = &boxes[offsets[s.id as usize] as usize..offsets[s.id as usize + 1] as usize];
        !mine.is_empty()
            && planes.iter().any(|p| {
                mine.iter().all(|b| {
                    let g = &world[b.joint as usize];
                    let (nj, wj) = moved(g, p);
                    let (c, h) = (Vec3::from(b.center).as_dvec3(), Vec3::from(b.half).as_dvec3());
                    g.is_finite() && nj.dot(c) + wj + nj.abs().dot(h) < 0.0
                })
            })
    };
    frustum || back || boxed
}

/// One frame of crowd culling on the GPU: per instance, whether each meshlet (by index) is
/// drawn, the counts and the survivors' header; checks that the survivor list holds each
/// drawn (instance, meshlet) once with the meshlet's own index range, and that the counts
/// agree with it.
struct Culled {
    drawn: Vec<Vec<bool>>,
    counts: Vec<[u32; 3]>,
    header: SurvivorHeader,
}

/// The survivors a frame draws: per instance, per meshlet, whether it is in the first
/// `instance_count` entries of the list (each entry checked against its meshlet's draw, none
/// twice).
fn survivors_drawn(draws: &[[u32; 2]], instances: usize, commands: &[u32], header: &SurvivorHeader) -> Vec<Vec<bool>> {
    let by_first: std::collections::HashMap<u32, usize> = draws.iter().enumerate().map(|(id, d)| (d[1], id)).collect();
    assert_eq!(by_first.len(), draws.len(), "meshlets share a first index");
    assert_eq!(header.vertex_count, draws.iter().map(|d| d[0]).max().unwrap());
    let mut drawn = vec![vec![false; draws.len()]; instances];
    for c in commands.chunks_exact(5).take(header.instance_count as usize) {
        let id = by_first[&c[2]];
        assert_eq!([c[0], c[1], c[3]], [draws[id][0], 1, 0], "survivor of meshlet {id}");
        let i = c[4] as usize;
        assert!(i < instances && !drawn[i][id], "instance {i} meshlet {id}: out of range or listed twice");
        drawn[i][id] = true;
    }
    drawn
}

#[allow(clippy::too_many_arguments)]
fn cull_on_gpu(
    gpu: &Gpu,
    pipelines: &CullPipelines,
    character: &GpuCharacter,
    draws: &[[u32; 2]],
    palette: &[Mat4],
    instances: &[CullInstance],
    camera: &Camera,
    tests: Tests,
    survivor_capacity: Option<u32>,
    tested: Option<&[usize]>,
) -> Culled {
    let device = &gpu.device;
    let storage = wgpu::BufferUsages::STORAGE;
    let init = |label: &str, contents: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage: storage })
    };
    let floats: Vec<f32> = palette.iter().flat_map(|m| m.to_cols_array()).collect();
    let palette_buffer = init("palette", bytemuck::cast_slice(&floats));
    let instance_buffer = init("instances", bytemuck::cast_slice(instances));
    let (n, m) = (instances.len() as u32, draws.len());
    let capacity = survivor_capacity.unwrap_or(n * m as u32);
    let crowd =
        CrowdCulling::new(device, pipelines, character, &palette_buffer, &instance_buffer, n, capacity).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    crowd.encode(&gpu.queue, &mut encoder, camera, tests, n, None).unwrap();
    gpu.queue.submit([encoder.finish()]);
    let header: SurvivorHeader = bytemuck::pod_read_unaligned(&read_buffer::<u8>(gpu, crowd.survivors(), 32));
    let commands: Vec<u32> = read_buffer(gpu, crowd.commands(), 20 * capacity as u64);
    let counts: Vec<u32> = read_buffer(gpu, crowd.counts(), 16 * n as u64);
    assert_eq!(header.instance_count, header.found.min(capacity), "{header:?}");
    assert_eq!(header.found, counts.chunks_exact(4).map(|c| c[0]).sum::<u32>(), "found and the visible counts");
    let drawn = survivors_drawn(draws, n as usize, &commands, &header);
    for (i, row) in drawn.iter().enumerate() {
        let visible = row.iter().filter(|&&d| d).count() as u32;
        if header.found <= capacity {
            assert_eq!(visible, counts[4 * i], "instance {i}: the visible count and the survivors disagree");
        }
        // Every meshlet tested, or with a LOD hierarchy, every one of the instance's cut.
        let tested = tested.map_or(m, |t| t[i]) as u32;
        assert_eq!(counts[4 * i] + counts[4 * i + 1] + counts[4 * i + 2], tested, "instance {i}'s counts");
        assert_eq!(counts[4 * i + 3], 0, "occluded without occlusion culling");
    }
    Culled { drawn, counts: counts.chunks_exact(4).map(|c| [c[0], c[1], c[2]]).collect(), header }
}

/// Per meshlet `(index count, first index)` in meshlet order.
fn meshlet_draws(baked: &skinlet::bake::Baked) -> Vec<[u32; 2]> {
    skinlet_gpu::mesh::meshlet_index_buffer(&baked.meshlets.view(&baked.meshlets.headers()), baked.mesh.positions.len())
        .unwrap()
        .1
}

#[test]
fn gpu_prepared_crowd_culling_is_exact_and_culls_what_the_cpu_culls() {
    let Some(gpu) = gpu() else { return };
    let pipelines = CullPipelines::new(&gpu.device).unwrap();
    let (mut tested, mut culled, mut cpu_culled, mut boxes_only) = (0usize, 0usize, 0usize, 0usize);
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let baked = bake(&asset, &character);
        let skin = &character.palette;
        let joints = skin.joints.len();
        let culler = boxed_culler(&asset, &character, &baked);
        let draws = meshlet_draws(&baked);
        let gpu_character = GpuCharacter::new(&gpu.device, &culler, &skin.inverse_bind, &draws).unwrap();
        let slots = culler.slots();
        let bind: Vec<Affine3A> = skin.inverse_bind.iter().map(|m| Affine3A::from_mat4(m.inverse())).collect();
        for orthographic in [false, true] {
            let params = CrowdParams { instances: 24, frames: 2, orthographic, ..CrowdParams::default() };
            let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
            let camera = &scene.camera;
            let mut poser = Poser::default();
            for tests in [Tests::Both, Tests::Frustum, Tests::Backface] {
                for f in 0..params.frames {
                    let (mut palette, mut instances, mut worlds) = (Vec::new(), Vec::new(), Vec::new());
                    let mut cpu_drawn = Vec::new();
                    for (k, p) in scene.placements.iter().enumerate() {
                        let clip = clips.get(p.clip).copied();
                        let mut skinning = Vec::new();
                        poser.skinning_matrices(
                            &asset.skeleton,
                            skin,
                            clip,
                            p.time(clip, f, params.fps),
                            &mut skinning,
                        );
                        let model = p.model.as_mat4();
                        let mode = MODES[(k + f) % 4];
                        palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
                        instances.push(CullInstance::new(model, mode));
                        // Exact joint matrices from the f32 inputs the GPU multiplies.
                        worlds.push(
                            (skinning.iter().zip(&skin.inverse_bind))
                                .map(|(s, ib)| model.as_dmat4() * Mat4::from(*s).as_dmat4() * ib.inverse().as_dmat4())
                                .collect::<Vec<DMat4>>(),
                        );
                        let (mut world, mut frame) = (Vec::new(), JointFrame::default());
                        joints_from_skinning(&Affine3A::from_mat4(model), &skinning, &bind, &mut world);
                        match mode {
                            CullMode::Bounds => culler.prepare(&world, camera, tests, &mut frame),
                            CullMode::BoundsAndBoxes => culler.prepare_with_boxes(&world, camera, tests, &mut frame),
                            CullMode::BoxesOnly => culler.prepare_boxes_only(&world, camera, tests, &mut frame),
                            CullMode::Keep => frame.set_keep_all(joints),
                        }
                        let (mut flags, mut visible) = (Vec::new(), Vec::new());
                        culler.cull(&frame, &mut flags, &mut visible);
                        cpu_drawn.push(visible.len());
                    }
                    let out = cull_on_gpu(
                        &gpu,
                        &pipelines,
                        &gpu_character,
                        &draws,
                        &palette,
                        &instances,
                        camera,
                        tests,
                        None,
                        None,
                    );
                    for (i, drawn) in out.drawn.iter().enumerate() {
                        let mode = MODES[(i + f) % 4];
                        for s in &slots {
                            if !drawn[s.id as usize] {
                                assert!(
                                    culled_exactly(&culler, s, &worlds[i], camera, tests, mode),
                                    "{name} {tests:?} ortho {orthographic} frame {f} instance {i} ({mode:?}): \
                                     meshlet {} culled on the GPU but not in exact arithmetic",
                                    s.id
                                );
                            }
                        }
                        let n = drawn.iter().filter(|&&d| !d).count();
                        if mode == CullMode::Keep {
                            assert_eq!(n, 0, "{name}: an instance in Keep mode lost meshlets");
                        }
                        if mode == CullMode::BoxesOnly {
                            boxes_only += n;
                        }
                        tested += drawn.len();
                        culled += n;
                        cpu_culled += drawn.len() - cpu_drawn[i];
                        assert_eq!(out.counts[i][1] + out.counts[i][2], n as u32);
                    }
                }
            }
        }
    }
    eprintln!(
        "{tested} meshlet tests: {culled} culled on the GPU ({boxes_only} by the any-pose boxes alone), \
         {cpu_culled} by the CPU culler; every GPU-culled meshlet culled in f64 too"
    );
    assert!(culled > 0 && boxes_only > 0, "nothing was culled: the check would be vacuous");
    // Both are conservative; they differ only near the margins (the CPU tests groups first).
    assert!(culled as f64 >= 0.99 * cpu_culled as f64 && culled as f64 <= 1.01 * cpu_culled as f64);
}

/// A small deterministic generator (xorshift).
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

#[test]
fn random_joint_matrices_cull_only_what_exact_arithmetic_culls() {
    let Some(gpu) = gpu() else { return };
    let pipelines = CullPipelines::new(&gpu.device).unwrap();
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let character = asset.character().unwrap();
    let baked = bake(&asset, &character);
    let skin = &character.palette;
    let joints = skin.joints.len();
    let culler = boxed_culler(&asset, &character, &baked);
    let draws = meshlet_draws(&baked);
    let gpu_character = GpuCharacter::new(&gpu.device, &culler, &skin.inverse_bind, &draws).unwrap();
    let slots = culler.slots();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut tested, mut culled) = (0usize, 0usize);
    for round in 0..24 {
        let orthographic = round % 2 == 1;
        let eye = Vec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(2.0, 6.0));
        let forward = (Vec3::new(rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), 0.0) - eye).normalize();
        let camera = if orthographic {
            Camera::orthographic(eye, forward, Vec3::Y, rng.range(0.5, 3.0), rng.range(0.5, 3.0), 0.0, 20.0)
        } else {
            Camera::perspective(eye, forward, Vec3::Y, rng.range(0.3, 1.2), 1.5, 0.05, 20.0)
        }
        .unwrap();
        let tests = [Tests::Both, Tests::Frustum, Tests::Backface][round % 3];
        let instances_n = 16;
        let (mut palette, mut instances, mut worlds) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..instances_n {
            let model = Mat4::from_translation(Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0));
            let mut world = Vec::new();
            for j in 0..joints {
                // Random affine skinning matrices: shear, non-uniform, negative and near-zero
                // scale, and now and then a non-finite entry.
                let (identity, scale) = [(1.0, 0.5), (-1.0, 0.5), (0.0, 1e-4), (1.0, 3.0)][(i + j) % 4];
                let mut cols: [Vec4; 4] = std::array::from_fn(|c| {
                    let v = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                    match c {
                        3 => v.extend(1.0),
                        0 => (v * scale + Vec3::X * identity).extend(0.0),
                        _ => (v * scale + Vec3::AXES[c] * identity.abs()).extend(0.0),
                    }
                });
                if (i * joints + j) % 97 == 5 {
                    cols[j % 3].y = [f32::NAN, f32::INFINITY][j % 2];
                }
                let s = Mat4::from_cols(cols[0], cols[1], cols[2], cols[3]);
                palette.push(s);
                world.push(model.as_dmat4() * s.as_dmat4() * skin.inverse_bind[j].inverse().as_dmat4());
            }
            instances.push(CullInstance::new(model, MODES[i % 3]));
            worlds.push(world);
        }
        let out =
            cull_on_gpu(&gpu, &pipelines, &gpu_character, &draws, &palette, &instances, &camera, tests, None, None);
        for (i, drawn) in out.drawn.iter().enumerate() {
            for s in &slots {
                if !drawn[s.id as usize] {
                    assert!(
                        culled_exactly(&culler, s, &worlds[i], &camera, tests, MODES[i % 3]),
                        "round {round} instance {i}: meshlet {} culled on the GPU but not in exact arithmetic",
                        s.id
                    );
                    culled += 1;
                }
                tested += 1;
            }
        }
    }
    eprintln!("{tested} meshlet tests on random joint matrices: {culled} culled, every one culled in f64 too");
    assert!(culled > tested / 20, "too little was culled for the check to mean anything");
}

#[test]
fn crowd_culling_refuses_bad_buffers_and_counts() {
    let Some(gpu) = gpu() else { return };
    let device = &gpu.device;
    let pipelines = CullPipelines::new(device).unwrap();
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let character = asset.character().unwrap();
    let baked = bake(&asset, &character);
    let skin = &character.palette;
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let draws = meshlet_draws(&baked);
    let err = |r: Result<GpuCharacter, skinlet_gpu::GpuError>| r.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(err(GpuCharacter::new(device, &culler, &skin.inverse_bind, &draws[1..])).contains("meshlet draws"));
    assert!(err(GpuCharacter::new(device, &culler, &skin.inverse_bind[1..], &draws)).contains("inverse bind"));
    let mut singular = skin.inverse_bind.clone();
    singular[0] = Mat4::ZERO;
    assert!(err(GpuCharacter::new(device, &culler, &singular, &draws)).contains("joint 0"));
    let character = GpuCharacter::new(device, &culler, &skin.inverse_bind, &draws).unwrap();
    let buffer = |size: u64, usage| {
        device.create_buffer(&wgpu::BufferDescriptor { label: None, size, usage, mapped_at_creation: false })
    };
    let storage = wgpu::BufferUsages::STORAGE;
    let joints = skin.joints.len() as u64;
    let palette = buffer(4 * joints * 64, storage);
    let instances = buffer(4 * 80, storage);
    let crowd_err = |p: &wgpu::Buffer, i: &wgpu::Buffer, n| {
        let survivors = n * character.meshlets();
        let crowd = CrowdCulling::new(device, &pipelines, &character, p, i, n, survivors);
        crowd.err().map(|e| e.to_string()).unwrap_or_default()
    };
    assert!(crowd_err(&palette, &instances, 5).contains("palette buffer holds"));
    assert!(crowd_err(&palette, &buffer(80, storage), 4).contains("instances buffer holds"));
    assert!(crowd_err(&buffer(4 * joints * 64, wgpu::BufferUsages::UNIFORM), &instances, 4).contains("STORAGE"));
    let huge = u32::MAX / 32;
    let e = CrowdCulling::new(device, &pipelines, &character, &palette, &instances, 4, huge).err().unwrap();
    assert!(e.to_string().contains("storage bindings"), "{e}");
    let mut odd = draws.clone();
    odd[1][0] -= 1;
    assert!(err(GpuCharacter::new(device, &culler, &skin.inverse_bind, &odd)).contains("whole triangles"));
    let crowd = CrowdCulling::new(device, &pipelines, &character, &palette, &instances, 4, 64).unwrap();
    let camera = Camera::perspective(Vec3::Z * 3.0, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 10.0).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    let e = crowd.encode(&gpu.queue, &mut encoder, &camera, Tests::Both, 5, None).unwrap_err();
    assert!(e.to_string().contains("capacity 4"), "{e}");
}

#[test]
fn an_overflowing_survivor_list_draws_what_it_wrote_and_a_later_frame_nothing_stale() {
    let Some(gpu) = gpu() else { return };
    let device = &gpu.device;
    let pipelines = CullPipelines::new(device).unwrap();
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let character = asset.character().unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let baked = bake(&asset, &character);
    let skin = &character.palette;
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let draws = meshlet_draws(&baked);
    let gpu_character = GpuCharacter::new(device, &culler, &skin.inverse_bind, &draws).unwrap();
    let params = CrowdParams { instances: 16, frames: 1, ..CrowdParams::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let (mut palette, mut instances, mut skinning) = (Vec::new(), Vec::new(), Vec::new());
    for p in &scene.placements {
        let clip = clips.get(p.clip).copied();
        Poser::default().skinning_matrices(&asset.skeleton, skin, clip, p.time(clip, 0, params.fps), &mut skinning);
        palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
        instances.push(CullInstance::new(p.model.as_mat4(), CullMode::Bounds));
    }
    let cull = |capacity| {
        let (palette, instances) = (&palette, &instances);
        cull_on_gpu(
            &gpu,
            &pipelines,
            &gpu_character,
            &draws,
            palette,
            instances,
            &scene.camera,
            Tests::Both,
            capacity,
            None,
        )
    };
    let whole = cull(None);
    let found = whole.header.found;
    assert!(found > 8 && whole.header.instance_count == found);
    for capacity in [0, 1, found / 2, found - 1, found] {
        let part = cull(Some(capacity));
        assert_eq!((part.header.found, part.header.instance_count), (found, capacity));
        // What was written is a part of the frame's survivors (each once: survivors_drawn).
        for (i, row) in part.drawn.iter().enumerate() {
            for (id, &d) in row.iter().enumerate() {
                assert!(!d || whole.drawn[i][id], "capacity {capacity}: instance {i} meshlet {id} drawn but culled");
            }
        }
    }
    // One crowd, two frames: a full one, then a camera facing away; the second frame's draw
    // has no survivors (the first frame's entries are still in the list, and not drawn).
    let storage = wgpu::BufferUsages::STORAGE;
    let init = |contents: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents, usage: storage })
    };
    let floats: Vec<f32> = palette.iter().flat_map(|m| m.to_cols_array()).collect();
    let (palette, instances) = (init(bytemuck::cast_slice(&floats)), init(bytemuck::cast_slice(&instances)));
    let n = scene.placements.len() as u32;
    let crowd = CrowdCulling::new(device, &pipelines, &gpu_character, &palette, &instances, n, found).unwrap();
    let Projection::Perspective { eye } = scene.camera.projection else { unreachable!() };
    let target = scene.camera.planes[0].truncate(); // any direction; below: the opposite of the crowd's
    let away = Camera::perspective(eye, eye + (eye - target).normalize(), Vec3::Y, 0.5, 1.5, 0.1, 0.2).unwrap();
    for (camera, expect) in [(&scene.camera, found), (&away, 0)] {
        let mut encoder = device.create_command_encoder(&Default::default());
        crowd.encode(&gpu.queue, &mut encoder, camera, Tests::Both, n, None).unwrap();
        gpu.queue.submit([encoder.finish()]);
        let header: SurvivorHeader = bytemuck::pod_read_unaligned(&read_buffer::<u8>(&gpu, crowd.survivors(), 32));
        assert_eq!((header.found, header.instance_count), (expect, expect));
    }
}

/// A character with a cluster LOD hierarchy (the demo's, `skinlet::bake::add_lod`): per
/// instance, the GPU tests exactly the clusters of its cut (`LodView::cut` at the instance's
/// threshold; full detail where the instance's mode is not culled by its bounds) and culls each as it culls the same cluster uploaded without a
/// hierarchy; thresholds on and between the groups' errors, 0, huge and infinite, in every
/// mode.
#[test]
fn lod_cuts_are_selected_on_the_gpu_as_on_the_cpu() {
    let Some(gpu) = gpu() else { return };
    let pipelines = CullPipelines::new(&gpu.device).unwrap();
    let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let character = asset.character().unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let mut baked = bake(&asset, &character);
    skinlet::bake::add_lod(&mut baked, &asset, &skinlet::meshlet::lod::LodParams::default()).unwrap();
    let skin = &character.palette;
    let base = baked.meshlets.len();
    let mut all = baked.meshlets.clone();
    all.append(&baked.lod.as_ref().unwrap().meshlets, 0);
    let draws =
        skinlet_gpu::mesh::meshlet_index_buffer(&all.view(&all.headers()), baked.mesh.positions.len()).unwrap().1;
    // Thresholds: below 0 and NaN (full detail), 0, a few of the groups' errors exactly and
    // halfway to the next, past every error, infinite.
    let mut group_errors: Vec<f32> = baked.lod.as_ref().unwrap().groups.iter().map(|g| g.1).collect();
    group_errors.sort_by(f32::total_cmp);
    let pick = |q: f64| group_errors[((group_errors.len() - 1) as f64 * q) as usize];
    let mut thresholds = vec![-1.0, f32::NAN, 0.0, 1e30, f32::INFINITY];
    for q in [0.1, 0.4, 0.7, 0.95] {
        thresholds.extend([pick(q), (pick(q) + pick((q + 0.05).min(1.0))) / 2.0]);
    }
    let (culler, errors, cuts) = skinlet::bake::with_view(&baked, |view| {
        let lod = view.lod().unwrap();
        let cuts: Vec<Vec<u32>> = (thresholds.iter())
            .map(|&t| {
                let mut cut = Vec::new();
                lod.cut(t, &mut cut);
                cut
            })
            .collect();
        Ok((view.lod_culler()?.unwrap(), lod.errors(), cuts))
    })
    .unwrap();
    assert_eq!(culler.len(), all.len());
    let plain = GpuCharacter::new(&gpu.device, &culler, &skin.inverse_bind, &draws).unwrap();
    let with_lod = GpuCharacter::with_lod(&gpu.device, &culler, &skin.inverse_bind, &draws, base, &errors).unwrap();
    // 13 thresholds × 4 modes: every pair once.
    let params = CrowdParams { instances: 4 * thresholds.len(), frames: 1, ..CrowdParams::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let (mut palette, mut instances, mut skinning, mut in_cut) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, p) in scene.placements.iter().enumerate() {
        let clip = clips.get(p.clip).copied();
        Poser::default().skinning_matrices(&asset.skeleton, skin, clip, p.time(clip, 0, params.fps), &mut skinning);
        palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
        let (t, mode) = (k % thresholds.len(), MODES[k % 4]);
        instances.push(CullInstance::with_lod(p.model.as_mat4(), mode, thresholds[t]));
        let full = matches!(mode, CullMode::BoxesOnly | CullMode::Keep);
        let mut cut = vec![false; all.len()];
        match full {
            true => cut[..base].fill(true),
            false => cuts[t].iter().for_each(|&c| cut[c as usize] = true),
        }
        in_cut.push(cut);
    }
    let tested: Vec<usize> = in_cut.iter().map(|c| c.iter().filter(|&&x| x).count()).collect();
    let run = |character: &GpuCharacter, tested| {
        let (palette, instances, camera) = (&palette, &instances, &scene.camera);
        let room = Some(instances.len() as u32 * character.most_drawn());
        cull_on_gpu(&gpu, &pipelines, character, &draws, palette, instances, camera, Tests::Both, room, tested)
    };
    // The survivor lists' room: every meshlet per instance without a hierarchy, the largest cut
    // (every threshold at and between the groups' errors, brute force) with one.
    assert_eq!(plain.most_drawn() as usize, all.len());
    let largest = skinlet::bake::with_view(&baked, |view| {
        let lod = view.lod().unwrap();
        let mut at: Vec<f32> = group_errors.iter().flat_map(|&e| [e, e.next_up()]).collect();
        at.extend([-1.0, 0.0]);
        let mut cut = Vec::new();
        Ok(at
            .iter()
            .map(|&t| {
                lod.cut(t, &mut cut);
                cut.len()
            })
            .max()
            .unwrap())
    })
    .unwrap();
    assert_eq!(with_lod.most_drawn() as usize, largest);
    let (everything, cut) = (run(&plain, None), run(&with_lod, Some(&tested)));
    let (mut coarse, mut culled) = (0, 0);
    for (i, (row, whole)) in cut.drawn.iter().zip(&everything.drawn).enumerate() {
        for c in 0..all.len() {
            assert_eq!(
                row[c],
                whole[c] && in_cut[i][c],
                "instance {i} (threshold {}, {:?}), cluster {c}: drawn {} where the cut has it {} and culling \
                 without a hierarchy draws it {}",
                thresholds[i % thresholds.len()],
                MODES[i % 4],
                row[c],
                in_cut[i][c],
                whole[c]
            );
            coarse += (row[c] && c >= base) as usize;
            culled += (in_cut[i][c] && !row[c]) as usize;
        }
    }
    assert!(coarse > 0 && culled > 0, "no coarse cluster drawn ({coarse}) or none culled ({culled}): vacuous");
    // Bad errors are refused.
    let mut bad = errors.clone();
    bad[base] = [f32::NAN, 1.0];
    assert!(GpuCharacter::with_lod(&gpu.device, &culler, &skin.inverse_bind, &draws, base, &bad).is_err());
    bad[base] = [2.0, 1.0];
    assert!(GpuCharacter::with_lod(&gpu.device, &culler, &skin.inverse_bind, &draws, base, &bad).is_err());
    assert!(GpuCharacter::with_lod(&gpu.device, &culler, &skin.inverse_bind, &draws, base, &errors[1..]).is_err());
}
