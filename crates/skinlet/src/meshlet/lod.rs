//! Cluster LOD: a hierarchy of clusters at decreasing detail over one part's meshlets, built
//! the way Nanite and meshoptimizer's `clusterlod.h` build theirs. Level 0 is the part's
//! meshlets. Each step groups adjacent clusters of the level not yet simplified
//! (meshoptimizer's `partitionClusters`), simplifies each group's triangles to about half with
//! the group's border locked, and splits the result into new clusters (meshoptimizer's
//! `buildMeshlets`), one level up; until one group is left, or no group simplifies further.
//!
//! Guarantee (tested): the vertices the groups share and those on an edge not used by exactly
//! two triangles (the part's open and non-manifold edges) are locked, so a group's new
//! clusters have exactly the boundary its child clusters had, and each group's error is at
//! least its children's groups' (monotone up the hierarchy). Hence the cut
//! [`LodHierarchy::cut`] picks for any threshold (a cluster whose own group's error is within
//! it and whose parent group's is not) covers the surface once, without cracks: its boundary
//! (the edges an odd number of its triangles use) is the part's; on a closed mesh every edge
//! of the cut is shared by exactly two of its triangles.
//!
//! The errors [`build`] stores are the simplifier's, in the bind pose (absolute, in the mesh's
//! units), each group's plus its children's groups' largest; [`crate::bounds::lod_error`]
//! replaces them by errors that hold under animation. Skin motion enters the simplification
//! itself through [`posed_attributes`]. The bake stores the hierarchy (`LODC`); run-time
//! selection is `skinlet_runtime::lod_select` (CPU) and `skinlet_gpu::crowd_culling` (GPU).

use super::{MeshletLimits, Meshlets};
use crate::clip::Clip;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use crate::{Error, Result};
use glam::Vec3;

/// A cluster of the hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct LodCluster {
    /// Its triangles, three mesh vertex indices each.
    pub triangles: Vec<u32>,
    /// 0 for the part's meshlets, one more per simplification.
    pub level: u32,
    /// The group whose simplification made it (`None` at level 0).
    pub group: Option<u32>,
    /// The group that simplified it into coarser clusters (`None` for a root cluster).
    pub parent: Option<u32>,
}

/// A group of clusters simplified together.
#[derive(Clone, Debug, PartialEq)]
pub struct LodGroup {
    /// The level of the clusters it made.
    pub level: u32,
    /// The clusters it simplified (its children) and the clusters it made.
    pub children: Vec<u32>,
    pub made: Vec<u32>,
    /// How far its clusters may be from the full detail surface: in the bind pose as the
    /// simplifier measures it (its own simplification's error plus its children's groups'
    /// largest), until `bounds::lod_error::bound_errors` replaces it by one that holds under
    /// animation.
    pub error: f32,
}

/// The hierarchy of one part.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LodHierarchy {
    pub clusters: Vec<LodCluster>,
    pub groups: Vec<LodGroup>,
}

/// How the hierarchy is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodParams {
    /// Clusters per group (meshoptimizer's partition target).
    pub group_size: usize,
    /// A group whose simplification keeps more than this share of its triangles is not made
    /// (its clusters wait for the next step, grouped again).
    pub max_kept: f32,
    /// The weight of each vertex attribute (see [`build`]) against positions in the
    /// simplifier's error.
    pub attribute_weight: f32,
}

impl Default for LodParams {
    fn default() -> Self {
        LodParams { group_size: 8, max_kept: 0.85, attribute_weight: 1.0 }
    }
}

/// Most attributes per vertex the simplifier takes.
pub const MAX_ATTRIBUTES: usize = 24;

impl LodHierarchy {
    /// The error of a cluster's own group (0 at level 0) and of its parent group (infinite
    /// for a root cluster).
    pub fn cluster_errors(&self, cluster: usize) -> (f32, f32) {
        let c = &self.clusters[cluster];
        let error = |g: Option<u32>, none: f32| g.map_or(none, |g| self.groups[g as usize].error);
        (error(c.group, 0.0), error(c.parent, f32::INFINITY))
    }

    /// The clusters drawn at error threshold `threshold`: those whose own group's error is
    /// at most it and whose parent group's is above it.
    pub fn cut(&self, threshold: f32) -> Vec<u32> {
        (0..self.clusters.len())
            .filter(|&c| {
                let (own, parent) = self.cluster_errors(c);
                own <= threshold && threshold < parent
            })
            .map(|c| c as u32)
            .collect()
    }
}

