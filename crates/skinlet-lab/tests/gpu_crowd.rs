//! The GPU-driven crowd (`skinlet_lab::gpu_crowd` on `skinlet_gpu::crowd_culling`): the
//! survivors, drawn with one call (pulled, or as indexed draws with a GPU count), give the
//! image of every meshlet drawn the same way pixel for pixel (but where meshlets tie in
//! depth), and every (instance, meshlet) with a visible fragment in
//! the unculled ID buffer is among them, on every shared asset and the demo, for clips and
//! for game poses under the pose guard; with two-phase occlusion culling too, also when the
//! camera cuts or moves through a wall of characters and when the crowd teleports. With the
//! triangle pass (`skinlet_gpu::triangle_culling`, one phase or two), every triangle with a
//! visible fragment in the unculled ID buffer is drawn.

#[path = "../../skinlet-gpu/tests/common/mod.rs"]
mod common;
use common::{assets, bake, gpu};
use glam::{Mat4, Vec3};
use skinlet::bounds::envelope::Envelope;
use skinlet::pose::Poser;
use skinlet_gpu::Gpu;
use skinlet_gpu::crowd_culling::CullMode;
use skinlet_lab::crowd::{Animation, CrowdParams, Layout, crowd, instance_pose};
use skinlet_lab::crowd_lod::{CrowdLod, silhouette_displacement};
use skinlet_lab::gpu_crowd::{CrowdFrame, CrowdView, GpuCrowd};
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::{MeshletCuller, Tests};
use skinlet_runtime::part_bounds::PoseBounds;
use std::collections::HashSet;

const LIGHT: Vec3 = Vec3::new(0.4, 0.8, 0.6);

