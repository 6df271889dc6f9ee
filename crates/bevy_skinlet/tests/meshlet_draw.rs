//! Bevy as the oracle for `SkinletMeshletPlugin` (headless, Bevy's renderer on the machine's
//! Vulkan device: lavapipe on CPU-only machines): the same animated crowd, same frame, drawn
//! by Bevy's own skinned mesh pipeline and by skinlet's meshlet draw (GPU culling on). The
//! tolerance: Bevy skins in its own order (joint matrices blended after its own product with
//! the inverse binds), so positions and normals round apart by a few ulps: interior pixels
//! shade within 2 levels of 255, and a silhouette pixel whose center a triangle edge nearly
//! touches may flip coverage (then any color): at most 1 in 200 drawn pixels differs by more
//! than 2 levels. skinlet's image with culling on equals its image with culling off exactly.

mod common;

use bevy::prelude::*;
use bevy_skinlet::{SkinletDrawnPart, SkinletInstance, SkinletMeshletPlugin, SkinletMeshletSettings, SkinletMeshlets};
use common::{app, asset_folder, settled_image, update_until};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 160;

fn write_png(path: &std::path::Path, rgba: &[u8]) {
    write_png_sized(path, rgba, WIDTH);
}

fn write_png_sized(path: &std::path::Path, rgba: &[u8], width: u32) {
    let height = (rgba.len() / 4) as u32 / width;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(std::fs::File::create(path).unwrap()), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header().unwrap().write_image_data(rgba).unwrap();
}

#[test]
fn skinlets_meshlet_draw_looks_like_bevys_own() {
    if !common::vulkan_available() {
        return;
    }
    let files = ["skinned/Xbot.glb", "skinned/BrainStem.glb", "@demo"];
    let Some((dir, characters)) = asset_folder("meshlet_draw", &files) else { return };
    let mut app = app(&dir, true);
    app.add_plugins(SkinletMeshletPlugin);
    common::watch_pipelines(&mut app);
    // Three rows, one character each; the camera sees part of each row, the others are
    // beside or behind it (culled).
    let roots = common::spawn_rows(app.world_mut(), &characters, &[0.0, -2.2, -4.4], 5);
    let at = Transform::from_xyz(0.0, 1.2, 4.0).looking_at(Vec3::new(0.0, 0.8, -1.0), Vec3::Y);
    common::readback_camera(app.world_mut(), WIDTH, HEIGHT, at);
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
    let skinlet = settled_image(&mut app);
    app.world_mut().resource_mut::<SkinletMeshletSettings>().culling = false;
    let unculled = settled_image(&mut app);
    let taken = {
        let world = app.world_mut();
        world.query::<&SkinletDrawnPart>().iter(world).count()
    };
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    write_png(&out.join("meshlet_draw_bevy.png"), &bevy);
    write_png(&out.join("meshlet_draw_skinlet.png"), &skinlet);
    write_png(&out.join("meshlet_draw_skinlet_unculled.png"), &unculled);
    let culled_away = skinlet.chunks(4).zip(unculled.chunks(4)).filter(|(a, b)| a != b).count();
    let diff: Vec<u8> = (bevy.chunks(4).zip(skinlet.chunks(4)))
        .flat_map(|(a, b)| {
            let d = (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap();
            [d.saturating_mul(8), d.saturating_mul(8), d.saturating_mul(8), 255]
        })
        .collect();
    write_png(&out.join("meshlet_draw_diff.png"), &diff);
    // Bevy's frame, skinlet's, and their difference (× 8) side by side.
    let row = 4 * WIDTH as usize;
    let side: Vec<u8> = (0..HEIGHT as usize)
        .flat_map(|y| [&bevy, &skinlet, &diff].map(|img| img[y * row..(y + 1) * row].to_vec()).concat())
        .collect();
    write_png_sized(&out.join("meshlet_draw_side_by_side.png"), &side, 3 * WIDTH);
    let per_pixel: Vec<u8> = (bevy.chunks(4).zip(skinlet.chunks(4)))
        .map(|(a, b)| (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap())
        .collect();
    let drawn = bevy.chunks(4).filter(|p| p[..3] != bevy[..3]).count();
    let differing = per_pixel.iter().filter(|&&d| d > 0).count();
    let large = per_pixel.iter().filter(|&&d| d > 2).count();
    eprintln!(
        "{taken} parts drawn by skinlet; {drawn} pixels drawn by Bevy; {differing} differ, {large} by more than 2, at most {} (images in {}); culled and unculled differ at {culled_away}",
        per_pixel.iter().max().unwrap(),
        out.display()
    );
    assert!(taken > 0 && drawn > (WIDTH * HEIGHT / 20) as usize);
    assert_eq!(culled_away, 0, "skinlet's culling changed {culled_away} pixels");
    assert!(large * 200 < drawn, "{large} of {drawn} pixels differ by more than 2 levels");
}
