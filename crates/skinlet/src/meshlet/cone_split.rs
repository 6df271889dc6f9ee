//! Cone-split builder (ours): skin-aware meshlets ([`super::skin_aware`]), then split where
//! their normal cone is too wide for backface culling to pay, within a meshlet budget.
//!
//! Why. A meshlet is backface-culled when the eye lies behind every one of its triangles'
//! planes; its normal cone (conservative-bounds paper, section 4) decides how often that
//! happens. For a cone of half-angle α < 90° and view directions spread evenly over the
//! sphere, the share of views that cull it is `(1 − sin α) / 2`: 25% at 30°, 6.7% at 60°,
//! none from 90° on. Greedy builders fill meshlets to the limits first, so on curved
//! characters many meshlets wrap around a limb and span more than 90° (never culled).
//!
//! Method. Each meshlet's value is its triangle count × `(1 − sin α) / 2`, with α the
//! narrowest cone around its rest face normals ([`crate::bounds::cone::reference_axis`]):
//! the expected number of triangles backface culling skips. A meshlet is split in two by
//! 2-means on its face normals (seeded by the normal farthest from its axis and the one
//! farthest from that), which on a smooth surface cuts it across its curvature into two
//! connected halves. Splits are taken greedily, largest gain in value first, while the gain
//! is positive and the meshlet count stays within `budget` × meshoptimizer's count on the
//! same mesh and limits. Splitting never moves a triangle across skin-aware partitions, so
//! the joint coherence that keeps animated bounds tight is kept.
//!
//! Guarantee: the output is a valid meshlet set of the same triangles ([`Meshlets::validate`]);
//! for the same mesh and parameters it is the same (no randomness, ties broken by index).

use super::{MeshletLimits, Meshlets, greedy, skin_aware};
use crate::bounds::cone::reference_axis;
use crate::model::SkinnedMesh;
use glam::{DVec3, Vec3};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub skin_aware: skin_aware::Params,
    /// At most this many times meshoptimizer's meshlet count on the same mesh (never fewer
    /// than the skin-aware builder's own).
    pub budget: f32,
}

impl Default for Params {
    fn default() -> Self {
        Params { skin_aware: skin_aware::Params::default(), budget: 1.3 }
    }
}

pub fn build(mesh: &SkinnedMesh, limits: MeshletLimits, params: &Params) -> Meshlets {
    let base = skin_aware::build(mesh, limits, &params.skin_aware);
    let reference = greedy::build(&mesh.triangles, &mesh.positions, limits, greedy::CONE_WEIGHT).len();
    let budget = ((params.budget.max(0.0) * reference as f32) as usize).max(base.len());
    let groups: Vec<Vec<[u32; 3]>> = base
        .meshlets
        .iter()
        .map(|m| {
            let verts = base.vertices_of(m);
            base.triangles_of(m).chunks_exact(3).map(|t| [0, 1, 2].map(|k| verts[t[k] as usize])).collect()
        })
        .collect();
    let (groups, roots) = split(&mesh.positions, groups, budget);
    // The halves of a split stay next to each other, in the base meshlets' order.
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by_key(|&g| (roots[g], g));
    let mut out = Meshlets::default();
    for tris in order.iter().map(|&g| &groups[g]) {
        let mut verts: Vec<u32> = Vec::new();
        let mut local: Vec<u8> = Vec::with_capacity(3 * tris.len());
        for &v in tris.iter().flatten() {
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

/// A candidate split of one group: its gain and the two halves (by triangle position).
struct Split {
    gain: f64,
    group: usize,
    halves: [Vec<usize>; 2],
}

impl PartialEq for Split {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Split {}
impl PartialOrd for Split {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Split {
    /// Largest gain first; among equal gains the lower group.
    fn cmp(&self, other: &Self) -> Ordering {
        self.gain.total_cmp(&other.gain).then(other.group.cmp(&self.group))
    }
}

/// The best 2-means split of `tris` by face normal, if it has two non-empty halves.
fn best_split(positions: &[Vec3], group: usize, tris: &[[u32; 3]]) -> Option<Split> {
    if tris.len() < 2 {
        return None;
    }
    // Degenerate triangles go with the first half; they never widen a cone.
    let normals: Vec<Option<DVec3>> = tris.iter().map(|t| face_normal(positions, t)).collect();
    let valid: Vec<DVec3> = normals.iter().flatten().copied().collect();
    if valid.len() < 2 {
        return None;
    }
    let (axis, _) = reference_axis(&valid);
    let farthest = |from: DVec3| valid.iter().copied().min_by(|a, b| a.dot(from).total_cmp(&b.dot(from)));
    let a = farthest(axis)?;
    let b = farthest(a)?;
    let mut centers = [a, b];
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
    let halves: [Vec<usize>; 2] = [0, 1].map(|k| (0..tris.len()).filter(|&i| side[i] == k).collect());
    if halves.iter().any(|h| h.is_empty()) {
        return None;
    }
    let value_of = |idx: &[usize]| {
        let n: Vec<DVec3> = idx.iter().filter_map(|&i| normals[i]).collect();
        value(&n, idx.len())
    };
    let gain = value_of(&halves[0]) + value_of(&halves[1]) - value(&valid, tris.len());
    Some(Split { gain, group, halves })
}

/// Splits groups greedily, largest gain first, while a split gains and the count stays
/// within `budget`. Also returns each group's base group.
fn split(positions: &[Vec3], mut groups: Vec<Vec<[u32; 3]>>, budget: usize) -> (Vec<Vec<[u32; 3]>>, Vec<usize>) {
    let mut roots: Vec<usize> = (0..groups.len()).collect();
    let mut heap: BinaryHeap<Split> =
        groups.iter().enumerate().filter_map(|(g, tris)| best_split(positions, g, tris)).collect();
    while groups.len() < budget {
        let Some(s) = heap.pop() else { break };
        if s.gain <= 1e-9 {
            break;
        }
        let tris = std::mem::take(&mut groups[s.group]);
        let [first, second] = s.halves.map(|h| h.iter().map(|&i| tris[i]).collect::<Vec<_>>());
        groups[s.group] = first;
        groups.push(second);
        roots.push(roots[s.group]);
        for g in [s.group, groups.len() - 1] {
            if let Some(next) = best_split(positions, g, &groups[g]) {
                heap.push(next);
            }
        }
    }
    (groups, roots)
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
    fn splits_pay_stay_within_budget_and_are_deterministic() {
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
