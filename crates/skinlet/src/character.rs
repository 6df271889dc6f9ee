//! The whole character: every node of a scene that draws a triangle mesh, merged into one
//! skinned mesh over one palette of *drivers*. A driver is a (node, inverse bind matrix)
//! pair; its skinning matrix is `global(node) × inverse_bind`. A skinned part keeps its
//! skin's joints (each a driver; glTF ignores the drawing node's own transform); a rigid or
//! static part is weight 1 on a driver of its own node with an identity inverse bind, so it
//! follows that node's global transform (a prop under a hand joint, an animated door, a
//! static base). Meshlets, bounds, culling, contours, overdraw and the GPU code then see one
//! [`SkinnedMesh`] and one [`Skin`] (the palette), whatever the scene holds.
//!
//! Guarantees: reference-skinning the merged mesh with the palette's matrices gives, for
//! every part, exactly what glTF draws for that node and primitive (the part's vertices in
//! scene space); parts keep their vertex and triangle ranges, in scene order, so a renderer
//! can bind one material per primitive. A single-skin file's palette is its skin, unchanged
//! (then one driver per rigid node, if any).
//!
//! ```
//! # let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 1000, ..Default::default() });
//! // `asset`: the demo character (skinlet-lab), as `skinlet::import::load` reads it.
//! let character = asset.character()?;
//! // Body and collar (two skins), anklet, propeller and two eyes (one mesh, two nodes).
//! assert_eq!(character.parts.len(), 6);
//! let mut matrices = Vec::new();
//! let clip = asset.clips.first();
//! skinlet::pose::Poser::default().skinning_matrices(&asset.skeleton, &character.palette, clip, 0.5, &mut matrices);
//! assert_eq!(matrices.len(), character.palette.joints.len());
//! # Ok::<(), skinlet::Error>(())
//! ```

use crate::clip::Clip;
use crate::model::{Asset, Influences, MorphDelta, MorphWeight, Morphs, Skeleton, Skin, SkinnedMesh};
use crate::{Error, Result};
use glam::{Mat4, Vec3};
use std::collections::HashMap;
use std::ops::Range;

/// How a part moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PartKind {
    /// Deformed by skin `skin` of the asset.
    Skinned { skin: u32 },
    /// Moved by its node's global transform.
    Rigid,
}

/// One drawing: a primitive of a mesh drawn by a node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Part {
    pub node: u32,
    pub mesh: u32,
    /// Index of the primitive in the glTF mesh.
    pub primitive: u32,
    pub kind: PartKind,
    /// The part's vertices and triangles in [`Character::mesh`].
    pub vertices: Range<u32>,
    pub triangles: Range<u32>,
}

/// Every drawing of a scene as one skinned mesh over one palette of drivers.
#[derive(Clone, Debug, PartialEq)]
pub struct Character {
    /// The drivers: `palette.joints[d]` is driver `d`'s node, `palette.inverse_bind[d]` its
    /// inverse bind matrix. The merged mesh's joint numbers index it.
    pub palette: Skin,
    pub mesh: SkinnedMesh,
    pub parts: Vec<Part>,
}

impl Character {
    /// Every vertex and normal (empty when the mesh has none) posed as glTF draws `clip` at
    /// time `t` (`None`: the rest pose with default morph weights), in scene space: morphs
    /// first, then skinning over the palette.
    pub fn posed(&self, skeleton: &Skeleton, clip: Option<&Clip>, t: f32) -> Result<(Vec<Vec3>, Vec<Vec3>)> {
        let (mut mats, mut weights) = (Vec::new(), Vec::new());
        crate::pose::Poser::default().skinning_matrices(skeleton, &self.palette, clip, t, &mut mats);
        self.mesh.morphs.weights_at(clip, t, &mut weights);
        let n = self.mesh.positions.len();
        let (mut op, mut on) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; self.mesh.normals.len()]);
        crate::skinning::skin_mesh(&self.mesh, &weights, &mats, &mut op, &mut on)?;
        Ok((op, on))
    }

    /// The parts some of whose vertices have morph deltas.
    pub fn morphed_parts(&self) -> impl Iterator<Item = &Part> {
        let m = &self.mesh.morphs;
        self.parts.iter().filter(|p| (p.vertices.start..p.vertices.end).any(|v| !m.of(v as usize).is_empty()))
    }

    /// The character of the parts `keep` accepts (given each part's index and the part): their
    /// vertices, triangles and morph deltas in the same order, over the same palette of
    /// drivers and morph weights (so poses and bakes of either agree on the kept parts).
    /// Errors when no part is kept.
    pub fn select(&self, mut keep: impl FnMut(usize, &Part) -> bool) -> Result<Character> {
        let kept: Vec<&Part> = self.parts.iter().enumerate().filter(|(i, p)| keep(*i, p)).map(|(_, p)| p).collect();
        if kept.is_empty() {
            return Err(Error::invalid("character", "no part is selected"));
        }
        let slices: Vec<SkinnedMesh> =
            kept.iter().map(|p| self.mesh.slice(p.vertices.clone(), p.triangles.clone())).collect();
        let mut mesh = crate::model::concat(&slices.iter().collect::<Vec<_>>());
        let vertices = kept.iter().flat_map(|p| p.vertices.start as usize..p.vertices.end as usize);
        mesh.morphs = self.mesh.morphs.select(vertices);
        let (mut v, mut t) = (0u32, 0u32);
        let parts = (kept.iter())
            .map(|p| {
                let part = Part {
                    vertices: v..v + p.vertices.len() as u32,
                    triangles: t..t + p.triangles.len() as u32,
                    ..(*p).clone()
                };
                (v, t) = (part.vertices.end, part.triangles.end);
                part
            })
            .collect();
        Ok(Character { palette: self.palette.clone(), mesh, parts })
    }

    /// Triangles of every part: a mesh counted once per node that draws it.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangles.len()
    }
}

