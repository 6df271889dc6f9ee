//! Ground-truth check of meshlet bounds: dense sampling of every clip (uniform times plus
//! every key time and every interval midpoint), reference skinning of every vertex with its
//! morph targets applied ([`crate::skinning`]), then each meshlet in its principal joint's
//! bind space with the tests the culler ([`skinlet_runtime::meshlet_cull`]) relies on: every skinned
//! vertex, moved back by the joint's inverse world matrix, inside the sphere, and every
//! triangle's face normal built from those points inside the cone (when the cone is below
//! 90°). The tolerance is the f32 rounding of the reference only: per vertex [`ROUNDING`] of
//! the magnitudes skinning sums (|M|·|p| + |t|), stretched into joint space by |A⁻¹|, plus
//! 1e-6 of the radius; for normals the angle such a move of the three vertices can cause
//! (1e-9 rad plus 2δ·perimeter/|n|). A joint whose matrix has no inverse cannot be checked
//! this way: its vertices are counted in [`VerifyReport::singular`] (the culler never
//! backface-culls them).

use super::sphere_cone::{MeshletBounds, key_intervals, rest_bounds};
use crate::clip::Clip;
use crate::meshlet::Meshlets;
use crate::model::{Skeleton, Skin, SkinnedMesh, Trs};
use crate::pose::{Poser, global_transforms, skinning_matrices};
use glam::{DMat3, Vec3};
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

