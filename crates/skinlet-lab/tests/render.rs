//! Every skinning pipeline renders the same image of a posed character (thesis fig. 3.2),
//! pixel for pixel: vertex-shader, compute-shader and mesh-shader skinning (skin-aware and
//! common-influences meshlets, full and slim vertices), on every shared skinned asset, the
//! morph-target test and the demo character, mid-clip. With SKINLET_REQUIRE_GPU=1 (CI, lavapipe) the mesh-shader paths
//! must run.

#[path = "../../skinlet-gpu/tests/common/mod.rs"]
mod common;
use common::{Posed, assets, gpu};
use glam::Vec3;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use skinlet_gpu::Gpu;
use skinlet_gpu::crowd_culling::{CullMode, GpuCharacter};
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_lab::gpu_crowd::{CrowdFrame, CrowdView, GpuCrowd};
use skinlet_lab::headless::{self, GpuOptions};
use skinlet_lab::render::{CrowdDraw, Culling, PosedInstance, Renderer, Skinning, TaskCulling, framing};
use skinlet_runtime::camera::Camera;
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};

#[test]
fn every_skinning_pipeline_draws_the_same_image() {
    let Some(gpu) = gpu() else { return };
    let renderer = Renderer::new(&gpu, 192, 192).unwrap();
    let (mut slim, mut meshlet_total) = (0, 0);
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let prepared = skinlet::bake::prepare_character(&character).unwrap();
        let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
        let common = skinlet::meshlet::build(&prepared, Builder::CommonInfluences, MeshletLimits::NVIDIA).unwrap();
        let mesh = prepared.mesh;
        let clip = asset.clips.first();
        let t = clip.map_or(0.0, |c| c.start + 0.4 * c.duration());
        let posed = Posed::new(&asset, skin, &mesh, clip, t);
        let view_proj = framing(&posed.positions, Vec3::new(0.3, 0.2, 1.0), 1.0).unwrap().view_proj;
        let gpu_mesh = GpuMesh::new(&gpu, &mesh.mesh_data(Some(meshlets.view(&meshlets.headers())))).unwrap();
        let light = Vec3::new(0.4, 0.8, 0.6);
        let by_vertex = renderer.render(&gpu, &gpu_mesh, posed.pose(), view_proj, light, Skinning::Vertex).unwrap();
        let by_compute = renderer.render(&gpu, &gpu_mesh, posed.pose(), view_proj, light, Skinning::Compute).unwrap();
        // The character covers part of the image (the test would pass on two blank images).
        let background = &by_vertex.rgba[..4];
        let covered = by_vertex.rgba.chunks(4).filter(|p| *p != background).count();
        assert!(covered > 200, "{name}: only {covered} pixels drawn");
        let mut others = vec![("compute".to_string(), by_compute)];
        if gpu.has_mesh_shaders() {
            for (builder, m) in [("skin-aware", &meshlets), ("common-influences", &common)] {
                let gpu_mesh = GpuMesh::new(&gpu, &mesh.mesh_data(Some(m.view(&m.headers())))).unwrap();
                let ml = gpu_mesh.meshlets.as_ref().unwrap();
                (slim, meshlet_total) = (slim + ml.slim, meshlet_total + ml.count);
                for path in [Skinning::Mesh, Skinning::MeshSlim] {
                    let image = renderer.render(&gpu, &gpu_mesh, posed.pose(), view_proj, light, path).unwrap();
                    others.push((format!("{path:?} on {builder} meshlets ({} of {} slim)", ml.slim, ml.count), image));
                }
            }
        }
        for (path, image) in others {
            let differing = by_vertex.rgba.chunks(4).zip(image.rgba.chunks(4)).filter(|(a, b)| a != b).count();
            assert_eq!(
                differing, 0,
                "{name}: {differing} of {covered} pixels differ between vertex and {path} skinning"
            );
        }
    }
    eprintln!("{slim} of {meshlet_total} meshlets slim");
    assert!(!gpu.has_mesh_shaders() || slim > 0, "no slim meshlet: the slim path was not exercised");
}

