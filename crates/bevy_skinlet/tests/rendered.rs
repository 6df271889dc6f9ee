//! The rendered proof (headless, Bevy's renderer on the machine's Vulkan device: lavapipe on
//! CPU-only machines): one frame of an animated crowd, drawn with skinlet's bounds culling the
//! mesh entities, equals the same frame drawn with `NoFrustumCulling` on every mesh entity,
//! byte for byte, while skinlet's boxes do cull part of the crowd. The same frame with every
//! skinlet box moved by its own width differs: the comparison sees a box that leaves part of
//! its entity out.

mod common;

use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{NoFrustumCulling, ViewVisibility};
use bevy::prelude::*;
use bevy_skinlet::{SkinletInstance, SkinletSystems};
use common::{app, asset_folder, settled_image, update_until};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 160;

/// When set, every box skinlet wrote this frame is moved by its own width along x: a box
/// that leaves half of its entity out.
#[derive(Resource, Default)]
struct Displace(bool);

fn displace_boxes(displace: Res<Displace>, instances: Query<&SkinletInstance>, mut aabbs: Query<&mut Aabb>) {
    if !displace.0 {
        return;
    }
    for &e in instances.iter().flat_map(SkinletInstance::part_entities) {
        if let Ok(mut aabb) = aabbs.get_mut(e) {
            aabb.center.x += 2.0 * aabb.half_extents.x;
        }
    }
}

fn write_png(path: &std::path::Path, rgba: &[u8]) {
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(std::fs::File::create(path).unwrap()), WIDTH, HEIGHT);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header().unwrap().write_image_data(rgba).unwrap();
}

#[test]
fn skinlets_bounds_cull_nothing_visible() {
    if !common::vulkan_available() {
        return;
    }
    let files = ["skinned/Fox.glb", "skinned/CesiumMan.glb", "morph/MorphStressTest.gltf", "@demo"];
    let Some((dir, characters)) = asset_folder("rendered", &files) else { return };
    let mut app = app(&dir, true);
    app.init_resource::<Displace>().add_systems(
        PostUpdate,
        displace_boxes
            .after(SkinletSystems::UpdateBounds)
            .before(bevy::camera::visibility::VisibilitySystems::CheckVisibility),
    );
    // A crowd in rows, one character per row; the camera stands between the first row
    // (behind it) and the others, so instances are behind it, beside the frustum, cut by its
    // sides and in full view.
    let roots = common::spawn_rows(app.world_mut(), &characters, &[4.4, 0.0, -2.2, -4.4], 6);
    let at = Transform::from_xyz(0.0, 1.0, 3.4).looking_at(Vec3::new(0.0, 0.7, -4.0), Vec3::Y);
    common::readback_camera(app.world_mut(), WIDTH, HEIGHT, at);
    update_until(&mut app, 3000, "every instance bound", |w| {
        roots.iter().all(|&(e, _)| w.get::<SkinletInstance>(e).is_some())
    });
    // Every instance plays a clip of its file (a different one, or a crossfade of two).
    for (i, &(root, c)) in roots.iter().enumerate() {
        common::play_clips(app.world_mut(), root, &characters[c], |nodes| {
            if nodes.len() >= 2 && i % 4 == 3 {
                vec![(nodes[0], 0.5), (nodes[1], 0.5)]
            } else {
                // One speed for all: Bevy 0.19.1 panics sampling a CUBICSPLINE morph-weight
                // curve exactly on a key or past its ends (`WideCubicKeyframeCurve`, the demo's
                // wave clip), which other speeds can reach within these frames.
                vec![(nodes[i % nodes.len()], 1.0)]
            }
        });
    }
    for _ in 0..25 {
        app.update();
    }
    app.world_mut().resource_mut::<Time<Virtual>>().pause();

    let culled_by_skinlet = settled_image(&mut app);
    let (mut visible, mut culled) = (0, 0);
    {
        let world = app.world_mut();
        let parts: Vec<Entity> =
            world.query::<&SkinletInstance>().iter(world).flat_map(|i| i.part_entities().to_vec()).collect();
        for e in parts {
            if world.get::<ViewVisibility>(e).unwrap().get() {
                visible += 1;
            } else {
                culled += 1;
            }
        }
    }
    assert!(
        visible > 0 && culled > 0,
        "the frame must show part of the crowd and cull the rest: {visible} visible, {culled} culled"
    );

    let meshes: Vec<Entity> = {
        let world = app.world_mut();
        world.query_filtered::<Entity, With<Mesh3d>>().iter(world).collect()
    };
    for &e in &meshes {
        app.world_mut().entity_mut(e).insert(NoFrustumCulling);
    }
    let unculled = settled_image(&mut app);
    for &e in &meshes {
        app.world_mut().entity_mut(e).remove::<NoFrustumCulling>();
    }
    app.world_mut().resource_mut::<Displace>().0 = true;
    let displaced = settled_image(&mut app);

    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    write_png(&out.join("rendered_skinlet.png"), &culled_by_skinlet);
    write_png(&out.join("rendered_unculled.png"), &unculled);
    write_png(&out.join("rendered_displaced.png"), &displaced);
    let drawn = unculled.chunks(4).filter(|p| p[..3] != unculled[..3]).count();
    assert!(drawn > (WIDTH * HEIGHT / 20) as usize, "the crowd covers only {drawn} pixels");
    let differing = common::differing_pixels(&culled_by_skinlet, &unculled);
    assert_eq!(
        differing,
        0,
        "{differing} pixels differ between skinlet's culling and none (images in {})",
        out.display()
    );
    assert!(displaced != unculled, "displaced boxes culled nothing visible: the comparison would miss a wrong box");
}
