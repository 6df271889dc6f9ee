//! Ground-truth check of meshlet spheres: dense sampling of every clip (uniform times plus
//! every key time and every interval midpoint), reference skinning of every vertex
//! ([`crate::skinning`]), and a world-space containment test of every meshlet vertex in its
//! sphere moved by the principal joint (center `G·c`, radius `r·σ_max(G)`), the test the
//! runtime culls with. A vertex outside by more than float rounding (1e-5 relative to the
//! radius, plus 1e-6 of the scene size) is a violation.

use super::sphere::{MeshletSphere, key_intervals, max_scale};
use crate::clip::Clip;
use crate::meshlet::Meshlets;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use crate::pose::{Poser, skinning_matrices};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VerifyReport {
    pub samples: usize,
    pub vertex_checks: usize,
    pub violations: usize,
    /// Largest distance beyond a sphere, relative to its radius (0 without violations).
    pub max_violation: f64,
    /// Mean over meshlets of stored radius ÷ largest radius needed over the samples.
    pub mean_radius_ratio: f64,
}

/// The sample times of a clip: `uniform` evenly spaced times, every key, every midpoint.
pub fn sample_times(clip: &Clip, uniform: usize) -> Vec<f32> {
    let mut t: Vec<f32> =
        (0..uniform).map(|k| clip.start + clip.duration() * k as f32 / (uniform - 1).max(1) as f32).collect();
    t.extend(clip.key_times());
    t.extend(key_intervals(clip).iter().map(|(a, b)| a + (b - a) / 2.0));
    t.sort_by(f32::total_cmp);
    t.dedup();
    t
}

pub fn verify_spheres(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    spheres: &[MeshletSphere],
    uniform: usize,
) -> VerifyReport {
    let times: Vec<(&Clip, f32)> =
        clips.iter().flat_map(|c| sample_times(c, uniform).into_iter().map(move |t| (*c, t))).collect();
    let scan = scan(skeleton, skin, &times, mesh, meshlets, spheres);
    let ratio = spheres
        .iter()
        .zip(&scan.needed)
        .map(|(s, &need)| if need > 1e-12 { s.radius as f64 / need } else { 1.0 })
        .sum::<f64>()
        / meshlets.len().max(1) as f64;
    VerifyReport {
        samples: times.len(),
        vertex_checks: scan.checks,
        violations: scan.violations,
        max_violation: scan.worst,
        mean_radius_ratio: ratio,
    }
}

/// The non-conservative baseline engines use (e.g. Unity's `AnimationClip.localBounds`):
/// the rest spheres' radii grown to the largest distance seen at `per_clip` evenly spaced
/// times of each clip. Between samples vertices can leave them.
pub fn sampled_spheres(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    per_clip: usize,
) -> Vec<MeshletSphere> {
    let mut spheres = super::sphere::rest_spheres(skin, mesh, meshlets);
    let times: Vec<(&Clip, f32)> = clips
        .iter()
        .flat_map(|c| {
            (0..per_clip).map(move |k| (*c, c.start + c.duration() * k as f32 / (per_clip - 1).max(1) as f32))
        })
        .collect();
    let needed = scan(skeleton, skin, &times, mesh, meshlets, &spheres).needed;
    for (s, n) in spheres.iter_mut().zip(needed) {
        s.radius = s.radius.max(n as f32);
    }
    spheres
}

struct Scan {
    violations: usize,
    worst: f64,
    checks: usize,
    /// Per meshlet, the largest joint-space distance of a vertex from the sphere's center.
    needed: Vec<f64>,
}

/// Skins the mesh at every time and checks every meshlet vertex against its moved sphere.
fn scan(
    skeleton: &Skeleton,
    skin: &Skin,
    times: &[(&Clip, f32)],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    spheres: &[MeshletSphere],
) -> Scan {
    let n = meshlets.len();
    let empty = || Scan { violations: 0, worst: 0.0, checks: 0, needed: vec![0.0; n] };
    let Some(inf) = &mesh.influences else { return empty() };
    let scene = mesh.positions.iter().map(|p| p.abs().max_element()).fold(1.0f32, f32::max) as f64;
    let per_time = |&(clip, t): &(&Clip, f32)| {
        let mut poser = Poser::default();
        let globals = poser.globals(skeleton, Some(clip), t).to_vec();
        let mut mats = Vec::new();
        skinning_matrices(skin, &globals, &mut mats);
        let mut p = vec![Vec3::ZERO; mesh.positions.len()];
        crate::skinning::skin_serial(inf, &mesh.positions, &[], &mats, &mut p, &mut []).expect("validated mesh");
        let mut out = empty();
        for (i, (m, s)) in meshlets.meshlets.iter().zip(spheres).enumerate() {
            let g = globals[skin.joints[s.joint as usize] as usize];
            let (center, radius) = (g.transform_point3(s.center.as_dvec3()), s.radius as f64 * max_scale(&g));
            let to_joint = g.inverse();
            for &v in meshlets.vertices_of(m) {
                let pv: DVec3 = p[v as usize].as_dvec3();
                let d = pv.distance(center);
                if d > radius * (1.0 + 1e-5) + 1e-6 * scene {
                    out.violations += 1;
                    out.worst = out.worst.max((d - radius) / radius.max(1e-12));
                }
                out.needed[i] = out.needed[i].max(to_joint.transform_point3(pv).distance(s.center.as_dvec3()));
                out.checks += 1;
            }
        }
        out
    };
    times.par_iter().map(per_time).reduce(empty, |a, b| Scan {
        violations: a.violations + b.violations,
        worst: a.worst.max(b.worst),
        checks: a.checks + b.checks,
        needed: a.needed.iter().zip(&b.needed).map(|(x, y)| x.max(*y)).collect(),
    })
}
