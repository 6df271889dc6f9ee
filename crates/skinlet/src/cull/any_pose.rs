//! Meshlet frustum culling that holds for any pose: per meshlet, one box per joint that
//! influences it, around its vertices in that joint's bind space (`inverse_bind · p`, morphs
//! within given weight ranges). The skinned vertex `Σ wⱼ·Gⱼ·(inverse_bindⱼ · p)` is a convex
//! combination of points of the joints' moved boxes, whatever the joint matrices `Gⱼ`
//! (shear, negative or zero scale included), so the meshlet lies in the convex hull of its
//! moved boxes, and is outside the frustum when all of them are outside one plane. This is
//! the per-joint box argument of Bevy's per-joint skinned bounds
//! (`per-joint-skinned-bounds-bevy-pr.txt`) applied per meshlet; Unreal's Nanite skinning
//! keeps a bone list per cluster for the same reason. No backface test: no normal bound
//! holds for every pose.
//!
//! It is the fallback when a pose leaves the pose envelope ([`crate::bounds::envelope`]),
//! and culls what the envelope's bounds keep where its caps are wide. Cost per meshlet
//! grows with its joint count, which skin-aware meshlets keep small. This module builds and
//! checks the boxes; [`super::meshlet::MeshletCuller::with_any_pose`] lays them out for
//! culling, where each box is tested exactly against the frustum planes moved into its
//! joint's space (f32, with a rounding margin far above the rounding).

use crate::bounds::Aabb;
use crate::bounds::meshlet::round_up;
use crate::bounds::vertex::morph_box;
use crate::meshlet::Meshlets;
use crate::model::{Skin, SkinnedMesh};
use crate::{Error, Result};
use glam::Vec3;

/// Per meshlet, a box per influencing joint, in that joint's bind space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AnyPoseBoxes {
    /// Boxes of meshlet `m`: `offsets[m]..offsets[m + 1]`.
    pub offsets: Vec<u32>,
    /// Per box: its joint (index into the skin's joints), center and half extents.
    pub joints: Vec<u16>,
    pub center: Vec<Vec3>,
    pub half: Vec<Vec3>,
}

impl AnyPoseBoxes {
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

    /// Checks boxes from outside (a file) against `meshlets` meshlets and `joints` joints:
    /// offsets from 0, non-decreasing, ending at the box count; joints in range; finite
    /// centers and non-negative finite half extents.
    pub fn check(&self, meshlets: usize, joints: usize) -> Result<()> {
        let bad = |what: String| Err(Error::invalid("any-pose boxes", what));
        let n = self.joints.len();
        if self.offsets.len() != meshlets + 1
            || self.offsets[0] != 0
            || *self.offsets.last().unwrap_or(&0) as usize != n
        {
            return bad(format!(
                "{} offsets ending at {:?} for {meshlets} meshlets and {n} boxes",
                self.offsets.len(),
                self.offsets.last()
            ));
        }
        if self.offsets.windows(2).any(|w| w[1] < w[0]) {
            return bad("offsets decrease".into());
        }
        if self.center.len() != n || self.half.len() != n {
            return bad(format!("{n} joints, {} centers, {} half extents", self.center.len(), self.half.len()));
        }
        if let Some(j) = self.joints.iter().find(|&&j| j as usize >= joints) {
            return bad(format!("a box of joint {j} of {joints}"));
        }
        if !(self.center.iter().all(|c| c.is_finite())
            && self.half.iter().all(|h| h.is_finite() && h.cmpge(Vec3::ZERO).all()))
        {
            return bad("a center or half extent is not finite, or negative".into());
        }
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