/// The character of scene `scene` of `asset` (`None`: the file's default scene, or scene 0,
/// or, for a file with no scenes, every root node).
pub fn character(asset: &Asset, scene: Option<usize>) -> Result<Character> {
    let roots = scene_roots(asset, scene)?;
    let skeleton = &asset.skeleton;
    let mut in_scene = vec![false; skeleton.nodes.len()];
    for &i in &skeleton.order {
        let node = &skeleton.nodes[i as usize];
        in_scene[i as usize] = roots.contains(&i) || node.parent.is_some_and(|p| in_scene[p as usize]);
    }
    let mut drivers: Vec<(u32, Mat4)> = Vec::new();
    let mut driver_of: HashMap<(u32, [u32; 16]), u16> = HashMap::new();
    let mut driver = |node: u32, ibm: Mat4| -> Result<u16> {
        let key = (node, ibm.to_cols_array().map(f32::to_bits));
        if let Some(&d) = driver_of.get(&key) {
            return Ok(d);
        }
        let d = u16::try_from(drivers.len())
            .ok()
            .filter(|&d| d < u16::MAX)
            .ok_or_else(|| Error::unsupported("character", "more than 65535 drivers (joints and rigid nodes)"))?;
        drivers.push((node, ibm));
        driver_of.insert(key, d);
        Ok(d)
    };
    // Skins' joints first, in the order of the nodes that draw with them, so a single-skin
    // file's palette starts with its skin.
    let mut skin_drivers: Vec<Option<Vec<u16>>> = vec![None; asset.skins.len()];
    let mut instances: Vec<_> = asset.instances.iter().filter(|i| in_scene[i.node as usize]).collect();
    instances.sort_by_key(|i| i.node);
    for inst in &instances {
        if let Some(s) = inst.skin {
            let skin = asset
                .skins
                .get(s as usize)
                .ok_or_else(|| Error::invalid(format!("node {}", inst.node), format!("skin {s} does not exist")))?;
            if skin_drivers[s as usize].is_none() {
                let map =
                    skin.joints.iter().zip(&skin.inverse_bind).map(|(&j, &m)| driver(j, m)).collect::<Result<_>>()?;
                skin_drivers[s as usize] = Some(map);
            }
        }
    }
    let mut merged: Vec<SkinnedMesh> = Vec::new();
    let mut parts = Vec::new();
    let mut morphs = Morphs::default();
    let (mut vertices, mut triangles) = (0u32, 0u32);
    for inst in &instances {
        let mesh = asset.meshes.get(inst.mesh as usize).ok_or_else(|| {
            Error::invalid(format!("node {}", inst.node), format!("mesh {} does not exist", inst.mesh))
        })?;
        for p in &mesh.primitives {
            let g = &p.geometry;
            let loc = || format!("node {} mesh {} ({:?}) primitive {}", inst.node, inst.mesh, mesh.name, p.index);
            let (kind, influences) = match inst.skin {
                Some(s) => {
                    let map = skin_drivers[s as usize].as_ref().expect("mapped above");
                    let inf = g.influences.as_ref().ok_or_else(|| {
                        Error::invalid(
                            loc(),
                            format!("the node has skin {s} but the primitive has no JOINTS_0/WEIGHTS_0"),
                        )
                    })?;
                    let mut out = inf.clone();
                    for (k, j) in out.joints.iter_mut().enumerate() {
                        if out.weights[k] == 0.0 {
                            *j = 0;
                            continue;
                        }
                        *j = *map.get(*j as usize).ok_or_else(|| {
                            Error::invalid(
                                format!("{} vertex {}", loc(), k / inf.stride),
                                format!("joint index {j} is out of range: skin {s} has {} joints", map.len()),
                            )
                        })?;
                    }
                    (PartKind::Skinned { skin: s }, out)
                }
                None => {
                    let d = driver(inst.node, Mat4::IDENTITY)?;
                    let n = g.positions.len();
                    let mut inf = Influences { stride: 4, joints: vec![0; 4 * n], weights: vec![0.0; 4 * n] };
                    (0..n).for_each(|v| (inf.joints[4 * v], inf.weights[4 * v]) = (d, 1.0));
                    (PartKind::Rigid, inf)
                }
            };
            let (nv, nt) = (g.positions.len() as u32, g.triangles.len() as u32);
            let too_big = || Error::unsupported("character", "more than 2^32 vertices or triangles");
            let (v_end, t_end) =
                (vertices.checked_add(nv).ok_or_else(too_big)?, triangles.checked_add(nt).ok_or_else(too_big)?);
            parts.push(Part {
                node: inst.node,
                mesh: inst.mesh,
                primitive: p.index as u32,
                kind,
                vertices: vertices..v_end,
                triangles: triangles..t_end,
            });
            (vertices, triangles) = (v_end, t_end);
            if !p.targets.is_empty() {
                // One weight per (node, target): the primitives of a mesh share their node's.
                let defaults = asset.node_weights.get(&inst.node).unwrap_or(&mesh.weights);
                let slots: Vec<u32> = (0..p.targets.len() as u32)
                    .map(|k| match morphs.weight_index(inst.node, k) {
                        Some(i) => i as u32,
                        None => {
                            let default = defaults.get(k as usize).copied().unwrap_or(0.0);
                            morphs.weights.push(MorphWeight { node: inst.node, target: k, default });
                            morphs.weights.len() as u32 - 1
                        }
                    })
                    .collect();
                let first = morphs.deltas.len();
                morphs.offsets.resize(vertices as usize - nv as usize + 1, first as u32);
                for v in 0..nv as usize {
                    for (t, &weight) in p.targets.iter().zip(&slots) {
                        let position = t.positions[v];
                        let normal = t.normals.get(v).copied().unwrap_or(Vec3::ZERO);
                        if position != Vec3::ZERO || normal != Vec3::ZERO {
                            morphs.deltas.push(MorphDelta { weight, position, normal });
                        }
                    }
                    morphs.offsets.push(morphs.deltas.len() as u32);
                }
            }
            merged.push(SkinnedMesh { influences: Some(influences), ..g.clone() });
        }
    }
    if parts.is_empty() {
        let which = scene.map_or("the scene".to_string(), |s| format!("scene {s}"));
        return Err(Error::invalid("character", format!("no node of {which} draws a triangle mesh")));
    }
    let mut mesh = crate::model::concat(&merged.iter().collect::<Vec<_>>());
    if !morphs.deltas.is_empty() {
        // Vertices after the last morphed part have no deltas.
        morphs.offsets.resize(vertices as usize + 1, morphs.deltas.len() as u32);
        mesh.morphs = morphs;
    } else {
        // Targets that move no vertex (all-zero deltas, as glTF Transform's `sparse` writes
        // them) leave no weights either: nothing they set changes the character.
        mesh.morphs = Morphs::default();
    }
    let name = match asset.skins.len() {
        1 => asset.skins[0].name.clone(),
        _ => "character".to_string(),
    };
    let (joints, inverse_bind) = drivers.into_iter().unzip();
    Ok(Character { palette: Skin { name, joints, inverse_bind }, mesh, parts })
}

/// The root nodes of the chosen scene.
fn scene_roots(asset: &Asset, scene: Option<usize>) -> Result<Vec<u32>> {
    let all_roots =
        || asset.skeleton.nodes.iter().enumerate().filter(|(_, n)| n.parent.is_none()).map(|(i, _)| i as u32).collect();
    match scene {
        Some(s) => asset.scenes.get(s).cloned().ok_or_else(|| {
            Error::invalid("scene", format!("scene {s} does not exist (the file has {})", asset.scenes.len()))
        }),
        None if asset.scenes.is_empty() => Ok(all_roots()),
        None => Ok(asset.scenes[asset.default_scene.unwrap_or(0).min(asset.scenes.len() - 1)].clone()),
    }
}