#[test]
fn a_pose_change_changes_the_image() {
    // The comparison above must be able to fail: two different poses give different images.
    let Some(gpu) = gpu() else { return };
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let character = asset.character().unwrap();
    let (skin, mesh, clip) = (&character.palette, &character.mesh, &asset.clips[0]);
    let renderer = Renderer::new(&gpu, 128, 128).unwrap();
    let gpu_mesh = GpuMesh::new(&gpu, &mesh.mesh_data(None)).unwrap();
    let view_proj = framing(&mesh.positions, Vec3::Z, 1.0).unwrap().view_proj;
    let mut images = Vec::new();
    for t in [0.2, 0.6] {
        let posed = Posed::new(&asset, skin, mesh, Some(clip), clip.start + t * clip.duration());
        images.push(renderer.render(&gpu, &gpu_mesh, posed.pose(), view_proj, Vec3::Y, Skinning::Vertex).unwrap());
    }
    assert_ne!(images[0], images[1]);
    assert!(renderer.render(&gpu, &gpu_mesh, &[][..], view_proj, Vec3::Y, Skinning::Vertex).is_err(), "no matrices");
    let posed = Posed::new(&asset, skin, mesh, Some(clip), clip.start);
    let no_meshlets = renderer.render(&gpu, &gpu_mesh, posed.pose(), view_proj, Vec3::Y, Skinning::Mesh);
    assert!(no_meshlets.is_err(), "mesh shading without meshlets");
    if gpu_mesh.morph_weights > 0 {
        let unmorphed = renderer.render(&gpu, &gpu_mesh, &posed.matrices, view_proj, Vec3::Y, Skinning::Vertex);
        assert!(unmorphed.is_err(), "a pose without the mesh's morph weights");
    }
}