/// Builds the hierarchy over `meshlets` (one part's, indexing `positions`), new clusters
/// within `limits`. `attributes` holds the same number of values (up to [`MAX_ATTRIBUTES`])
/// for each vertex, or none: the simplifier keeps their interpolation close too (skinlet
/// passes the vertices' positions at sampled poses, [`posed_attributes`], so that a group
/// is simplified where it stays flat in motion, not only in the bind pose). Errors on bad
/// limits, parameters or attribute counts, or meshlets that index past `positions`.
pub fn build(
    positions: &[Vec3],
    attributes: &[f32],
    meshlets: &Meshlets,
    limits: MeshletLimits,
    params: LodParams,
) -> Result<LodHierarchy> {
    limits.check()?;
    if params.group_size < 2
        || !(params.max_kept > 0.0 && params.max_kept < 1.0)
        || !(params.attribute_weight >= 0.0 && params.attribute_weight.is_finite())
    {
        return Err(Error::invalid(
            "cluster LOD",
            format!("{params:?}: need group_size ≥ 2, 0 < max_kept < 1, attribute_weight ≥ 0"),
        ));
    }
    let per_vertex = if positions.is_empty() { 0 } else { attributes.len() / positions.len() };
    if per_vertex * positions.len() != attributes.len() || per_vertex > MAX_ATTRIBUTES {
        return Err(Error::invalid(
            "cluster LOD",
            format!(
                "{} attribute values for {} vertices: need the same number for each, at most {MAX_ATTRIBUTES}",
                attributes.len(),
                positions.len()
            ),
        ));
    }
    let attributes = Attributes { values: attributes, weights: vec![params.attribute_weight; per_vertex] };
    let mut lod = LodHierarchy::default();
    for m in &meshlets.meshlets {
        let vertices = &meshlets.vertices[m.vertex_offset as usize..][..m.vertex_count as usize];
        let local = &meshlets.triangles[m.triangle_offset as usize..][..3 * m.triangle_count as usize];
        let triangles: Vec<u32> = local.iter().map(|&l| vertices[l as usize]).collect();
        if let Some(&v) = triangles.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(Error::invalid("cluster LOD", format!("a meshlet names vertex {v} of {}", positions.len())));
        }
        lod.clusters.push(LodCluster { triangles, level: 0, group: None, parent: None });
    }
    let bytes = meshopt::typed_to_bytes(positions);
    let adapter = meshopt::VertexDataAdapter::new(bytes, std::mem::size_of::<Vec3>(), 0)
        .map_err(|e| Error::invalid("cluster LOD", e.to_string()))?;
    // The clusters not simplified yet.
    let mut frontier: Vec<u32> = (0..lod.clusters.len() as u32).collect();
    while frontier.len() > 1 {
        let indices: Vec<u32> =
            frontier.iter().flat_map(|&c| lod.clusters[c as usize].triangles.iter().copied()).collect();
        let counts: Vec<u32> = frontier.iter().map(|&c| lod.clusters[c as usize].triangles.len() as u32).collect();
        let mut partition = vec![0u32; frontier.len()];
        let groups = meshopt::partition_clusters(&mut partition, &indices, &counts, positions.len(), params.group_size);
        let lock = locks(&lod, &frontier, &partition, positions.len());
        let mut next = Vec::new();
        let mut simplified = false;
        for g in 0..groups as u32 {
            let children: Vec<u32> =
                frontier.iter().zip(&partition).filter(|&(_, &p)| p == g).map(|(&c, _)| c).collect();
            match simplify_group(&mut lod, &adapter, &attributes, &lock, &children, limits, params)? {
                Some(made) => {
                    next.extend(made);
                    simplified = true;
                }
                None => next.extend(children),
            }
        }
        // A single group that would not simplify further is the root.
        if !simplified || groups == 1 && next.len() >= frontier.len() {
            break;
        }
        frontier = next;
    }
    Ok(lod)
}

/// Per-vertex attribute values and their weights (one per attribute).
struct Attributes<'a> {
    values: &'a [f32],
    weights: Vec<f32>,
}

/// Each vertex's positions at `poses` times spread evenly over `clips` one after the other
/// (3 values per pose, vertex after vertex), scaled to the mesh's units: attributes for
/// [`build`]. None without clips.
pub fn posed_attributes(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    poses: usize,
) -> Result<Vec<f32>> {
    let poses = poses.min(MAX_ATTRIBUTES / 3);
    let total: f32 = clips.iter().map(|c| c.end - c.start).sum();
    if clips.is_empty() || poses == 0 {
        return Ok(Vec::new());
    }
    let n = mesh.positions.len();
    let rest = crate::skinning::posed_positions(skeleton, skin, mesh, None, None)?;
    // Scene units per mesh unit: the rest pose's extent over the bind pose's.
    let extent = |p: &[Vec3]| {
        let (lo, hi) = p.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &q| (a.min(q), b.max(q)));
        (hi - lo).length()
    };
    let scale = extent(&rest) / extent(&mesh.positions);
    let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
    let mut out = vec![0.0f32; n * 3 * poses];
    for k in 0..poses {
        // The k-th of `poses` evenly spaced moments through the clips played in turn.
        let (mut at, mut clip) = (total * (k as f32 + 0.5) / poses as f32, clips[0]);
        for &c in clips {
            clip = c;
            if at <= c.end - c.start {
                break;
            }
            at -= c.end - c.start;
        }
        let t = (clip.start + at).min(clip.end);
        let posed = crate::skinning::posed_positions(skeleton, skin, mesh, Some(clip), Some(t))?;
        for (v, p) in posed.iter().enumerate() {
            out[(v * poses + k) * 3..][..3].copy_from_slice(&(*p / scale).to_array());
        }
    }
    Ok(out)
}