/// How far f32 skinning may move a reference vertex, relative to the magnitudes it sums:
/// eight units of f32 rounding (2⁻²⁴ each).
pub const ROUNDING: f64 = 8.0 / (1u32 << 24) as f64;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VerifyReport {
    pub samples: usize,
    pub vertex_checks: usize,
    pub normal_checks: usize,
    pub vertex_violations: usize,
    pub normal_violations: usize,
    /// Vertex checks skipped because the joint's matrix had no inverse (a zero scale).
    pub singular: usize,
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

/// Checks `bounds` over every clip in `clips` at [`sample_times`]`(clip, uniform)`. Errors
/// when the inputs do not belong together (see [`check_inputs`]).
pub fn verify_bounds(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
    uniform: usize,
) -> crate::Result<VerifyReport> {
    check_inputs(skin, mesh, meshlets, bounds)?;
    let times: Vec<PoseAt> =
        clips.iter().flat_map(|c| sample_times(c, uniform).into_iter().map(move |t| PoseAt::Clip(c, t))).collect();
    Ok(report(&times, &scan(skeleton, skin, &times, mesh, meshlets, bounds), bounds))
}

/// That the mesh, its meshlets and bounds belong to `skin`: influences and principal joints
/// within its joints, morph targets within the mesh, meshlet vertices within the mesh, one
/// bound per meshlet.
pub fn check_inputs(
    skin: &Skin,
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
) -> crate::Result<()> {
    let joints = skin.joints.len();
    if let Some(inf) = &mesh.influences {
        inf.check(joints)?;
    }
    mesh.morphs.check(mesh.positions.len())?;
    let bad = |what: String| Err(crate::Error::invalid("verify", what));
    if bounds.len() != meshlets.len() {
        return bad(format!("{} bounds for {} meshlets", bounds.len(), meshlets.len()));
    }
    if let Some(v) = meshlets.vertices.iter().find(|&&v| v as usize >= mesh.positions.len()) {
        return bad(format!("a meshlet uses vertex {v} of {}", mesh.positions.len()));
    }
    if let Some(b) = bounds.iter().find(|b| b.joint as usize >= joints) {
        return bad(format!("a meshlet's principal joint {} is not one of the skin's {joints}", b.joint));
    }
    Ok(())
}

/// [`verify_bounds`] for poses given directly: every node's local transform (skeleton order)
/// and the morph weights' values, e.g. poses inside a pose envelope, blended or perturbed.
/// Errors when a pose has not one transform per node and one value per morph weight.
pub fn verify_poses(
    skeleton: &Skeleton,
    skin: &Skin,
    poses: &[(Vec<Trs>, Vec<f32>)],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
) -> crate::Result<VerifyReport> {
    if let Some(k) =
        poses.iter().position(|(l, w)| l.len() != skeleton.nodes.len() || w.len() != mesh.morphs.weights.len())
    {
        return Err(crate::Error::invalid(
            "verify",
            format!(
                "pose {k} has {} local transforms for {} nodes and {} morph weight values for {}",
                poses[k].0.len(),
                skeleton.nodes.len(),
                poses[k].1.len(),
                mesh.morphs.weights.len()
            ),
        ));
    }
    check_inputs(skin, mesh, meshlets, bounds)?;
    let poses: Vec<PoseAt> = poses.iter().map(|(l, w)| PoseAt::Locals(l, w)).collect();
    Ok(report(&poses, &scan(skeleton, skin, &poses, mesh, meshlets, bounds), bounds))
}

/// A pose to check: a clip at a time, or local transforms and morph weights.
#[derive(Clone, Copy)]
enum PoseAt<'a> {
    Clip(&'a Clip, f32),
    Locals(&'a [Trs], &'a [f32]),
}

fn report(poses: &[PoseAt], s: &Scan, bounds: &[MeshletBounds]) -> VerifyReport {
    let n = bounds.len().max(1) as f64;
    let radius_ratio = bounds
        .iter()
        .zip(&s.needed_radius)
        .map(|(b, &need)| if need > 1e-12 { b.radius as f64 / need } else { 1.0 })
        .sum::<f64>()
        / n;
    let coned: Vec<f64> = bounds
        .iter()
        .zip(&s.needed_angle)
        .filter(|(b, _)| (b.cone_angle as f64) < FRAC_PI_2)
        .map(|(b, &need)| if need > 1e-9 { b.cone_angle as f64 / need } else { 1.0 })
        .collect();
    VerifyReport {
        samples: poses.len(),
        vertex_checks: s.vertex_checks,
        normal_checks: s.normal_checks,
        vertex_violations: s.vertex_violations,
        normal_violations: s.normal_violations,
        singular: s.singular,
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
    let times: Vec<PoseAt> = clips
        .iter()
        .flat_map(|c| {
            (0..per_clip)
                .map(move |k| PoseAt::Clip(c, c.start + c.duration() * k as f32 / (per_clip - 1).max(1) as f32))
        })
        .collect();
    let s = scan(skeleton, skin, &times, mesh, meshlets, &bounds);
    for ((b, r), a) in bounds.iter_mut().zip(s.needed_radius).zip(s.needed_angle) {
        b.radius = b.radius.max(r as f32);
        if (b.cone_angle as f64) < FRAC_PI_2 {
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
    singular: usize,
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
            singular: 0,
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
        self.singular += o.singular;
        self.worst = self.worst.max(o.worst);
        self.needed_radius.iter_mut().zip(&o.needed_radius).for_each(|(a, b)| *a = a.max(*b));
        self.needed_angle.iter_mut().zip(&o.needed_angle).for_each(|(a, b)| *a = a.max(*b));
        self
    }
}

/// Skins the mesh at every time and checks every meshlet's vertices and face normals in its
/// principal joint's bind space, as the culler tests them.
fn scan(
    skeleton: &Skeleton,
    skin: &Skin,
    poses: &[PoseAt],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
) -> Scan {
    let n = meshlets.len();
    let Some(inf) = &mesh.influences else { return Scan::new(n) };
    let per_time = |pose: &PoseAt| {
        let (mut globals, mut mats, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        match *pose {
            PoseAt::Clip(clip, t) => {
                globals = Poser::default().globals(skeleton, Some(clip), t).to_vec();
                mesh.morphs.weights_at(Some(clip), t, &mut weights);
            }
            PoseAt::Locals(locals, w) => {
                global_transforms(skeleton, locals, &mut globals);
                weights.extend_from_slice(w);
            }
        }
        skinning_matrices(skin, &globals, &mut mats);
        let (morphed, _) = mesh.morphed(&weights);
        let mut p = vec![Vec3::ZERO; mesh.positions.len()];
        crate::skinning::skin_serial(inf, &morphed, &[], &mats, &mut p, &mut []).expect("validated mesh");
        // Per vertex, how far f32 rounding may have moved the reference: a few ulps of the
        // magnitudes skinning sums (|M|·|p| + |t|), which exceed the result's when the blended
        // matrix nearly collapses.
        let rounding: Vec<f64> = (0..p.len())
            .map(|v| {
                let m = crate::skinning::blend_matrix(inf, v, &mats);
                let q = morphed[v].abs();
                let sum = m.matrix3.x_axis.abs() * q.x
                    + m.matrix3.y_axis.abs() * q.y
                    + m.matrix3.z_axis.abs() * q.z
                    + m.translation.abs();
                ROUNDING * sum.max_element() as f64
            })
            .collect();
        let mut out = Scan::new(n);
        let mut q = Vec::new();
        let mut err = Vec::new();
        for (i, (m, b)) in meshlets.meshlets.iter().zip(bounds).enumerate() {
            let g = globals[skin.joints[b.joint as usize] as usize];
            let verts = meshlets.vertices_of(m);
            let a = DMat3::from_mat4(g);
            let det = a.determinant();
            if det == 0.0 || !det.is_finite() {
                out.singular += verts.len();
                continue;
            }
            // Into the joint's bind space, where the culler tests the sphere and the cone; the
            // reference's rounding grows there by at most |A⁻¹| (Frobenius norm).
            let to_joint = g.inverse();
            let inv = DMat3::from_mat4(to_joint);
            let stretch =
                (inv.x_axis.length_squared() + inv.y_axis.length_squared() + inv.z_axis.length_squared()).sqrt();
            q.clear();
            q.extend(verts.iter().map(|&v| to_joint.transform_point3(p[v as usize].as_dvec3())));
            err.clear();
            err.extend(verts.iter().map(|&v| stretch * rounding[v as usize]));
            let (center, radius) = (b.center.as_dvec3(), b.radius as f64);
            for (qv, e) in q.iter().zip(&err) {
                let d = qv.distance(center);
                if d > radius * (1.0 + 1e-6) + e {
                    out.vertex_violations += 1;
                    out.worst = out.worst.max((d - radius) / radius.max(1e-12));
                }
                out.needed_radius[i] = out.needed_radius[i].max(d);
                out.vertex_checks += 1;
            }
            // Face normals from the joint-space vertices: (A⁻¹u)×(A⁻¹v) = det(A)⁻¹·Aᵀ(u×v),
            // the bind-space normal whose cone the culler tests (mirroring included).
            let (axis, alpha) = (b.cone_axis.as_dvec3(), b.cone_angle as f64);
            for t in meshlets.triangles_of(m).chunks_exact(3) {
                let [i1, i2, i3] = [0, 1, 2].map(|k| t[k] as usize);
                let (q1, q2, q3) = (q[i1], q[i2], q[i3]);
                let nj = (q2 - q1).cross(q3 - q1);
                let len = nj.length();
                if len == 0.0 {
                    continue;
                }
                out.normal_checks += 1;
                let angle = (nj.dot(axis) / len).clamp(-1.0, 1.0).acos();
                out.needed_angle[i] = out.needed_angle[i].max(angle);
                if alpha < FRAC_PI_2 {
                    // Moving each vertex by δ turns the normal by at most 2δ·perimeter/|n|.
                    let perimeter = (q2 - q1).length() + (q3 - q1).length() + (q3 - q2).length();
                    let delta = err[i1].max(err[i2]).max(err[i3]);
                    if angle > alpha + 1e-9 + 2.0 * delta * perimeter / len {
                        out.normal_violations += 1;
                        out.worst = out.worst.max((angle - alpha) / alpha.max(1e-12));
                    }
                }
            }
        }
        out
    };
    poses.par_iter().map(per_time).reduce(|| Scan::new(n), Scan::merge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bounds::sphere_cone::meshlet_bounds;
    use crate::clip::{Channel, Interpolation};
    use crate::meshlet::{Builder, MeshletLimits, build, prepare};
    use crate::model::{Influences, Node, Trs};
    use glam::{Mat4, Quat, Vec4};

    /// A flat 4×4 grid in the bind-space plane x = 0, rigidly bound to a joint that stretches
    /// x four times and shears it into y, under a root that turns about y over the clip.
    fn stretched_patch() -> (Skeleton, Skin, Clip, SkinnedMesh) {
        let stretch = Mat4::from_cols(Vec4::new(4.0, 0.8, 0.0, 0.0), Vec4::Y, Vec4::Z, Vec4::new(0.0, 1.0, 0.0, 1.0));
        let skeleton = Skeleton::new(vec![
            Node { name: "root".into(), parent: None, rest: Trs::IDENTITY, matrix: None },
            Node { name: "stretched".into(), parent: Some(0), rest: Trs::IDENTITY, matrix: Some(stretch) },
        ])
        .unwrap();
        let skin = Skin { name: "skin".into(), joints: vec![1], inverse_bind: vec![Mat4::IDENTITY] };
        let turn = Channel {
            node: 0,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![Quat::IDENTITY, Quat::from_rotation_y(1.2)],
        };
        let clip = Clip { name: "turn".into(), rotations: vec![turn], start: 0.0, end: 1.0, ..Clip::default() };
        let positions: Vec<Vec3> =
            (0..16).map(|i| Vec3::new(0.0, (i % 4) as f32 * 0.3, (i / 4) as f32 * 0.3)).collect();
        let triangles = (0..3)
            .flat_map(|y| (0..3).map(move |x| y * 4 + x))
            .flat_map(|i| [[i, i + 1, i + 5], [i, i + 5, i + 4]])
            .collect();
        let influences = Influences { stride: 4, joints: vec![0; 64], weights: [1.0, 0.0, 0.0, 0.0].repeat(16) };
        let mesh = SkinnedMesh { positions, triangles, influences: Some(influences), ..SkinnedMesh::default() };
        (skeleton, skin, clip, mesh)
    }

    #[test]
    fn a_mesh_of_another_skin_is_an_error_not_a_panic() {
        // Vertex 0 on joint 3 of a one-joint skin: skinning it would index past the matrices.
        let (skeleton, skin, clip, mut mesh) = stretched_patch();
        mesh.influences.as_mut().unwrap().joints[0] = 3;
        let e = verify_bounds(&skeleton, &skin, &[&clip], &mesh, &Meshlets::default(), &[], 5).unwrap_err().to_string();
        assert!(e.contains("vertex 0 uses joint 3 of 1"), "{e}");
    }

    /// Under strong non-uniform scale and shear, bounds that a world-space sphere (radius ×
    /// the largest scale) would accept but the culler's joint-space sphere does not are caught,
    /// and so is a cone that misses the bind-space normals.
    #[test]
    fn checks_in_the_culler_space_under_stretch_and_shear() {
        let (skeleton, skin, clip, mesh) = stretched_patch();
        let prepared = prepare(&mesh).unwrap();
        let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
        let bounds = meshlet_bounds(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets).unwrap();
        let check = |bounds: &[MeshletBounds]| {
            verify_bounds(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets, bounds, 20).unwrap()
        };
        let good = check(&bounds);
        assert_eq!(good.violations(), 0, "{good:?}");
        assert!(good.vertex_checks > 0 && good.normal_checks > 0 && good.singular == 0, "{good:?}");

        // Half the radius: every skinned vertex is still within that radius × 4 (≤ the joint's
        // largest scale) of the moved center, so a world-space check would pass.
        let halved: Vec<MeshletBounds> =
            bounds.iter().map(|b| MeshletBounds { radius: b.radius / 2.0, ..*b }).collect();
        let mut poser = Poser::default();
        for t in sample_times(&clip, 20) {
            let g = poser.globals(&skeleton, Some(&clip), t)[1];
            for (m, b) in meshlets.meshlets.iter().zip(&halved) {
                let center = g.transform_point3(b.center.as_dvec3());
                for &v in meshlets.vertices_of(m) {
                    let p = g.transform_point3(prepared.mesh.positions[v as usize].as_dvec3());
                    assert!(p.distance(center) <= b.radius as f64 * 4.0);
                }
            }
        }
        let r = check(&halved);
        assert!(r.vertex_violations > 0 && r.normal_violations == 0, "{r:?}");

        // The cone tilted by 0.2 rad and narrowed to 0.1 rad misses the (flat) normals.
        let perp = bounds[0].cone_axis.any_orthonormal_vector();
        let tilted: Vec<MeshletBounds> = bounds
            .iter()
            .map(|b| MeshletBounds { cone_axis: Quat::from_axis_angle(perp, 0.2) * b.cone_axis, cone_angle: 0.1, ..*b })
            .collect();
        let r = check(&tilted);
        assert!(r.normal_violations > 0 && r.vertex_violations == 0, "{r:?}");
    }
}
