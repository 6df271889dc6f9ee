//! The skinned-character data model: node hierarchy, skins, triangle meshes with up to
//! eight joint influences per vertex, and the instances that tie a mesh to a skin.
//!
//! Node indices are the glTF node indices of the source file, so every report and JSON
//! output can be matched against the file. Clips live in [`crate::clip`].

use glam::{Mat4, Vec3};

/// A local transform as glTF stores it: `T * R * S`.
pub use skinlet_runtime::Trs;

/// One node of the scene hierarchy: a joint, or any node above or beside joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub name: String,
    pub parent: Option<u32>,
    /// Rest (non-animated) local transform.
    pub rest: Trs,
    /// glTF nodes given by `matrix` keep it here: their local transform is this matrix
    /// (which may hold shear) and `rest` is ignored. Animated nodes never have one.
    pub matrix: Option<Mat4>,
}

/// The node hierarchy of one file (or the demo character).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Skeleton {
    pub nodes: Vec<Node>,
    /// Every node index once, parents before their children.
    pub order: Vec<u32>,
}

impl Skeleton {
    /// Builds the hierarchy from nodes whose `parent` fields are set; checks that the parent
    /// links form a forest (no cycle, parents in range) and computes the traversal order.
    pub fn new(nodes: Vec<Node>) -> crate::Result<Self> {
        let n = nodes.len();
        let mut children: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for (i, node) in nodes.iter().enumerate() {
            match node.parent {
                None => roots.push(i as u32),
                Some(p) if (p as usize) < n && p as usize != i => children[p as usize].push(i as u32),
                Some(p) => {
                    return Err(crate::Error::invalid(
                        format!("node {i} ({:?})", node.name),
                        format!("parent {p} is not a valid node (there are {n} nodes)"),
                    ));
                }
            }
        }
        let mut order = Vec::with_capacity(n);
        let mut stack: Vec<u32> = roots.into_iter().rev().collect();
        while let Some(i) = stack.pop() {
            order.push(i);
            stack.extend(children[i as usize].iter().rev());
        }
        if order.len() != n {
            let mut reached = vec![false; n];
            order.iter().for_each(|&i| reached[i as usize] = true);
            let bad = reached.iter().position(|r| !r).unwrap_or(0);
            return Err(crate::Error::invalid(
                format!("node {bad} ({:?})", nodes[bad].name),
                "the node hierarchy has a cycle through this node",
            ));
        }
        Ok(Skeleton { nodes, order })
    }

    /// Number of parent links from `node` up to its root.
    pub fn depth(&self, node: u32) -> usize {
        let mut d = 0;
        let mut cur = self.nodes[node as usize].parent;
        while let Some(p) = cur {
            d += 1;
            cur = self.nodes[p as usize].parent;
        }
        d
    }

    /// `node` and all its ancestors, from `node` up to the root.
    pub fn ancestry(&self, node: u32) -> impl Iterator<Item = u32> + '_ {
        std::iter::successors(Some(node), move |&n| self.nodes[n as usize].parent)
    }
}

/// A skin: the joints (node indices) a mesh's JOINTS attribute refers to, and their
/// inverse bind matrices (identity where the file gives none, as glTF specifies).
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    pub name: String,
    pub joints: Vec<u32>,
    pub inverse_bind: Vec<Mat4>,
}

/// Per-vertex joint influences, `stride` (4 or 8, at most 8) slots per vertex. Within a vertex the
/// non-zero weights come first and sum to 1; unused slots have weight 0 and joint 0. Joint
/// numbers index [`Skin::joints`]. The order of the non-zero slots means nothing to skinning:
/// the importer and the demo write them by decreasing weight, [`crate::meshlet::prepare()`]
/// sorts them by joint (the order a bake stores), and code that needs a vertex's strongest
/// influence asks [`Influences::strongest`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Influences {
    pub stride: usize,
    pub joints: Vec<u16>,
    pub weights: Vec<f32>,
}

impl Influences {
    pub fn vertex_count(&self) -> usize {
        self.joints.len().checked_div(self.stride).unwrap_or(0)
    }