/// The vertices no simplification of this level may move: those used by clusters of two
/// groups (`partition`: each `frontier` cluster's group), and those on an edge the level's
/// clusters use other than twice (the part's open and non-manifold edges, and any the
/// simplifier made): the simplifier removes no locked vertex.
fn locks(lod: &LodHierarchy, frontier: &[u32], partition: &[u32], vertices: usize) -> Vec<bool> {
    let mut lock = vec![false; vertices];
    let mut owner = vec![u32::MAX; vertices];
    let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for (&c, &g) in frontier.iter().zip(partition) {
        for t in lod.clusters[c as usize].triangles.chunks_exact(3) {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                let o = &mut owner[a as usize];
                if *o == u32::MAX {
                    *o = g;
                } else if *o != g {
                    lock[a as usize] = true;
                }
            }
        }
    }
    for (&(a, b), _) in edges.iter().filter(|&(_, &n)| n != 2) {
        lock[a as usize] = true;
        lock[b as usize] = true;
    }
    lock
}

/// Simplifies the group of `children` (the `lock`ed vertices kept) and splits it into new
/// clusters: their indices, or `None` (nothing changed) when it keeps too many triangles.
fn simplify_group(
    lod: &mut LodHierarchy,
    adapter: &meshopt::VertexDataAdapter,
    attributes: &Attributes,
    lock: &[bool],
    children: &[u32],
    limits: MeshletLimits,
    params: LodParams,
) -> Result<Option<Vec<u32>>> {
    let indices: Vec<u32> = children.iter().flat_map(|&c| lod.clusters[c as usize].triangles.iter().copied()).collect();
    let target = (indices.len() / 3 / 2 * 3).max(3);
    let options = meshopt::SimplifyOptions::Sparse
        | meshopt::SimplifyOptions::ErrorAbsolute
        | meshopt::SimplifyOptions::Regularize;
    let mut error = 0.0f32;
    let kept = if attributes.weights.is_empty() {
        meshopt::simplify_with_locks(&indices, adapter, lock, target, f32::MAX, options, Some(&mut error))
    } else {
        let stride = std::mem::size_of_val(attributes.weights.as_slice());
        let (values, weights) = (attributes.values, &attributes.weights);
        let e = Some(&mut error);
        meshopt::simplify_with_attributes_and_locks(
            &indices,
            adapter,
            values,
            weights,
            stride,
            lock,
            target,
            f32::MAX,
            options,
            e,
        )
    };
    if kept.is_empty() || kept.len() as f32 > params.max_kept * indices.len() as f32 {
        return Ok(None);
    }
    let split = meshopt::build_meshlets(&kept, adapter, limits.max_vertices, limits.max_triangles, 0.0);
    let group = lod.groups.len() as u32;
    let level = 1 + children.iter().map(|&c| lod.clusters[c as usize].level).max().unwrap_or(0);
    let below = children.iter().map(|&c| lod.cluster_errors(c as usize).0).fold(0.0, f32::max);
    let mut made = Vec::new();
    for m in &split.meshlets {
        let vertices = &split.vertices[m.vertex_offset as usize..][..m.vertex_count as usize];
        let local = &split.triangles[m.triangle_offset as usize..][..3 * m.triangle_count as usize];
        made.push(lod.clusters.len() as u32);
        let triangles = local.iter().map(|&l| vertices[l as usize]).collect();
        lod.clusters.push(LodCluster { triangles, level, group: Some(group), parent: None });
    }
    for &c in children {
        lod.clusters[c as usize].parent = Some(group);
    }
    lod.groups.push(LodGroup { level, children: children.to_vec(), made: made.clone(), error: below + error });
    Ok(Some(made))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// A closed sphere of `n` × 2n quads (poles fanned), welded.
    fn sphere(n: u32) -> (Vec<Vec3>, Vec<u32>) {
        let mut positions = vec![Vec3::Y, -Vec3::Y];
        let ring = |i: u32, j: u32| 2 + (i - 1) * 2 * n + j % (2 * n);
        for i in 1..n {
            let theta = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..2 * n {
                let phi = std::f32::consts::PI * j as f32 / n as f32;
                positions.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
            }
        }
        let mut indices = Vec::new();
        for j in 0..2 * n {
            indices.extend([0, ring(1, j + 1), ring(1, j)]);
            indices.extend([1, ring(n - 1, j), ring(n - 1, j + 1)]);
            for i in 1..n - 1 {
                let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1));
                indices.extend([a, b, d, a, d, c]);
            }
        }
        (positions, indices)
    }

    fn meshlets_of(positions: &[Vec3], indices: &[u32], limits: MeshletLimits) -> Meshlets {
        let bytes = meshopt::typed_to_bytes(positions);
        let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).unwrap();
        let m = meshopt::build_meshlets(indices, &adapter, limits.max_vertices, limits.max_triangles, 0.0);
        let mut out = Meshlets::default();
        for k in &m.meshlets {
            out.meshlets.push(super::super::Meshlet {
                vertex_offset: out.vertices.len() as u32,
                triangle_offset: out.triangles.len() as u32,
                joint_offset: 0,
                vertex_count: k.vertex_count as u16,
                triangle_count: k.triangle_count as u16,
                joint_count: 0,
            });
            out.vertices.extend(&m.vertices[k.vertex_offset as usize..][..k.vertex_count as usize]);
            out.triangles.extend(&m.triangles[k.triangle_offset as usize..][..3 * k.triangle_count as usize]);
        }
        out
    }

    /// Each undirected edge of the triangles and how many triangles have it.
    fn edges(triangles: impl Iterator<Item = [u32; 3]>) -> HashMap<(u32, u32), u32> {
        let mut count = HashMap::new();
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        count
    }

    #[test]
    fn every_cut_of_a_closed_mesh_is_closed_and_errors_grow_up_the_hierarchy() {
        let limits = MeshletLimits::NVIDIA;
        let (positions, indices) = sphere(48);
        let meshlets = meshlets_of(&positions, &indices, limits);
        let lod = build(&positions, &[], &meshlets, limits, LodParams::default()).unwrap();
        let levels = lod.clusters.iter().map(|c| c.level).max().unwrap();
        let roots = lod.clusters.iter().filter(|c| c.parent.is_none()).count();
        let top: usize = lod.clusters.iter().filter(|c| c.parent.is_none()).map(|c| c.triangles.len() / 3).sum();
        eprintln!(
            "{} meshlets, {levels} levels, {} groups, {roots} root clusters of {top} triangles (of {})",
            meshlets.len(),
            lod.groups.len(),
            indices.len() / 3
        );
        assert!(levels >= 3, "{levels} levels");
        assert!(top * 8 < indices.len() / 3, "the coarsest cut keeps {top} of {} triangles", indices.len() / 3);
        assert!(roots < meshlets.len() / 4, "{roots} root clusters of {}", meshlets.len());
        for g in &lod.groups {
            for &c in &g.children {
                let own = lod.cluster_errors(c as usize).0;
                assert!(own <= g.error, "a group's error {} below its child's group's {own}", g.error);
            }
        }
        // Thresholds from full detail to the coarsest, and between every pair of errors.
        let mut errors: Vec<f32> = lod.groups.iter().map(|g| g.error).collect();
        errors.extend([0.0, f32::MAX]);
        errors.sort_by(f32::total_cmp);
        for &t in &errors {
            let cut = lod.cut(t);
            let triangles = cut.iter().flat_map(|&c| lod.clusters[c as usize].triangles.chunks_exact(3));
            let count = edges(triangles.map(|t| [t[0], t[1], t[2]]));
            let open: Vec<_> = count.iter().filter(|&(_, &n)| n != 2).collect();
            assert!(
                open.is_empty(),
                "threshold {t}: {} edges not shared by two triangles: {:?}",
                open.len(),
                &open[..open.len().min(4)]
            );
        }
        let full = lod.cut(0.0);
        assert_eq!(full.len(), meshlets.len(), "threshold 0 draws the meshlets");
    }

    #[test]
    fn bad_parameters_and_vertices_are_errors() {
        let limits = MeshletLimits::NVIDIA;
        let (positions, indices) = sphere(8);
        let meshlets = meshlets_of(&positions, &indices, limits);
        let bad = LodParams { group_size: 1, ..Default::default() };
        assert!(build(&positions, &[], &meshlets, limits, bad).is_err());
        assert!(build(&positions[..10], &[], &meshlets, limits, LodParams::default()).is_err());
        let uneven = vec![0.0; positions.len() * 3 + 1];
        assert!(build(&positions, &uneven, &meshlets, limits, LodParams::default()).is_err());
        let too_many = vec![0.0; positions.len() * (MAX_ATTRIBUTES + 1)];
        assert!(build(&positions, &too_many, &meshlets, limits, LodParams::default()).is_err());
    }
}
