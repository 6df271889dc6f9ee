//! Bevy as the oracle for `SkinletMeshletPlugin` (headless, Bevy's renderer on the machine's
//! Vulkan device: lavapipe on CPU-only machines): the same animated crowd (one row textured),
//! same frame, under a light casting shadows onto the characters and a ground plane (two
//! instances' parts marked `NotShadowCaster`), drawn by Bevy's own skinned mesh pipeline and
//! by skinlet's meshlet draw (GPU culling on). The tolerance: Bevy skins in its own order
//! (joint matrices blended after its own product with the inverse binds), so positions and
//! normals round apart by a few ulps: interior pixels shade within 2 levels of 255, and a
//! silhouette pixel whose center a triangle edge nearly touches may flip coverage (then any
//! color): at most 1 in 200 of the pixels the characters and their shadows change differs by
//! more than 2 levels. skinlet's image with culling on equals its image with culling off
//! exactly; given back to Bevy, the frame is Bevy's again. With a depth and normal prepass on
//! the camera, a quad in front of it showing the prepass textures (Bevy's `prepass_utils`)
//! shows the same for both, within the same tolerance.

mod common;

use bevy::prelude::*;
use bevy_skinlet::{
    SkinletDrawnPart, SkinletInstance, SkinletMeshletPlugin, SkinletMeshletSettings, SkinletMeshletStats,
    SkinletMeshlets,
};
use common::{app, asset_folder, settled_image, update_until};

/// Shows the camera's prepass: world normal (x, y) and depth (× `scale.x`) as colors, or
/// where `scale.w` is 1 its motion vectors (× `scale.x`, 0 at 0.5) and depth.
#[derive(Asset, TypePath, bevy::render::render_resource::AsBindGroup, Clone)]
struct ShowPrepass {
    #[uniform(0)]
    scale: Vec4,
}

impl Material for ShowPrepass {
    fn fragment_shader() -> bevy::shader::ShaderRef {
        "show_prepass.wgsl".into()
    }

    fn enable_prepass() -> bool {
        false
    }
}

const SHOW_PREPASS_WGSL: &str = "
#import bevy_pbr::{prepass_utils, forward_io::VertexOutput}
@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<uniform> scale: vec4<f32>;
@fragment
fn fragment(mesh: VertexOutput) -> @location(0) vec4<f32> {
    if scale.w == 1.0 {
        let m = prepass_utils::prepass_motion_vector(mesh.position, 0u);
        let d = prepass_utils::prepass_depth(mesh.position, 0u);
        return vec4(m * scale.x + vec2(0.5), d * scale.x, 1.0);
    }
    let n = prepass_utils::prepass_normal(mesh.position, 0u);
    let d = prepass_utils::prepass_depth(mesh.position, 0u);
    return vec4(n.xy * 0.5 + vec2(0.5), d * scale.x, 1.0);
}
";

/// The counts of a frame after the image settled, for each of `bakes` (they are read back
/// when the GPU is done, not every frame).
fn latest_stats_after(
    app: &mut App,
    bakes: usize,
) -> bevy::platform::collections::HashMap<AssetId<bevy_skinlet::Bake>, bevy_skinlet::MeshletStats> {
    let settled = app.world().resource::<SkinletMeshletStats>().latest().values().map(|s| s.frame).max();
    update_until(app, 300, "counts of a frame after the image settled", |w| {
        let stats = w.resource::<SkinletMeshletStats>().latest();
        stats.len() == bakes && stats.values().all(|s| Some(s.frame) > settled)
    });
    app.world().resource::<SkinletMeshletStats>().latest()
}

const WIDTH: u32 = 256;
const HEIGHT: u32 = 160;

/// How many pixels of skinlet's frame differ from Bevy's by more than 2 levels; both frames
/// and their difference (× 8) side by side go to `name`.png in the target's temporary folder.
fn over_2_levels(bevy: &[u8], skinlet: &[u8], name: &str) -> usize {
    let per_pixel = common::pixel_differences(bevy, skinlet);
    let side = common::side_by_side(&[bevy, skinlet, &common::difference_image(&per_pixel)], WIDTH);
    common::write_png(&std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}.png")), &side, 3 * WIDTH);
    per_pixel.iter().filter(|&&d| d > 2).count()
}