    /// The non-zero influences of vertex `v` as (joint, weight) pairs.
    pub fn of(&self, v: usize) -> impl Iterator<Item = (u16, f32)> + '_ {
        let r = v * self.stride..(v + 1) * self.stride;
        self.joints[r.clone()].iter().zip(&self.weights[r]).take_while(|(_, w)| **w != 0.0).map(|(j, w)| (*j, *w))
    }

    /// Sorts each vertex's non-zero influences by joint (stable; the zero-weight slots that
    /// end the list stay last). Skinning is unchanged in value; with every vertex in joint
    /// order, a meshlet whose vertices share a joint set can hold the joints once and its
    /// vertices only weights, summed in the same order as the full vertices are.
    pub fn sort_by_joint(&mut self) {
        let stride = self.stride;
        let mut pairs: Vec<(u16, f32)> = Vec::with_capacity(stride);
        for v in 0..self.vertex_count() {
            pairs.clear();
            pairs.extend(self.of(v));
            pairs.sort_by_key(|&(j, _)| j);
            for (k, &(j, w)) in pairs.iter().enumerate() {
                self.joints[v * stride + k] = j;
                self.weights[v * stride + k] = w;
            }
        }
    }

    /// Vertex `v`'s largest weight and its joint (the lower joint on a tie), whatever the
    /// slot order; `None` for a vertex without influences.
    pub fn strongest(&self, v: usize) -> Option<(u16, f32)> {
        self.of(v).fold(None, |best, (j, w)| match best {
            Some((bj, bw)) if bw > w || (bw == w && bj < j) => Some((bj, bw)),
            _ => Some((j, w)),
        })
    }

    /// Checks the layout: stride 4 or 8, as many weights as joints, every joint below
    /// `joints`, weights finite and in [0, 1], non-zero ones first, each vertex's summing to 1
    /// (within 1e-3).
    pub fn check(&self, joints: usize) -> crate::Result<()> {
        Ok(skinlet_runtime::bake_view::check_influences(self.stride, &self.joints, &self.weights, joints)?)
    }

    /// Number of non-zero weights of vertex `v`.
    pub fn count(&self, v: usize) -> usize {
        self.weights[v * self.stride..(v + 1) * self.stride].iter().take_while(|w| **w != 0.0).count()
    }
}

/// A triangle mesh (one glTF primitive), optionally skinned.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinnedMesh {
    pub positions: Vec<Vec3>,
    /// Empty when the source has no normals.
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// `None` for a mesh with no JOINTS/WEIGHTS attributes.
    pub influences: Option<Influences>,
    /// Morph target deltas (empty: none). Morphs apply before skinning, as glTF specifies.
    pub morphs: Morphs,
}

/// One morph weight of a mesh (target `target` of the mesh node `node` draws, its default
/// weight) and one vertex's displacement by one weight: the records the bake file stores.
pub use skinlet_runtime::bake_view::{BakedMorphDelta as MorphDelta, BakedMorphWeight as MorphWeight};

/// Morph targets of a mesh, stored like skin influences: a palette of weights (the frame's
/// values are sampled per weight, like joint matrices per joint) and, per vertex, the
/// deltas that move it (only non-zero ones, so a face's targets cost nothing on the body).
/// The morphed vertex is `p + Σ wₖ·dₖ` over the vertex's deltas in stored order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Morphs {
    pub weights: Vec<MorphWeight>,
    /// Vertex `v`'s deltas are `deltas[offsets[v]..offsets[v + 1]]`; empty when the mesh has
    /// no deltas at all.
    pub offsets: Vec<u32>,
    pub deltas: Vec<MorphDelta>,
}

