//! GPU contour extraction (patch culling pass, indirect edge test pass) returns exactly the
//! CPU brute force's edge set: on the shared static scans (the paper's 42 × 6 views, plus
//! orthographic ones and eyes inside the model) and on every shared skinned asset and the demo,
//! skinned on the GPU, over sampled frames of a clip, with each window's bounds and with the
//! bounds over every clip. It also tests exactly as many edges as the CPU patch extractor.
//! (Drawing the extracted lines: skinlet-lab's tests/contour_view.rs.)

mod common;
use common::{assets, assets_dir, gpu};

use glam::{DMat4, Vec3};
use skinlet::bounds::refine::Refinement;
use skinlet::contour::patches::{self, PatchParams};
use skinlet::contour::skinned::{SkinnedMethod, SkinnedParams, build, skinned_edges};
use skinlet::contour::{Edges, Projection, Tested, brute_force};
use skinlet::pose::Poser;
use skinlet_gpu::Gpu;
use skinlet_gpu::contours::{ContourExtraction, ContourView, Extracted, GpuContours, positions_buffer};
use skinlet_gpu::mesh::{GpuMesh, Pose};
use skinlet_gpu::skinning::ComputeSkinning;
use skinlet_lab::contour_eval::{frame, views};

/// Orthographic views along 12 directions and eyes inside the model.
fn more_views(positions: &[Vec3]) -> Vec<Projection> {
    let (center, size) = frame(positions);
    let mut v: Vec<Projection> = skinlet::overdraw::viewpoints::icosphere(0)
        .into_iter()
        .map(|dir| Projection::Orthographic { dir: -dir })
        .collect();
    v.push(Projection::Perspective { eye: center });
    v.push(Projection::Perspective { eye: center + Vec3::splat(0.2 * size as f32) });
    v
}

/// Compares one GPU extraction with brute force and the CPU extractor's tested count;
/// returns the GPU's result.
fn check(
    name: &str,
    gpu_result: Extracted,
    positions: &[Vec3],
    edges: &Edges,
    view: Projection,
    cpu: Tested,
) -> Extracted {
    let mut reference = Vec::new();
    brute_force(positions, edges, view, &mut reference);
    if gpu_result.edges != reference {
        let missing: Vec<_> = reference.iter().filter(|e| gpu_result.edges.binary_search(e).is_err()).take(5).collect();
        let extra: Vec<_> = gpu_result.edges.iter().filter(|e| reference.binary_search(e).is_err()).take(5).collect();
        panic!(
            "{name} {view:?}: GPU {} contour edges, brute force {}; missing {missing:?}, extra {extra:?}",
            gpu_result.edges.len(),
            reference.len()
        );
    }
    assert_eq!(gpu_result.tested as usize, cpu.edges, "{name} {view:?}: edges tested on the GPU and the CPU");
    gpu_result
}

fn extraction(gpu: &Gpu) -> ContourExtraction {
    ContourExtraction::new(gpu).expect("lavapipe and desktop GPUs have SHADER_F64")
}

#[test]
fn static_scans_match_brute_force() {
    let Some(gpu) = gpu() else { return };
    let pipes = extraction(&gpu);
    let mut meshes: Vec<(String, Vec<Vec3>, Vec<[u32; 3]>)> = Vec::new();
    let (p, t) = skinlet_lab::demo::uv_sphere(24, 48);
    meshes.push(("uv sphere".into(), p, t));
    let files = ["spot.obj", "stanford-bunny.obj", "kitten.obj", "bob_tri.obj"];
    for (dir, file) in assets_dir().into_iter().flat_map(|d| files.map(|f| (d.clone(), f))) {
        let path = dir.join("static").join(file);
        let asset = skinlet::import::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (mesh, _, _) = skinlet::weld::weld(&asset.character().unwrap().mesh);
        meshes.push((file.into(), mesh.positions, mesh.triangles));
    }
    for (name, positions, triangles) in meshes {
        let mut edges = Edges::build(&positions, &triangles).unwrap();
        if name.starts_with('k') {
            edges.drop_concave(&positions, |_| true);
        }
        let p = patches::build(&positions, &edges, &PatchParams::default());
        let shape = GpuContours::new(&gpu, &edges, &p).unwrap();
        let buffer = positions_buffer(&gpu, &positions);
        let mut all = views(&positions);
        all.extend(more_views(&positions));
        let (mut tested, mut found, mut out) = (0u64, 0u64, Vec::new());
        for &view in &all {
            let cpu = p.extract(&positions, &edges, view, &mut out);
            let r = pipes.extract(&gpu, &shape, &buffer, &ContourView::fixed(view)).unwrap();
            let r = check(&name, r, &positions, &edges, view, cpu);
            tested += r.tested as u64;
            found += r.edges.len() as u64;
        }
        let share = tested as f64 / (all.len() * edges.len()) as f64;
        eprintln!(
            "{name}: {} views, {} patches, {found} contour edges, {:.0}% of edges tested",
            all.len(),
            p.len(),
            share * 100.0
        );
        assert!(found > 0 && share < 0.8, "{name}: the patch pass must cull");
    }
}

