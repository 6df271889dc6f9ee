//! Bakes made by Bevy's asset processing (the `bake` feature): a `.skinlet.ron` recipe beside a
//! glTF file is baked when Bevy processes assets; the processed file holds exactly the bytes
//! `bake_gltf` makes, loads as a `Bake`, is left alone when nothing changed, and is rebaked
//! when the glTF file changes. Without processing the recipe loads as the same bake; a recipe
//! with an unknown builder or a missing file fails to load with an error that names it.

mod common;

use bevy::asset::{AssetMode, LoadState};
use bevy::prelude::*;
use bevy_skinlet::Bake;
use bevy_skinlet::bake_processor::{BakeRecipe, SkinletBakePlugin, bake_gltf};
use std::path::Path;

/// Runs an app on `source` (processing into `processed` when given) until `file` loads or
/// fails; the bake's bytes or the load error.
fn load(source: &Path, processed: Option<&Path>, file: &str) -> Result<Vec<u8>, String> {
    let assets = AssetPlugin {
        file_path: source.to_string_lossy().into_owned(),
        processed_file_path: processed
            .map_or_else(|| format!("{}-processed", source.display()), |p| p.to_string_lossy().into_owned()),
        mode: if processed.is_some() { AssetMode::Processed } else { AssetMode::Unprocessed },
        ..Default::default()
    };
    let mut app = common::app_with(assets, false);
    app.add_plugins(SkinletBakePlugin);
    if processed.is_some() {
        // Every asset processed (a recipe whose glTF file changed is rebaked after the file
        // itself is processed) before the bake is read.
        common::update_until(&mut app, 100_000, "the processor finished", |world| {
            let processor = world.resource::<bevy::asset::processor::AssetProcessor>();
            bevy::tasks::block_on(processor.get_state()) == bevy::asset::processor::ProcessorState::Finished
        });
    }
    let handle: Handle<Bake> = app.world().resource::<AssetServer>().load(file.to_string());
    let mut out = None;
    common::update_until(&mut app, 100_000, "the recipe loaded or failed", |world| {
        let state = world.resource::<AssetServer>().get_load_state(&handle);
        out = match state {
            Some(LoadState::Loaded) => {
                Some(Ok(world.resource::<Assets<Bake>>().get(&handle).unwrap().bytes().to_vec()))
            }
            Some(LoadState::Failed(e)) => Some(Err(e.to_string())),
            _ => None,
        };
        out.is_some()
    });
    out.unwrap()
}

/// Writes a recipe as a person would (the format in `bake_processor`'s docs).
fn write_recipe(dir: &Path, name: &str, recipe: &BakeRecipe) {
    let margin = recipe.envelope_margin_degrees.map_or("None".to_string(), |m| format!("Some({m:?})"));
    let text = format!("(gltf: {:?}, builder: {:?}, envelope_margin_degrees: {margin})", recipe.gltf, recipe.builder);
    std::fs::write(dir.join(name), text).unwrap();
}

#[test]
fn recipes_are_baked_when_bevy_processes_assets_and_rebaked_on_change() {
    let Some((dir, characters)) = common::asset_folder("processor", &["skinned/Fox.glb", "skinned/CesiumMan.glb"])
    else {
        return;
    };
    let (source, processed) = (dir.join("source"), dir.join("processed"));
    std::fs::create_dir_all(&source).unwrap();
    let fox = std::fs::read(dir.join(&characters[0].file)).unwrap();
    let cesium = std::fs::read(dir.join(&characters[1].file)).unwrap();
    std::fs::write(source.join("character.glb"), &fox).unwrap();
    let recipe = BakeRecipe::new("character.glb");
    write_recipe(&source, "character.skinlet.ron", &recipe);
    let expected = bake_gltf(&fox, Path::new("character.glb"), &recipe).unwrap();
    let stored = processed.join("character.skinlet.ron");

    // First run: baked into the processed folder, loaded from there.
    assert_eq!(load(&source, Some(&processed), "character.skinlet.ron").unwrap(), expected);
    assert_eq!(std::fs::read(&stored).unwrap(), expected, "the processed file is the bake");
    let first = std::fs::metadata(&stored).unwrap().modified().unwrap();

    // Second run, nothing changed: the stored bake is used as it is.
    std::thread::sleep(std::time::Duration::from_millis(20));
    assert_eq!(load(&source, Some(&processed), "character.skinlet.ron").unwrap(), expected);
    assert_eq!(std::fs::metadata(&stored).unwrap().modified().unwrap(), first, "rebaked though nothing changed");

    // The glTF file changes: the recipe is rebaked from the new file.
    std::fs::write(source.join("character.glb"), &cesium).unwrap();
    let changed = bake_gltf(&cesium, Path::new("character.glb"), &recipe).unwrap();
    assert_ne!(changed, expected);
    assert_eq!(load(&source, Some(&processed), "character.skinlet.ron").unwrap(), changed);
    assert_eq!(std::fs::read(&stored).unwrap(), changed);

    // Without processing, the recipe loads as the same bake.
    assert_eq!(load(&source, None, "character.skinlet.ron").unwrap(), changed);
}

#[test]
fn a_bad_recipe_is_a_load_error_that_names_it() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad_recipes");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let demo =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 500, ..Default::default() });
    std::fs::write(dir.join("demo.glb"), skinlet::export::to_glb(&demo).unwrap()).unwrap();
    write_recipe(&dir, "builder.skinlet.ron", &BakeRecipe { builder: "fastest".into(), ..BakeRecipe::new("demo.glb") });
    write_recipe(&dir, "missing.skinlet.ron", &BakeRecipe::new("nowhere.glb"));
    write_recipe(
        &dir,
        "margin.skinlet.ron",
        &BakeRecipe { envelope_margin_degrees: Some(200.0), ..BakeRecipe::new("demo.glb") },
    );
    std::fs::write(dir.join("garbled.skinlet.ron"), "(gltf: 3)").unwrap();
    for (file, says) in [
        ("builder.skinlet.ron", "unknown builder \"fastest\""),
        ("missing.skinlet.ron", "nowhere.glb"),
        ("margin.skinlet.ron", "envelope margin 200"),
        ("garbled.skinlet.ron", "not a bake recipe"),
    ] {
        let error = load(&dir, None, file).unwrap_err();
        assert!(error.contains(file) && error.contains(says), "{file}: {error}");
    }
    // Fields left out take the defaults: the demo character baked with an envelope.
    std::fs::write(dir.join("short.skinlet.ron"), "(gltf: \"demo.glb\")").unwrap();
    let bytes = load(&dir, None, "short.skinlet.ron").unwrap();
    assert!(Bake::from_bytes(&bytes).unwrap().has_envelope());
}