#[test]
fn skinlets_meshlet_draw_looks_like_bevys_own() {
    if !common::vulkan_available() {
        return;
    }
    let files = ["skinned/Fox.glb", "skinned/Xbot.glb", "skinned/BrainStem.glb", "@demo"];
    let Some((dir, characters)) = asset_folder("meshlet_draw", &files) else { return };
    std::fs::write(dir.join("show_prepass.wgsl"), SHOW_PREPASS_WGSL).unwrap();
    let mut app = app(&dir, true);
    app.add_plugins((SkinletMeshletPlugin, MaterialPlugin::<ShowPrepass>::default()));
    common::watch_pipelines(&mut app);
    // Four rows, one character each (the Fox is textured); the camera sees part of each row,
    // the others are beside or behind it (culled).
    let roots = common::spawn_rows(app.world_mut(), &characters, &[1.2, 0.0, -2.2, -4.4], 5);
    let at = Transform::from_xyz(0.0, 1.2, 4.0).looking_at(Vec3::new(0.0, 0.8, -1.0), Vec3::Y);
    let camera = common::readback_camera(app.world_mut(), WIDTH, HEIGHT, at);
    // The light casts shadows onto a ground plane (a Bevy mesh) and the characters.
    {
        let world = app.world_mut();
        for mut light in world.query::<&mut DirectionalLight>().iter_mut(world) {
            light.shadow_maps_enabled = true;
        }
        let ground = world.resource_mut::<Assets<Mesh>>().add(Plane3d::default().mesh().size(24.0, 24.0));
        let gray = world.resource_mut::<Assets<StandardMaterial>>().add(Color::srgb(0.6, 0.6, 0.6));
        world.spawn((Mesh3d(ground), MeshMaterial3d(gray)));
    }
    update_until(&mut app, 3000, "every instance bound", |w| {
        roots.iter().all(|&(e, _)| w.get::<SkinletInstance>(e).is_some())
    });
    // The middle Fox and the middle Xbot cast no shadow (Bevy reads the marker on each mesh
    // entity).
    for &(root, _) in [roots[2], roots[7]].iter() {
        let parts = app.world().get::<SkinletInstance>(root).unwrap().part_entities().to_vec();
        for e in parts {
            app.world_mut().entity_mut(e).insert(bevy::light::NotShadowCaster);
        }
    }
    for (i, &(root, c)) in roots.iter().enumerate() {
        common::play_clips(app.world_mut(), root, &characters[c], |nodes| vec![(nodes[i % nodes.len()], 1.0)]);
    }
    for _ in 0..25 {
        app.update();
    }
    app.world_mut().resource_mut::<Time<Virtual>>().pause();

    let bevy = settled_image(&mut app);
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(SkinletMeshlets);
    }
    let skinlet = settled_image(&mut app);
    // The counts read back: every bake drawn in one draw, culled, no list overflow.
    let stats = latest_stats_after(&mut app, characters.len());
    assert_eq!(stats.len(), characters.len());
    for s in stats.values() {
        eprintln!("{s:?}");
        assert!(s.culled && s.instances == 5 && s.triangles_dropped == 0, "{s:?}");
        assert!(0 < s.meshlets_drawn && s.meshlets_drawn <= s.meshlets_tested_visible, "{s:?}");
        assert!(s.meshlets_tested_visible <= s.meshlets_total && s.triangles_drawn < s.triangles_total, "{s:?}");
        // Each of the light's cascades culls its own list.
        assert!(s.shadow_views > 0 && s.shadow_triangles_drawn < s.shadow_triangles_total, "{s:?}");
    }
    let tested: u64 = stats.values().map(|s| s.meshlets_tested_visible).sum();
    assert!(tested < stats.values().map(|s| s.meshlets_total).sum(), "no meshlet culled");
    let drawn_without_occlusion: u64 = stats.values().map(|s| s.meshlets_drawn).sum();
    // Occlusion culling among the characters (3 rounds over each bake's 5 instances): the
    // rows behind are partly hidden by the rows in front.
    app.world_mut().resource_mut::<SkinletMeshletSettings>().occlusion_rounds = 3;
    let occluded = settled_image(&mut app);
    let stats = latest_stats_after(&mut app, characters.len());
    for s in stats.values() {
        eprintln!("occlusion culling: {s:?}");
        assert!(s.culled && s.occlusion_rounds == 3 && s.triangles_dropped == 0, "{s:?}");
        assert!(s.meshlets_drawn <= s.meshlets_tested_visible, "{s:?}");
    }
    let drawn_with_occlusion: u64 = stats.values().map(|s| s.meshlets_drawn).sum();
    assert!(
        drawn_with_occlusion < drawn_without_occlusion,
        "occlusion culling drew {drawn_with_occlusion} meshlets, {drawn_without_occlusion} without it"
    );
    // The same on a camera with 4× MSAA (occlusion culling tests any point of a pixel against
    // its farthest sample): equal to its own unculled image.
    app.world_mut().entity_mut(camera).insert(Msaa::Sample4);
    let drawn_msaa = [0, 3].map(|rounds| {
        app.world_mut().resource_mut::<SkinletMeshletSettings>().occlusion_rounds = rounds;
        settled_image(&mut app);
        let stats = latest_stats_after(&mut app, characters.len());
        assert!(stats.values().all(|s| s.culled && s.occlusion_rounds == rounds), "{stats:?}");
        stats.values().map(|s| s.meshlets_drawn).sum::<u64>()
    });
    let occluded_msaa = settled_image(&mut app);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = false;
    let unculled_msaa = settled_image(&mut app);
    let differing = common::differing_pixels(&occluded_msaa, &unculled_msaa);
    let [without, with] = drawn_msaa;
    eprintln!("4× MSAA: {with} meshlets drawn with occlusion culling, {without} without; {differing} pixels differ");
    assert_eq!(differing, 0, "with 4× MSAA, occlusion culling changed {differing} pixels");
    assert!(with < without, "with 4× MSAA, occlusion culling drew {with} meshlets, {without} without it");
    app.world_mut().entity_mut(camera).insert(Msaa::Off);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().occlusion_rounds = 0;
    let unculled = settled_image(&mut app);
    let taken = {
        let world = app.world_mut();
        world.query::<&SkinletDrawnPart>().iter(world).count()
    };
    // Unmarked, the instances are Bevy's again: its own frame, exactly.
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).remove::<SkinletMeshlets>();
    }
    let given_back = settled_image(&mut app);
    let left = app.world_mut().query::<&SkinletDrawnPart>().iter(app.world()).count();
    assert_eq!(left, 0, "parts still taken over after the marker was removed");
    assert!(given_back == bevy, "Bevy's frame after the instances were given back differs from its first");
    // Where the characters and their shadows are: what differs from the frame without them.
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(Visibility::Hidden);
    }
    let empty = settled_image(&mut app);
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    common::write_png(&out.join("meshlet_draw_bevy.png"), &bevy, WIDTH);
    common::write_png(&out.join("meshlet_draw_skinlet.png"), &skinlet, WIDTH);
    common::write_png(&out.join("meshlet_draw_skinlet_unculled.png"), &unculled, WIDTH);
    let culled_away = common::differing_pixels(&skinlet, &unculled);
    let occluded_away = common::differing_pixels(&occluded, &unculled);
    let per_pixel = common::pixel_differences(&bevy, &skinlet);
    let diff = common::difference_image(&per_pixel);
    common::write_png(&out.join("meshlet_draw_diff.png"), &diff, WIDTH);
    // Bevy's frame, skinlet's, and their difference (× 8) side by side.
    let side = common::side_by_side(&[&bevy, &skinlet, &diff], WIDTH);
    common::write_png(&out.join("meshlet_draw_side_by_side.png"), &side, 3 * WIDTH);
    let drawn = common::differing_pixels(&bevy, &empty);
    let differing = per_pixel.iter().filter(|&&d| d > 0).count();
    let large = per_pixel.iter().filter(|&&d| d > 2).count();
    eprintln!(
        "{taken} parts drawn by skinlet; {drawn} pixels show characters or their shadows; {differing} differ, {large} by more than 2, at most {} (images in {}); culled and unculled differ at {culled_away}",
        per_pixel.iter().max().unwrap(),
        out.display()
    );
    assert!(taken > 0 && drawn > (WIDTH * HEIGHT / 20) as usize);
    assert_eq!(culled_away, 0, "skinlet's culling changed {culled_away} pixels");
    assert_eq!(occluded_away, 0, "skinlet's occlusion culling changed {occluded_away} pixels");
    assert!(large * 200 < drawn, "{large} of {drawn} pixels differ by more than 2 levels");

    // The prepass: a depth and normal prepass on the camera, shown by a quad just in front of
    // it (not in the prepass itself); without the characters, with Bevy's, with skinlet's.
    let quad = {
        let world = app.world_mut();
        // (Motion vectors too: skinlet writes none, but its pipeline must fit the pass.)
        use bevy::core_pipeline::prepass::{DepthPrepass, MotionVectorPrepass, NormalPrepass};
        world.entity_mut(camera).insert((DepthPrepass, NormalPrepass, MotionVectorPrepass));
        let mesh = world.resource_mut::<Assets<Mesh>>().add(Rectangle::new(4.0, 4.0));
        let material =
            world.resource_mut::<Assets<ShowPrepass>>().add(ShowPrepass { scale: Vec4::new(8.0, 0.0, 0.0, 0.0) });
        let quad = (Mesh3d(mesh), MeshMaterial3d(material), Transform::from_xyz(0.0, 0.0, -0.5));
        world.spawn((quad, bevy::light::NotShadowCaster, ChildOf(camera))).id()
    };
    let empty_prepass = settled_image(&mut app);
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(Visibility::Inherited);
    }
    let bevy_prepass = settled_image(&mut app);
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(SkinletMeshlets);
    }
    let skinlet_prepass = settled_image(&mut app);
    assert!(app.world().get_entity(quad).is_ok());
    let large = over_2_levels(&bevy_prepass, &skinlet_prepass, "meshlet_draw_prepass_side_by_side");
    let drawn = common::differing_pixels(&bevy_prepass, &empty_prepass);
    eprintln!("prepass: {drawn} pixels show characters; {large} differ by more than 2 levels");
    assert!(drawn > (WIDTH * HEIGHT / 20) as usize, "the prepass shows no characters: {drawn} pixels");
    assert!(large * 200 < drawn, "prepass: {large} of {drawn} pixels differ by more than 2 levels");
}

