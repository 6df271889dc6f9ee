//! Building the any-pose boxes of [`skinlet_runtime::any_pose`] (per meshlet, a box per
//! influencing joint in that joint's bind space, morphs within given weight ranges): valid
//! for any pose, the culler's fallback when a pose leaves the pose envelope.

use crate::bounds::Aabb;
use crate::bounds::sphere_cone::round_up;
use crate::bounds::vertex::morph_box;
use crate::meshlet::Meshlets;
use crate::model::{Skin, SkinnedMesh};
use crate::{Error, Result};
use glam::Vec3;
pub use skinlet_runtime::any_pose::AnyPoseBoxes;

/// The boxes of every meshlet: per vertex and nonzero influence, the vertex's box over
/// the morph weight `ranges` (one per `mesh.morphs.weights`; see
/// [`crate::bounds::vertex::morph_box`]) moved into the joint's bind space, grown by
/// [`crate::bounds::INFLATE`] for f32 rounding and rounded outwards to f32.
pub fn build(skin: &Skin, mesh: &SkinnedMesh, meshlets: &Meshlets, ranges: &[(f64, f64)]) -> Result<AnyPoseBoxes> {
    let inf =
        mesh.influences.as_ref().ok_or_else(|| Error::invalid("any-pose boxes", "the mesh has no skin weights"))?;
    mesh.morphs.check(mesh.positions.len())?;
    if ranges.len() != mesh.morphs.weights.len() {
        return Err(Error::invalid(
            "any-pose boxes",
            format!("{} weight ranges for {} morph weights", ranges.len(), mesh.morphs.weights.len()),
        ));
    }
    inf.check(skin.joints.len())?;
    let ibm: Vec<glam::DMat4> = skin.inverse_bind.iter().map(|m| m.as_dmat4()).collect();
    let mut out = AnyPoseBoxes { offsets: vec![0], ..AnyPoseBoxes::default() };
    let mut boxes: Vec<(u16, Aabb)> = Vec::new();
    for m in &meshlets.meshlets {
        boxes.clear();
        for &v in meshlets.vertices_of(m) {
            let rest = morph_box(mesh, v as usize, ranges);
            for (j, _) in inf.of(v as usize) {
                let b = rest.transformed(&ibm[j as usize]);
                match boxes.iter_mut().find(|(bj, _)| *bj == j) {
                    Some((_, acc)) => *acc = acc.union(&b),
                    None => boxes.push((j, b)),
                }
            }
        }
        boxes.sort_by_key(|(j, _)| *j);
        for (j, b) in &boxes {
            let b = b.inflated(crate::bounds::INFLATE);
            // The f32 center, and half extents rounded up from it: the stored box
            // contains the f64 one.
            let c = ((b.min + b.max) / 2.0).as_vec3();
            let h = (b.max - c.as_dvec3()).max(c.as_dvec3() - b.min);
            out.joints.push(*j);
            out.center.push(c);
            out.half.push(Vec3::new(round_up(h.x), round_up(h.y), round_up(h.z)));
        }
        out.offsets.push(out.joints.len() as u32);
    }
    Ok(out)
}
