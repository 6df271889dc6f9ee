//! Cone-split builder (ours): meshlets grown for backface culling. Normal-coherent pieces
//! inside the skin-aware partitions ([`super::skin_aware`]) are merged back where little is
//! lost and split where much is gained, within a meshlet budget.
//!
//! Why. A meshlet is backface-culled when the eye lies behind every one of its triangles'
//! planes; its normal cone (conservative-bounds paper, section 4) decides how often that
//! happens. For a cone of half-angle α < 90° and view directions spread evenly over the
//! sphere, the share of views that cull it is `(1 − sin α) / 2`: 25% at 30°, 6.7% at 60°,
//! none from 90° on. Greedy builders fill meshlets to the limits first, so on curved
//! characters many meshlets wrap around a limb as a ring and span more than 90°; halving a
//! ring leaves two half-rings, still past 90°. Strips along the limb, each facing one way,
//! are what culls.
//!
//! Method. A meshlet's *value* is its triangle count × `(1 − sin α) / 2`, with α the
//! narrowest cone around its rest face normals ([`crate::bounds::cone::reference_axis`]):
//! the expected number of triangles backface culling skips.
//!
//! 1. Over-segment: the skin-aware partitions (dominant joint, rigid or blended; small ones
//!    folded into a neighbour), each cut by face normal into six classes (the nearest of
//!    ±x, ±y, ±z, so every class spans at most 54.7° from its axis), each class packed by
//!    meshoptimizer's greedy builder with the skin-aware cone weight.
//! 2. Merge: pairs of pieces of one skin-aware partition that share a vertex and fit the
//!    limits, the smallest loss of value first, while a merge loses nothing or the count is
//!    over budget.
//! 3. Where merges cannot reach the budget, partitions fall back to one greedy run over the
//!    partition, the least value per meshlet saved first (and the whole mesh to the
//!    skin-aware meshlets if that is not enough).
//! 4. Split what budget is left: a piece is cut in two by 2-means on its face normals,
//!    largest gain in value first, while a split gains.
//!
//! The budget is `budget` × meshoptimizer's meshlet count on the same parts and limits, or
//! the skin-aware builder's count where that is more. Pieces never cross skin-aware
//! partitions (so the joint coherence that keeps animated bounds tight is kept) nor parts.
//!
//! Guarantee: the output is a valid meshlet set of the same triangles ([`Meshlets::validate`]),
//! each meshlet within one part, the parts in order; for the same mesh and parameters it is
//! the same (no randomness, ties broken by index).

use super::{MeshletLimits, Meshlets, PartRange, greedy, skin_aware};
use crate::bounds::cone::reference_axis;
use crate::model::SkinnedMesh;
use glam::{DVec3, Vec3};
use std::cmp::{Ordering, Reverse};
use std::collections::{BTreeMap, BinaryHeap};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub skin_aware: skin_aware::Params,
    /// At most this many times meshoptimizer's meshlet count on the same mesh, or the
    /// skin-aware builder's count where that is more.
    pub budget: f32,
}

impl Default for Params {
    fn default() -> Self {
        Params { skin_aware: skin_aware::Params::default(), budget: 1.3 }
    }
}

/// Builds the meshlets of a mesh that is one part.
pub fn build(mesh: &SkinnedMesh, limits: MeshletLimits, params: &Params) -> Meshlets {
    let whole = PartRange { vertices: 0..mesh.positions.len() as u32, triangles: 0..mesh.triangles.len() as u32 };
    build_parts(mesh, &[whole], limits, params)
}

/// A skin-aware partition: part index and partition key ([`skin_aware::partitions`]).
type Partition = (u32, u32);

/// A piece of the mesh: its triangles and skin-aware partition.
#[derive(Clone, Debug)]
struct Piece {
    triangles: Vec<[u32; 3]>,
    partition: Partition,
}