/// Close to the face of the demo with materials (`common::demo_with_materials`): a
/// double-sided normal-mapped body with turned triangles (drawn, normals reversed), single-sided
/// parts with turned triangles (holes), every morph weight at 1 (the mouth's target moves
/// normals too), parts hidden by their nodes, a light casting shadows: Bevy's frame and skinlet's within the tolerance of
/// the crowd test, skinlet's culled equal to its unculled, also with a second camera (each
/// camera's image). Then the motion vectors (a quad in front of the camera shows them): the
/// frame right after an instance moved, Bevy's and skinlet's.
#[test]
fn double_sided_normal_mapped_morphed_parts_look_like_bevys() {
    if !common::vulkan_available() {
        return;
    }
    let Some((dir, characters)) = asset_folder("meshlet_materials", &["@demo-materials"]) else { return };
    std::fs::write(dir.join("show_prepass.wgsl"), SHOW_PREPASS_WGSL).unwrap();
    let mut app = app(&dir, true);
    app.add_plugins((SkinletMeshletPlugin, MaterialPlugin::<ShowPrepass>::default()));
    common::watch_pipelines(&mut app);
    let roots = common::spawn_rows(app.world_mut(), &characters, &[0.0], 3);
    let camera = common::readback_camera(app.world_mut(), WIDTH, HEIGHT, Transform::default());
    for mut light in app.world_mut().query::<&mut DirectionalLight>().iter_mut(app.world_mut()) {
        light.shadow_maps_enabled = true;
    }
    update_until(&mut app, 3000, "every instance bound", |w| {
        roots.iter().all(|&(e, _)| w.get::<SkinletInstance>(e).is_some())
    });
    let (root, _) = roots[1];
    let nodes = common::node_entities(app.world_mut(), root);
    let descendants: Vec<Entity> =
        app.world_mut().query::<&Children>().query(app.world()).iter_descendants(root).collect();
    let set_weights = |app: &mut App, w: f32| {
        for &e in &descendants {
            if let Some(mut weights) = app.world_mut().get_mut::<bevy::mesh::morph::MorphWeights>(e) {
                weights.weights_mut().fill(w);
            }
        }
    };
    set_weights(&mut app, 1.0);
    // Parts hidden by their nodes (Bevy hides their meshes, so must skinlet): this instance's
    // collar and propeller, its neighbours' bodies.
    let node_of = |name: &str| characters[0].asset.skeleton.nodes.iter().position(|n| n.name == name).unwrap();
    for (root, name) in [(root, "collar"), (root, "propeller"), (roots[0].0, "body"), (roots[2].0, "body")] {
        let node = common::node_entities(app.world_mut(), root)[node_of(name)].unwrap();
        app.world_mut().entity_mut(node).insert(Visibility::Hidden);
    }
    for _ in 0..5 {
        app.update();
    }
    // In front of the face: from the head joint through the middle of the eyes.
    let at = |name: &str| {
        let node = characters[0].asset.skeleton.nodes.iter().position(|n| n.name == name).unwrap();
        app.world().get::<GlobalTransform>(nodes[node].unwrap()).unwrap().translation()
    };
    let (head, eyes) = (at("head"), (at("eye_l") + at("eye_r")) / 2.0);
    let eye = eyes + (eyes - head).normalize() * 1.2 + Vec3::Y * 0.3;
    app.world_mut().entity_mut(camera).insert(Transform::from_translation(eye).looking_at(head, Vec3::Y));
    let bevy = settled_image(&mut app);
    // Every list (the camera's, each shadow cascade's, the second camera's below) starts with
    // room for 64 triangles: each must grow to what its culling finds.
    app.world_mut().resource_mut::<SkinletMeshletSettings>().list_triangles = 64;
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(SkinletMeshlets);
    }
    update_until(&mut app, 300, "the lists grown", |w| {
        let stats = w.resource::<SkinletMeshletStats>().latest();
        stats.values().any(|s| s.culled && s.triangles_dropped == 0 && s.list_triangles > 64)
    });
    let skinlet = settled_image(&mut app);
    let stats = latest_stats_after(&mut app, 1);
    for s in stats.values() {
        eprintln!("{s:?}");
        assert!(
            s.triangles_dropped == 0 && s.triangles_drawn > 64 && s.list_triangles >= s.triangles_drawn as u32,
            "{s:?}"
        );
    }
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = false;
    let unculled = settled_image(&mut app);
    let drawn = common::drawn_pixels(&bevy);
    let large = over_2_levels(&bevy, &skinlet, "meshlet_materials_side_by_side");
    let culled_away = common::differing_pixels(&skinlet, &unculled);
    eprintln!(
        "{drawn} pixels drawn; {large} differ by more than 2 levels; culled and unculled differ at {culled_away}"
    );
    assert!(drawn > (WIDTH * HEIGHT / 8) as usize, "the close up shows too little: {drawn} pixels");
    assert!(large * 200 < drawn, "{large} of {drawn} pixels differ by more than 2 levels");
    assert_eq!(culled_away, 0, "skinlet's culling changed {culled_away} pixels");

    // A second camera, looking from elsewhere with 4× MSAA (each camera culls its own list):
    // each camera's image with culling on equals its image with culling off.
    let second = common::Frames::default();
    let at = Transform::from_translation(eye + Vec3::new(1.5, 1.0, 0.5)).looking_at(head, Vec3::Y);
    let other = common::camera_read_into(app.world_mut(), WIDTH, HEIGHT, at, second.clone());
    app.world_mut().entity_mut(other).insert((Camera { order: 1, ..default() }, Msaa::Sample4));
    let images = [true, false].map(|culling| {
        app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = culling;
        let first = settled_image(&mut app);
        // (And the second camera's last three images equal: its list has grown.)
        update_until(&mut app, 300, "the second camera's image settled", |_| {
            let images = second.0.lock().unwrap();
            matches!(&images[..], [.., a, b, c] if a == b && b == c)
        });
        let last = second.0.lock().unwrap().last().unwrap().clone();
        (first, last)
    });
    let [(first_culled, second_culled), (first_unculled, second_unculled)] = &images;
    let differ = common::differing_pixels;
    let (first_away, second_away) = (differ(first_culled, first_unculled), differ(second_culled, second_unculled));
    eprintln!("two cameras: culled and unculled differ at {first_away} and {second_away} pixels");
    assert_eq!((first_away, second_away), (0, 0), "with two cameras, culling changed pixels");
    assert!(common::drawn_pixels(second_culled) > 1000 && differ(first_culled, second_culled) > 1000);
    app.world_mut().entity_mut(other).despawn();

    // Motion vectors: depth and motion vector prepasses on the camera, a quad just in front of
    // it showing the motion vectors.
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = true;
    let shown = {
        use bevy::core_pipeline::prepass::{DepthPrepass, MotionVectorPrepass, NormalPrepass};
        let world = app.world_mut();
        world.entity_mut(camera).insert((DepthPrepass, NormalPrepass, MotionVectorPrepass));
        let mesh = world.resource_mut::<Assets<Mesh>>().add(Rectangle::new(4.0, 4.0));
        let material = ShowPrepass { scale: Vec4::new(8.0, 0.0, 0.0, 1.0) };
        let material = world.resource_mut::<Assets<ShowPrepass>>().add(material);
        let quad = (Mesh3d(mesh), MeshMaterial3d(material.clone()), Transform::from_xyz(0.0, 0.0, -0.5));
        world.spawn((quad, bevy::light::NotShadowCaster, ChildOf(camera)));
        material
    };
    // From a settled frame with the instance at `start` and its morph weights at `from`: the
    // first frame after it moved by `by` and its weights went to `to`.
    let start = *app.world().get::<Transform>(root).unwrap();
    let frames = app.world().resource::<common::Frames>().clone();
    let moved = |app: &mut App, by: Vec3, from: f32, to: f32| {
        app.world_mut().entity_mut(root).insert(start);
        set_weights(app, from);
        let before = settled_image(app);
        let seen = frames.0.lock().unwrap().len();
        app.world_mut().entity_mut(root).insert(start.with_translation(start.translation + by));
        set_weights(app, to);
        update_until(app, 100, "a frame after the move", |_| {
            frames.0.lock().unwrap()[seen..].iter().any(|f| *f != before)
        });
        let first = frames.0.lock().unwrap()[seen..].iter().find(|f| **f != before).unwrap().clone();
        let changed = common::differing_pixels(&first, &before);
        (first, changed)
    };
    let by = Vec3::new(0.1, 0.05, 0.0);
    // skinlet's: the instance moved, its weights held at 0; a weight change alone (0 to 1: the
    // face moves, the rest stays).
    let (skinlet, moving) = moved(&mut app, by, 0.0, 0.0);
    let (_, face) = moved(&mut app, Vec3::ZERO, 0.0, 1.0);
    // The same move with the weights held at 1: the frame before's weights are 1 too, so the
    // vectors (red and green; blue is depth) are the move's (they differ from the move at 0
    // only where the morphed shape covers other pixels).
    let (held, _) = moved(&mut app, by, 1.0, 1.0);
    let vector_differs = |(a, b): (&[u8], &[u8])| a[0].abs_diff(b[0]).max(a[1].abs_diff(b[1])) > 2;
    let morph_moved = held.chunks(4).zip(skinlet.chunks(4)).filter(|&p| vector_differs(p)).count();
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).remove::<SkinletMeshlets>();
    }
    // Bevy's, the same move. (With the weights held at 1, Bevy's motion vectors move the
    // morphed vertices by their morph displacement as well, as if the weights had been 0 the
    // frame before: its prepass pipeline seems specialized before the previous weights
    // existed. skinlet's stay the move's.)
    let (bevy, _) = moved(&mut app, by, 0.0, 0.0);
    let large = over_2_levels(&bevy, &skinlet, "meshlet_motion_side_by_side");
    eprintln!(
        "motion vectors: {moving} pixels moved, {large} differ by more than 2 levels; {face} moved by the weights; held at 1, {morph_moved} differ from held at 0"
    );
    assert!(moving > 2000, "too few pixels moved for a test: {moving}");
    assert!(large * 200 < moving, "motion vectors: {large} of {moving} pixels differ by more than 2 levels");
    assert!(50 < face && face * 2 < moving, "{face} pixels moved by the morph weights, {moving} by the move");
    // (One run: 637; with the frame before's weights taken as 0, as Bevy's own vectors have
    // them, 1,501.)
    assert!(morph_moved * 10 < moving, "held at 1, {morph_moved} of {moving} moving pixels differ from held at 0");

    // The normal prepass (the quad shows the normals' x and y): the normal-mapped body's
    // normals (and the double-sided back faces'), Bevy's and skinlet's.
    app.world_mut().resource_mut::<Assets<ShowPrepass>>().get_mut(&shown).unwrap().scale.w = 0.0;
    let bevy = settled_image(&mut app);
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(SkinletMeshlets);
    }
    let skinlet = settled_image(&mut app);
    let (drawn, large) = (common::drawn_pixels(&bevy), over_2_levels(&bevy, &skinlet, "meshlet_normals_side_by_side"));
    eprintln!("normal prepass: {drawn} pixels drawn; {large} differ by more than 2 levels");
    assert!(drawn > (WIDTH * HEIGHT / 8) as usize, "the normal prepass shows too little: {drawn} pixels");
    assert!(large * 200 < drawn, "normal prepass: {large} of {drawn} pixels differ by more than 2 levels");
}