impl Morphs {
    /// The deltas as the runtime's view of a bake's `MRPH` holds them (`None` without any).
    pub fn view(&self) -> Option<skinlet_runtime::bake_view::MorphView<'_>> {
        (!self.is_empty()).then_some(skinlet_runtime::bake_view::MorphView {
            weights: &self.weights,
            offsets: &self.offsets,
            deltas: &self.deltas,
        })
    }

    /// True when no vertex has a delta.
    pub fn is_empty(&self) -> bool {
        self.deltas.is_empty()
    }

    /// The deltas of vertex `v` (none where the offsets do not say: see [`Morphs::check`]).
    pub fn of(&self, v: usize) -> &[MorphDelta] {
        let range = self.offsets.get(v..v + 2).and_then(|r| self.deltas.get(r[0] as usize..r[1] as usize));
        range.unwrap_or(&[])
    }

    /// The value of every weight when `clip` plays at time `t` (`None`: the defaults).
    pub fn weights_at(&self, clip: Option<&crate::clip::Clip>, t: f32, out: &mut Vec<f32>) {
        out.clear();
        out.extend(self.weights.iter().map(|w| w.default));
        for ch in clip.into_iter().flat_map(|c| &c.weights) {
            if let Some(k) = self.weight_index(ch.channel.node, ch.target) {
                out[k] = ch.channel.sample(t);
            }
        }
    }

    /// The weight of target `target` of node `node`, if the mesh has it.
    pub fn weight_index(&self, node: u32, target: u32) -> Option<usize> {
        self.weights.iter().position(|w| w.node == node && w.target == target)
    }

    /// Vertex `v` with its deltas weighted by `values` (see [`Morphs::weights_at`]; a weight
    /// without a value counts as 0) added.
    #[inline]
    pub fn morph(&self, v: usize, values: &[f32], position: Vec3, normal: Vec3) -> (Vec3, Vec3) {
        let (mut p, mut n) = (position, normal);
        for d in self.of(v) {
            let w = values.get(d.weight as usize).copied().unwrap_or(0.0);
            p += w * d.position;
            n += w * d.normal;
        }
        (p, n)
    }

    /// The morphs of vertices `kept` (in that order), e.g. after welding or slicing.
    pub fn select(&self, kept: impl Iterator<Item = usize>) -> Morphs {
        if self.is_empty() {
            return Morphs { weights: self.weights.clone(), ..Morphs::default() };
        }
        let mut out = Morphs { weights: self.weights.clone(), offsets: vec![0], deltas: Vec::new() };
        for v in kept {
            out.deltas.extend_from_slice(self.of(v));
            out.offsets.push(out.deltas.len() as u32);
        }
        out
    }

    /// Checks the layout against a mesh of `vertices` vertices: offsets, weight indices and
    /// finite deltas.
    pub fn check(&self, vertices: usize) -> crate::Result<()> {
        match self.view() {
            Some(view) => Ok(view.check(vertices)?),
            // No deltas: no offsets, or one zero per vertex and one more.
            None if !(self.offsets.is_empty()
                || self.offsets.len() == vertices + 1 && self.offsets.iter().all(|&o| o == 0)) =>
            {
                Err(crate::Error::invalid(
                    "morph targets",
                    format!("{} vertex offsets without deltas", self.offsets.len()),
                ))
            }
            None if self.weights.iter().any(|w| !w.default.is_finite()) => {
                Err(crate::Error::invalid("morph targets", "a morph weight's default is not finite"))
            }
            None => Ok(()),
        }
    }
}

impl SkinnedMesh {
    /// The vertices as the runtime's view of a bake's `VERT` holds them (stride 0 without
    /// skin weights).
    pub fn vertex_view(&self) -> skinlet_runtime::bake_view::VertexView<'_> {
        let (stride, joints, weights) = match &self.influences {
            Some(inf) => (inf.stride, &inf.joints[..], &inf.weights[..]),
            None => (0, &[][..], &[][..]),
        };
        skinlet_runtime::bake_view::VertexView {
            positions: &self.positions,
            normals: &self.normals,
            stride,
            joints,
            weights,
        }
    }

    /// The mesh as a GPU upload reads it, with `meshlets` of it if given
    /// ([`crate::meshlet::Meshlets::view`]).
    pub fn mesh_data<'a>(
        &'a self,
        meshlets: Option<skinlet_runtime::bake_view::MeshletView<'a>>,
    ) -> skinlet_runtime::bake_view::MeshData<'a> {
        skinlet_runtime::bake_view::MeshData {
            vertices: self.vertex_view(),
            triangles: &self.triangles,
            morphs: self.morphs.view(),
            meshlets,
        }
    }

    /// A copy of vertices `vertices` and triangles `triangles`, renumbered from 0 (the
    /// triangles must use only those vertices, as a [`crate::Part`]'s do).
    pub fn slice(&self, vertices: std::ops::Range<u32>, triangles: std::ops::Range<u32>) -> SkinnedMesh {
        let v = vertices.start as usize..vertices.end as usize;
        SkinnedMesh {
            positions: self.positions[v.clone()].to_vec(),
            normals: if self.normals.is_empty() { Vec::new() } else { self.normals[v.clone()].to_vec() },
            triangles: self.triangles[triangles.start as usize..triangles.end as usize]
                .iter()
                .map(|t| t.map(|i| i - vertices.start))
                .collect(),
            influences: self.influences.as_ref().map(|inf| Influences {
                stride: inf.stride,
                joints: inf.joints[v.start * inf.stride..v.end * inf.stride].to_vec(),
                weights: inf.weights[v.start * inf.stride..v.end * inf.stride].to_vec(),
            }),
            morphs: self.morphs.select(v),
        }
    }

    /// Positions and normals (empty when the mesh has none) with the morph weights `values`
    /// applied: the shape skinning then poses.
    pub fn morphed(&self, values: &[f32]) -> (Vec<Vec3>, Vec<Vec3>) {
        let (mut p, mut n) = (self.positions.clone(), self.normals.clone());
        if !self.morphs.is_empty() {
            for (v, pv) in p.iter_mut().enumerate() {
                let (mp, mn) = self.morphs.morph(v, values, *pv, n.get(v).copied().unwrap_or(Vec3::ZERO));
                *pv = mp;
                if let Some(nv) = n.get_mut(v) {
                    *nv = mn;
                }
            }
        }
        (p, n)
    }

    /// Triangles that repeat a vertex or have zero area (valid, but they draw nothing).
    pub fn degenerate_triangles(&self) -> usize {
        let p = &self.positions;
        self.triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| p[i as usize]);
                t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || (b - a).cross(c - a) == Vec3::ZERO
            })
            .count()
    }
}

