//! GPU meshlet culling returns exactly the CPU culling's visible set: the crowd scene of every
//! shared skinned asset and the demo character, perspective and orthographic, each culling
//! pipeline (both tests, frustum only, backface only), several frames, each instance-frame
//! with the bounds, the bounds and the any-pose boxes, or the boxes alone.

mod common;
use common::{assets, bake, boxed_culler, gpu};
use glam::Affine3A;
use skinlet::clip::Clip;
use skinlet::pose::Poser;
use skinlet_gpu::cull::ComputeCulling;
use skinlet_lab::crowd::{CrowdParams, crowd};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};

#[test]
fn gpu_culling_matches_the_cpu_on_the_crowd_scene() {
    let Some(gpu) = gpu() else { return };
    let culling = ComputeCulling::new(&gpu).unwrap();
    let mut checked = (0usize, 0usize, 0usize);
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let baked = bake(&asset, &character);
        let skin = &character.palette;
        let culler = boxed_culler(&asset, &character, &baked);
        for orthographic in [false, true] {
            let params = CrowdParams { instances: 24, frames: 3, orthographic, ..CrowdParams::default() };
            let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
            let mut poser = Poser::default();
            for tests in [Tests::Both, Tests::Frustum, Tests::Backface] {
                let mut frames = Vec::new();
                let mut cpu = Vec::new();
                let mut boxes_only = Vec::new();
                for f in 0..params.frames {
                    for (k, p) in scene.placements.iter().enumerate() {
                        let clip = clips.get(p.clip).copied();
                        let t = clip.map_or(0.0, |c| c.start + (p.offset + f as f32 * 0.1).fract() * c.duration());
                        let g = poser.globals(&asset.skeleton, clip, t);
                        let world: Vec<Affine3A> = skin
                            .joints
                            .iter()
                            .map(|&j| Affine3A::from_mat4((p.model * g[j as usize]).as_mat4()))
                            .collect();
                        let mut frame = JointFrame::default();
                        let prepare = [MeshletCuller::prepare, MeshletCuller::prepare_with_boxes][k % 2];
                        boxes_only.push(k % 3 == 0);
                        match k % 3 {
                            0 => culler.prepare_boxes_only(&world, &scene.camera, tests, &mut frame),
                            _ => prepare(&culler, &world, &scene.camera, tests, &mut frame),
                        }
                        let (mut flags, mut visible) = (Vec::new(), Vec::new());
                        let counts = culler.cull(&frame, &mut flags, &mut visible);
                        visible.sort_unstable();
                        cpu.push((visible, counts));
                        frames.push(frame);
                    }
                }
                let on_gpu = culling.cull(&gpu, &culler, &frames).unwrap();
                assert_eq!(on_gpu.len(), cpu.len());
                for (i, ((mut ids, counts), (cpu_ids, cpu_counts))) in on_gpu.into_iter().zip(&cpu).enumerate() {
                    ids.sort_unstable();
                    assert_eq!(&ids, cpu_ids, "{name} {tests:?} ortho {orthographic}: instance-frame {i}");
                    assert_eq!(&counts, cpu_counts, "{name} {tests:?} ortho {orthographic}: instance-frame {i}");
                    checked.0 += counts.meshlets;
                    checked.1 += counts.meshlets - counts.visible;
                    if boxes_only[i] {
                        checked.2 += counts.frustum;
                    }
                }
            }
        }
    }
    eprintln!(
        "{} meshlet tests, {} culled ({} by the any-pose boxes alone), every one as on the CPU",
        checked.0, checked.1, checked.2
    );
    assert!(checked.1 > 0 && checked.2 > 0, "nothing was culled: the comparison would be vacuous");
}