/// Draws `frame` every way; checks the images, the draw calls and that the survivors hold
/// every visible meshlet. Returns the meshlets drawn after frustum and backface culling, after
/// occlusion culling too, with a visible fragment (the oracle), in all, and with a triangle
/// drawn by occlusion culling with the triangle pass.
fn check_frame(gpu: &Gpu, crowd: &GpuCrowd, frame: &CrowdFrame, what: &str) -> [usize; 5] {
    // Each way of drawing is compared with every meshlet drawn the same way (every instance
    // kept): lavapipe rasterizes a pixel here and there differently between one instanced
    // draw, a pulled draw and a multi-draw of the same triangles (a different vertex shader
    // or draw path, the same arithmetic).
    let keep = vec![CullMode::Keep; frame.modes.len()];
    let unculled = CrowdFrame { modes: &keep, ..*frame };
    let oracle = crowd.draw(gpu, frame, CrowdView::Ids, LIGHT).unwrap();
    let ties = oracle.ties.unwrap();
    let visible: HashSet<u32> = oracle.ids.unwrap().into_iter().filter(|&id| id != 0).map(|id| id - 1).collect();
    let visible_triangles: HashSet<u32> =
        oracle.triangle_ids.unwrap().into_iter().filter(|&id| id != 0).map(|id| id - 1).collect();
    let triangles = crowd.triangles();
    assert!(!visible.is_empty(), "{what}: nothing visible");
    // Occlusion culling twice: with the bits the crowd's last frame left, then with this
    // frame's.
    let mut views = vec![
        CrowdView::Pulled,
        CrowdView::Occluded,
        CrowdView::Occluded,
        CrowdView::Triangles,
        CrowdView::OccludedTriangles,
        CrowdView::OccludedTriangles,
    ];
    if gpu.has_indirect_count() {
        views.push(CrowdView::Indexed);
    } else if std::env::var("SKINLET_REQUIRE_GPU").is_ok_and(|v| v == "1") {
        panic!("the adapter lacks MULTI_DRAW_INDIRECT_COUNT: the indexed survivors' draw is not tested");
    }
    let (mut survivors, mut occluded, mut by_triangles) = (0, 0, 0);
    // Every meshlet drawn each way (pulled, indexed), once per frame.
    let mut references = std::collections::HashMap::new();
    for view in views {
        let same_way = if view == CrowdView::Indexed { view } else { CrowdView::Pulled };
        let reference = references
            .entry(same_way == CrowdView::Indexed)
            .or_insert_with(|| crowd.draw(gpu, &unculled, same_way, LIGHT).unwrap().image.unwrap());
        let drawn = crowd.draw(gpu, frame, view, LIGHT).unwrap();
        let listed: u32 = drawn.headers.iter().map(|h| h.found).sum();
        // One draw per list, the second's once per round.
        let draws = if drawn.headers.len() == 2 { 2 * crowd.occlusion_rounds() } else { 1 };
        assert_eq!(drawn.draw_calls, draws, "{what} {view:?}");
        let (a, b) = (&reference.rgba, &drawn.image.as_ref().unwrap().rgba);
        // Where two meshlets' nearest fragments tie in depth, draw order picks the color (and
        // the survivors' order is not the unculled draw's); elsewhere every pixel is equal.
        let differing: Vec<usize> = (0..ties.len()).filter(|&p| a[4 * p..4 * p + 4] != b[4 * p..4 * p + 4]).collect();
        let untied = differing.iter().filter(|&&p| !ties[p]).count();
        // The triangle views draw with another vertex shader than the ID view and the
        // reference, whose positions lavapipe may round apart: a near tie there can go either
        // way (every visible triangle is drawn: below). At most 1 pixel in 10,000.
        let allowed = if drawn.triangle_headers.is_empty() { 0 } else { ties.len() / 10_000 };
        assert!(
            untied <= allowed,
            "{what} {view:?}: {untied} pixels without a depth tie differ from the unculled image"
        );
        let list: HashSet<u32> = match drawn.triangle_headers.is_empty() {
            true => {
                let list: HashSet<u32> =
                    crowd.survivors(gpu).unwrap().iter().map(|&[i, m]| i * crowd.meshlets() + m).collect();
                assert_eq!(list.len(), listed as usize, "{what} {view:?}: survivors listed twice or past the capacity");
                list
            }
            false => {
                let drawn_triangles = crowd.drawn_triangles(gpu).unwrap();
                let list: HashSet<u32> =
                    drawn_triangles.iter().map(|t| t.instance * crowd.meshlets() + t.meshlet).collect();
                let listed: HashSet<u32> =
                    drawn_triangles.iter().map(|t| t.instance * triangles + t.triangle).collect();
                if let Some(missing) = visible_triangles.difference(&listed).next() {
                    panic!(
                        "{what} {view:?}: triangle {} of instance {} is visible and was culled",
                        missing % triangles,
                        missing / triangles
                    );
                }
                let headers = &drawn.triangle_headers;
                let meshlets: u32 = headers.iter().map(|h| h.meshlets).sum();
                assert_eq!(list.len(), meshlets as usize, "{what} {view:?}: meshlets with triangles, counted");
                assert_eq!(
                    drawn_triangles.len() as u32,
                    headers.iter().map(|h| h.found).sum::<u32>(),
                    "{what} {view:?}: triangles listed past the capacity"
                );
                list
            }
        };
        if let Some(missing) = visible.difference(&list).next() {
            panic!(
                "{what} {view:?}: meshlet {} of instance {} is visible and was culled",
                missing % crowd.meshlets(),
                missing / crowd.meshlets()
            );
        }
        if view == CrowdView::Pulled {
            survivors = list.len();
        }
        if view == CrowdView::Occluded {
            occluded = list.len();
        }
        if view == CrowdView::OccludedTriangles {
            by_triangles = list.len();
        }
    }
    [survivors, occluded, visible.len(), frame.modes.len() * crowd.meshlets() as usize, by_triangles]
}

/// The palettes and morph weights of `scene` at frame `f`, each instance playing its clip,
/// instance i standing where placement `order[i]` stands.
fn clip_pose(
    asset: &skinlet::Asset,
    baked: &skinlet::bake::Baked,
    scene: &skinlet_lab::crowd::Crowd,
    fps: f32,
    f: usize,
    order: &[usize],
) -> (Vec<Mat4>, Vec<f32>) {
    let (skin, clips) = (baked.palette(), &asset.clips);
    let mut poser = Poser::default();
    let (mut palette, mut weights, mut w) = (Vec::new(), Vec::new(), Vec::new());
    for &k in order {
        let pl = &scene.placements[k];
        let clip = clips.get(pl.clip);
        let t = pl.time(clip, f, fps);
        let globals = poser.globals(&asset.skeleton, clip, t);
        let (mut joints, mut skinning) = (Vec::new(), Vec::new());
        pl.world_matrices(&skin, globals, &mut joints, &mut skinning);
        palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
        baked.mesh.morphs.weights_at(clip, t, &mut w);
        weights.extend(&w);
    }
    (palette, weights)
}