#[test]
fn skinned_assets_match_brute_force() {
    let Some(gpu) = gpu() else { return };
    let pipes = extraction(&gpu);
    let skinning = ComputeSkinning::new(&gpu).unwrap();
    let how = Refinement { max_rounds: 2, ..Refinement::NONE };
    for (name, asset) in assets() {
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let (mesh, _, _) = skinlet::weld::weld(&character.mesh);
        let edges = skinned_edges(&mesh, true).unwrap();
        let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().take(2).collect();
        let sp = build(&asset.skeleton, skin, &clips, &mesh, &edges, &SkinnedParams::new(SkinnedMethod::Animated, how))
            .unwrap();
        let shape = GpuContours::skinned(&gpu, &edges, &sp).unwrap();
        let buffers = GpuMesh::new(&gpu, &mesh.mesh_data(None)).unwrap();
        let mut poser = Poser::default();
        let (mut frames, mut found) = (0, 0);
        let (mut matrices, mut weights, mut out) = (Vec::new(), Vec::new(), Vec::new());
        for (c, clip) in clips.iter().enumerate() {
            for f in [0.15f32, 0.6, 0.95] {
                let t = clip.start + f * clip.duration();
                poser.skinning_matrices(&asset.skeleton, skin, Some(clip), t, &mut matrices);
                let globals = poser.globals(&asset.skeleton, Some(clip), t);
                let inverses: Vec<DMat4> = skin.joints.iter().map(|&j| globals[j as usize].inverse()).collect();
                mesh.morphs.weights_at(Some(clip), t, &mut weights);
                let pose = Pose { matrices: &matrices, morph_weights: &weights };
                skinning.skin(&gpu, &buffers, pose).unwrap();
                // The contours of the GPU-skinned positions (equal to the CPU's on lavapipe:
                // tests/skinning.rs), compared with the CPU's extraction of the same.
                let (positions, _) = skinning.read(&gpu, &buffers).unwrap();
                let (center, size) = frame(&positions);
                let mut all: Vec<Projection> = skinlet::overdraw::viewpoints::icosphere(0)
                    .into_iter()
                    .flat_map(|d| [0.8, 4.0].map(|s| Projection::Perspective { eye: center + d * (s * size) as f32 }))
                    .collect();
                all.extend(more_views(&positions));
                for &view in &all {
                    for at in [Some((c, t)), None] {
                        let cpu = sp.extract_prepared(&positions, &edges, &inverses, at, view, &mut out);
                        let v = ContourView::skinned(&sp, &inverses, at, view);
                        let r = pipes.extract(&gpu, &shape, &buffers.out_positions, &v).unwrap();
                        found += check(&format!("{name} t={t} {at:?}"), r, &positions, &edges, view, cpu).edges.len();
                    }
                }
                frames += all.len();
            }
        }
        eprintln!("{name}: {frames} frame-views × 2 bound sets, {found} contour edges, equal to brute force");
        assert!(found > 0, "{name}");
    }
}

#[test]
fn patches_of_other_edges_are_an_error() {
    let Some(gpu) = gpu() else { return };
    let (p, t) = skinlet_lab::demo::uv_sphere(8, 16);
    let edges = Edges::build(&p, &t).unwrap();
    let patches = patches::build(&p, &edges, &PatchParams::default());
    let (p2, t2) = skinlet_lab::demo::uv_sphere(9, 16);
    let other = Edges::build(&p2, &t2).unwrap();
    assert!(GpuContours::new(&gpu, &other, &patches).is_err());
    // Positions too few for the edges' vertices.
    let shape = GpuContours::new(&gpu, &edges, &patches).unwrap();
    let short = positions_buffer(&gpu, &p[..p.len() / 2]);
    let view = ContourView::fixed(Projection::Perspective { eye: Vec3::splat(5.0) });
    assert!(extraction(&gpu).extract(&gpu, &shape, &short, &view).is_err());
}
