//! Every skinning pipeline renders the same image of a posed character (thesis fig. 3.2),
//! pixel for pixel: vertex-shader, compute-shader and mesh-shader skinning (skin-aware
//! meshlets), on every shared skinned asset and the demo character, mid-clip. With
//! SKINLET_REQUIRE_GPU=1 (CI, lavapipe) the mesh-shader path must run.

mod common;
use common::{assets, gpu};
use glam::{Affine3A, Vec3};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use skinlet_gpu::mesh::GpuMesh;
use skinlet_gpu::render::{Renderer, Skinning, framing};
use skinlet_gpu::{Gpu, GpuOptions};

#[test]
fn every_skinning_pipeline_draws_the_same_image() {
    let Some(gpu) = gpu() else { return };
    let renderer = Renderer::new(&gpu, 192, 192).unwrap();
    for (name, asset) in assets() {
        let Some(skin_index) = asset.instances.iter().find_map(|i| i.skin) else { continue };
        let skin = &asset.skins[skin_index as usize];
        let prepared = skinlet::meshlet::prepare(&asset.combined_mesh(Some(skin_index)));
        let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
        let mesh = prepared.mesh;
        let clip = asset.clips.first();
        let t = clip.map_or(0.0, |c| c.start + 0.4 * c.duration());
        let mut matrices: Vec<Affine3A> = Vec::new();
        Poser::default().skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
        let mut posed = vec![Vec3::ZERO; mesh.positions.len()];
        let inf = mesh.influences.as_ref().unwrap();
        skinlet::skinning::skin(inf, &mesh.positions, &[], &matrices, &mut posed, &mut []).unwrap();
        let view_proj = framing(&posed, Vec3::new(0.3, 0.2, 1.0), 1.0).view_proj;
        let gpu_mesh = GpuMesh::new(&gpu, &mesh, Some(&meshlets)).unwrap();
        let light = Vec3::new(0.4, 0.8, 0.6);
        let by_vertex = renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, light, Skinning::Vertex).unwrap();
        let by_compute = renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, light, Skinning::Compute).unwrap();
        // The character covers part of the image (the test would pass on two blank images).
        let background = &by_vertex.rgba[..4];
        let covered = by_vertex.rgba.chunks(4).filter(|p| *p != background).count();
        assert!(covered > 200, "{name}: only {covered} pixels drawn");
        let mut others = vec![("compute", by_compute)];
        if gpu.has_mesh_shaders() {
            let by_mesh = renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, light, Skinning::Mesh).unwrap();
            others.push(("mesh", by_mesh));
        }
        for (path, image) in others {
            let differing = by_vertex.rgba.chunks(4).zip(image.rgba.chunks(4)).filter(|(a, b)| a != b).count();
            assert_eq!(
                differing, 0,
                "{name}: {differing} of {covered} pixels differ between vertex and {path} skinning"
            );
        }
    }
}

#[test]
fn a_pose_change_changes_the_image() {
    // The comparison above must be able to fail: two different poses give different images.
    let Some(gpu) = gpu() else { return };
    let asset = skinlet::demo::demo_character(&skinlet::demo::DemoParams { triangles: 4000, ..Default::default() });
    let (skin, mesh, clip) = (&asset.skins[0], asset.combined_mesh(Some(0)), &asset.clips[0]);
    let renderer = Renderer::new(&gpu, 128, 128).unwrap();
    let gpu_mesh = GpuMesh::new(&gpu, &mesh, None).unwrap();
    let view_proj = framing(&mesh.positions, Vec3::Z, 1.0).view_proj;
    let mut images = Vec::new();
    for t in [0.2, 0.6] {
        let mut matrices = Vec::new();
        Poser::default().skinning_matrices(
            &asset.skeleton,
            skin,
            Some(clip),
            clip.start + t * clip.duration(),
            &mut matrices,
        );
        images.push(renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, Vec3::Y, Skinning::Vertex).unwrap());
    }
    assert_ne!(images[0], images[1]);
    assert!(renderer.render(&gpu, &gpu_mesh, &[], view_proj, Vec3::Y, Skinning::Vertex).is_err(), "no matrices");
    let mut matrices = Vec::new();
    Poser::default().skinning_matrices(&asset.skeleton, skin, Some(clip), clip.start, &mut matrices);
    let no_meshlets = renderer.render(&gpu, &gpu_mesh, &matrices, view_proj, Vec3::Y, Skinning::Mesh);
    assert!(no_meshlets.is_err(), "mesh shading without meshlets");
}