#[test]
fn survivors_draw_the_unculled_image_and_hold_every_visible_meshlet() {
    let Some(gpu) = gpu() else { return };
    let mut all = assets();
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    all.push(("demo".into(), demo));
    let mut totals = [0usize; 5];
    for (name, asset) in all {
        let character = asset.character().unwrap();
        let baked = bake(&asset, &character);
        let skin = baked.palette();
        let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
        let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
        let params = CrowdParams { instances: 24, frames: 2, ..Default::default() };
        let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
        let crowd = GpuCrowd::new(&gpu, &baked, &culler, 24, 320, 180).unwrap();
        let in_place: Vec<usize> = (0..scene.placements.len()).collect();
        for f in 0..params.frames {
            let (palette, weights) = clip_pose(&asset, &baked, &scene, params.fps, f, &in_place);
            let modes = vec![CullMode::Bounds; scene.placements.len()];
            for tests in [Tests::Both, Tests::Frustum] {
                let frame = CrowdFrame {
                    palette: &palette,
                    modes: &modes,
                    weights: &weights,
                    lod_thresholds: &[],
                    camera: &scene.camera,
                    tests,
                };
                let counts = check_frame(&gpu, &crowd, &frame, &format!("{name} frame {f} {tests:?}"));
                totals.iter_mut().zip(counts).for_each(|(t, c)| *t += c);
            }
        }
    }
    let [drawn, occluded, visible, meshlets, by_triangles] = totals;
    eprintln!(
        "{meshlets} (instance, meshlet) pairs: {drawn} drawn, {occluded} with occlusion culling, {by_triangles} with \
         a triangle drawn by it and the triangle pass, {visible} with a visible fragment"
    );
    assert!(drawn < meshlets, "nothing was culled: the comparison would be vacuous");
}

