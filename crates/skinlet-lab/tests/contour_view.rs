//! The renderer's contour view: on every shared skinned asset and the demo, posed in a clip
//! and skinned on the GPU, it draws the plain compute-skinned image plus lines; the edges it
//! extracted are brute force's for the camera (and as many were tested as the CPU patch
//! extractor tests), and every pixel it changes has a line color.

#[path = "../../skinlet-gpu/tests/common/mod.rs"]
mod common;
use common::{assets, gpu};

use glam::{DMat4, Vec3};
use skinlet::bounds::refine::Refinement;
use skinlet::contour::brute_force;
use skinlet::contour::skinned::{SkinnedMethod, SkinnedParams, build, skinned_edges};
use skinlet::pose::Poser;
use skinlet_gpu::contours::{ContourExtraction, ContourView, GpuContours};
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_gpu::skinning::ComputeSkinning;
use skinlet_lab::render::{Renderer, Skinning, framing};

#[test]
fn the_contour_view_draws_brute_forces_edges() {
    let Some(gpu) = gpu() else { return };
    let pipes = ContourExtraction::new(&gpu).expect("lavapipe and desktop GPUs have SHADER_F64");
    let skinning = ComputeSkinning::new(&gpu).unwrap();
    let renderer = Renderer::new(&gpu, 160, 160).unwrap();
    let how = Refinement { max_rounds: 2, ..Refinement::NONE };
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let (mesh, _, _) = skinlet::weld::weld(&character.mesh);
        let edges = skinned_edges(&mesh, true).unwrap();
        let clip = &asset.clips[0];
        let params = SkinnedParams::new(SkinnedMethod::Animated, how);
        let sp = build(&asset.skeleton, skin, &[clip], &mesh, &edges, &params).unwrap();
        let shape = GpuContours::skinned(&gpu, &edges, &sp).unwrap();
        let buffers = GpuMesh::new(&gpu, &mesh.mesh_data(None)).unwrap();
        let t = clip.start + 0.15 * clip.duration();
        let mut poser = Poser::default();
        let (mut matrices, mut weights) = (Vec::new(), Vec::new());
        poser.skinning_matrices(&asset.skeleton, skin, Some(clip), t, &mut matrices);
        let globals = poser.globals(&asset.skeleton, Some(clip), t);
        let inverses: Vec<DMat4> = skin.joints.iter().map(|&j| globals[j as usize].inverse()).collect();
        mesh.morphs.weights_at(Some(clip), t, &mut weights);
        let pose = Pose { matrices: &matrices, morph_weights: &weights };
        skinning.skin(&gpu, &buffers, pose).unwrap();
        let (positions, _) = skinning.read(&gpu, &buffers).unwrap();

        let camera = framing(&positions, Vec3::new(0.3, 0.2, 1.0), 1.0).unwrap();
        let light = Vec3::new(0.4, 0.8, 0.6);
        let plain = renderer.render(&gpu, &buffers, pose, camera.view_proj, light, Skinning::Compute).unwrap();
        let view = ContourView::skinned(&sp, &inverses, Some((0, t)), camera.projection);
        let cpu = sp.extract_prepared(&positions, &edges, &inverses, Some((0, t)), camera.projection, &mut Vec::new());
        let (lined, found) =
            renderer.render_contours(&gpu, &buffers, pose, camera.view_proj, light, &pipes, &shape, &view).unwrap();
        let mut reference = Vec::new();
        brute_force(&positions, &edges, camera.projection, &mut reference);
        assert_eq!(found.edges, reference, "{name}: the drawn contour edges");
        assert_eq!(found.tested as usize, cpu.edges, "{name}: edges tested on the GPU and the CPU");
        let lines = [[255, 140, 26, 255], [107, 69, 31, 255]];
        let mut changed = 0;
        for (a, b) in plain.rgba.chunks_exact(4).zip(lined.rgba.chunks_exact(4)) {
            if a != b {
                assert!(lines.iter().any(|l| l == b), "{name}: a pixel {b:?} that is no line color");
                changed += 1;
            }
        }
        assert!(changed > 0, "{name}: no contour line drawn");
    }
}