#[test]
fn culled_drawing_gives_the_unculled_image() {
    // The paper's section 6 pipeline: a task shader culls meshlets with the baked bounds and
    // launches mesh workgroups for the survivors only, which may also cull triangles one by
    // one (thesis 5.1.3); and, forced on a device opened without mesh shaders, the fallback: a
    // compute pass writes one indirect draw per meshlet (culled ones empty), drawn by
    // vertex-shader skinning. Culling is conservative and back faces are culled by the
    // rasterizer anyway, so each image must equal the unculled one of the same device; views
    // close enough to cut the character make the frustum test work too. The triangles drawn
    // are those of the CPU's visible meshlets, and with per-triangle culling the CPU's kept ones.
    let Some(gpu) = gpu() else { return };
    let fallback = Gpu::new(GpuOptions { no_mesh_shaders: true, ..GpuOptions::default() }).unwrap();
    assert!(!fallback.has_mesh_shaders());
    let mut devices = vec![(&fallback, Renderer::new(&fallback, 160, 160).unwrap())];
    if gpu.has_mesh_shaders() {
        devices.push((&gpu, Renderer::new(&gpu, 160, 160).unwrap()));
    } else {
        eprintln!("{} has no mesh shaders: the fallback only", gpu.info.name);
    }
    let mut culled_total = 0;
    for (name, asset) in assets() {
        let Some(skin_index) = asset.instances.iter().find_map(|i| i.skin) else { continue };
        let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
        let how = skinlet::bounds::refine::Refinement::NONE;
        let (baked, _) = skinlet::bake::bake(
            &asset,
            skin_index,
            &clips,
            Builder::SkinAware,
            MeshletLimits::NVIDIA,
            &how,
            &mut |_| {},
        )
        .unwrap();
        let skin = &asset.skins[skin_index as usize];
        let culler = skinlet::cull::meshlet::MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len());
        let clip = clips.first().copied();
        let t = clip.map_or(0.0, |c| c.start + 0.6 * c.duration());
        let mut poser = Poser::default();
        let mut matrices = Vec::new();
        poser.skinning_matrices(&asset.skeleton, skin, clip, t, &mut matrices);
        let mut joints = Vec::new();
        skinlet::pose::joint_globals(skin, poser.globals(&asset.skeleton, clip, t), &mut joints);
        let mut posed = vec![Vec3::ZERO; baked.mesh.positions.len()];
        let inf = baked.mesh.influences.as_ref().unwrap();
        skinlet::skinning::skin(inf, &baked.mesh.positions, &[], &matrices, &mut posed, &mut []).unwrap();
        for (device, renderer) in &devices {
            let mesh_shaders = device.has_mesh_shaders();
            let gpu_mesh = GpuMesh::new(device, &baked.mesh, Some(&baked.meshlets)).unwrap();
            for (dir, zoom) in [(Vec3::new(0.3, 0.2, 1.0), 1.0), (Vec3::new(-1.0, 0.4, -0.5), 2.5)] {
                let camera = framing(&posed, dir, zoom);
                let mut frame = skinlet::cull::meshlet::JointFrame::default();
                culler.prepare(&joints, &camera, skinlet::cull::meshlet::Tests::Both, &mut frame);
                let mut visible = Vec::new();
                let counts = culler.cull(&frame, &mut Vec::new(), &mut visible);
                culled_total += counts.meshlets - counts.visible;
                let light = Vec3::new(0.4, 0.8, 0.6);
                let unculled = if mesh_shaders { Skinning::Mesh } else { Skinning::Vertex };
                let all = renderer.render(device, &gpu_mesh, &matrices, camera.view_proj, light, unculled).unwrap();
                // The CPU's per-triangle culling of the visible meshlets, on the same skinned positions.
                let kept =
                    skinlet::cull::triangle::cull_triangles(&baked.meshlets, &visible, &posed, camera.projection, None);
                let in_visible: u32 =
                    visible.iter().map(|&m| baked.meshlets.meshlets[m as usize].triangle_count as u32).sum();
                let per_triangle = if mesh_shaders { kept.kept as u32 } else { in_visible };
                for (triangles, expected) in [(None, in_visible), (Some(camera.projection), per_triangle)] {
                    let (culled, drawn) = renderer
                        .render_culled(
                            device,
                            &gpu_mesh,
                            &matrices,
                            camera.view_proj,
                            light,
                            &culler,
                            &frame,
                            triangles,
                        )
                        .unwrap();
                    let differing = all.rgba.chunks(4).zip(culled.rgba.chunks(4)).filter(|(a, b)| a != b).count();
                    let what = format!("{name} zoom {zoom} mesh shaders {mesh_shaders} triangles {triangles:?}");
                    assert_eq!(differing, 0, "{what}: {differing} pixels differ ({counts:?})");
                    assert_eq!(drawn, expected, "{what}: triangles drawn");
                }
            }
        }
    }
    assert!(culled_total > 0, "no meshlet was culled: the comparison would be vacuous");
}
