//! Conservative box of a skinned vertex over a time interval, in the space of a target
//! joint (paper section 3.1 and 3.3). For influence `i` the vertex's bind position in joint
//! `i`'s frame, `IBMᵢ·v`, is carried step by step up the hierarchy with each node's local
//! motion (child to parent) to the lowest common ancestor, then down to the target with
//! inverse motions (eq. 2); never through decomposed global matrices, whose intermediate
//! extremes would be missed. The per-influence boxes are combined by the weighted Minkowski
//! sum (fig. 7): `Σ wᵢ·Bᵢ`, since the skinned point in target space is `Σ wᵢ·qᵢ(t)`.

use super::Aabb;
use super::motion::{Motion, node_motion};
use crate::Result;
use crate::clip::Clip;
use crate::model::{Influences, Skeleton, Skin};
use glam::{DVec3, Vec3};

/// Motions of every node during one interval `[t1, t2]` of a clip.
pub struct IntervalMotions {
    pub t1: f32,
    pub t2: f32,
    motions: Vec<Motion>,
    /// Parent links from each node to its root.
    depth: Vec<u32>,
}

impl IntervalMotions {
    /// Errors when `[t1, t2]` spans a key of some channel.
    pub fn new(skeleton: &Skeleton, clip: Option<&Clip>, t1: f32, t2: f32) -> Result<IntervalMotions> {
        let motions = skeleton
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| node_motion(n, i as u32, clip, t1, t2))
            .collect::<Result<Vec<_>>>()?;
        let mut depth = vec![0u32; skeleton.nodes.len()];
        for &i in &skeleton.order {
            if let Some(p) = skeleton.nodes[i as usize].parent {
                depth[i as usize] = depth[p as usize] + 1;
            }
        }
        Ok(IntervalMotions { t1, t2, motions, depth })
    }

    /// All points `global(to)⁻¹ · global(from) · x`, x in `b`, over the interval.
    pub fn carry(&self, skeleton: &Skeleton, from: u32, to: u32, b: Aabb) -> Aabb {
        let parent = |n: u32| skeleton.nodes[n as usize].parent;
        // Climb to the lowest common ancestor: `from`'s side applies motions on the way up,
        // `to`'s side is remembered and undone top-down afterwards.
        let (mut a, mut t, mut b) = (Some(from), Some(to), b);
        let mut down = [0u32; 64];
        let mut down_spill = Vec::new();
        let mut n_down = 0;
        let depth = |n: Option<u32>| n.map_or(-1, |n| self.depth[n as usize] as i64);
        while a != t {
            if depth(a) >= depth(t) {
                let n = a.expect("deeper side is a node");
                b = self.motions[n as usize].apply(&b);
                a = parent(n);
            } else {
                let n = t.expect("deeper side is a node");
                if n_down < down.len() {
                    down[n_down] = n
                } else {
                    down_spill.push(n)
                }
                n_down += 1;
                t = parent(n);
            }
        }
        for n in down_spill.iter().rev().chain(down[..n_down.min(down.len())].iter().rev()) {
            b = self.motions[*n as usize].apply_inverse(&b);
        }
        // Unbounded (a scale through zero): keep it unbounded rather than NaN.
        if b.is_finite() { b } else { Aabb::EVERYWHERE }
    }
}

/// Box containing vertex `v` (bind position `position`) at every time of the interval, in
/// the space of skin joint `target` (`global(joint node, t)⁻¹ · p(t)`), in exact arithmetic:
/// callers add [`super::INFLATE`] where f32 rounding of the reference must be covered. A
/// vertex bound to `target` alone gives a point.
pub fn vertex_box(
    skeleton: &Skeleton,
    skin: &Skin,
    motions: &IntervalMotions,
    influences: &Influences,
    v: usize,
    position: Vec3,
    target: u16,
) -> Aabb {
    let to = skin.joints[target as usize];
    let mut sum = Aabb::point(DVec3::ZERO);
    for (j, w) in influences.of(v) {
        let bind = skin.inverse_bind[j as usize].as_dmat4().transform_point3(position.as_dvec3());
        let b = motions.carry(skeleton, skin.joints[j as usize], to, Aabb::point(bind));
        let w = w as f64;
        sum.min += w * b.min;
        sum.max += w * b.max;
    }
    sum
}