#[test]
fn culled_drawing_gives_the_unculled_image() {
    // The paper's section 6 pipeline: a task shader culls meshlets with the baked bounds and
    // launches mesh workgroups for the survivors only (compacted by subgroup operations, and
    // on a device opened without subgroups by atomics alone), which may also cull triangles one
    // by one (thesis 5.1.3). (Without mesh shaders this renderer does not cull: the GPU-driven
    // crowd does, tests/gpu_crowd.rs.) Culling is conservative and back faces are culled by the
    // rasterizer anyway, so each image must equal the unculled one of the same device; views
    // close enough to cut the character make the frustum test work too. The task shaders
    // launch exactly the meshlets crowd culling's compute pass keeps on the same GPU-prepared
    // records, which cull about what the CPU culler culls; with per-triangle culling the
    // triangles drawn are the CPU's kept ones of those meshlets.
    let Some(gpu) = gpu() else { return };
    if !gpu.has_mesh_shaders() {
        return eprintln!("{} has no mesh shaders: no task culling to draw", gpu.info.name);
    }
    let no_subgroups = headless::gpu(GpuOptions { no_subgroups: true, ..GpuOptions::default() }).unwrap();
    assert!(!no_subgroups.has_subgroups());
    let devices = [
        (&gpu, Renderer::new(&gpu, 160, 160).unwrap()),
        (&no_subgroups, Renderer::new(&no_subgroups, 160, 160).unwrap()),
    ];
    let mut culled_total = 0;
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
        let baked = common::bake(&asset, &character);
        let skin = &character.palette;
        let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
        let clip = clips.first().copied();
        let t = clip.map_or(0.0, |c| c.start + 0.6 * c.duration());
        let mut poser = Poser::default();
        let at = Posed::new(&asset, skin, &baked.mesh, clip, t);
        let (posed, pose) = (&at.positions, at.pose());
        let mut joints = Vec::new();
        skinlet::pose::joint_globals(skin, poser.globals(&asset.skeleton, clip, t), &mut joints);
        for (device, renderer) in &devices {
            let gpu_mesh =
                GpuMesh::new(device, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers()))))
                    .unwrap();
            let character = gpu_character(device, &baked, &culler);
            for (dir, zoom) in [(Vec3::new(0.3, 0.2, 1.0), 1.0), (Vec3::new(-1.0, 0.4, -0.5), 2.5)] {
                let camera = framing(posed, dir, zoom).unwrap();
                let one = [PosedInstance { pose, cull: Some(CullMode::Bounds) }];
                let visible = compute_survivors(device, &baked, &culler, &one, &camera);
                // About what the CPU culler culls (it tests joints' groups first, with other margins).
                let mut frame = skinlet_runtime::meshlet_cull::JointFrame::default();
                culler.prepare(&joints, &camera, Tests::Both, &mut frame);
                let counts = culler.cull(&frame, &mut Vec::new(), &mut Vec::new());
                let culled = counts.meshlets - visible[0].len();
                assert!(
                    culled.abs_diff(counts.meshlets - counts.visible) * 50 <= counts.meshlets,
                    "{name}: {counts:?}"
                );
                culled_total += culled;
                let light = Vec3::new(0.4, 0.8, 0.6);
                let all = renderer.render(device, &gpu_mesh, pose, camera.view_proj, light, Skinning::Mesh).unwrap();
                // The CPU's per-triangle culling of the visible meshlets, on the same skinned positions.
                let kept = skinlet::cull::triangle::cull_triangles(
                    &baked.meshlets,
                    &visible[0],
                    posed,
                    camera.projection,
                    None,
                );
                let in_visible = triangles_of(&baked, &visible);
                for (triangles, expected) in [(None, in_visible), (Some(camera.projection), kept.kept as u32)] {
                    let cull = TaskCulling {
                        character: &character,
                        camera: &camera,
                        tests: Tests::Both,
                        culling: Culling::Task,
                        triangles,
                    };
                    let (culled, drawn, meshlets) =
                        renderer.render_culled(device, &gpu_mesh, pose, light, cull, CullMode::Bounds).unwrap();
                    let differing = all.rgba.chunks(4).zip(culled.rgba.chunks(4)).filter(|(a, b)| a != b).count();
                    let subgroups = device.has_subgroups();
                    let what = format!("{name} zoom {zoom} subgroups {subgroups} triangles {triangles:?}");
                    assert_eq!(differing, 0, "{what}: {differing} pixels differ ({counts:?})");
                    assert_eq!(drawn, expected, "{what}: triangles drawn");
                    assert_eq!(meshlets as usize, visible[0].len(), "{what}: meshlets drawn");
                }
                // The paper's three task pipelines, one per culling class.
                let culling = Culling::TaskByClass;
                let cull = TaskCulling {
                    character: &character,
                    camera: &camera,
                    tests: Tests::Both,
                    culling,
                    triangles: None,
                };
                let how = CrowdDraw::Culled(cull, Skinning::Mesh);
                let d = renderer.render_crowd(device, &gpu_mesh, &one, camera.view_proj, light, how).unwrap();
                let differing = differing_pixels(&all, &d.image);
                assert_eq!(differing, 0, "{name} zoom {zoom} by class: {differing} pixels differ");
                assert_eq!(d.triangles, Some(in_visible), "{name} zoom {zoom} by class: triangles drawn");
            }
        }
    }
    assert!(culled_total > 0, "no meshlet was culled: the comparison would be vacuous");
}

/// A 320×180 renderer and the 4,000-triangle demo character, baked: the crowd tests' scene.
fn crowd_setup(gpu: &Gpu) -> (Renderer, skinlet::Asset, skinlet::bake::Baked) {
    let renderer = Renderer::new(gpu, 320, 180).unwrap();
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let baked = common::bake(&demo, &demo.character().unwrap());
    (renderer, demo, baked)
}

