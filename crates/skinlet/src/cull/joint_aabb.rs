//! Building whole-mesh per-joint boxes (the approach of Bevy's "per-joint skinned bounds"
//! pull request, `per-joint-skinned-bounds-bevy-pr.txt`), whose run-time update is
//! [`skinlet_runtime::joint_boxes`]: each joint gets the box of the bind-pose vertices with a
//! nonzero weight on it, in mesh space or in the joint's own space ([`JointSpace`]).
//!
//! Beyond the pull request: [`fold_leaves`] folds leaf joints (fingers, face) into an
//! ancestor's box, which the PR suggests but which is unsafe as it describes it (the folded
//! vertices do not move with the ancestor); here the folded box is the conservative box of
//! those vertices in the ancestor's space over every key interval of the given clips
//! ([`crate::bounds::vertex`]), so it stays a guarantee for those clips.

use crate::bounds::Aabb as DAabb;
use crate::bounds::sphere_cone::key_intervals;
use crate::bounds::vertex::{IntervalMotions, clip_weight_ranges, morph_box};
use crate::clip::Clip;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use crate::{Error, Result};
pub use skinlet_runtime::joint_boxes::{Box3, JointBoxes, JointSpace, Policy, points_box};

/// Boxes of the vertices with a nonzero weight on each joint. A vertex that morph targets
/// move counts with its box over every weight value of `clips` (no clip: the default
/// weights; see [`crate::bounds::vertex::clip_weight_ranges`]), so the boxes hold for
/// those clips. Errors when the mesh has no skin weights or a joint index has no inverse
/// bind matrix.
pub fn joint_boxes(mesh: &SkinnedMesh, skin: &Skin, space: JointSpace, clips: &[&Clip]) -> Result<JointBoxes> {
    let inf = mesh.influences.as_ref().ok_or_else(|| Error::invalid("joint boxes", "the mesh has no skin weights"))?;
    mesh.morphs.check(mesh.positions.len())?;
    let ranges = clip_weight_ranges(&mesh.morphs, clips)?;
    let mut boxes = vec![DAabb::EMPTY; skin.joints.len()];
    for v in 0..mesh.positions.len() {
        let rest = morph_box(mesh, v, &ranges);
        for (j, _) in inf.of(v) {
            let ibm = skin.inverse_bind.get(j as usize).ok_or_else(|| {
                Error::invalid("joint boxes", format!("vertex {v} uses joint {j} of {}", skin.joints.len()))
            })?;
            let q = match space {
                JointSpace::Mesh => rest,
                JointSpace::Joint => rest.transformed(&ibm.as_dmat4()),
            };
            boxes[j as usize] = boxes[j as usize].union(&q);
        }
    }
    Ok(JointBoxes::from_boxes(space, &extents(&boxes))?)
}

/// Folds leaf joints into ancestors, `levels` times (a leaf: a skin joint with no skin
/// joint below it that still has a box). The folded vertices' boxes are carried into the
/// ancestor's space conservatively over every key interval of `clips`, so the result is
/// a guarantee for those clips (not for other animation). Joint space only.
pub fn fold_leaves(
    boxes_in: &JointBoxes,
    skeleton: &Skeleton,
    skin: &Skin,
    mesh: &SkinnedMesh,
    clips: &[&Clip],
    levels: usize,
) -> Result<JointBoxes> {
    if boxes_in.space != JointSpace::Joint {
        return Err(Error::unsupported("joint boxes", "folding needs boxes in joint space"));
    }
    let inf = mesh.influences.as_ref().ok_or_else(|| Error::invalid("joint boxes", "the mesh has no skin weights"))?;
    mesh.morphs.check(mesh.positions.len())?;
    let n = skin.joints.len();
    // Nearest ancestor joint of each joint (skin order), through non-joint nodes.
    let slot_of_node = |node: u32| skin.joints.iter().position(|&x| x == node);
    let parent: Vec<Option<usize>> = (0..n)
        .map(|j| {
            let mut p = skeleton.nodes[skin.joints[j] as usize].parent;
            while let Some(node) = p {
                if let Some(s) = slot_of_node(node) {
                    return Some(s);
                }
                p = skeleton.nodes[node as usize].parent;
            }
            None
        })
        .collect();
    let mut target: Vec<usize> = (0..n).collect();
    let mut alive: Vec<bool> = (0..n).map(|j| boxes_in.joints.contains(&(j as u16))).collect();
    for _ in 0..levels {
        let has_child: Vec<bool> = (0..n).map(|j| (0..n).any(|k| alive[k] && parent[k] == Some(j))).collect();
        let leaves: Vec<usize> = (0..n).filter(|&j| alive[j] && !has_child[j] && parent[j].is_some()).collect();
        for j in leaves {
            alive[j] = false;
            let p = parent[j].expect("leaves have a parent");
            alive[p] = true;
            for t in target.iter_mut().filter(|t| **t == j) {
                *t = p;
            }
        }
    }
    let mut boxes = vec![DAabb::EMPTY; n];
    let mut motions = Vec::new();
    for c in clips {
        for (a, b) in key_intervals(c) {
            motions.push(IntervalMotions::new(skeleton, &mesh.morphs, Some(c), a, b)?);
        }
    }
    if motions.is_empty() {
        motions.push(IntervalMotions::new(skeleton, &mesh.morphs, None, 0.0, 0.0)?);
    }
    for v in 0..mesh.positions.len() {
        for (j, _) in inf.of(v) {
            let (j, t) = (j as usize, target[j as usize]);
            let ibm = skin.inverse_bind[j].as_dmat4();
            for mo in &motions {
                let q = mo.rest_box(mesh, v).transformed(&ibm);
                let carried = if t == j { q } else { mo.carry(skeleton, skin.joints[j], skin.joints[t], q) };
                boxes[t] = boxes[t].union(&carried);
            }
        }
    }
    if boxes.iter().any(|b| !b.is_finite() && b.min.cmple(b.max).all()) {
        return Err(Error::unsupported("joint boxes", "a folded joint's motion is unbounded (a scale through zero)"));
    }
    Ok(JointBoxes::from_boxes(JointSpace::Joint, &extents(&boxes))?)
}

/// f64 boxes as the `(min, max)` extents [`JointBoxes::from_boxes`] takes.
fn extents(boxes: &[DAabb]) -> Vec<(glam::DVec3, glam::DVec3)> {
    boxes.iter().map(|b| (b.min, b.max)).collect()
}
