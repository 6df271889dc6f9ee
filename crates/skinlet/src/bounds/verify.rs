//! Ground-truth check of meshlet bounds: dense sampling of every clip (uniform times plus
//! every key time and every interval midpoint), reference skinning of every vertex with its
//! morph targets applied ([`crate::skinning`]), then in world space, as the runtime culls: every meshlet vertex in
//! its moved sphere ([`world_sphere`]) and every triangle's face normal in its moved cone
//! ([`world_cone`]). Tolerances are float rounding of the f32 reference only: 1e-5 of the
//! radius plus 1e-6 of the scene size for points; for normals the angle that f32 rounding of
//! the triangle's vertices can cause (1e-6 rad plus 2δ·perimeter/|n|, δ = 2.4e-7 × the
//! magnitudes skinning sums, |M|·|p| + |t|: moving each vertex by δ turns the face normal by
//! at most that much).

use super::meshlet::{MeshletBounds, key_intervals, rest_bounds, world_cone, world_sphere};
use crate::clip::Clip;
use crate::meshlet::Meshlets;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use crate::pose::{Poser, skinning_matrices};
use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VerifyReport {
    pub samples: usize,
    pub vertex_checks: usize,
    pub normal_checks: usize,
    pub vertex_violations: usize,
    pub normal_violations: usize,
    /// Largest excess beyond a bound: distance ÷ radius for points, angle ÷ cone angle for normals.
    pub max_violation: f64,
    /// Mean over meshlets of stored radius ÷ largest radius needed over the samples.
    pub mean_radius_ratio: f64,
    /// Mean over meshlets with a useful cone of stored angle ÷ largest angle needed.
    pub mean_angle_ratio: f64,
}

impl VerifyReport {
    pub fn violations(&self) -> usize {
        self.vertex_violations + self.normal_violations
    }
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

pub fn verify_bounds(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
    uniform: usize,
) -> VerifyReport {
    let times: Vec<(&Clip, f32)> =
        clips.iter().flat_map(|c| sample_times(c, uniform).into_iter().map(move |t| (*c, t))).collect();
    let s = scan(skeleton, skin, &times, mesh, meshlets, bounds);
    let n = meshlets.len().max(1) as f64;
    let radius_ratio = bounds
        .iter()
        .zip(&s.needed_radius)
        .map(|(b, &need)| if need > 1e-12 { b.radius as f64 / need } else { 1.0 })
        .sum::<f64>()
        / n;
    let coned: Vec<f64> = bounds
        .iter()
        .zip(&s.needed_angle)
        .filter(|(b, _)| (b.cone_angle as f64) < std::f64::consts::FRAC_PI_2)
        .map(|(b, &need)| if need > 1e-9 { b.cone_angle as f64 / need } else { 1.0 })
        .collect();
    VerifyReport {
        samples: times.len(),
        vertex_checks: s.vertex_checks,
        normal_checks: s.normal_checks,
        vertex_violations: s.vertex_violations,
        normal_violations: s.normal_violations,
        max_violation: s.worst,
        mean_radius_ratio: radius_ratio,
        mean_angle_ratio: if coned.is_empty() { 1.0 } else { coned.iter().sum::<f64>() / coned.len() as f64 },
    }
}

/// The non-conservative baseline engines use (e.g. Unity's `AnimationClip.localBounds`):
/// rest bounds grown to the largest radius and normal angle seen at `per_clip` evenly spaced
/// times of each clip. Between samples vertices and normals can leave them.
pub fn sampled_bounds(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    per_clip: usize,
) -> Vec<MeshletBounds> {
    let mut bounds = rest_bounds(skin, mesh, meshlets);
    let times: Vec<(&Clip, f32)> = clips
        .iter()
        .flat_map(|c| {
            (0..per_clip).map(move |k| (*c, c.start + c.duration() * k as f32 / (per_clip - 1).max(1) as f32))
        })
        .collect();
    let s = scan(skeleton, skin, &times, mesh, meshlets, &bounds);
    for ((b, r), a) in bounds.iter_mut().zip(s.needed_radius).zip(s.needed_angle) {
        b.radius = b.radius.max(r as f32);
        if (b.cone_angle as f64) < std::f64::consts::FRAC_PI_2 {
            b.cone_angle = b.cone_angle.max(a as f32);
        }
    }
    bounds
}

#[derive(Clone)]
struct Scan {
    vertex_checks: usize,
    normal_checks: usize,
    vertex_violations: usize,
    normal_violations: usize,
    worst: f64,
    /// Per meshlet: largest joint-space distance of a vertex from the center, and largest
    /// joint-space angle of a face normal from the cone axis.
    needed_radius: Vec<f64>,
    needed_angle: Vec<f64>,
}

impl Scan {
    fn new(n: usize) -> Scan {
        Scan {
            vertex_checks: 0,
            normal_checks: 0,
            vertex_violations: 0,
            normal_violations: 0,
            worst: 0.0,
            needed_radius: vec![0.0; n],
            needed_angle: vec![0.0; n],
        }
    }

