//! Contour extraction cost per view, one core: brute force against the patch decomposition
//! (Reduced Sphere), the SNCH hierarchy and meshoptimizer meshlets as patches on the Stanford
//! bunny with concave edges dropped (the paper's setup), and brute force against rigid-part
//! and animated-bounds patches on one frame of a skinned character. Views: the paper's 42
//! directions at 10 model sizes; criterion's elements are edges.
//!
//! Without the shared assets a generated bumpy sphere stands in for the bunny.
//! Run: `cargo bench -p skinlet --bench contours`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{DMat4, Vec3};
use skinlet::contour::patches::PatchParams;
use skinlet::contour::skinned::{SkinnedMethod, SkinnedParams, build, refinement, skinned_edges};
use skinlet::contour::{Edges, Projection};
use skinlet::overdraw::viewpoints::icosphere;
use skinlet::pose::{Poser, skinning_matrices};
use skinlet_lab::contour_eval::{Extractor, Method, frame};
use skinlet_lab::demo::uv_sphere;
use std::hint::black_box;
use std::path::PathBuf;

fn assets() -> PathBuf {
    std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")))
}

fn views(p: &[Vec3]) -> Vec<Projection> {
    let (center, size) = frame(p);
    icosphere(1).into_iter().map(|d| Projection::Perspective { eye: center + d * (10.0 * size) as f32 }).collect()
}

fn static_mesh(c: &mut Criterion) {
    let (name, mesh) = match skinlet::import::load(&assets().join("static/stanford-bunny.obj")) {
        Ok(a) => ("bunny", skinlet::weld::weld(&a.character().unwrap().mesh).0),
        Err(_) => {
            let (mut p, t) = uv_sphere(120, 240);
            p.iter_mut().enumerate().for_each(|(i, v)| *v *= 1.0 + 0.05 * ((i * 7919 % 101) as f32 / 101.0));
            ("sphere", skinlet::SkinnedMesh { positions: p, triangles: t, ..Default::default() })
        }
    };
    let mut edges = Edges::build(&mesh.positions, &mesh.triangles).unwrap();
    edges.drop_concave(&mesh.positions, |_| true);
    let views = views(&mesh.positions);
    let mut g = c.benchmark_group(format!("contours/{name}"));
    g.throughput(Throughput::Elements((edges.len() * views.len()) as u64));
    let mut out = Vec::new();
    for m in [Method::Brute, Method::Patches, Method::Snch, Method::Meshlets] {
        let x = Extractor::build(m, &mesh.positions, &mesh.triangles, &edges, &PatchParams::default());
        g.bench_function(m.name(), |b| {
            b.iter(|| {
                for &v in &views {
                    black_box(x.extract(&mesh.positions, &edges, v, &mut out));
                }
            })
        });
    }
    g.finish();
}

fn skinned_mesh(c: &mut Criterion) {
    let Ok(asset) = skinlet::import::load(&assets().join("skinned/CesiumMan.glb")) else { return };
    let character = asset.character().unwrap();
    let skin = &character.palette;
    let mesh = skinlet::weld::weld(&character.mesh).0;
    let edges = skinned_edges(&mesh, false).unwrap();
    let clips: Vec<_> = asset.clips.iter().collect();
    let how = refinement(None, 8);
    let built: Vec<_> = [SkinnedMethod::Rigid, SkinnedMethod::Animated]
        .map(|m| (m, build(&asset.skeleton, skin, &clips, &mesh, &edges, &SkinnedParams::new(m, how)).unwrap()))
        .into_iter()
        .collect();
    // One frame in the middle of the first clip.
    let clip = &asset.clips[0];
    let mut poser = Poser::default();
    let t = clip.start + 0.5 * clip.duration();
    let globals = poser.globals(&asset.skeleton, Some(clip), t).to_vec();
    let mut m = Vec::new();
    skinning_matrices(skin, &globals, &mut m);
    let mut p = vec![Vec3::ZERO; mesh.positions.len()];
    skinlet::skinning::skin(mesh.influences.as_ref().unwrap(), &mesh.positions, &[], &m, &mut p, &mut []).unwrap();
    let joints: Vec<DMat4> = skin.joints.iter().map(|&j| globals[j as usize]).collect();
    let views = views(&p);
    let mut g = c.benchmark_group("contours/CesiumMan");
    g.throughput(Throughput::Elements((edges.len() * views.len()) as u64));
    let mut out = Vec::new();
    g.bench_function("brute", |b| {
        b.iter(|| {
            for &v in &views {
                black_box(skinlet::contour::brute_force(&p, &edges, v, &mut out));
            }
        })
    });
    for (method, x) in &built {
        g.bench_function(method.name(), |b| {
            b.iter(|| {
                for &v in &views {
                    black_box(x.extract(&p, &edges, &joints, Some((0, t)), v, &mut out));
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, static_mesh, skinned_mesh);
criterion_main!(benches);
