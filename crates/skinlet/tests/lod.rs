//! The cluster LOD hierarchy on the shared characters and the demo character, part by part:
//! whatever the threshold, the cut's boundary is the full detail part's (the edges used by
//! an odd number of its triangles: no cracks between groups of different detail), and
//! errors grow up the hierarchy. (An edge's count can change: simplifying a thin part far
//! enough pinches two sheets together along an edge, used by four triangles, or folds a
//! triangle pair onto a locked open edge, used by three.)

mod common;
use common::{assets_dir, boundary, part_meshlets};

use skinlet::meshlet::lod::{LodParams, build};
use skinlet::meshlet::{Builder, MeshletLimits};

#[test]
fn every_cut_keeps_each_parts_boundary_on_every_character() {
    let demo = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams::default());
    let mut characters = vec![("demo".to_string(), demo.character().unwrap())];
    if let Some(dir) = assets_dir() {
        for name in ["Xbot.glb", "mannequiny.glb", "BrainStem.glb", "Fox.glb", "CesiumMan.glb"] {
            let asset = skinlet::import::load(&dir.join("skinned").join(name)).unwrap();
            characters.push((name.to_string(), asset.character().unwrap()));
        }
    }
    let limits = MeshletLimits::NVIDIA;
    for (name, character) in &characters {
        let prepared = skinlet::bake::prepare_character(character).unwrap();
        let meshlets = skinlet::meshlet::build(&prepared, Builder::SkinAware, limits).unwrap();
        let (mut groups, mut cuts) = (0, 0);
        for part in &prepared.parts {
            let mine = part_meshlets(&meshlets, &part.vertices);
            let full: Vec<u32> =
                prepared.mesh.triangles[part.triangles.start as usize..part.triangles.end as usize].concat();
            let lod = build(&prepared.mesh.positions, &[], &mine, limits, LodParams::default()).unwrap();
            let borders = boundary(full.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
            for g in &lod.groups {
                for &c in &g.children {
                    assert!(lod.cluster_errors(c as usize).0 <= g.error, "{name}: errors not monotone");
                }
            }
            let mut thresholds: Vec<f32> = lod.groups.iter().map(|g| g.error).collect();
            thresholds.extend([0.0, f32::MAX]);
            for t in thresholds {
                let cut = lod.cut(t);
                let triangles = cut.iter().flat_map(|&c| lod.clusters[c as usize].triangles.chunks_exact(3));
                let found = boundary(triangles.map(|t| [t[0], t[1], t[2]]));
                assert!(
                    found == borders,
                    "{name}, a part at threshold {t}: the cut's boundary differs from the part's ({} edges against {})",
                    found.len(),
                    borders.len()
                );
                cuts += 1;
            }
            groups += lod.groups.len();
        }
        eprintln!("{name}: {} parts, {groups} groups, {cuts} cuts checked", prepared.parts.len());
        assert!(groups > 0, "{name}: nothing simplified");
    }
}
