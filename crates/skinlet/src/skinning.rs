//! Reference linear blend skinning (LBS), the ground truth every bound in skinlet is
//! checked against: `p' = (Σ wᵢ Mᵢ) p` and `n' = normalize(cof(Σ wᵢ Mᵢ) n)` where `cof` is the
//! cofactor matrix (det × inverse-transpose, sign-corrected), i.e. the exact normal
//! transform of the blended linear map, also under non-uniform or negative scale.
//! [`skin_mesh`] first adds each vertex's morph target deltas (`p + Σ wₖ·dₖ`, normals alike),
//! as glTF specifies.
//!
//! Each vertex is computed independently in a fixed order, so the parallel and serial
//! entry points give bit-identical results.

use crate::model::{Influences, Morphs, SkinnedMesh};
use crate::{Error, Result};
use glam::{Affine3A, Mat3A, Vec3, Vec3A};
use rayon::prelude::*;

const CHUNK: usize = 4096;
/// Below this many vertices [`skin`] stays on the calling thread: waking the pool costs more
/// than it saves (measured: Xbot.glb's 12k- and 16k-vertex primitives skinned 2× slower in
/// parallel on a 2-core VM; the 1M-triangle demo 1.4× faster). See docs/PERFORMANCE.md.
const PARALLEL_MIN_VERTICES: usize = 50_000;

/// The blended skinning matrix of vertex `v`.
#[inline]
pub fn blend_matrix(influences: &Influences, v: usize, matrices: &[Affine3A]) -> Affine3A {
    let mut m = Affine3A { matrix3: Mat3A::ZERO, translation: Vec3A::ZERO };
    for (j, w) in influences.of(v) {
        let s = &matrices[j as usize];
        m.matrix3 += s.matrix3 * w;
        m.translation += s.translation * w;
    }
    m
}

/// Transforms a normal by the blended matrix `m` (inverse-transpose up to a positive scale).
#[inline]
pub fn transform_normal(m: &Affine3A, n: Vec3) -> Vec3 {
    let (a, b, c) = (m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis);
    let cof = Mat3A::from_cols(b.cross(c), c.cross(a), a.cross(b));
    let det = a.dot(b.cross(c));
    let r = Vec3::from(cof * Vec3A::from(n)) * det.signum();
    r.normalize_or_zero()
}

/// Checks lengths and joint numbers; returns the normal output slice to use (empty when the
/// mesh has no normals).
fn checked<'o>(
    influences: &Influences,
    positions: &[Vec3],
    normals: &[Vec3],
    matrices: &[Affine3A],
    out_positions: &[Vec3],
    out_normals: &'o mut [Vec3],
) -> Result<&'o mut [Vec3]> {
    let n = influences.vertex_count();
    if positions.len() != n || !(normals.is_empty() || normals.len() == n) {
        return Err(Error::invalid(
            "skinning",
            format!("{n} influence sets but {} positions and {} normals", positions.len(), normals.len()),
        ));
    }
    if let Some(j) = influences.joints.iter().copied().max().filter(|&j| j as usize >= matrices.len()) {
        return Err(Error::invalid(
            "skinning",
            format!("joint {j} used but only {} skinning matrices", matrices.len()),
        ));
    }
    let out_normals = if normals.is_empty() { &mut [][..] } else { out_normals };
    if out_positions.len() != n || out_normals.len() != normals.len() {
        return Err(Error::invalid("skinning", "output slices must have the input's lengths"));
    }
    Ok(out_normals)
}

/// Morph targets and the frame's weight values, applied to each vertex before skinning.
#[derive(Clone, Copy)]
struct Morphing<'a> {
    morphs: &'a Morphs,
    values: &'a [f32],
}