#[test]
fn crowd_draws_agree_and_are_timed() {
    // The gpu-bench scene: a crowd of instances in one render pass. Every pipeline, culled
    // or not, draws the same image; task-culled drawing draws exactly the triangles of the
    // meshlets crowd culling's compute pass keeps; devices with timestamp queries (lavapipe
    // has them) time the frame.
    let Some(gpu) = gpu() else { return };
    let (renderer, demo, baked) = crowd_setup(&gpu);
    let clips: Vec<&skinlet::clip::Clip> = demo.clips.iter().collect();
    let skin = &baked.palette();
    let params = skinlet_lab::crowd::CrowdParams { instances: 12, ..Default::default() };
    let scene = skinlet_lab::crowd::crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let mut poser = Poser::default();
    let mut matrices = Vec::new();
    for pl in &scene.placements {
        let clip = clips[pl.clip];
        let t = pl.time(Some(clip), 0, params.fps);
        let globals = poser.globals(&demo.skeleton, Some(clip), t);
        let (mut joints, mut skinning, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        pl.world_matrices(skin, globals, &mut joints, &mut skinning);
        baked.mesh.morphs.weights_at(Some(clip), t, &mut weights);
        matrices.push((skinning, weights));
    }
    let instances: Vec<PosedInstance> = (matrices.iter())
        .map(|(m, w)| PosedInstance { pose: Pose { matrices: m, morph_weights: w }, cull: Some(CullMode::Bounds) })
        .collect();
    let expected = triangles_of(&baked, &compute_survivors(&gpu, &baked, &culler, &instances, &scene.camera));
    let character = gpu_character(&gpu, &baked, &culler);
    let mesh_gpu =
        GpuMesh::new(&gpu, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers())))).unwrap();
    let (view_proj, light) = (scene.camera.view_proj, Vec3::new(0.4, 0.8, 0.6));
    let draw = |how| renderer.render_crowd(&gpu, &mesh_gpu, &instances, view_proj, light, how).unwrap();
    let reference = draw(CrowdDraw::Plain(Skinning::Vertex));
    let background = &reference.image.rgba[..4];
    let covered = reference.image.rgba.chunks(4).filter(|p| *p != background).count();
    assert!(covered > 500, "only {covered} pixels drawn");
    assert!(expected < 12 * baked.meshlets.meshlets.iter().map(|m| m.triangle_count as u32).sum::<u32>());
    // Pixel for pixel within each front end (vertex-fed: VS, CS; mesh-shader-fed: MS, MS
    // slim, both task-culled by flags and by class; vertex-fed culled drawing is gpu_crowd's,
    // tests/gpu_crowd.rs). Across the two, lavapipe clips triangles that cross the view's sides
    // in different code, so a few pixels there may differ.
    let camera = &scene.camera;
    let culled = |culling, skinning| {
        CrowdDraw::Culled(
            TaskCulling { character: &character, camera, tests: Tests::Both, culling, triangles: None },
            skinning,
        )
    };
    let mut drawn = vec![("compute", draw(CrowdDraw::Plain(Skinning::Compute)), None)];
    let mut mesh_reference = None;
    if gpu.has_mesh_shaders() {
        let mesh = draw(CrowdDraw::Plain(Skinning::Mesh));
        let across = differing_pixels(&mesh.image, &reference.image);
        assert!(across * 200 <= covered, "mesh vs vertex skinning: {across} of {covered} pixels differ");
        drawn.push(("mesh slim", draw(CrowdDraw::Plain(Skinning::MeshSlim)), None));
        for skinning in [Skinning::Mesh, Skinning::MeshSlim] {
            for culling in [Culling::Task, Culling::TaskByClass] {
                drawn.push(("mesh task culled", draw(culled(culling, skinning)), Some(expected)));
            }
        }
        mesh_reference = Some(mesh);
        let mismatched = renderer.render_crowd(
            &gpu,
            &mesh_gpu,
            &instances,
            view_proj,
            light,
            culled(Culling::Task, Skinning::Vertex),
        );
        assert!(mismatched.is_err(), "task culling with vertex skinning is an error");
    }
    for (what, d, triangles) in drawn {
        let same = if what.starts_with("mesh") { mesh_reference.as_ref().unwrap() } else { &reference };
        let n = differing_pixels(&d.image, &same.image);
        assert_eq!(n, 0, "{what}: {n} of {covered} pixels differ within its front end");
        assert_eq!(d.triangles, triangles, "{what}: triangles drawn");
        if gpu.has_timestamps() {
            assert!(d.gpu_ms.is_some_and(|t| t > 0.0 && t < 60_000.0), "{what}: GPU time {:?}", d.gpu_ms);
        }
    }
}

