//! Shared by the GPU tests: the device (or a skip, unless SKINLET_REQUIRE_GPU=1) and the
//! shared skinned assets plus the demo character.
#![allow(dead_code)]

use skinlet::Asset;
use skinlet_gpu::{Gpu, GpuOptions};
use std::path::PathBuf;

pub fn gpu() -> Option<Gpu> {
    match Gpu::new(GpuOptions::default()) {
        Ok(g) => Some(g),
        Err(e) if std::env::var("SKINLET_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("{e}"),
        Err(e) => {
            eprintln!("skipping: {e}");
            None
        }
    }
}

pub fn assets() -> Vec<(String, Asset)> {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    let mut out = Vec::new();
    match std::fs::read_dir(dir.join("skinned")) {
        Ok(entries) => {
            let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
            paths.sort();
            for p in paths.into_iter().filter(|p| p.extension().is_some_and(|e| e == "glb" || e == "gltf")) {
                let asset = skinlet::import::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                out.push((p.file_name().unwrap().to_string_lossy().into_owned(), asset));
            }
        }
        Err(e) if std::env::var("SKINLET_REQUIRE_ASSETS").is_ok_and(|v| v == "1") => {
            panic!("{}: {e}", dir.display())
        }
        Err(e) => eprintln!("no shared assets ({}: {e}); the demo character only", dir.display()),
    }
    let demo = skinlet::demo::demo_character(&skinlet::demo::DemoParams::default());
    out.push(("@demo".into(), demo));
    out
}

/// A bake of the whole character over every clip: skin-aware meshlets with NVIDIA's limits,
/// bounds from key intervals only.
pub fn bake(asset: &Asset, character: &skinlet::Character) -> skinlet::bake::Baked {
    let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
    let limits = skinlet::meshlet::MeshletLimits::NVIDIA;
    let how = skinlet::bounds::refine::Refinement::NONE;
    skinlet::bake::bake(asset, character, &clips, skinlet::meshlet::Builder::SkinAware, limits, &how, &mut |_| {})
        .unwrap()
        .0
}