/// One glTF mesh: its triangle primitives (points and lines are skipped at import).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub name: String,
    pub primitives: Vec<Primitive>,
    /// Default morph weights, one per target (empty: all zero).
    pub weights: Vec<f32>,
}

impl Mesh {
    /// Number of morph targets (every primitive of a mesh has the same number).
    pub fn morph_targets(&self) -> usize {
        self.primitives.first().map_or(0, |p| p.targets.len())
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Primitive {
    /// Index of the primitive in the glTF mesh.
    pub index: usize,
    pub geometry: SkinnedMesh,
    /// Morph targets: every primitive of a mesh has the same number.
    pub targets: Vec<MorphTarget>,
}

/// One morph target of a primitive: per vertex, a position delta and (empty when the file
/// gives none) a normal delta. Tangent deltas are not read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTarget {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
}

/// A node that draws a mesh, with the skin that deforms it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Instance {
    pub node: u32,
    pub mesh: u32,
    pub skin: Option<u32>,
}

/// Everything skinlet reads from one file.
#[derive(Clone, Debug, Default)]
pub struct Asset {
    pub skeleton: Skeleton,
    pub skins: Vec<Skin>,
    pub meshes: Vec<Mesh>,
    pub instances: Vec<Instance>,
    pub clips: Vec<crate::clip::Clip>,
    /// The root nodes of each glTF scene (empty for files without scenes: then every root
    /// node is drawn).
    pub scenes: Vec<Vec<u32>>,
    /// The file's `scene` (the one to draw by default).
    pub default_scene: Option<usize>,
    /// Nodes whose `weights` override their mesh's default morph weights.
    pub node_weights: std::collections::BTreeMap<u32, Vec<f32>>,
    pub report: ImportReport,
}

/// What the importer changed or skipped, so nothing is hidden from the user.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImportReport {
    pub warnings: Vec<String>,
    /// Vertices whose weights did not sum to 1 (beyond 1e-3) and were renormalized.
    pub renormalized_vertices: usize,
    /// Vertices whose weights were all zero; they were bound fully to their first joint slot.
    pub zero_weight_vertices: usize,
    /// Triangles with a repeated index or zero area (kept; they draw nothing).
    pub degenerate_triangles: usize,
}

/// Merged copy of several meshes (indices offset), e.g. every primitive drawn with one skin.
pub fn concat(meshes: &[&SkinnedMesh]) -> SkinnedMesh {
    let mut out = SkinnedMesh::default();
    let stride = meshes.iter().filter_map(|m| m.influences.as_ref().map(|i| i.stride)).max();
    // Normals when any mesh has them (zero vectors for the vertices of those without).
    let with_normals = meshes.iter().any(|m| !m.normals.is_empty());
    let mut inf = stride.map(|stride| Influences { stride, joints: Vec::new(), weights: Vec::new() });
    let with_morphs = meshes.iter().any(|m| !m.morphs.is_empty());
    for m in meshes {
        let base = out.positions.len() as u32;
        // Each mesh's morph weights are its own: appended to the palette, indices offset.
        let first_weight = out.morphs.weights.len() as u32;
        out.morphs.weights.extend_from_slice(&m.morphs.weights);
        if with_morphs {
            if out.morphs.offsets.is_empty() {
                out.morphs.offsets.push(0);
            }
            for v in 0..m.positions.len() {
                let deltas = m.morphs.of(v).iter().map(|d| MorphDelta { weight: d.weight + first_weight, ..*d });
                out.morphs.deltas.extend(deltas);
                out.morphs.offsets.push(out.morphs.deltas.len() as u32);
            }
        }
        out.positions.extend_from_slice(&m.positions);
        if with_normals && m.normals.is_empty() {
            out.normals.resize(out.positions.len(), Vec3::ZERO);
        } else if with_normals {
            out.normals.extend_from_slice(&m.normals);
        }
        out.triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
        if let Some(dst) = &mut inf {
            for v in 0..m.positions.len() {
                let src = m.influences.as_ref();
                for k in 0..dst.stride {
                    let (j, w) = src
                        .and_then(|s| (k < s.stride).then(|| (s.joints[v * s.stride + k], s.weights[v * s.stride + k])))
                        .unwrap_or((0, 0.0));
                    dst.joints.push(j);
                    dst.weights.push(w);
                }
            }
        }
    }
    out.influences = inf;
    out
}