/// Builds the meshlets of a mesh made of `parts` ([`super::prepare_parts`]); the budget
/// counts over all parts.
pub fn build_parts(mesh: &SkinnedMesh, parts: &[PartRange], limits: MeshletLimits, params: &Params) -> Meshlets {
    let ctx = Context { positions: &mesh.positions, limits };
    let mut reference = 0;
    // Skin-aware partitions (part, key) and the normal class of every triangle.
    let mut partition = vec![(0, 0); mesh.triangles.len()];
    let mut skin_aware = Meshlets::default();
    for (k, p) in parts.iter().enumerate() {
        let range = p.triangles.start as usize..p.triangles.end as usize;
        reference += greedy::build(&mesh.triangles[range.clone()], &mesh.positions, limits, greedy::CONE_WEIGHT).len();
        let part = mesh.slice(p.vertices.clone(), p.triangles.clone());
        let keys = skin_aware::partitions(&part, limits, &params.skin_aware);
        skin_aware.append(&skin_aware::build_partitioned(&part, &keys, limits, &params.skin_aware), p.vertices.start);
        for (slot, key) in partition[range].iter_mut().zip(keys) {
            *slot = (k as u32, key);
        }
    }
    let class = |t: &[u32; 3]| {
        let n = face_normal(&mesh.positions, t).unwrap_or(DVec3::X);
        (0..6).max_by(|&a, &b| n.dot(AXES[a]).total_cmp(&n.dot(AXES[b]))).unwrap_or(0)
    };
    let mut by_partition: BTreeMap<Partition, Vec<[u32; 3]>> = BTreeMap::new();
    let mut by_class: BTreeMap<(Partition, usize), Vec<[u32; 3]>> = BTreeMap::new();
    for (t, &p) in mesh.triangles.iter().zip(&partition) {
        by_partition.entry(p).or_default().push(*t);
        by_class.entry((p, class(t))).or_default().push(*t);
    }
    let cone_weight = params.skin_aware.cone_weight;
    let pieces: Vec<Piece> = by_class.iter().flat_map(|(&(p, _), tris)| ctx.greedy(tris, p, cone_weight)).collect();
    let budget = ((params.budget.max(0.0) * reference as f32) as usize).max(skin_aware.len());
    let mut pieces = ctx.merge(pieces, budget);
    if pieces.len() > budget {
        pieces = ctx.fall_back(pieces, &by_partition, budget, cone_weight);
        if pieces.len() > budget {
            return skin_aware;
        }
    }
    let mut pieces = ctx.split(pieces, budget);
    // Parts in order, and inside a part the partitions.
    pieces.sort_by_key(|p| p.partition);
    let mut out = Meshlets::default();
    for piece in &pieces {
        let mut verts: Vec<u32> = Vec::new();
        let mut local: Vec<u8> = Vec::with_capacity(3 * piece.triangles.len());
        for &v in piece.triangles.iter().flatten() {
            let at = verts.iter().position(|&x| x == v).unwrap_or_else(|| {
                verts.push(v);
                verts.len() - 1
            });
            local.push(at as u8);
        }
        meshopt::optimize_meshlet_level(&mut verts, &mut local, 0);
        out.push(&verts, &local);
    }
    out
}

const AXES: [DVec3; 6] = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z];

/// The unit face normal of a triangle (none when degenerate).
fn face_normal(positions: &[Vec3], t: &[u32; 3]) -> Option<DVec3> {
    let [a, b, c] = t.map(|v| positions[v as usize].as_dvec3());
    (b - a).cross(c - a).try_normalize()
}

/// Expected triangles skipped by backface culling: count × (1 − sin α) / 2 for the
/// narrowest cone (half-angle α) around the normals.
fn value(normals: &[DVec3], triangles: usize) -> f64 {
    if normals.is_empty() {
        return 0.0;
    }
    let (_, cos) = reference_axis(normals);
    if cos <= 0.0 {
        return 0.0;
    }
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    triangles as f64 * (1.0 - sin) / 2.0
}

/// A candidate merge or split, taken largest `gain` first (a merge's gain is minus its
/// loss); ties by `order`, lowest first.
struct Candidate<T> {
    gain: f64,
    order: (usize, usize),
    what: T,
}

