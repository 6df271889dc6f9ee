//! The joint-box update of Bevy's per-joint skinned bounds pull request
//! (`per-joint-skinned-bounds-bevy-pr.txt`), reimplemented as the baseline that
//! [`JointBoxes::update_all`] is measured against, and the workload both run on.
//!
//! As the PR describes it: joint boxes `{center, half_size}` in mesh space, shared by all
//! instances (they live in the mesh asset); per instance, each joint's world transform is
//! fetched through its entity (location lookup with a generation check, then the table row,
//! as an ECS query does), multiplied by the joint's inverse bind pose, the box moved into
//! world space with Arvo's method, and the union moved into entity space by the inverse of
//! the entity's transform. Mesh entities and joint entities live in different archetype
//! tables, so the rows are not the entity indices. `flat` skips the location lookup (entity
//! index = row), an idealized layout.
//!
//! Ours ([`Workload::palette`]): joint-space boxes moved by entity-space joint matrices, one
//! array for all instances, no matrix product and no lookup.

use crate::crowd::{CrowdParams, posed_crowd};
use glam::{Affine3A, Vec3A};
use skinlet::cull::joint_aabb::{Box3, JointBoxes, JointSpace, joint_boxes};
use skinlet::model::Asset;
use skinlet::pose::Poser;
use skinlet::{Character, Result};

/// Bevy's mesh-space joint box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointAabb {
    pub center: Vec3A,
    pub half_size: Vec3A,
}

/// An ECS entity's location: generation and table row (Bevy's `EntityMeta`, reduced).
#[derive(Clone, Copy, Debug, PartialEq)]
struct EntityMeta {
    generation: u32,
    row: u32,
}

/// One character in Bevy's layout: its joint entities and its mesh entity, each
/// `(entity index, generation)`.
#[derive(Clone, Debug, PartialEq)]
struct BevyInstance {
    joints: Vec<(u32, u32)>,
    entity: (u32, u32),
}

/// Bevy's data: the mesh asset's joint boxes (with the skin joint of each), the shared
/// inverse bind poses asset, per instance the joint entities and the mesh entity, and one
/// scene-wide array of global transforms (an ECS component table).
#[derive(Clone, Debug, PartialEq)]
pub struct BevyScene {
    boxes: Vec<(usize, JointAabb)>,
    inverse_bindposes: Vec<Affine3A>,
    instances: Vec<BevyInstance>,
    transforms: Vec<Affine3A>,
    metas: Vec<EntityMeta>,
}

impl BevyScene {
    /// `Query::get(entity)` for the global transform.
    #[inline]
    fn transform(&self, (index, generation): (u32, u32), flat: bool) -> Option<&Affine3A> {
        if flat {
            return self.transforms.get(index as usize);
        }
        let meta = self.metas.get(index as usize)?;
        if meta.generation != generation {
            return None;
        }
        self.transforms.get(meta.row as usize)
    }

    /// Number of instances.
    pub fn len(&self) -> usize {
        self.instances.len()
    }

    pub fn is_empty(&self) -> bool {
        self.instances.is_empty()
    }

    /// Joint boxes per instance.
    pub fn boxes(&self) -> usize {
        self.boxes.len()
    }

    /// The entity-space box of every instance into `out` (cleared first).
    pub fn update(&self, flat: bool, out: &mut Vec<Box3>) {
        out.clear();
        for inst in &self.instances {
            let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
            for &(j, b) in &self.boxes {
                let Some(joint) = self.transform(inst.joints[j], flat) else { continue };
                let world_from_mesh = *joint * self.inverse_bindposes[j];
                let center = world_from_mesh.transform_point3a(b.center);
                let m = world_from_mesh.matrix3;
                let half =
                    m.x_axis.abs() * b.half_size.x + m.y_axis.abs() * b.half_size.y + m.z_axis.abs() * b.half_size.z;
                lo = lo.min(center - half);
                hi = hi.max(center + half);
            }
            // World box to entity space (Arvo again, with the inverse entity transform).
            let Some(entity) = self.transform(inst.entity, flat) else { continue };
            let inv = entity.inverse();
            let (c, h) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
            let m = inv.matrix3;
            let center = inv.transform_point3a(c);
            let half = m.x_axis.abs() * h.x + m.y_axis.abs() * h.y + m.z_axis.abs() * h.z;
            out.push(Box3 { min: (center - half).into(), max: (center + half).into() });
        }
    }
}

/// `instances` copies of a character, each at a random time of a clip, placed as in the
/// crowd scene: the data of both updates.
#[derive(Clone, Debug)]
pub struct Workload {
    /// Bevy's layout, with the ECS lookup.
    pub bevy: BevyScene,
    /// The same, entity index = table row.
    pub bevy_flat: BevyScene,
    /// Our joint-space boxes.
    pub boxes: JointBoxes,
    /// Entity-space joint matrices of every instance, `stride` per instance.
    pub palette: Vec<Affine3A>,
    pub stride: usize,
    /// The character posed.
    pub character: Character,
}

