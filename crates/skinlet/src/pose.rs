//! From local transforms to skinning matrices: global node transforms (parent × local,
//! evaluated in double precision along [`Skeleton::order`]) and per-joint skinning
//! matrices `global(joint) × inverse_bind(joint)`, as glTF 2.0 section 3.7.3 defines.
//! The transform of the node that instantiates a skinned mesh is ignored, as the spec says.

use crate::clip::Clip;
use crate::model::{Skeleton, Skin, Trs};
use glam::{Affine3A, DMat4, Mat4};

/// Global transforms of every node for the given local transforms (one per node; a node
/// past the end of `locals` keeps its rest transform).
pub fn global_transforms(skeleton: &Skeleton, locals: &[Trs], out: &mut Vec<DMat4>) {
    out.clear();
    out.resize(skeleton.nodes.len(), DMat4::IDENTITY);
    for &i in &skeleton.order {
        let node = &skeleton.nodes[i as usize];
        let local = match node.matrix {
            Some(m) => m.as_dmat4(),
            None => locals.get(i as usize).unwrap_or(&node.rest).to_dmat4(),
        };
        out[i as usize] = match node.parent {
            Some(p) => out[p as usize] * local,
            None => local,
        };
    }
}

/// The global matrices of a skin's joints, in skin order (what joint-space bounds are moved
/// by), in f32. A joint whose node is past `globals` (a skin of another file) gets a NaN
/// matrix, which every culling test takes for "unknown": never culled.
pub fn joint_globals(skin: &Skin, globals: &[DMat4], out: &mut Vec<Affine3A>) {
    out.clear();
    out.extend(skin.joints.iter().map(|&j| Affine3A::from_mat4(global(globals, j).as_mat4())));
}

/// Skinning matrices `global × inverse_bind` of a skin's joints (NaN for a joint whose node
/// is past `globals`, as [`joint_globals`]).
pub fn skinning_matrices(skin: &Skin, globals: &[DMat4], out: &mut Vec<Affine3A>) {
    out.clear();
    out.extend(skin.joints.iter().zip(&skin.inverse_bind).map(|(&j, ibm)| {
        let m: Mat4 = (global(globals, j) * ibm.as_dmat4()).as_mat4();
        Affine3A::from_mat4(m)
    }));
}

/// Node `j`'s global matrix, NaN past the end of `globals`.
fn global(globals: &[DMat4], j: u32) -> DMat4 {
    globals.get(j as usize).copied().unwrap_or(DMat4::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Node;

    #[test]
    fn a_skin_of_another_file_gets_nan_matrices_not_a_panic() {
        let skeleton =
            Skeleton::new(vec![Node { name: "root".into(), parent: None, rest: Trs::IDENTITY, matrix: None }]).unwrap();
        let mut globals = Vec::new();
        global_transforms(&skeleton, &[], &mut globals);
        assert_eq!(globals, [DMat4::IDENTITY], "too few locals: the rest pose");
        let skin = Skin { name: "other".into(), joints: vec![0, 7], inverse_bind: vec![Mat4::IDENTITY; 2] };
        let mut out = Vec::new();
        skinning_matrices(&skin, &globals, &mut out);
        assert!(out[0] == Affine3A::IDENTITY && out[1].translation.is_nan());
        joint_globals(&skin, &globals, &mut out);
        assert!(out[0] == Affine3A::IDENTITY && out[1].translation.is_nan());
    }
}

/// Reusable scratch space for posing one skeleton many times without allocating.
#[derive(Default)]
pub struct Poser {
    locals: Vec<Trs>,
    globals: Vec<DMat4>,
}

impl Poser {
    /// Global transforms of every node for `clip` at time `t` (`None`: the rest pose).
    pub fn globals(&mut self, skeleton: &Skeleton, clip: Option<&Clip>, t: f32) -> &[DMat4] {
        match clip {
            Some(c) => c.sample_locals(skeleton, t, &mut self.locals),
            None => {
                self.locals.clear();
                self.locals.extend(skeleton.nodes.iter().map(|n| n.rest));
            }
        }
        global_transforms(skeleton, &self.locals, &mut self.globals);
        &self.globals
    }

    /// Skinning matrices of `skin` for `clip` at time `t`.
    pub fn skinning_matrices(
        &mut self,
        skeleton: &Skeleton,
        skin: &Skin,
        clip: Option<&Clip>,
        t: f32,
        out: &mut Vec<Affine3A>,
    ) {
        self.globals(skeleton, clip, t);
        skinning_matrices(skin, &self.globals, out);
    }
}