impl<T> PartialEq for Candidate<T> {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl<T> Eq for Candidate<T> {}
impl<T> PartialOrd for Candidate<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Candidate<T> {
    fn cmp(&self, other: &Self) -> Ordering {
        self.gain.total_cmp(&other.gain).then(Reverse(self.order).cmp(&Reverse(other.order)))
    }
}

struct Context<'a> {
    positions: &'a [Vec3],
    limits: MeshletLimits,
}

impl Context<'_> {
    fn normal(&self, t: &[u32; 3]) -> Option<DVec3> {
        face_normal(self.positions, t)
    }

    fn value(&self, tris: &[[u32; 3]]) -> f64 {
        let n: Vec<DVec3> = tris.iter().filter_map(|t| self.normal(t)).collect();
        value(&n, tris.len())
    }

    fn vertices(tris: &[[u32; 3]]) -> Vec<u32> {
        let mut v: Vec<u32> = tris.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// meshoptimizer's greedy meshlets of `tris`, as pieces of `partition`.
    fn greedy(&self, tris: &[[u32; 3]], partition: Partition, cone_weight: f32) -> Vec<Piece> {
        let built = greedy::build(tris, self.positions, self.limits, cone_weight);
        let piece = |m| Piece { triangles: built.mesh_triangles(m).collect(), partition };
        built.meshlets.iter().map(piece).collect()
    }

    /// Merges pieces of one partition that share a vertex and fit the limits, smallest
    /// loss first, while a merge loses nothing or there are more than `budget` pieces.
    fn merge(&self, mut pieces: Vec<Piece>, budget: usize) -> Vec<Piece> {
        let mut verts: Vec<Vec<u32>> = pieces.iter().map(|p| Self::vertices(&p.triangles)).collect();
        let mut values: Vec<f64> = pieces.iter().map(|p| self.value(&p.triangles)).collect();
        let mut alive = vec![true; pieces.len()];
        let mut version = vec![0u32; pieces.len()];
        let mut at_vertex: Vec<Vec<usize>> = vec![Vec::new(); self.positions.len()];
        for (p, vs) in verts.iter().enumerate() {
            vs.iter().for_each(|&v| at_vertex[v as usize].push(p));
        }
        let neighbours = |p: usize, verts: &[Vec<u32>], at_vertex: &[Vec<usize>]| {
            let mut n: Vec<usize> = verts[p].iter().flat_map(|&v| at_vertex[v as usize].iter().copied()).collect();
            n.sort_unstable();
            n.dedup();
            n.retain(|&q| q != p);
            n
        };
        type Pair = (usize, usize, u32, u32);
        let candidate = |a: usize, b: usize, pieces: &[Piece], verts: &[Vec<u32>], values: &[f64], version: &[u32]| {
            let (a, b) = (a.min(b), a.max(b));
            let (pa, pb) = (&pieces[a], &pieces[b]);
            if pa.partition != pb.partition || pa.triangles.len() + pb.triangles.len() > self.limits.max_triangles {
                return None;
            }
            let shared = verts[a].iter().filter(|v| verts[b].binary_search(v).is_ok()).count();
            if verts[a].len() + verts[b].len() - shared > self.limits.max_vertices {
                return None;
            }
            let union: Vec<[u32; 3]> = pa.triangles.iter().chain(&pb.triangles).copied().collect();
            let loss = values[a] + values[b] - self.value(&union);
            Some(Candidate { gain: -loss, order: (a, b), what: (a, b, version[a], version[b]) as Pair })
        };
        let mut heap = BinaryHeap::new();
        for a in 0..pieces.len() {
            for b in neighbours(a, &verts, &at_vertex).into_iter().filter(|&b| b > a) {
                heap.extend(candidate(a, b, &pieces, &verts, &values, &version));
            }
        }
        let mut count = pieces.len();
        while let Some(c) = heap.pop() {
            let (a, b, va, vb) = c.what;
            if !alive[a] || !alive[b] || version[a] != va || version[b] != vb {
                continue;
            }
            if c.gain < -1e-9 && count <= budget {
                break;
            }
            let moved = std::mem::take(&mut pieces[b].triangles);
            pieces[a].triangles.extend(moved);
            alive[b] = false;
            count -= 1;
            version[a] += 1;
            for &v in &verts[b] {
                let list = &mut at_vertex[v as usize];
                list.retain(|&x| x != b);
                if !list.contains(&a) {
                    list.push(a);
                }
            }
            verts[a] = Self::vertices(&pieces[a].triangles);
            values[a] = self.value(&pieces[a].triangles);
            for n in neighbours(a, &verts, &at_vertex) {
                heap.extend(candidate(a, n, &pieces, &verts, &values, &version));
            }
        }
        pieces.into_iter().zip(alive).filter_map(|(p, alive)| alive.then_some(p)).collect()
    }

    /// Replaces partitions' pieces by the partition's plain greedy meshlets, the least value
    /// per meshlet saved first, until at most `budget` remain (or none is left to replace).
    fn fall_back(
        &self,
        pieces: Vec<Piece>,
        by_partition: &BTreeMap<Partition, Vec<[u32; 3]>>,
        budget: usize,
        cone_weight: f32,
    ) -> Vec<Piece> {
        let mut options = Vec::new();
        for (&p, tris) in by_partition {
            let plain = self.greedy(tris, p, cone_weight);
            let now: Vec<&Piece> = pieces.iter().filter(|q| q.partition == p).collect();
            if now.len() > plain.len() {
                let value_now: f64 = now.iter().map(|q| self.value(&q.triangles)).sum();
                let value_plain: f64 = plain.iter().map(|q| self.value(&q.triangles)).sum();
                let per_meshlet = (value_now - value_plain) / (now.len() - plain.len()) as f64;
                options.push((per_meshlet, p, now.len(), plain));
            }
        }
        options.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut count = pieces.len();
        let mut replaced: BTreeMap<Partition, Vec<Piece>> = BTreeMap::new();
        for (_, p, now, plain) in options {
            if count <= budget {
                break;
            }
            count -= now - plain.len();
            replaced.insert(p, plain);
        }
        let mut kept: Vec<Piece> = pieces.into_iter().filter(|q| !replaced.contains_key(&q.partition)).collect();
        kept.extend(replaced.into_values().flatten());
        kept
    }

    /// The best 2-means split of a piece by face normal, if it has two non-empty halves.
    fn best_split(&self, index: usize, piece: &Piece) -> Option<Candidate<[Vec<[u32; 3]>; 2]>> {
        let tris = &piece.triangles;
        let normals: Vec<Option<DVec3>> = tris.iter().map(|t| self.normal(t)).collect();
        let valid: Vec<DVec3> = normals.iter().flatten().copied().collect();
        if valid.len() < 2 {
            return None;
        }
        let (axis, _) = reference_axis(&valid);
        let farthest = |from: DVec3| valid.iter().copied().min_by(|a, b| a.dot(from).total_cmp(&b.dot(from)));
        let a = farthest(axis)?;
        let b = farthest(a)?;
        let mut centers = [a, b];
        // Degenerate triangles go with the first half; they never widen a cone.
        let mut side = vec![0usize; tris.len()];
        for _ in 0..8 {
            let mut changed = false;
            for (s, n) in side.iter_mut().zip(&normals) {
                let new = n.map_or(0, |n| (n.dot(centers[1]) > n.dot(centers[0])) as usize);
                changed |= new != *s;
                *s = new;
            }
            for (k, c) in centers.iter_mut().enumerate() {
                let sum: DVec3 = normals.iter().zip(&side).filter(|&(_, &s)| s == k).filter_map(|(n, _)| *n).sum();
                *c = sum.try_normalize().unwrap_or(*c);
            }
            if !changed {
                break;
            }
        }
        let halves: [Vec<[u32; 3]>; 2] =
            [0, 1].map(|k| tris.iter().zip(&side).filter(|&(_, &s)| s == k).map(|(t, _)| *t).collect());
        if halves.iter().any(|h| h.is_empty()) {
            return None;
        }
        let gain = self.value(&halves[0]) + self.value(&halves[1]) - self.value(tris);
        Some(Candidate { gain, order: (index, 0), what: halves })
    }

    /// Splits pieces greedily, largest gain first, while a split gains and the count stays
    /// within `budget`. The halves keep their piece's partition.
    fn split(&self, mut pieces: Vec<Piece>, budget: usize) -> Vec<Piece> {
        let mut heap: BinaryHeap<_> = pieces.iter().enumerate().filter_map(|(i, p)| self.best_split(i, p)).collect();
        while pieces.len() < budget {
            let Some(c) = heap.pop() else { break };
            if c.gain <= 1e-9 {
                break;
            }
            let i = c.order.0;
            let [first, second] = c.what;
            let partition = pieces[i].partition;
            pieces[i].triangles = first;
            pieces.push(Piece { triangles: second, partition });
            for i in [i, pieces.len() - 1] {
                heap.extend(self.best_split(i, &pieces[i]));
            }
        }
        pieces
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Influences;

    /// A thin open tube along y (a limb): `segments` around, `rings` along, one joint.
    fn tube(segments: u32, rings: u32) -> SkinnedMesh {
        let mut positions = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let a = std::f32::consts::TAU * s as f32 / segments as f32;
                positions.push(Vec3::new(0.1 * a.cos(), 0.05 * r as f32, -0.1 * a.sin()));
            }
        }
        let at = |r: u32, s: u32| r * segments + s % segments;
        let mut triangles = Vec::new();
        for r in 0..rings - 1 {
            for s in 0..segments {
                let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
                triangles.extend([[a, b, c], [b, d, c]]);
            }
        }
        let n = positions.len();
        let influences = Influences { stride: 1, joints: vec![0; n], weights: vec![1.0; n] };
        SkinnedMesh { positions, triangles, influences: Some(influences), ..SkinnedMesh::default() }
    }

    /// Expected backface-culled triangles over evenly spread views, summed over meshlets.
    fn culled(mesh: &SkinnedMesh, m: &Meshlets) -> f64 {
        m.meshlets
            .iter()
            .map(|h| {
                let v = m.vertices_of(h);
                let tris: Vec<[u32; 3]> =
                    m.triangles_of(h).chunks_exact(3).map(|t| [0, 1, 2].map(|k| v[t[k] as usize])).collect();
                let normals: Vec<DVec3> = tris.iter().filter_map(|t| face_normal(&mesh.positions, t)).collect();
                value(&normals, tris.len())
            })
            .sum()
    }

    #[test]
    fn pieces_pay_stay_within_budget_and_are_deterministic() {
        let mesh = super::super::prepare(&tube(24, 120)).mesh;
        let limits = MeshletLimits::NVIDIA;
        let params = Params::default();
        let ours = build(&mesh, limits, &params);
        ours.validate(&mesh.triangles, limits).unwrap();
        assert_eq!(ours, build(&mesh, limits, &params), "deterministic");
        let base = skin_aware::build(&mesh, limits, &params.skin_aware);
        let reference = greedy::build(&mesh.triangles, &mesh.positions, limits, greedy::CONE_WEIGHT);
        assert!(ours.len() > base.len(), "meshlets around a tube span wide cones: some split");
        assert!(ours.len() as f32 <= params.budget * reference.len() as f32, "{} vs {}", ours.len(), reference.len());
        let (ours_culled, base_culled) = (culled(&mesh, &ours), culled(&mesh, &base));
        assert!(ours_culled > 1.1 * base_culled, "{ours_culled} vs skin-aware {base_culled}");
        // No budget beyond the base: the skin-aware meshlets, repacked.
        let none = build(&mesh, limits, &Params { budget: 0.0, ..params });
        assert_eq!(none.len(), base.len());
    }
}