#[allow(clippy::too_many_arguments)]
fn skin_range(
    influences: &Influences,
    morphing: Option<Morphing>,
    start: usize,
    positions: &[Vec3],
    normals: &[Vec3],
    matrices: &[Affine3A],
    out_p: &mut [Vec3],
    out_n: &mut [Vec3],
) {
    for i in 0..out_p.len() {
        let v = start + i;
        let m = blend_matrix(influences, v, matrices);
        let n = normals.get(v).copied().unwrap_or(Vec3::ZERO);
        let (p, n) = match morphing {
            Some(mo) => mo.morphs.morph(v, mo.values, positions[v], n),
            None => (positions[v], n),
        };
        out_p[i] = m.transform_point3(p);
        if !out_n.is_empty() {
            out_n[i] = transform_normal(&m, n);
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn skin_all(
    influences: &Influences,
    morphing: Option<Morphing>,
    positions: &[Vec3],
    normals: &[Vec3],
    matrices: &[Affine3A],
    out_positions: &mut [Vec3],
    out_normals: &mut [Vec3],
    parallel: bool,
) -> Result<()> {
    let out_normals = checked(influences, positions, normals, matrices, out_positions, out_normals)?;
    if !parallel || positions.len() < PARALLEL_MIN_VERTICES {
        skin_range(influences, morphing, 0, positions, normals, matrices, out_positions, out_normals);
    } else if out_normals.is_empty() {
        out_positions.par_chunks_mut(CHUNK).enumerate().for_each(|(c, op)| {
            skin_range(influences, morphing, c * CHUNK, positions, normals, matrices, op, &mut []);
        });
    } else {
        out_positions.par_chunks_mut(CHUNK).zip(out_normals.par_chunks_mut(CHUNK)).enumerate().for_each(
            |(c, (op, on))| skin_range(influences, morphing, c * CHUNK, positions, normals, matrices, op, on),
        );
    }
    Ok(())
}

/// Skins every vertex, in parallel for large meshes. `normals` may be empty (then
/// `out_normals` is ignored).
pub fn skin(
    influences: &Influences,
    positions: &[Vec3],
    normals: &[Vec3],
    matrices: &[Affine3A],
    out_positions: &mut [Vec3],
    out_normals: &mut [Vec3],
) -> Result<()> {
    skin_all(influences, None, positions, normals, matrices, out_positions, out_normals, true)
}

/// Same as [`skin`], on the calling thread only.
pub fn skin_serial(
    influences: &Influences,
    positions: &[Vec3],
    normals: &[Vec3],
    matrices: &[Affine3A],
    out_positions: &mut [Vec3],
    out_normals: &mut [Vec3],
) -> Result<()> {
    skin_all(influences, None, positions, normals, matrices, out_positions, out_normals, false)
}

/// Skins a whole mesh: each vertex first moved by its morph deltas weighted by `weights`
/// (the frame's values of [`Morphs::weights`], see [`Morphs::weights_at`]; may be empty
/// for a mesh without morphs), then skinned like [`skin`]. `out_normals` may be empty.
pub fn skin_mesh(
    mesh: &SkinnedMesh,
    weights: &[f32],
    matrices: &[Affine3A],
    out_positions: &mut [Vec3],
    out_normals: &mut [Vec3],
) -> Result<()> {
    let inf = mesh.influences.as_ref().ok_or_else(|| Error::invalid("skinning", "the mesh has no skin weights"))?;
    let morphing = if mesh.morphs.is_empty() {
        None
    } else {
        mesh.morphs.check(mesh.positions.len())?;
        if weights.len() != mesh.morphs.weights.len() {
            return Err(Error::invalid(
                "skinning",
                format!("{} morph weight values for {} morph weights", weights.len(), mesh.morphs.weights.len()),
            ));
        }
        Some(Morphing { morphs: &mesh.morphs, values: weights })
    };
    let normals = if out_normals.is_empty() { &[][..] } else { &mesh.normals[..] };
    skin_all(inf, morphing, &mesh.positions, normals, matrices, out_positions, out_normals, true)
}

/// The positions of `mesh` (over the joints of `joints`, morphs applied) posed by `clip` at time `t` (`None`:
/// the clip's start), or in the rest pose without a clip: scene space, where a crowd is laid
/// out and a camera framed.
pub fn posed_positions(
    skeleton: &crate::Skeleton,
    joints: &crate::Skin,
    mesh: &crate::SkinnedMesh,
    clip: Option<&crate::clip::Clip>,
    t: Option<f32>,
) -> Result<Vec<Vec3>> {
    let (mut mats, mut weights) = (Vec::new(), Vec::new());
    let t = t.unwrap_or(clip.map_or(0.0, |c| c.start));
    crate::pose::Poser::default().skinning_matrices(skeleton, joints, clip, t, &mut mats);
    mesh.morphs.weights_at(clip, t, &mut weights);
    let mut out = vec![Vec3::ZERO; mesh.positions.len()];
    skin_mesh(mesh, &weights, &mats, &mut out, &mut [])?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    fn one_joint(n: usize) -> Influences {
        let mut inf = Influences { stride: 4, joints: vec![0; 4 * n], weights: vec![0.0; 4 * n] };
        (0..n).for_each(|v| inf.weights[4 * v] = 1.0);
        inf
    }

    #[test]
    fn single_influence_follows_a_known_rotation() {
        // Joint at (0, 1, 0) rotated 90° about Z; inverse bind moves the vertex into joint space.
        let joint = Affine3A::from_rotation_translation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2), Vec3::Y);
        let inverse_bind = Affine3A::from_translation(-Vec3::Y);
        let m = joint * inverse_bind;
        let (p, n) = ([Vec3::new(2.0, 1.0, 0.0)], [Vec3::X]);
        let (mut op, mut on) = ([Vec3::ZERO], [Vec3::ZERO]);
        skin(&one_joint(1), &p, &n, &[m], &mut op, &mut on).unwrap();
        // (2, 0, 0) from the joint rotates to (0, 2, 0), plus the joint's (0, 1, 0).
        assert!((op[0] - Vec3::new(0.0, 3.0, 0.0)).length() < 1e-6, "{}", op[0]);
        assert!((on[0] - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn normals_use_the_inverse_transpose() {
        // Non-uniform scale x2 along X: a 45° surface normal tilts towards X⁻¹ scaling.
        let m = Affine3A::from_scale(Vec3::new(2.0, 1.0, 1.0));
        let (mut op, mut on) = ([Vec3::ZERO], [Vec3::ZERO]);
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        skin(&one_joint(1), &[Vec3::ONE], &[n], &[m], &mut op, &mut on).unwrap();
        assert!((on[0] - Vec3::new(0.5, 1.0, 0.0).normalize()).length() < 1e-6);
        // Mirroring keeps the normal pointing out of the mirrored surface.
        let m = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        skin(&one_joint(1), &[Vec3::ONE], &[Vec3::X], &[m], &mut op, &mut on).unwrap();
        assert!((on[0] + Vec3::X).length() < 1e-6);
    }

    /// Three joints: a translation by (0, 2, 0), a 90° turn about z, a uniform scale by 2.
    fn three_joints() -> [Affine3A; 3] {
        [
            Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)),
            Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2),
            Affine3A::from_scale(Vec3::splat(2.0)),
        ]
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-6
    }

    #[test]
    fn three_influences_blend_as_computed_by_hand() {
        // Weights 0.5, 0.3, 0.2 on the point (1, 0, 0): 0.5·(1, 2, 0) + 0.3·(0, 1, 0) +
        // 0.2·(2, 0, 0) = (0.9, 1.3, 0). The blended linear part is L = 0.9·I_xy + 0.3·Rz
        // (a turn by atan(1/3) times √0.9 in xy) and 1.2 along z, so the normal (0, 1, 0)
        // turns like a vector: (−1, 3, 0)/√10; and (1, 0, 1)/√2 goes by L⁻ᵀ to (1, 1/3, 5/6),
        // i.e. (6, 2, 5)/√65. The slots in any order give the same result.
        let mats = three_joints();
        let n = [Vec3::Y, Vec3::new(1.0, 0.0, 1.0).normalize()];
        let want_n = [Vec3::new(-1.0, 3.0, 0.0) / 10f32.sqrt(), Vec3::new(6.0, 2.0, 5.0) / 65f32.sqrt()];
        for (joints, weights) in [([0, 1, 2, 0], [0.5, 0.3, 0.2, 0.0]), ([2, 0, 1, 0], [0.2, 0.5, 0.3, 0.0])] {
            let inf = Influences { stride: 4, joints: [joints; 2].concat(), weights: [weights; 2].concat() };
            let (mut op, mut on) = ([Vec3::ZERO; 2], [Vec3::ZERO; 2]);
            skin(&inf, &[Vec3::X; 2], &n, &mats, &mut op, &mut on).unwrap();
            assert!(close(op[0], Vec3::new(0.9, 1.3, 0.0)) && close(op[1], op[0]), "{op:?}");
            assert!(close(on[0], want_n[0]) && close(on[1], want_n[1]), "{on:?}");
        }
    }

    #[test]
    fn eight_influences_and_morphs_as_computed_by_hand() {
        // Stride 8: eight joints translating by k·(1, 0, 0), k = 0..7, weights 1/8 each move
        // a point by their mean, (3.5, 0, 0).
        let mats: Vec<Affine3A> = (0..8).map(|k| Affine3A::from_translation(Vec3::X * k as f32)).collect();
        let inf = Influences { stride: 8, joints: (0..8).rev().collect(), weights: vec![0.125; 8] };
        let mut op = [Vec3::ZERO];
        skin(&inf, &[Vec3::new(0.0, 1.0, 0.0)], &[], &mats, &mut op, &mut []).unwrap();
        assert!(close(op[0], Vec3::new(3.5, 1.0, 0.0)), "{:?}", op[0]);

        // Morphs first, then skinning: the point (1, 0, 0) with deltas (0, 0, 1) at weight
        // 0.5 and (1, 0, 0) at weight 0.25 rests at (1.25, 0, 0.5); the three joints above
        // at weights 0.5, 0.3, 0.2 take it to 0.5·(1.25, 2, 0.5) + 0.3·(0, 1.25, 0.5) +
        // 0.2·(2.5, 0, 1) = (1.125, 1.375, 0.6).
        let delta = |weight: u32, position: Vec3| crate::model::MorphDelta { weight, position, normal: Vec3::ZERO };
        let weight = |target: u32| crate::model::MorphWeight { node: 0, target, default: 0.0 };
        let mesh = SkinnedMesh {
            positions: vec![Vec3::X],
            influences: Some(Influences { stride: 4, joints: vec![0, 1, 2, 0], weights: vec![0.5, 0.3, 0.2, 0.0] }),
            morphs: crate::model::Morphs {
                weights: vec![weight(0), weight(1)],
                offsets: vec![0, 2],
                deltas: vec![delta(0, Vec3::Z), delta(1, Vec3::X)],
            },
            ..SkinnedMesh::default()
        };
        skin_mesh(&mesh, &[0.5, 0.25], &three_joints(), &mut op, &mut []).unwrap();
        assert!(close(op[0], Vec3::new(1.125, 1.375, 0.6)), "{:?}", op[0]);
    }

    #[test]
    fn serial_and_parallel_are_bit_identical() {
        let n = PARALLEL_MIN_VERTICES + 3 * CHUNK + 17;
        let mut seed = 1u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32
        };
        let mats: Vec<Affine3A> = (0..5)
            .map(|_| {
                Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.5 + rnd()),
                    Quat::from_rotation_y(6.0 * rnd()),
                    Vec3::splat(rnd()),
                )
            })
            .collect();
        let mut inf = Influences { stride: 4, joints: vec![0; 4 * n], weights: vec![0.0; 4 * n] };
        for v in 0..n {
            let (a, b) = (rnd(), rnd());
            inf.joints[4 * v..4 * v + 3].copy_from_slice(&[(v % 5) as u16, ((v + 1) % 5) as u16, ((v + 3) % 5) as u16]);
            inf.weights[4 * v..4 * v + 3].copy_from_slice(&[0.5 + a / 4.0, 0.5 - a / 4.0 - b / 4.0, b / 4.0]);
        }
        let p: Vec<Vec3> = (0..n).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
        let nrm: Vec<Vec3> = p.iter().map(|v| v.normalize()).collect();
        let (mut p1, mut n1, mut p2, mut n2) =
            (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n], vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        skin(&inf, &p, &nrm, &mats, &mut p1, &mut n1).unwrap();
        skin_serial(&inf, &p, &nrm, &mats, &mut p2, &mut n2).unwrap();
        assert!(p1.iter().zip(&p2).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
        assert!(n1.iter().zip(&n2).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
    }

    #[test]
    fn bad_joint_or_lengths_are_errors() {
        let mut inf = one_joint(1);
        inf.joints[0] = 3;
        let e = skin(&inf, &[Vec3::ZERO], &[], &[Affine3A::IDENTITY], &mut [Vec3::ZERO], &mut []).unwrap_err();
        assert!(e.to_string().contains("joint 3"), "{e}");
        let e = skin(&one_joint(2), &[Vec3::ZERO], &[], &[Affine3A::IDENTITY], &mut [Vec3::ZERO], &mut []).unwrap_err();
        assert!(e.to_string().contains("2 influence sets"), "{e}");
    }
}
