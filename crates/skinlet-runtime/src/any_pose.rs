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
//! It is the fallback when a pose leaves the pose envelope ([`crate::pose_guard`]),
//! and culls what the envelope's bounds keep where its caps are wide. Cost per meshlet
//! grows with its joint count, which skin-aware meshlets keep small. The baker builds the
//! boxes (`skinlet::cull::any_pose::build`); this module holds and checks them, and
//! [`crate::meshlet_cull::MeshletCuller::with_any_pose`] lays them out for culling, where
//! each box is tested exactly against the frustum planes moved into its joint's space (f32,
//! with a rounding margin far above the rounding).

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
