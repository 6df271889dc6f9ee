//! Meshlet builders on the real assets: validity for every builder and limit preset, and
//! the targets on Xbot.glb (meshoptimizer parity, skin-aware rigidity at small cost).

mod common;
use common::assets_dir;

use skinlet::meshlet::{Builder, MeshletLimits, build, flat, stats};
use std::path::PathBuf;

fn files(dir: &std::path::Path) -> Vec<PathBuf> {
    let mut f: Vec<PathBuf> = ["skinned", "static"]
        .iter()
        .flat_map(|d| std::fs::read_dir(dir.join(d)).unwrap().map(|e| e.unwrap().path()))
        .collect();
    f.sort();
    f
}

#[test]
fn every_builder_is_valid_on_every_asset() {
    let Some(dir) = assets_dir() else { return };
    for path in files(&dir) {
        let asset = skinlet::import::load(&path).unwrap();
        let prepared = skinlet::bake::prepare_character(&asset.character().unwrap()).unwrap();
        assert!(!prepared.mesh.triangles.is_empty(), "{}", path.display());
        for limits in [MeshletLimits::NVIDIA, MeshletLimits::LARGE, MeshletLimits::SMALL] {
            let mut count = [0; Builder::ALL.len()];
            for (b, count) in Builder::ALL.into_iter().zip(&mut count) {
                let m = build(&prepared, b, limits).unwrap();
                m.validate(&prepared.mesh.triangles, limits)
                    .unwrap_or_else(|e| panic!("{} {} {limits:?}: {e}", path.display(), b.name()));
                assert_eq!(flat::from_bytes(&flat::to_bytes(&m)).unwrap(), m);
                *count = m.len();
            }
            // cone-split's budget: 1.3× meshoptimizer's count, unless the skin-aware
            // meshlets already take more.
            let of = |b: Builder| count[Builder::ALL.iter().position(|&x| x == b).unwrap()];
            let (split, meshopt, skin_aware) = (of(Builder::ConeSplit), of(Builder::Meshopt), of(Builder::SkinAware));
            assert!(
                split as f32 <= 1.3 * meshopt as f32 || split <= skin_aware,
                "{} {limits:?}: cone-split {split}, meshopt {meshopt}, skin-aware {skin_aware}",
                path.display()
            );
        }
    }
}

#[test]
fn xbot_meshopt_parity_and_skin_aware_targets() {
    let Some(dir) = assets_dir() else { return };
    let asset = skinlet::import::load(&dir.join("skinned/Xbot.glb")).unwrap();
    let prepared = skinlet::bake::prepare_character(&asset.character().unwrap()).unwrap();
    let limits = MeshletLimits { max_vertices: 64, max_triangles: 124 };
    let ours = build(&prepared, Builder::Meshopt, limits).unwrap();
    // meshoptimizer called directly on the same prepared index buffer, part by part.
    let bytes = meshopt::typed_to_bytes(&prepared.mesh.positions);
    let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).unwrap();
    let direct: usize = (prepared.parts.iter())
        .map(|p| {
            let tris = &prepared.mesh.triangles[p.triangles.start as usize..p.triangles.end as usize];
            let indices: Vec<u32> = tris.iter().flatten().copied().collect();
            meshopt::build_meshlets(&indices, &adapter, 64, 124, 0.25).len()
        })
        .sum();
    let ratio = ours.len() as f64 / direct as f64;
    assert!((ratio - 1.0).abs() <= 0.02, "meshopt builder {} vs meshoptimizer {direct}", ours.len());

    let skin_aware = build(&prepared, Builder::SkinAware, limits).unwrap();
    let (so, ss) = (stats::compute(&prepared.mesh, &ours), stats::compute(&prepared.mesh, &skin_aware));
    eprintln!(
        "meshopt {} meshlets {:.1}% dominant; skin-aware {} meshlets {:.1}% dominant",
        so.meshlets, so.dominant_joint_pct, ss.meshlets, ss.dominant_joint_pct
    );
    assert!(ss.dominant_joint_pct > so.dominant_joint_pct, "skin-aware must be more rigid than meshopt");
    assert!(ss.meshlets as f64 <= 1.15 * so.meshlets as f64, "skin-aware uses too many meshlets");
}