    fn merge(mut self, o: Scan) -> Scan {
        self.vertex_checks += o.vertex_checks;
        self.normal_checks += o.normal_checks;
        self.vertex_violations += o.vertex_violations;
        self.normal_violations += o.normal_violations;
        self.worst = self.worst.max(o.worst);
        self.needed_radius.iter_mut().zip(&o.needed_radius).for_each(|(a, b)| *a = a.max(*b));
        self.needed_angle.iter_mut().zip(&o.needed_angle).for_each(|(a, b)| *a = a.max(*b));
        self
    }
}

/// Skins the mesh at every time and checks every meshlet's vertices and face normals.
fn scan(
    skeleton: &Skeleton,
    skin: &Skin,
    times: &[(&Clip, f32)],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
) -> Scan {
    let n = meshlets.len();
    let Some(inf) = &mesh.influences else { return Scan::new(n) };
    let scene = mesh.positions.iter().map(|p| p.abs().max_element()).fold(1.0f32, f32::max) as f64;
    let any_cone = bounds.iter().any(|b| (b.cone_angle as f64) < std::f64::consts::FRAC_PI_2);
    let per_time = |&(clip, t): &(&Clip, f32)| {
        let mut poser = Poser::default();
        let globals = poser.globals(skeleton, Some(clip), t).to_vec();
        let (mut mats, mut weights) = (Vec::new(), Vec::new());
        skinning_matrices(skin, &globals, &mut mats);
        mesh.morphs.weights_at(Some(clip), t, &mut weights);
        let (morphed, _) = mesh.morphed(&weights);
        let mut p = vec![Vec3::ZERO; mesh.positions.len()];
        crate::skinning::skin_serial(inf, &morphed, &[], &mats, &mut p, &mut []).expect("validated mesh");
        // Per vertex, the magnitudes skinning sums (|M|·|p| + |t|): f32 rounds relative to
        // them, which exceed the result's when the joint's matrix nearly collapses.
        let sums: Vec<f64> = if any_cone {
            (0..p.len())
                .map(|v| {
                    let m = crate::skinning::blend_matrix(inf, v, &mats);
                    let q = morphed[v].abs();
                    (m.matrix3.x_axis.abs() * q.x
                        + m.matrix3.y_axis.abs() * q.y
                        + m.matrix3.z_axis.abs() * q.z
                        + m.translation.abs())
                    .max_element() as f64
                })
                .collect()
        } else {
            Vec::new()
        };
        let mut out = Scan::new(n);
        for (i, (m, b)) in meshlets.meshlets.iter().zip(bounds).enumerate() {
            let g = globals[skin.joints[b.joint as usize] as usize];
            let (center, radius) = world_sphere(b, &g);
            let to_joint = g.inverse();
            let verts = meshlets.vertices_of(m);
            for &v in verts {
                let pv: DVec3 = p[v as usize].as_dvec3();
                let d = pv.distance(center);
                if d > radius * (1.0 + 1e-5) + 1e-6 * scene {
                    out.vertex_violations += 1;
                    out.worst = out.worst.max((d - radius) / radius.max(1e-12));
                }
                out.needed_radius[i] =
                    out.needed_radius[i].max(to_joint.transform_point3(pv).distance(b.center.as_dvec3()));
                out.vertex_checks += 1;
            }
            // Face normals: world n = cof(A)·n_joint, so n_joint ∝ sign(det A)·Aᵀ·n.
            let a = DMat3::from_mat4(g);
            let back = a.transpose() * a.determinant().signum();
            let cone = world_cone(b, &g);
            for t in meshlets.triangles_of(m).chunks_exact(3) {
                let [p1, p2, p3] = [0, 1, 2].map(|k| p[verts[t[k] as usize] as usize].as_dvec3());
                let nw = (p2 - p1).cross(p3 - p1);
                let len = nw.length();
                if len == 0.0 {
                    continue;
                }
                out.normal_checks += 1;
                let nj = (back * nw).normalize_or_zero();
                out.needed_angle[i] = out.needed_angle[i].max(nj.dot(b.cone_axis.as_dvec3()).clamp(-1.0, 1.0).acos());
                if let Some((axis, alpha)) = cone {
                    // Moving each vertex by δ turns the normal by at most 2δ·perimeter/|n|;
                    // δ: a few f32 ulps of the magnitudes skinning summed.
                    let perimeter = (p2 - p1).length() + (p3 - p1).length() + (p3 - p2).length();
                    let magnitude =
                        [0, 1, 2].map(|k| sums[verts[t[k] as usize] as usize]).into_iter().fold(0.0, f64::max);
                    let delta = 2.4e-7 * magnitude;
                    let tol = 1e-6 + 2.0 * delta * perimeter / len;
                    let angle = (nw.dot(axis) / len).clamp(-1.0, 1.0).acos();
                    if angle > alpha + tol {
                        out.normal_violations += 1;
                        out.worst = out.worst.max((angle - alpha) / alpha.max(1e-12));
                    }
                }
            }
        }
        out
    };
    times.par_iter().map(per_time).reduce(|| Scan::new(n), Scan::merge)
}
