//! Per-meshlet bounding spheres that hold over whole clips (paper section 5, fig. 9).
//!
//! Each meshlet gets a principal joint (largest summed weight over its vertices, section 3)
//! and a reference sphere: the rest-pose bounding sphere of its vertices in that joint's bind
//! space (`inverse_bind · position`). Its radius is then extended until the sphere contains
//! the meshlet's conservative box ([`super::vertex`]) over every key interval of every given
//! clip. At run time the sphere is moved by the joint's global matrix `G`: center `G·c`,
//! radius `r·σ_max(G)` ([`max_scale`]), which contains every skinned vertex at every time.

use super::vertex::{IntervalMotions, vertex_box};
use crate::Result;
use crate::clip::Clip;
use crate::meshlet::{Meshlets, stats::principal_joint};
use crate::model::{Skeleton, Skin, SkinnedMesh};
use glam::{DMat4, DVec3, Vec3};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshletSphere {
    /// Principal joint (index into the skin's joints).
    pub joint: u16,
    /// Center in the joint's bind space.
    pub center: Vec3,
    /// Radius that holds over every interval of the clips the bounds were computed for.
    pub radius: f32,
    /// Radius of the rest-pose sphere.
    pub rest_radius: f32,
}

/// The key intervals of a clip: consecutive distinct key times (one degenerate interval for a
/// single key). Outside them every channel is constant, so they cover all times.
pub fn key_intervals(clip: &Clip) -> Vec<(f32, f32)> {
    let keys = clip.key_times();
    match keys.len() {
        0 => vec![(0.0, 0.0)],
        1 => vec![(keys[0], keys[0])],
        _ => keys.windows(2).map(|w| (w[0], w[1])).collect(),
    }
}

/// Spheres for every meshlet, conservative over every key interval of every clip in `clips`
/// (no clip: the rest pose only).
pub fn meshlet_spheres(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
) -> Result<Vec<MeshletSphere>> {
    let Some(inf) = &mesh.influences else {
        return Err(crate::Error::invalid("meshlet bounds", "the mesh has no skin weights"));
    };
    let mut spheres = rest_spheres(skin, mesh, meshlets);
    let intervals: Vec<(&Clip, f32, f32)> =
        clips.iter().flat_map(|c| key_intervals(c).into_iter().map(move |(a, b)| (*c, a, b))).collect();
    let motions =
        intervals.iter().map(|&(c, a, b)| IntervalMotions::new(skeleton, Some(c), a, b)).collect::<Result<Vec<_>>>()?;
    spheres.par_iter_mut().zip(&meshlets.meshlets).for_each(|(s, m)| {
        let c = s.center.as_dvec3();
        let mut r = s.radius as f64;
        for mo in &motions {
            for &v in meshlets.vertices_of(m) {
                let b = vertex_box(skeleton, skin, mo, inf, v as usize, mesh.positions[v as usize], s.joint);
                r = r.max(b.max_distance(c));
            }
        }
        // Round up so the f32 radius still contains the f64 one.
        s.radius = next_up(r as f32, r);
    });
    Ok(spheres)
}

fn next_up(x: f32, exact: f64) -> f32 {
    if (x as f64) >= exact { x } else { f32::from_bits(x.to_bits() + 1) }
}

/// An upper bound of the largest singular value of `m`'s 3×3 part: the square root of the
/// largest Gershgorin row sum of `mᵀm` (exact for rotations with uniform scale).
pub fn max_scale(m: &DMat4) -> f64 {
    let a = glam::DMat3::from_mat4(*m);
    let ata = a.transpose() * a;
    (0..3).map(|i| (0..3).map(|j| ata.col(j)[i].abs()).sum::<f64>()).fold(0.0, f64::max).sqrt()
}

/// Rest-pose spheres: principal joint, bounding sphere of the meshlet's vertices in that
/// joint's bind space (center of their box, radius to the farthest vertex).
pub fn rest_spheres(skin: &Skin, mesh: &SkinnedMesh, meshlets: &Meshlets) -> Vec<MeshletSphere> {
    meshlets
        .meshlets
        .iter()
        .map(|m| {
            let verts = meshlets.vertices_of(m);
            let joint = principal_joint(mesh, verts).map_or(0, |(j, _)| j);
            let ibm = skin.inverse_bind[joint as usize].as_dmat4();
            let bind: Vec<DVec3> =
                verts.iter().map(|&v| ibm.transform_point3(mesh.positions[v as usize].as_dvec3())).collect();
            let (lo, hi) = bind.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
            let center = (lo + hi) / 2.0;
            let r = bind.iter().map(|p| p.distance(center)).fold(0.0, f64::max);
            MeshletSphere { joint, center: center.as_vec3(), radius: next_up(r as f32, r), rest_radius: r as f32 }
        })
        .collect()
}