#[test]
fn game_poses_cull_on_the_gpu_as_on_the_cpu() {
    // IK poses (some joints beyond their range of motion): per instance the CPU pose guard
    // picks the envelope bounds (with the any-pose boxes), or the any-pose boxes alone; the
    // task shaders draw exactly the meshlets crowd culling's compute pass keeps (about the
    // CPU's visible ones) and the same image as without culling.
    use skinlet_lab::crowd::{Animation, CrowdParams, crowd, instance_pose};
    use skinlet_runtime::meshlet_cull::JointFrame;
    let Some(gpu) = gpu() else { return };
    let (renderer, demo, mut baked) = crowd_setup(&gpu);
    let clips: Vec<&skinlet::clip::Clip> = demo.clips.iter().collect();
    let skin = &baked.palette();
    let envelope =
        skinlet::bounds::envelope::Envelope::from_clips(&demo.skeleton, skin, &baked.mesh, &clips, 0.2).unwrap();
    skinlet::bake::add_envelope(&mut baked, &demo, envelope).unwrap();
    let e = baked.envelope.as_ref().unwrap();
    let culler = MeshletCuller::new(&e.bounds, &e.classes, skin.joints.len()).unwrap();
    let (guard, culler) = (e.envelope.guard().unwrap(), culler.with_any_pose(&e.any_pose).unwrap());
    let params = CrowdParams { instances: 12, animation: Animation::Ik, seed: 3, ..Default::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let (mut poses, mut modes, mut cpu_visible, mut refused, mut culled_refused) = (Vec::new(), Vec::new(), 0, 0, 0);
    let (mut locals, mut weights, mut globals) = (Vec::new(), Vec::new(), Vec::new());
    for (i, pl) in scene.placements.iter().enumerate() {
        instance_pose(&demo.skeleton, &clips, &baked, &params, i, pl, 0, &mut locals, &mut weights);
        skinlet::pose::global_transforms(&demo.skeleton, &locals, &mut globals);
        let (mut joints, mut skinning) = (Vec::new(), Vec::new());
        pl.world_matrices(skin, &globals, &mut joints, &mut skinning);
        let mut frame = JointFrame::default();
        let admitted = guard.admits(&locals, &weights);
        if admitted {
            culler.prepare_with_boxes(&joints, &scene.camera, Tests::Both, &mut frame);
        } else {
            culler.prepare_boxes_only(&joints, &scene.camera, Tests::Both, &mut frame);
        }
        let mut visible = Vec::new();
        let counts = culler.cull(&frame, &mut Vec::new(), &mut visible);
        if !admitted {
            refused += 1;
            culled_refused += counts.frustum;
        }
        cpu_visible += visible.len();
        poses.push((skinning, weights.clone()));
        modes.push(if admitted { CullMode::BoundsAndBoxes } else { CullMode::BoxesOnly });
    }
    assert!(refused > 0 && refused < 12, "the guard refused {refused} of 12 instances");
    assert!(culled_refused > 0, "the any-pose boxes culled nothing of the refused instances");
    let instances: Vec<PosedInstance> = (poses.iter().zip(&modes))
        .map(|((m, w), &mode)| PosedInstance { pose: Pose { matrices: m, morph_weights: w }, cull: Some(mode) })
        .collect();
    let visible = compute_survivors(&gpu, &baked, &culler, &instances, &scene.camera);
    let gpu_visible: usize = visible.iter().map(Vec::len).sum();
    assert!(
        gpu_visible.abs_diff(cpu_visible) * 50 <= cpu_visible,
        "{gpu_visible} meshlets kept, {cpu_visible} on the CPU"
    );
    let expected = triangles_of(&baked, &visible);
    let character = gpu_character(&gpu, &baked, &culler);
    let mesh_gpu =
        GpuMesh::new(&gpu, &baked.mesh.mesh_data(Some(baked.meshlets.view(&baked.meshlets.headers())))).unwrap();
    let (view_proj, light) = (scene.camera.view_proj, Vec3::new(0.4, 0.8, 0.6));
    let draw = |how| renderer.render_crowd(&gpu, &mesh_gpu, &instances, view_proj, light, how).unwrap();
    let all: u32 = 12 * baked.meshlets.meshlets.iter().map(|m| m.triangle_count as u32).sum::<u32>();
    assert!(expected < all, "nothing culled");
    if !gpu.has_mesh_shaders() {
        return eprintln!("no mesh shaders: task culling not drawn (gpu_crowd draws the vertex-fed path)");
    }
    let reference = draw(CrowdDraw::Plain(Skinning::Mesh));
    for culling in [Culling::Task, Culling::TaskByClass] {
        let skinning = Skinning::Mesh;
        let cull =
            TaskCulling { character: &character, camera: &scene.camera, tests: Tests::Both, culling, triangles: None };
        let culled = draw(CrowdDraw::Culled(cull, skinning));
        assert_eq!(culled.triangles, Some(expected), "{culling:?}: triangles drawn");
        let n = differing_pixels(&culled.image, &reference.image);
        assert_eq!(n, 0, "{culling:?}: culled and unculled images differ");
    }
}

/// The meshlets crowd culling's compute pass keeps (per instance, sorted), on the same joint
/// records task culling reads (`skinlet_lab::gpu_crowd`'s pulled view): the task shaders must
/// launch exactly these.
fn compute_survivors(
    gpu: &Gpu,
    baked: &skinlet::bake::Baked,
    culler: &MeshletCuller,
    instances: &[PosedInstance],
    camera: &Camera,
) -> Vec<Vec<u32>> {
    let crowd = GpuCrowd::new(gpu, baked, culler, instances.len() as u32, 64, 36).unwrap();
    let palette: Vec<glam::Mat4> =
        instances.iter().flat_map(|i| i.pose.matrices.iter().map(|&m| glam::Mat4::from(m))).collect();
    let modes: Vec<CullMode> = instances.iter().map(|i| i.cull.unwrap()).collect();
    let weights: Vec<f32> = instances.iter().flat_map(|i| i.pose.morph_weights.iter().copied()).collect();
    let frame = CrowdFrame {
        palette: &palette,
        modes: &modes,
        weights: &weights,
        lod_thresholds: &[],
        camera,
        tests: Tests::Both,
    };
    crowd.draw(gpu, &frame, CrowdView::Pulled, Vec3::Y).unwrap();
    let mut kept = vec![Vec::new(); instances.len()];
    for [i, m] in crowd.survivors(gpu).unwrap() {
        kept[i as usize].push(m);
    }
    kept.iter_mut().for_each(|k| k.sort_unstable());
    kept
}

/// `baked`'s meshlets uploaded for culling.
fn gpu_character(gpu: &Gpu, baked: &skinlet::bake::Baked, culler: &MeshletCuller) -> GpuCharacter {
    let headers = baked.meshlets.headers();
    let view = baked.meshlets.view(&headers);
    let (_, draws) = skinlet_gpu::mesh::meshlet_index_buffer(&view, baked.mesh.positions.len()).unwrap();
    GpuCharacter::new(&gpu.device, culler, &baked.inverse_bind, &draws).unwrap()
}

/// Triangles of meshlets `visible`.
fn triangles_of(baked: &skinlet::bake::Baked, visible: &[Vec<u32>]) -> u32 {
    visible.iter().flatten().map(|&m| baked.meshlets.meshlets[m as usize].triangle_count as u32).sum()
}

fn differing_pixels(a: &skinlet_lab::render::Image, b: &skinlet_lab::render::Image) -> usize {
    a.rgba.chunks(4).zip(b.rgba.chunks(4)).filter(|(x, y)| x != y).count()
}

#[test]
fn gpu_overdraw_matches_the_cpu_rasterizer() {
    // The overdraw view measures OVR on the GPU: fragments that pass a "less" depth test, in
    // index-buffer order. skinlet's CPU rasterizer (the one the orders were optimized with)
    // must agree: the same pixels covered, per-pixel counts equal on all but 0.1% of them
    // (depth ties: f32 on the GPU, f64 on the CPU), OVR within 0.1%, for the prepared order
    // and its reverse.
    let Some(gpu) = gpu() else { return };
    let size = 192;
    let renderer = Renderer::new(&gpu, size, size).unwrap();
    let mut raster = skinlet::overdraw::measure::Raster::new(size, size);
    let mut checked = 0;
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let mesh = skinlet::bake::prepare_character(&character).unwrap().mesh;
        let clip = asset.clips.first();
        let t = clip.map_or(0.0, |c| c.start + 0.3 * c.duration());
        let pose = Posed::new(&asset, skin, &mesh, clip, t);
        let posed = &pose.positions;
        let framing = skinlet::overdraw::cluster::Framing::of(std::slice::from_ref(posed));
        let view_proj = framing.view_proj(framing.eye(Vec3::new(0.3, 0.2, 1.0).normalize(), 3.0));
        let reversed: Vec<[u32; 3]> = mesh.triangles.iter().rev().copied().collect();
        let mut ratios = Vec::new();
        for order in [mesh.triangles.clone(), reversed] {
            let ordered = skinlet::model::SkinnedMesh { triangles: order.clone(), ..mesh.clone() };
            let gpu_mesh = GpuMesh::new(&gpu, &ordered.mesh_data(None)).unwrap();
            let (counts, on_gpu) = renderer.render_overdraw(&gpu, &gpu_mesh, pose.pose(), view_proj).unwrap();
            let on_cpu = raster.render(posed, &order, &view_proj);
            let pixels = counts.iter().zip(&raster.shaded).filter(|(a, b)| a != b).count();
            eprintln!(
                "{name}: OVR GPU {:.4} CPU {:.4}, {} vs {} pixels covered, {pixels} pixels count differently",
                on_gpu.ratio(),
                on_cpu.ratio(),
                on_gpu.covered,
                on_cpu.covered
            );
            assert!(on_cpu.covered > 100, "{name}: the view misses the character");
            assert_eq!(on_gpu.covered, on_cpu.covered, "{name}: pixels covered");
            assert!(pixels * 1000 <= on_cpu.covered as usize, "{name}: {pixels} pixels count differently");
            let relative = (on_gpu.ratio() / on_cpu.ratio() - 1.0).abs();
            assert!(relative < 1e-3, "{name}: GPU OVR {} vs CPU {}", on_gpu.ratio(), on_cpu.ratio());
            ratios.push(on_gpu.ratio());
        }
        checked += (ratios[0] != ratios[1]) as usize;
    }
    assert!(checked > 0, "no asset where the order changes the overdraw: the test would be vacuous");
}