#[test]
fn game_poses_under_the_pose_guard_draw_every_visible_meshlet() {
    // IK poses (some joints beyond their range of motion): per instance the pose guard picks
    // the envelope bounds with the any-pose boxes, or the boxes alone; one instance is drawn
    // whole (as when its morph weights leave their ranges).
    let Some(gpu) = gpu() else { return };
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let mut baked = bake(&demo, &demo.character().unwrap());
    let clips: Vec<&skinlet::clip::Clip> = demo.clips.iter().collect();
    let skin = baked.palette();
    let envelope =
        skinlet::bounds::envelope::Envelope::from_clips(&demo.skeleton, &skin, &baked.mesh, &clips, 0.2).unwrap();
    skinlet::bake::add_envelope(&mut baked, &demo, envelope).unwrap();
    let e = baked.envelope.as_ref().unwrap();
    let guard = e.envelope.guard().unwrap();
    let culler =
        MeshletCuller::new(&e.bounds, &e.classes, skin.joints.len()).unwrap().with_any_pose(&e.any_pose).unwrap();
    let params = CrowdParams { instances: 16, animation: Animation::Ik, seed: 3, ..Default::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let crowd = GpuCrowd::new(&gpu, &baked, &culler, 16, 320, 180).unwrap();
    let (mut palette, mut weights, mut modes) = (Vec::new(), Vec::new(), Vec::new());
    let (mut locals, mut w, mut globals) = (Vec::new(), Vec::new(), Vec::new());
    for (i, pl) in scene.placements.iter().enumerate() {
        instance_pose(&demo.skeleton, &clips, &baked, &params, i, pl, 0, &mut locals, &mut w);
        skinlet::pose::global_transforms(&demo.skeleton, &locals, &mut globals);
        let (mut joints, mut skinning) = (Vec::new(), Vec::new());
        pl.world_matrices(&skin, &globals, &mut joints, &mut skinning);
        palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
        modes.push(match (i, guard.admits(&locals, &w)) {
            (5, _) => CullMode::Keep,
            (_, true) => CullMode::BoundsAndBoxes,
            (_, false) => CullMode::BoxesOnly,
        });
        weights.extend(&w);
    }
    let refused = modes.iter().filter(|&&m| m == CullMode::BoxesOnly).count();
    assert!(refused > 0 && refused < 15, "the guard refused {refused} of 16 instances");
    let frame = CrowdFrame {
        palette: &palette,
        modes: &modes,
        weights: &weights,
        lod_thresholds: &[],
        camera: &scene.camera,
        tests: Tests::Both,
    };
    let [drawn, _, _, meshlets, _] = check_frame(&gpu, &crowd, &frame, "IK poses");
    assert!(drawn < meshlets, "nothing was culled");
}

#[test]
fn occlusion_culling_misses_nothing_when_the_camera_cuts_or_the_crowd_teleports() {
    // A dense crowd seen from street level: the first rows hide most of the rest. The camera
    // walks up to the first row, through it (what it hid is visible at once), cuts back and to
    // the side; then the crowd's instances swap places. Every frame: the image equals the
    // unculled one and every visible meshlet is drawn (check_frame), whatever the visibility
    // bits of the frame before. With a forward depth range in one round,
    // and with Bevy's infinite reverse-Z (the pyramid then keeps the nearest depth) and 5 rounds
    // (the other tests: GpuCrowd::new's).
    let Some(gpu) = gpu() else { return };
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let baked = bake(&demo, &demo.character().unwrap());
    let skin = baked.palette();
    let clips: Vec<&skinlet::clip::Clip> = demo.clips.iter().collect();
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len()).unwrap();
    let params = CrowdParams { instances: 64, layout: Layout::Dense, ..Default::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    let (lo, hi) =
        (baked.mesh.positions.iter()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| (l.min(*p), h.max(*p)));
    let size = ((hi - lo).length() / 2.0).max(1e-6);
    let modes = vec![CullMode::Bounds; scene.placements.len()];
    let pose = |f: usize, order: &[usize]| clip_pose(&demo, &baked, &scene, params.fps, f, order);
    let in_place: Vec<usize> = (0..scene.placements.len()).collect();
    for (reversed, rounds) in [(false, 1), (true, 5)] {
        let crowd = GpuCrowd::with_depth_range(&gpu, &baked, &culler, 64, 320, 180, reversed, rounds, None).unwrap();
        let camera = |eye: Vec3, forward: Vec3| {
            let (fov, aspect) = (50f32.to_radians(), 16.0 / 9.0);
            if reversed {
                let view_proj = Mat4::perspective_infinite_reverse_rh(fov, aspect, 0.05 * size)
                    * Mat4::look_to_rh(eye, forward, Vec3::Y);
                Camera::from_view_proj(view_proj, Projection::Perspective { eye }).unwrap()
            } else {
                Camera::perspective(eye, eye + forward, Vec3::Y, fov, aspect, 0.05 * size, 80.0 * size).unwrap()
            }
        };
        let z = |depth: f32| Vec3::new(0.0, 0.0, -depth * size);
        let walk = [
            camera(z(0.0), Vec3::NEG_Z),
            camera(z(1.5), Vec3::NEG_Z),
            camera(z(2.8), Vec3::NEG_Z),
            camera(z(3.3), Vec3::NEG_Z), // inside the first row
            camera(z(4.0), Vec3::NEG_Z), // past it: what it hid, visible at once
            camera(z(0.0), Vec3::NEG_Z), // a cut back
            camera(Vec3::new(30.0 * size, 0.0, -20.0 * size), Vec3::NEG_X), // a cut to the side
        ];
        let (mut culled_by_occlusion, mut checked) = (0, 0);
        for (f, cam) in walk.iter().enumerate() {
            let (palette, weights) = pose(f, &in_place);
            let frame = CrowdFrame {
                palette: &palette,
                modes: &modes,
                weights: &weights,
                lod_thresholds: &[],
                camera: cam,
                tests: Tests::Both,
            };
            let [drawn, occluded, ..] =
                check_frame(&gpu, &crowd, &frame, &format!("reversed {reversed}: walk frame {f}"));
            culled_by_occlusion += drawn - occluded;
            checked += 1;
        }
        // The crowd teleports: every instance moves to another's place (the bits describe where it
        // stood), twice.
        for (k, shift) in [7, 31].into_iter().enumerate() {
            let order: Vec<usize> = (0..scene.placements.len()).map(|i| (i + shift) % scene.placements.len()).collect();
            let (palette, weights) = pose(10 + k, &order);
            let frame = CrowdFrame {
                palette: &palette,
                modes: &modes,
                weights: &weights,
                lod_thresholds: &[],
                camera: &walk[0],
                tests: Tests::Both,
            };
            let [drawn, occluded, ..] =
                check_frame(&gpu, &crowd, &frame, &format!("reversed {reversed}: teleport {k}"));
            culled_by_occlusion += drawn - occluded;
            checked += 1;
        }
        eprintln!(
            "reversed {reversed}, {checked} frames: occlusion culled {culled_by_occlusion} meshlets the frustum and \
         backface tests kept"
        );
        assert!(culled_by_occlusion > 0, "reversed {reversed}: occlusion culled nothing: the test would be vacuous");
    }
}

/// Cluster LOD in the GPU-driven crowd (the demo's hierarchy, a dense crowd): every survivor
/// is a cluster of its instance's CPU cut (`LodView::cut` at the threshold `CrowdLod` gives
/// it), coarse clusters are drawn and fewer triangles than at full detail, the silhouettes
/// against the background move by at most the pixels asked for plus half a pixel's diagonal
/// (rasterization at pixel centers), and two-phase occlusion culling covers the same pixels
/// with a subset of the survivors.
#[test]
fn lod_crowd_draws_cuts_whose_silhouettes_stay_within_the_pixels() {
    lod_crowd(false);
}

/// The same with every instance posed inside the pose envelope (10° around the clips, half
/// the poses on its boundary: what crossfades, additive layers and IK reach), drawing the cuts
/// of the errors within it (`LodView::envelope`) culled with its bounds
/// (`BakeView::lod_envelope_culler`).
#[test]
fn lod_crowd_within_the_envelope_draws_cuts_whose_silhouettes_stay_within_the_pixels() {
    lod_crowd(true);
}

fn lod_crowd(within_envelope: bool) {
    let Some(gpu) = gpu() else { return };
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 4000, ..Default::default() });
    let mut baked = bake(&demo, &demo.character().unwrap());
    let clips: Vec<&skinlet::clip::Clip> = demo.clips.iter().collect();
    if within_envelope {
        let margin = 10f64.to_radians();
        let envelope = Envelope::from_clips(&demo.skeleton, &baked.palette(), &baked.mesh, &clips, margin).unwrap();
        skinlet::bake::add_envelope(&mut baked, &demo, envelope).unwrap();
    }
    skinlet::bake::add_lod(&mut baked, &demo, &skinlet::meshlet::lod::LodParams::default()).unwrap();
    let skin = baked.palette();
    let params = CrowdParams { instances: 64, layout: Layout::Dense, ..Default::default() };
    let scene = crowd(&baked.mesh.positions, clips.len(), &params).unwrap();
    // Within the envelope, errors are larger (it holds every pose around the clips): a coarser
    // threshold draws visible coarse clusters there too.
    let (width, height, pixels) = (640, 360, if within_envelope { 4.0 } else { 2.0 });
    // Poses inside the envelope, one per instance.
    let inside = baked.envelope.as_ref().map(|e| e.envelope.sample_poses(&demo.skeleton, scene.placements.len(), 3));
    let guard = baked.envelope.as_ref().map(|e| e.envelope.guard().unwrap());
    let (mut palette, mut weights, mut poser, mut globals) = (Vec::new(), Vec::new(), Poser::default(), Vec::new());
    let (culler, errors, thresholds, cuts) = skinlet::bake::with_view(&baked, |view| {
        let lod = if within_envelope { view.lod().unwrap().envelope().unwrap() } else { *view.lod().unwrap() };
        let crowd_lod = CrowdLod::new(view, &scene.camera, width, height)?;
        let (mut thresholds, mut cuts, mut w) = (Vec::new(), Vec::new(), Vec::new());
        for (i, pl) in scene.placements.iter().enumerate() {
            let clip = clips.get(pl.clip).copied();
            let t = pl.time(clip, 0, params.fps);
            let pose = match (&inside, clip) {
                (Some(inside), _) => {
                    let (locals, pose_weights) = &inside[i];
                    assert!(guard.as_ref().unwrap().admits(locals, pose_weights), "a pose inside the envelope");
                    skinlet::pose::global_transforms(&demo.skeleton, locals, &mut globals);
                    w.clone_from(pose_weights);
                    PoseBounds::Envelope
                }
                (None, clip) => {
                    globals = poser.globals(&demo.skeleton, clip, t).to_vec();
                    baked.mesh.morphs.weights_at(clip, t, &mut w);
                    match clip {
                        Some(_) => PoseBounds::ClipAt { clip: pl.clip as u32, time: t },
                        None => PoseBounds::Clips,
                    }
                }
            };
            let (mut joints, mut skinning) = (Vec::new(), Vec::new());
            pl.world_matrices(&skin, &globals, &mut joints, &mut skinning);
            palette.extend(skinning.iter().map(|&m| Mat4::from(m)));
            weights.extend(&w);
            let threshold = crowd_lod.threshold(pixels, &joints, &w, pose);
            let mut cut = Vec::new();
            lod.cut(threshold, &mut cut);
            thresholds.push(threshold);
            cuts.push(cut.into_iter().collect::<HashSet<u32>>());
        }
        let culler = if within_envelope { view.lod_envelope_culler()? } else { view.lod_culler()? };
        Ok((culler.unwrap(), lod.errors(), thresholds, cuts))
    })
    .unwrap();
    let n = scene.placements.len();
    let crowd =
        GpuCrowd::with_depth_range(&gpu, &baked, &culler, n as u32, width, height, false, 4, Some(&errors)).unwrap();
    let modes = vec![CullMode::Bounds; n];
    let frame = |lod: bool| CrowdFrame {
        palette: &palette,
        modes: &modes,
        weights: &weights,
        lod_thresholds: if lod { &thresholds } else { &[] },
        camera: &scene.camera,
        tests: Tests::Both,
    };
    let base = baked.meshlets.len() as u32;
    let triangles = |survivors: &[[u32; 2]]| -> usize {
        let all = [&baked.meshlets.meshlets[..], &baked.lod.as_ref().unwrap().meshlets.meshlets[..]].concat();
        survivors.iter().map(|&[_, m]| all[m as usize].triangle_count as usize).sum()
    };
    // Draws a view of the frame; its survivors and coverage (from depth: cleared to 1).
    let drawn = |lod: bool, view: CrowdView| {
        crowd.draw(&gpu, &frame(lod), view, LIGHT).unwrap();
        let covered: Vec<bool> = crowd.depth(&gpu).unwrap().iter().map(|&z| z < 1.0).collect();
        (crowd.survivors(&gpu).unwrap(), covered)
    };
    let (full, full_covered) = drawn(false, CrowdView::Pulled);
    let (cut, cut_covered) = drawn(true, CrowdView::Pulled);
    assert!(full.iter().all(|&[_, m]| m < base), "full detail drew a coarse cluster");
    for &[i, m] in &cut {
        assert!(cuts[i as usize].contains(&m), "instance {i} drew cluster {m}, not in its cut");
    }
    let coarse = cut.iter().filter(|&&[_, m]| m >= base).count();
    assert!(coarse > 0 && triangles(&cut) < triangles(&full), "{coarse} coarse clusters drawn");
    // Coloured by level: the same pixels covered, some of them by coarse (coloured) clusters.
    let by_level = crowd.draw(&gpu, &frame(true), CrowdView::PulledByLevel, LIGHT).unwrap().image.unwrap();
    let by_level_covered: Vec<bool> = crowd.depth(&gpu).unwrap().iter().map(|&z| z < 1.0).collect();
    assert!(by_level_covered == cut_covered);
    assert!(by_level.rgba.chunks(4).zip(&cut_covered).any(|(p, &c)| c && (p[0] != p[1] || p[1] != p[2])));
    let moved = silhouette_displacement(&full_covered, &cut_covered, width as usize, height as usize);
    assert!(moved <= pixels + std::f32::consts::FRAC_1_SQRT_2, "silhouettes moved {moved} px");
    // Occlusion culling, twice (the second frame with the first's visibility bits).
    drawn(true, CrowdView::Occluded);
    let (occluded, occluded_covered) = drawn(true, CrowdView::Occluded);
    let pulled: HashSet<[u32; 2]> = cut.iter().copied().collect();
    assert!(occluded.iter().all(|s| pulled.contains(s)) && occluded.len() < cut.len());
    assert!(occluded_covered == cut_covered, "occlusion culling changed the covered pixels");
    eprintln!(
        "LOD at {pixels} px (within the envelope: {within_envelope}): {} of {} triangles drawn ({coarse} coarse clusters), {} survivors with occlusion \
         culling; silhouettes moved up to {moved:.2} px",
        triangles(&cut),
        triangles(&full),
        occluded.len()
    );
}