impl Asset {
    /// The whole character of the default scene (see [`crate::character`]).
    pub fn character(&self) -> crate::Result<crate::character::Character> {
        crate::character::character(self, None)
    }

    /// A static mesh as an asset: one root node drawing one mesh named `name`. Errors name
    /// the first vertex that is not finite or triangle that indexes past the vertices.
    pub fn from_static(name: &str, positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> crate::Result<Asset> {
        use crate::Error;
        if let Some(v) = positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid(format!("{name} vertex {v}"), "position is NaN or infinite"));
        }
        let n = positions.len();
        if let Some(t) = triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n)) {
            return Err(Error::invalid(
                format!("{name} triangle {t}"),
                format!("index out of range (only {n} vertices): {:?}", triangles[t]),
            ));
        }
        if triangles.is_empty() {
            return Err(Error::invalid(name, "no triangles"));
        }
        let geometry = SkinnedMesh { positions, triangles, ..SkinnedMesh::default() };
        let degenerate = geometry.degenerate_triangles();
        let root = Node { name: "root".into(), parent: None, rest: Trs::IDENTITY, matrix: None };
        let mut asset = Asset {
            skeleton: Skeleton::new(vec![root])?,
            meshes: vec![Mesh {
                name: name.to_string(),
                primitives: vec![Primitive { index: 0, geometry, targets: Vec::new() }],
                weights: Vec::new(),
            }],
            instances: vec![Instance { node: 0, mesh: 0, skin: None }],
            ..Asset::default()
        };
        asset.report.degenerate_triangles = degenerate;
        Ok(asset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strongest_influence_ignores_slot_order_and_checks_catch_bad_layouts() {
        let inf = Influences {
            stride: 4,
            joints: vec![3, 1, 5, 0, 2, 4, 0, 0],
            weights: vec![0.2, 0.5, 0.3, 0.0, 0.5, 0.5, 0.0, 0.0],
        };
        assert_eq!(inf.strongest(0), Some((1, 0.5)));
        assert_eq!(inf.strongest(1), Some((2, 0.5)), "a tie goes to the lower joint");
        let mut sorted = inf.clone();
        sorted.sort_by_joint();
        assert_eq!((sorted.strongest(0), sorted.strongest(1)), (inf.strongest(0), inf.strongest(1)));
        assert!(inf.check(6).is_ok());
        assert!(inf.check(5).unwrap_err().to_string().contains("joint 5 of 5"));
        for (slot, w, what) in
            [(7, 0.1, "after a zero"), (1, 0.4, "sum to"), (1, f32::NAN, "weight NaN"), (1, -0.5, "weight -0.5")]
        {
            let mut bad = inf.clone();
            bad.weights[slot] = w;
            let e = bad.check(6).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
    }

    #[test]
    fn sorting_influences_keeps_each_vertex_pairs() {
        // Slots after the first zero weight are not influences and stay where they are.
        let mut inf = Influences {
            stride: 4,
            joints: vec![7, 2, 5, 0, 3, 1, 9, 4, 6, 6, 1, 8],
            weights: vec![0.5, 0.3, 0.2, 0.0, 0.6, 0.4, 0.0, 0.9, 0.25, 0.25, 0.5, 0.0],
        };
        let before: Vec<Vec<(u16, f32)>> = (0..3).map(|v| inf.of(v).collect()).collect();
        inf.sort_by_joint();
        assert_eq!(inf.joints, [2, 5, 7, 0, 1, 3, 9, 4, 1, 6, 6, 8]);
        assert_eq!(inf.weights, [0.3, 0.2, 0.5, 0.0, 0.4, 0.6, 0.0, 0.9, 0.5, 0.25, 0.25, 0.0]);
        for (v, pairs) in before.into_iter().enumerate() {
            let mut sorted = pairs.clone();
            sorted.sort_by_key(|p| p.0);
            assert_eq!(inf.of(v).collect::<Vec<_>>(), sorted);
        }
    }
}