impl Workload {
    /// Poses `instances` copies of the whole character of `asset` (seeded random times).
    pub fn new(asset: &Asset, instances: usize, seed: u64) -> Result<Workload> {
        let character = asset.character()?;
        let (skin, mesh) = (&character.palette, &character.mesh);
        let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
        let boxes = joint_boxes(mesh, skin, JointSpace::Joint, &clips)?;
        let mesh_boxes = joint_boxes(mesh, skin, JointSpace::Mesh, &clips)?;
        let scene = posed_crowd(
            &asset.skeleton,
            skin,
            mesh,
            &clips,
            &CrowdParams { instances, seed, ..CrowdParams::default() },
        )?;
        let stride = skin.joints.len();
        let mut poser = Poser::default();
        let mut flat = BevyScene {
            boxes: mesh_boxes
                .joints
                .iter()
                .zip(mesh_boxes.center.iter().zip(&mesh_boxes.half))
                .map(|(&j, (&c, &h))| (j as usize, JointAabb { center: c, half_size: h }))
                .collect(),
            inverse_bindposes: skin.inverse_bind.iter().map(|m| Affine3A::from_mat4(*m)).collect(),
            instances: Vec::with_capacity(instances),
            transforms: Vec::with_capacity(instances * (stride + 1)),
            metas: Vec::new(),
        };
        let mut palette = Vec::with_capacity(instances * stride);
        for p in &scene.placements {
            let clip = asset.clips.get(p.clip);
            let t = clip.map_or(0.0, |c| c.start + p.offset * c.duration());
            let g = poser.globals(&asset.skeleton, clip, t);
            let entity = flat.transforms.len() as u32;
            flat.transforms.push(Affine3A::from_mat4(p.model.as_mat4()));
            let first = flat.transforms.len() as u32;
            for &j in &skin.joints {
                palette.push(Affine3A::from_mat4(g[j as usize].as_mat4()));
                flat.transforms.push(Affine3A::from_mat4((p.model * g[j as usize]).as_mat4()));
            }
            let joints = (first..first + stride as u32).map(|e| (e, 0)).collect();
            flat.instances.push(BevyInstance { joints, entity: (entity, 0) });
        }
        // The ECS layout: mesh entities in one table, joint entities in another (each in
        // spawn order), reached through the entities' locations.
        let is_mesh = {
            let mut v = vec![false; flat.transforms.len()];
            flat.instances.iter().for_each(|i| v[i.entity.0 as usize] = true);
            v
        };
        let meshes = flat.instances.len() as u32;
        let (mut next_mesh, mut next_joint) = (0u32, meshes);
        let mut bevy = flat.clone();
        bevy.metas = is_mesh
            .iter()
            .map(|&m| {
                let slot = if m { &mut next_mesh } else { &mut next_joint };
                *slot += 1;
                EntityMeta { generation: 0, row: *slot - 1 }
            })
            .collect();
        for (e, meta) in bevy.metas.iter().enumerate() {
            bevy.transforms[meta.row as usize] = flat.transforms[e];
        }
        Ok(Workload { bevy, bevy_flat: flat, boxes, palette, stride, character })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::{DemoParams, demo_character};

    /// Both baseline layouts find the same transforms, and the baseline's boxes and ours
    /// hold every skinned vertex of every instance.
    #[test]
    fn baseline_and_ours_bound_the_skinned_instances() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let character = asset.character().unwrap();
        let (skin, mesh) = (&character.palette, character.mesh.clone());
        let w = Workload::new(&asset, 40, 3).unwrap();
        let (mut bevy, mut flat) = (Vec::new(), Vec::new());
        w.bevy.update(false, &mut bevy);
        w.bevy_flat.update(true, &mut flat);
        assert_eq!(bevy, flat, "the ECS lookup must find the same transforms");
        let mut ours = vec![Box3::EMPTY; w.bevy.len()];
        w.boxes.update_all(&w.palette, w.stride, &mut ours).unwrap();
        let mut skinned = vec![glam::Vec3::ZERO; mesh.positions.len()];
        for (i, joints) in w.palette.chunks_exact(w.stride).enumerate() {
            let skinning: Vec<Affine3A> =
                joints.iter().zip(&skin.inverse_bind).map(|(g, ibm)| *g * Affine3A::from_mat4(*ibm)).collect();
            let inf = mesh.influences.as_ref().unwrap();
            skinlet::skinning::skin(inf, &mesh.positions, &[], &skinning, &mut skinned, &mut []).unwrap();
            for b in [bevy[i], ours[i]] {
                let slack = 1e-4 * b.diagonal();
                let grown = Box3 { min: b.min - slack, max: b.max + slack };
                assert!(skinned.iter().all(|&p| grown.contains(p)), "instance {i}: {b:?}");
            }
        }
    }
}