/// With Bevy's occlusion culling on the camera (`OcclusionCulling`, `DepthPrepass`), skinlet's
/// occlusion culling starts from Bevy's depth after its early prepass: a wall (a Bevy mesh)
/// in front of two rows of characters hides some of them from skinlet's culling too. Fewer
/// meshlets drawn than with skinlet's own occlusion culling alone (same round), the image
/// equal to skinlet's unculled one (also with 4× MSAA), and Bevy's frame (its own occlusion
/// culling on) and skinlet's within the crowd test's tolerance.
#[test]
fn bevys_meshes_hide_characters_under_bevys_occlusion_culling() {
    use bevy::core_pipeline::prepass::DepthPrepass;
    use bevy::render::occlusion_culling::OcclusionCulling;
    if !common::vulkan_available() {
        return;
    }
    let Some((dir, characters)) = asset_folder("meshlet_occluders", &["skinned/Xbot.glb", "@demo"]) else { return };
    let mut app = app(&dir, true);
    app.add_plugins(SkinletMeshletPlugin);
    common::watch_pipelines(&mut app);
    let roots = common::spawn_rows(app.world_mut(), &characters, &[0.0, -2.2], 5);
    let at = Transform::from_xyz(0.0, 1.2, 4.0).looking_at(Vec3::new(0.0, 0.8, -1.0), Vec3::Y);
    let camera = common::readback_camera(app.world_mut(), WIDTH, HEIGHT, at);
    {
        // A wall hiding the left of both rows, and the ground.
        let world = app.world_mut();
        let wall = world.resource_mut::<Assets<Mesh>>().add(Cuboid::new(2.4, 2.6, 0.2));
        let ground = world.resource_mut::<Assets<Mesh>>().add(Plane3d::default().mesh().size(24.0, 24.0));
        let gray = world.resource_mut::<Assets<StandardMaterial>>().add(Color::srgb(0.6, 0.6, 0.6));
        world.spawn((Mesh3d(wall), MeshMaterial3d(gray.clone()), Transform::from_xyz(-1.3, 1.3, 2.0)));
        world.spawn((Mesh3d(ground), MeshMaterial3d(gray)));
        world.entity_mut(camera).insert((DepthPrepass, OcclusionCulling));
    }
    update_until(&mut app, 3000, "every instance bound", |w| {
        roots.iter().all(|&(e, _)| w.get::<SkinletInstance>(e).is_some())
    });
    for (i, &(root, c)) in roots.iter().enumerate() {
        common::play_clips(app.world_mut(), root, &characters[c], |nodes| vec![(nodes[i % nodes.len()], 1.0)]);
    }
    for _ in 0..25 {
        app.update();
    }
    app.world_mut().resource_mut::<Time<Virtual>>().pause();
    let bevy = settled_image(&mut app);
    for &(root, _) in &roots {
        app.world_mut().entity_mut(root).insert(SkinletMeshlets);
    }
    // Each image culled with (`bevy`) and without Bevy's depth, and the meshlets it drew.
    let culled = |app: &mut App, bevy_occluders: bool| {
        if bevy_occluders {
            app.world_mut().entity_mut(camera).insert(OcclusionCulling);
        } else {
            app.world_mut().entity_mut(camera).remove::<OcclusionCulling>();
        }
        let image = settled_image(app);
        let stats = latest_stats_after(app, characters.len());
        for s in stats.values() {
            eprintln!("Bevy's depth {bevy_occluders}: {s:?}");
            assert!(s.culled && s.occlusion_rounds == 1 && s.triangles_dropped == 0, "{s:?}");
            assert_eq!(s.bevy_occluders, bevy_occluders, "{s:?}");
        }
        (image, stats.values().map(|s| s.meshlets_drawn).sum::<u64>())
    };
    // (0 rounds asked: Bevy's occlusion culling turns skinlet's on, in one round.)
    let (skinlet, drawn_behind_bevy) = culled(&mut app, true);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().occlusion_rounds = 1;
    let (_, drawn_own) = culled(&mut app, false);
    assert!(
        drawn_behind_bevy < drawn_own,
        "{drawn_behind_bevy} meshlets drawn with Bevy's depth, {drawn_own} with skinlet's own occlusion culling"
    );
    // (Unculled with Bevy's occlusion culling on too: the same Bevy passes.)
    app.world_mut().entity_mut(camera).insert(OcclusionCulling);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = false;
    let unculled = settled_image(&mut app);
    let differing = common::differing_pixels(&skinlet, &unculled);
    assert_eq!(differing, 0, "culling behind Bevy's depth changed {differing} pixels");
    // 4× MSAA: Bevy's depth has the camera's samples, copied as it is.
    app.world_mut().entity_mut(camera).insert(Msaa::Sample4);
    let unculled_msaa = settled_image(&mut app);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = true;
    let (skinlet_msaa, drawn_msaa) = culled(&mut app, true);
    let differing = common::differing_pixels(&skinlet_msaa, &unculled_msaa);
    eprintln!(
        "meshlets drawn: {drawn_behind_bevy} with Bevy's depth, {drawn_own} without; with 4× MSAA {drawn_msaa}, {differing} pixels differ from unculled"
    );
    assert_eq!(differing, 0, "with 4× MSAA, culling behind Bevy's depth changed {differing} pixels");
    let (drawn, large) =
        (common::drawn_pixels(&bevy), over_2_levels(&bevy, &skinlet, "meshlet_occluders_side_by_side"));
    eprintln!("Bevy's frame and skinlet's: {large} of {drawn} drawn pixels differ by more than 2 levels");
    assert!(large * 200 < drawn, "{large} of {drawn} pixels differ by more than 2 levels");
}
