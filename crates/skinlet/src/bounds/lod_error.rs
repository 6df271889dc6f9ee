//! Errors of a cluster LOD hierarchy ([`crate::meshlet::lod`]) that hold under animation:
//! for every pose of the clips (each of their key intervals, as for the meshlet bounds), a cut
//! whose groups all have errors within `e` is within `e` of the full detail mesh, skinned, both
//! ways. A cut at `e` is every cluster whose own group's error is at most `e` and whose parent
//! group's is above it; with errors that grow up the hierarchy it replaces, group by group,
//! children by the clusters made from them. Two ways to assign such errors are bounded, and a
//! part keeps the one whose cuts draw fewer triangles (the geometric mean over thresholds from
//! 1/8 to 1/512 of its size):
//!
//! - Summed: a group's own error bounds the two-sided distance between its clusters and its
//!   children; its stored error adds its children's groups' largest. A point of the cut is
//!   within its group's error of the full mesh by induction down the hierarchy; a full detail
//!   point reaches the cut through a chain of groups, each within its own error.
//! - Direct: every cluster stands for a set of full detail triangles, its region (a part's
//!   meshlets their own; a group's clusters share out its children's regions, each full detail
//!   triangle going to the made cluster nearest its centroid in the bind pose). A group's
//!   direct error bounds the distance from its clusters to the group's region and from each
//!   cluster's region to that cluster; its stored error is the larger of that and its
//!   children's groups'. A cut's regions partition the full detail mesh, so each full detail
//!   point is within its cluster's error of it, and no level adds to another.
//!
//! How. Distances are bounded through fixed pairs of points. Each triangle on one side is
//! covered by sub-triangles (itself, or midpoint subdivisions where one match would be
//! loose), each matched with one triangle of the other side, each corner with a fixed point
//! of it (its nearest in the rest pose); the triangle matched is the one whose pairs stay
//! nearest over the rest pose and each clip's start, middle and end (pairs nearest in one
//! pose can part in motion, across a bending joint). A skinned triangle is the affine image of its bind
//! triangle and the distance to a triangle is convex, so any point of a skinned sub-triangle
//! is at most its corners' largest distance to their paired points away from the other side.
//! Such a distance `S(P) − S(Q)`, with `P − Q = Σ cᵥ v` over mesh vertices (`Σ cᵥ = 0`), is
//! bounded in the node space of the group's principal joint `r`: per influence joint `k`,
//! with `αᵥ = cᵥ wᵥₖ` summing to `sₖ` and `Tₖ(t) = global(r)⁻¹ global(k) IBMₖ`,
//! `Σ αᵥ Tₖ(t) mᵥ = sₖ Tₖ(t) m₀ + Lin Tₖ(t) Σ αᵥ (mᵥ − m₀)` (`m`: morphed rest positions,
//! `m₀` one of them): the carried box of [`super::vertex`] weighted by the weight difference
//! `sₖ`, plus a ball of `Tₖ`'s stretch times the bind-pose vector (grown by the morph
//! deltas' reach). The sum's length times the stretch of `global(r)` bounds the distance in
//! scene units. Where a fast motion between two keys makes the worst interval's bound loose,
//! that interval is halved (up to 4 times) while its halves bound tighter. Exact arithmetic:
//! the f32 rounding of skinning (about 1e-7 of the positions' magnitude) is not included.
//!
//! Within a pose envelope ([`super::envelope`]: crossfades, additive layers, IK), the same
//! pairs are bounded over the envelope's motions as over one more interval, from a pose inside
//! it (the caps' centres, the boxes' middles) and with the morph deltas' reach over its weight
//! ranges: a second set of errors, for the instances the pose guard admits.
//!
//! The hierarchy's shape is the simplifier's; only the errors are replaced.

use super::Aabb;
use super::envelope::Envelope;
use super::motion::spectral_bound;
use super::sphere_cone::key_intervals;
use super::vertex::{IntervalMotions, clip_weight_ranges, morph_box};
use crate::clip::Clip;
use crate::meshlet::lod::LodHierarchy;
use crate::meshlet::stats::principal_joint;
use crate::model::{Skeleton, Skin, SkinnedMesh, Trs};
use crate::pose::Poser;
use crate::{Error, Result};
use glam::{DMat3, DMat4, DVec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// How many times a sub-triangle is split at most (4 pieces each time).
const MAX_DEPTH: u32 = 3;
/// A sub-triangle is split while its match is this much looser than its corners' own
/// nearest distances.
const LOOSE: f64 = 1.05;

/// Replaces every group's error by one that holds at every pose of `clips` (none: the rest
/// pose), summed or direct (above), whichever draws fewer triangles. `lod` is over `mesh`'s
/// vertices (the mesh the meshlets were built on), skinned by `skin`. With an `envelope`, also
/// returns per group an error that holds at every pose inside it (chosen the same way, on its
/// own: the same pairs bounded over the envelope's motions instead of the clips').
pub fn bound_errors(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    envelope: Option<&Envelope>,
    mesh: &SkinnedMesh,
    lod: &mut LodHierarchy,
) -> Result<Option<Vec<f32>>> {
    let ctx = Ctx::new(skeleton, skin, clips, envelope, mesh)?;
    let own = group_bounds(&ctx, clips, lod, |ctx, g| {
        let group = &lod.groups[g];
        let (children, made) = (triangles(lod, &group.children), triangles(lod, &group.made));
        let mut pairs = Vec::new();
        match_pairs(ctx, &children, &made, &mut pairs);
        match_pairs(ctx, &made, &children, &mut pairs);
        (children, pairs)
    })?;
    let regions = regions(mesh, lod);
    let direct = group_bounds(&ctx, clips, lod, |ctx, g| {
        let made = &lod.groups[g].made;
        let region = triangles_of(&regions, made);
        let mut pairs = Vec::new();
        for &c in made {
            let cluster = &lod.clusters[c as usize].triangles;
            match_pairs(ctx, cluster, &region, &mut pairs);
            match_pairs(ctx, &regions[c as usize], cluster, &mut pairs);
        }
        (region, pairs)
    })?;
    // Triangles of the cuts at thresholds from 1/8 to 1/512 of the part's size.
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for c in lod.clusters.iter().filter(|c| c.group.is_none()) {
        for &v in &c.triangles {
            (lo, hi) = (lo.min(mesh.positions[v as usize].as_dvec3()), hi.max(mesh.positions[v as usize].as_dvec3()));
        }
    }
    let size = (hi - lo).length() as f32;
    // Summed or direct errors, from the bounds `at` (0: the clips', 1: the envelope's).
    let mut choose = |at: usize| -> Vec<f32> {
        let pick = |b: &[[f64; 2]]| b.iter().map(|b| b[at]).collect::<Vec<f64>>();
        let summed = stored(lod, &pick(&own), |own, below| own + below);
        let largest = stored(lod, &pick(&direct), f64::max);
        // The log of the cuts' triangles, summed (each threshold counts alike).
        let mut drawn = |errors: &[f32]| -> f64 {
            errors.iter().zip(&mut lod.groups).for_each(|(&e, g)| g.error = e);
            let cut_triangles =
                |e: f32| lod.cut(e).iter().map(|&c| lod.clusters[c as usize].triangles.len()).sum::<usize>();
            (3..=9).map(|k| (cut_triangles(size * 0.5f32.powi(k)).max(1) as f64).ln()).sum()
        };
        if drawn(&largest) <= drawn(&summed) { largest } else { summed }
    };
    let within_envelope = envelope.map(|_| choose(1));
    let keep = choose(0);
    keep.iter().zip(&mut lod.groups).for_each(|(&e, g)| g.error = e);
    Ok(within_envelope)
}

/// Stored errors from each group's `own` bound and its children's groups' largest stored
/// error (`combine(own, below)`), rounded up to f32 (NaN, no bound, as infinity).
fn stored(lod: &LodHierarchy, own: &[f64], combine: impl Fn(f64, f64) -> f64) -> Vec<f32> {
    let mut out: Vec<f32> = Vec::with_capacity(own.len());
    // Groups come after their children's groups: each sees its children's final errors.
    for (group, &own) in lod.groups.iter().zip(own) {
        let below = (group.children.iter())
            .filter_map(|&c| lod.clusters[c as usize].group.map(|g| out[g as usize]))
            .fold(0.0f32, f32::max);
        let error = combine(own, below as f64);
        let rounded = if error.is_nan() { f32::INFINITY } else { error as f32 };
        out.push(if (rounded as f64) < error { rounded.next_up() } else { rounded });
    }
    out
}

/// The triangles of `clusters`, three mesh vertices each.
fn triangles(lod: &LodHierarchy, clusters: &[u32]) -> Vec<u32> {
    clusters.iter().flat_map(|&c| lod.clusters[c as usize].triangles.iter().copied()).collect()
}

/// Each cluster's region, as full detail triangles (three mesh vertices each; see the module
/// comment).
fn regions(mesh: &SkinnedMesh, lod: &LodHierarchy) -> Vec<Vec<u32>> {
    let position = |v: u32| mesh.positions[v as usize].as_dvec3();
    let mut out: Vec<Vec<u32>> =
        lod.clusters.iter().map(|c| if c.group.is_none() { c.triangles.clone() } else { Vec::new() }).collect();
    // Groups come after their children's groups.
    for group in &lod.groups {
        let made: Vec<(Aabb, Vec<[DVec3; 3]>)> = (group.made.iter())
            .map(|&c| {
                let corners: Vec<[DVec3; 3]> = (lod.clusters[c as usize].triangles.chunks_exact(3))
                    .map(|t| [position(t[0]), position(t[1]), position(t[2])])
                    .collect();
                let mut bounds = Aabb::point(corners.first().map_or(DVec3::ZERO, |t| t[0]));
                corners.iter().flatten().for_each(|&p| bounds.extend(p));
                (bounds, corners)
            })
            .collect();
        let region = triangles_of(&out, &group.children);
        // Each full detail triangle to the made cluster with the triangle nearest its centroid.
        let owners: Vec<usize> = region
            .par_chunks_exact(3)
            .map(|t| {
                let p = (position(t[0]) + position(t[1]) + position(t[2])) / 3.0;
                let (mut best, mut near) = (0usize, f64::INFINITY);
                for (k, (bounds, triangles)) in made.iter().enumerate() {
                    if box_distance(bounds, p) >= near {
                        continue;
                    }
                    for t in triangles {
                        let d = (closest_point(t, p).0 - p).length();
                        if d < near {
                            (best, near) = (k, d);
                        }
                    }
                }
                best
            })
            .collect();
        for (t, &k) in region.chunks_exact(3).zip(&owners) {
            if let Some(&c) = group.made.get(k) {
                out[c as usize].extend_from_slice(t);
            }
        }
    }
    out
}

/// The regions of `clusters`, one after the other.
fn triangles_of(regions: &[Vec<u32>], clusters: &[u32]) -> Vec<u32> {
    clusters.iter().flat_map(|&c| regions[c as usize].iter().copied()).collect()
}

/// Per group, the largest paired distance over every interval of `clips` and over the
/// envelope's motions (0 without one), the pairs and the triangles whose principal joint they
/// are bounded in given by `pairs_of`.
fn group_bounds(
    ctx: &Ctx,
    clips: &[&Clip],
    lod: &LodHierarchy,
    pairs_of: impl Fn(&Ctx, usize) -> (Vec<u32>, Vec<Vec<(u32, f64)>>) + Sync,
) -> Result<Vec<[f64; 2]>> {
    let (skeleton, mesh) = (ctx.skeleton, ctx.mesh);
    let intervals: Vec<(Option<&Clip>, f32, f32)> = if clips.is_empty() {
        vec![(None, 0.0, 0.0)]
    } else {
        clips.iter().flat_map(|&c| key_intervals(c).into_iter().map(move |(a, b)| (Some(c), a, b))).collect()
    };
    (0..lod.groups.len())
        .into_par_iter()
        .map(|g| {
            let (principal, pairs) = pairs_of(ctx, g);
            let terms = ctx.terms(&principal, &pairs, &ctx.reach)?;
            let within_envelope = match &ctx.envelope {
                Some(e) => ctx.terms(&principal, &pairs, &e.reach)?.bound(ctx, &e.motions, &e.at, &e.globals, true),
                None => 0.0,
            };
            let (mut poser, mut at) = (Poser::default(), Vec::new());
            let mut bound = |clip: Option<&Clip>, t1: f32, t2: f32| -> Result<f64> {
                let motions = IntervalMotions::new(skeleton, &mesh.morphs, clip, t1, t2)?;
                match clip {
                    Some(c) => c.sample_locals(skeleton, t1, &mut at),
                    None => at = skeleton.nodes.iter().map(|n| n.rest).collect(),
                }
                let globals = poser.globals(skeleton, clip, t1);
                Ok(terms.bound(ctx, &motions, &at, globals, false))
            };
            let mut heap = std::collections::BinaryHeap::new();
            for &(clip, t1, t2) in &intervals {
                heap.push(Interval { bound: bound(clip, t1, t2)?, clip, t1, t2, halved: 0 });
            }
            // The worst interval is halved while that makes it tighter (a fast motion between
            // two keys is bounded loosely over the whole interval); the worst left is the
            // error.
            let mut halvings = HALVINGS_PER_GROUP;
            while let Some(worst) = heap.pop() {
                let (clip, mid, halved) = (worst.clip, (worst.t1 + worst.t2) / 2.0, worst.halved + 1);
                if halvings == 0
                    || halved > INTERVAL_HALVINGS
                    || !(worst.t1 < mid && mid < worst.t2)
                    || !worst.bound.is_finite()
                {
                    return Ok([worst.bound, within_envelope]);
                }
                halvings -= 1;
                let halves = [
                    Interval { bound: bound(clip, worst.t1, mid)?, clip, t1: worst.t1, t2: mid, halved },
                    Interval { bound: bound(clip, mid, worst.t2)?, clip, t1: mid, t2: worst.t2, halved },
                ];
                // No tighter: the whole interval's bound is the largest.
                if halves.iter().any(|h| h.bound >= worst.bound) {
                    return Ok([worst.bound, within_envelope]);
                }
                heap.extend(halves);
            }
            Ok([0.0, within_envelope])
        })
        .collect()
}

/// How many times an interval is halved at most, and how many halvings one group's bound
/// makes at most.
const INTERVAL_HALVINGS: u32 = 4;
const HALVINGS_PER_GROUP: u32 = 64;

/// A time interval of a clip (within one key interval) and the bound over it, ordered by
/// the bound.
struct Interval<'a> {
    bound: f64,
    clip: Option<&'a Clip>,
    t1: f32,
    t2: f32,
    halved: u32,
}

impl PartialEq for Interval<'_> {
    fn eq(&self, other: &Self) -> bool {
        self.bound.total_cmp(&other.bound).is_eq()
    }
}

impl Eq for Interval<'_> {}

impl PartialOrd for Interval<'_> {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Interval<'_> {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.bound.total_cmp(&other.bound)
    }
}

struct Ctx<'a> {
    skeleton: &'a Skeleton,
    skin: &'a Skin,
    mesh: &'a SkinnedMesh,
    /// How far each vertex's morph deltas can move it within the weights' ranges over the clips.
    reach: Vec<f64>,
    envelope: Option<EnvelopeMotions>,
    /// Each vertex's skinned positions at `poses` poses (vertex after vertex): the rest pose,
    /// then [`POSES_PER_CLIP`] times of each clip. Pairs are matched where they stay near at
    /// all of them.
    posed: Vec<DVec3>,
    poses: usize,
}

/// What the errors within a pose envelope are bounded over: its motions, a pose inside it
/// (each listed node at its centre rotation and the centres of its boxes; the others at rest)
/// with its nodes' global transforms, and each vertex's morph reach within its weight ranges.
struct EnvelopeMotions {
    motions: IntervalMotions,
    at: Vec<Trs>,
    globals: Vec<DMat4>,
    reach: Vec<f64>,
}

/// How many poses of each clip pairs are matched at: its start, middle and end (more did not
/// tighten Xbot's errors; each costs time).
const POSES_PER_CLIP: usize = 3;

/// One joint `k`'s share of a paired difference: `s · Tₖ(t) m₀` (the carried box of a
/// vertex, [`Terms::carried`]`[carried]`) plus `Lin Tₖ(t)` (joint [`Terms::joints`]`[joint]`)
/// applied to `offset` (bind pose) and to at most `reach` more (morph deltas).
struct Term {
    joint: u32,
    carried: u32,
    s: f64,
    offset: DVec3,
    reach: f64,
}

/// The paired differences of one group, in the space of its principal joint.
struct Terms {
    principal: u16,
    terms: Vec<Term>,
    /// Each pair's terms: `terms[ends[i - 1]..ends[i]]`.
    ends: Vec<u32>,
    /// The joints the terms use, and the (vertex, joint) whose carried boxes they use.
    joints: Vec<u16>,
    carried: Vec<(u32, u16)>,
}

impl<'a> Ctx<'a> {
    fn new(
        skeleton: &'a Skeleton,
        skin: &'a Skin,
        clips: &[&Clip],
        envelope: Option<&Envelope>,
        mesh: &'a SkinnedMesh,
    ) -> Result<Ctx<'a>> {
        if mesh.influences.is_none() {
            return Err(Error::invalid("cluster LOD errors", "the mesh has no skin weights"));
        }
        let reach = |ranges: &[(f64, f64)]| -> Vec<f64> {
            (0..mesh.positions.len())
                .map(|v| {
                    let (b, p) = (morph_box(mesh, v, ranges), mesh.positions[v].as_dvec3());
                    (b.min - p).abs().max((b.max - p).abs()).length()
                })
                .collect()
        };
        let envelope = match envelope {
            Some(e) => {
                e.check(skeleton.nodes.len(), mesh.morphs.weights.len())?;
                let mut at: Vec<Trs> = skeleton.nodes.iter().map(|n| n.rest).collect();
                for r in &e.nodes {
                    let middle = |(lo, hi): (glam::Vec3, glam::Vec3)| (lo + hi) / 2.0;
                    at[r.node as usize] = Trs {
                        rotation: r.centre.normalize(),
                        translation: middle(r.translation),
                        scale: middle(r.scale),
                    };
                }
                let mut globals = Vec::new();
                crate::pose::global_transforms(skeleton, &at, &mut globals);
                let reach = reach(&e.weight_ranges());
                Some(EnvelopeMotions { motions: e.motions(skeleton), at, globals, reach })
            }
            None => None,
        };
        let reach = reach(&clip_weight_ranges(&mesh.morphs, clips)?);
        let mut times: Vec<(Option<&Clip>, Option<f32>)> = vec![(None, None)];
        for &c in clips {
            let last = (POSES_PER_CLIP - 1) as f32;
            times.extend((0..POSES_PER_CLIP).map(|k| (Some(c), Some(c.start + c.duration() * k as f32 / last))));
        }
        let poses = times.len();
        let mut posed = vec![DVec3::ZERO; mesh.positions.len() * poses];
        for (p, &(clip, t)) in times.iter().enumerate() {
            let at = crate::skinning::posed_positions(skeleton, skin, mesh, clip, t)?;
            for (v, x) in at.iter().enumerate() {
                posed[v * poses + p] = x.as_dvec3();
            }
        }
        Ok(Ctx { skeleton, skin, mesh, reach, envelope, posed, poses })
    }

    fn position(&self, v: u32) -> DVec3 {
        self.mesh.positions[v as usize].as_dvec3()
    }

    /// Vertex `v` skinned at pose `p` (0: the rest pose).
    fn posed(&self, v: u32, p: usize) -> DVec3 {
        self.posed[v as usize * self.poses + p]
    }

    /// Paired differences (coefficients over mesh vertices, [`match_pairs`]) as joint terms,
    /// in the space of the principal joint of `triangles`' vertices, each vertex's morph
    /// deltas moving it at most `reach`.
    fn terms(&self, triangles: &[u32], pairs: &[Vec<(u32, f64)>], reach: &[f64]) -> Result<Terms> {
        let inf = self.mesh.influences.as_ref().expect("checked by group_bounds");
        let mut vertices: Vec<u32> = triangles.to_vec();
        vertices.sort_unstable();
        vertices.dedup();
        let principal = principal_joint(self.mesh, &vertices)
            .ok_or_else(|| Error::invalid("cluster LOD errors", "a group without skinned vertices"))?
            .0;
        let mut out = Terms { principal, terms: Vec::new(), ends: Vec::new(), joints: Vec::new(), carried: Vec::new() };
        let (mut joint_slot, mut carried_slot) = (HashMap::new(), HashMap::new());
        let mut joints: Vec<(u16, f64, u32, f64)> = Vec::new();
        for coefficients in pairs {
            // Per joint: the sum of α, the vertex with the largest |α| and that |α|.
            joints.clear();
            for &(v, c) in coefficients {
                for (k, w) in inf.of(v as usize) {
                    let alpha = c * w as f64;
                    match joints.iter_mut().find(|j| j.0 == k) {
                        Some(j) => {
                            j.1 += alpha;
                            if alpha.abs() > j.3 {
                                (j.2, j.3) = (v, alpha.abs());
                            }
                        }
                        None => joints.push((k, alpha, v, alpha.abs())),
                    }
                }
            }
            for &(k, s, v0, _) in &joints {
                let (p0, mut offset, mut reach_sum) = (self.position(v0), DVec3::ZERO, 0.0);
                for &(v, c) in coefficients {
                    let w: f64 = inf.of(v as usize).filter(|j| j.0 == k).map(|j| j.1 as f64).sum();
                    offset += c * w * (self.position(v) - p0);
                    reach_sum += (c * w).abs() * reach[v as usize];
                }
                let reach = reach_sum + s.abs() * reach[v0 as usize];
                if s != 0.0 || offset != DVec3::ZERO || reach != 0.0 {
                    let joint = *joint_slot.entry(k).or_insert_with(|| {
                        out.joints.push(k);
                        out.joints.len() as u32 - 1
                    });
                    let carried = if s == 0.0 {
                        u32::MAX
                    } else {
                        *carried_slot.entry((v0, k)).or_insert_with(|| {
                            out.carried.push((v0, k));
                            out.carried.len() as u32 - 1
                        })
                    };
                    out.terms.push(Term { joint, carried, s, offset, reach });
                }
            }
            out.ends.push(out.terms.len() as u32);
        }
        Ok(out)
    }
}

impl Terms {
    /// The largest paired distance over one interval, in scene units. `at`: every node's
    /// local transform at the interval's start, `globals` their global transforms: `Lin Tₖ`
    /// is split into its value there (applied exactly) and its deviation over the interval.
    ///
    /// `relative` (wide motions, a pose envelope's): each pair's bound is also taken with
    /// the carried boxes relative to one of its joints `j`, and the smallest kept. The boxes
    /// of `Tₖ m₀` in the principal joint's space each span the whole motion of `k` relative
    /// to it, independently, where their weighted sum only moves with the joints' motions
    /// relative to each other: with `Σₖ sₖ = σ` (0 up to rounding for normalized weights),
    /// `Σₖ sₖ Tₖ m₀ = Lin Tⱼ Σₖ sₖ Uⱼₖ m₀ + σ tⱼ`, `Uⱼₖ = Tⱼ⁻¹ Tₖ` (`k`'s motion relative to
    /// `j`, a short chain for the joints of one vertex) and `tⱼ` the translation of `Tⱼ`.
    fn bound(&self, ctx: &Ctx, motions: &IntervalMotions, at: &[Trs], globals: &[DMat4], relative: bool) -> f64 {
        let (skeleton, skin) = (ctx.skeleton, ctx.skin);
        let r = skin.joints[self.principal as usize];
        let to_r = globals[r as usize].inverse();
        let boxes: Vec<Aabb> = (self.carried.iter())
            .map(|&(v, k)| {
                let rest =
                    motions.rest_box(ctx.mesh, v as usize).transformed(&skin.inverse_bind[k as usize].as_dmat4());
                motions.carry(skeleton, skin.joints[k as usize], r, rest)
            })
            .collect();
        // Per joint: its linear part at the start, its deviation and its stretch.
        let linear: Vec<(DMat3, f64, f64)> = (self.joints.iter())
            .map(|&k| {
                let (node, ibm) = (skin.joints[k as usize], skin.inverse_bind[k as usize].as_dmat4());
                let ibm_norm = spectral_bound(&DMat3::from_mat4(ibm));
                (
                    DMat3::from_mat4(to_r * globals[node as usize] * ibm),
                    motions.deviation(skeleton, node, r, at) * ibm_norm,
                    motions.stretch(skeleton, node, Some(r)) * ibm_norm,
                )
            })
            .collect();
        let mut cache = RelativeCache::default();
        let mut worst = 0.0f64;
        let mut start = 0usize;
        for &end in &self.ends {
            let pair_terms = &self.terms[start..end as usize];
            start = end as usize;
            let mut sums = PairSums { shifts: DVec3::ZERO, offsets: 0.0, reach: 0.0 };
            for t in pair_terms {
                let (start_linear, deviation, stretch) = &linear[t.joint as usize];
                sums.shifts += *start_linear * t.offset;
                sums.offsets += times(*deviation, t.offset.length());
                sums.reach += times(*stretch, t.reach);
            }
            let (mut lo, mut hi) = (sums.shifts, sums.shifts);
            for t in pair_terms.iter().filter(|t| t.s != 0.0) {
                let b = &boxes[t.carried as usize];
                let (a, c) = (b.min * t.s, b.max * t.s);
                lo += a.min(c);
                hi += a.max(c);
            }
            let mut pair = lo.abs().max(hi.abs()).length() + sums.offsets + sums.reach;
            for j in pair_terms.iter().filter(|t| relative && t.s != 0.0) {
                pair =
                    pair.min(self.relative_bound(ctx, motions, at, r, &linear, pair_terms, j.joint, &sums, &mut cache));
            }
            // Unbounded (a scale through zero, a singular joint): NaN or ∞ is no bound.
            worst = if pair.is_nan() { f64::INFINITY } else { worst.max(pair) };
        }
        let scene = motions.stretch(skeleton, r, None);
        let out = times(worst, scene);
        if out.is_nan() { f64::INFINITY } else { out }
    }

    /// One pair's bound with the carried part relative to its joint `self.joints[slot]`
    /// (see [`Terms::bound`]), in the principal joint `r`'s space: `Y = Σₖ sₖ Uⱼₖ m₀` as a
    /// box and as a ball (whichever bounds tighter), the offsets' part as `Lin Tⱼ Σₖ Lin Uⱼₖ
    /// offₖ` where that is tighter than [`PairSums::offsets`].
    #[allow(clippy::too_many_arguments)]
    fn relative_bound(
        &self,
        ctx: &Ctx,
        motions: &IntervalMotions,
        at: &[Trs],
        r: u32,
        linear: &[(DMat3, f64, f64)],
        pair_terms: &[Term],
        slot: u32,
        sums: &PairSums,
        cache: &mut RelativeCache,
    ) -> f64 {
        let (skeleton, skin) = (ctx.skeleton, ctx.skin);
        let joint = self.joints[slot as usize];
        let (node_j, ibm_j) = (skin.joints[joint as usize], skin.inverse_bind[joint as usize].as_dmat4());
        let bind_j = ibm_j.inverse();
        let (mut y_lo, mut y_hi, mut y_centre, mut y_radius, mut sigma) =
            (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0.0, 0.0);
        for t in pair_terms.iter().filter(|t| t.s != 0.0) {
            let (v, k) = self.carried[t.carried as usize];
            let (b, ball) = cache.carried.entry((v, k, joint)).or_insert_with(|| {
                let (ibm_k, node_k) = (skin.inverse_bind[k as usize].as_dmat4(), skin.joints[k as usize]);
                let rest = motions.rest_box(ctx.mesh, v as usize);
                let b = motions.carry(skeleton, node_k, node_j, rest.transformed(&ibm_k));
                // An unbounded box stays unbounded (0 · ∞ would make it NaN).
                let b = if b.is_finite() { b.transformed(&bind_j) } else { Aabb::EVERYWHERE };
                let (c, radius) = ((rest.min + rest.max) / 2.0, (rest.max - rest.min).length() / 2.0);
                let moved = (ibm_k.transform_point3(c), radius * spectral_bound(&DMat3::from_mat4(ibm_k)));
                let (c, radius) = motions.carry_ball(skeleton, node_k, node_j, at, moved);
                let ball = (bind_j.transform_point3(c), radius * spectral_bound(&DMat3::from_mat4(bind_j)));
                // Both hold: the box is also within the ball's.
                (Aabb { min: b.min.max(ball.0 - ball.1), max: b.max.min(ball.0 + ball.1) }, ball)
            });
            let (a, c) = (b.min * t.s, b.max * t.s);
            y_lo += a.min(c);
            y_hi += a.max(c);
            y_centre += t.s * ball.0;
            y_radius += times(t.s.abs(), ball.1);
            sigma += t.s;
        }
        let (linear_j, deviation_j, _) = &linear[slot as usize];
        let norm_j = spectral_bound(linear_j);
        // `Lin Tⱼ Y`: its value at the start applied exactly (to the box, or the ball's
        // centre), and its deviation.
        let abs = DMat3::from_cols(linear_j.x_axis.abs(), linear_j.y_axis.abs(), linear_j.z_axis.abs());
        let (moved, spread) = (*linear_j * ((y_lo + y_hi) / 2.0), abs * ((y_hi - y_lo) / 2.0));
        let (lo, hi) = (sums.shifts + moved - spread, sums.shifts + moved + spread);
        let by_box = lo.abs().max(hi.abs()).length() + times(*deviation_j, y_lo.abs().max(y_hi.abs()).length());
        let by_ball = (sums.shifts + *linear_j * y_centre).length()
            + times(norm_j, y_radius)
            + times(*deviation_j, y_centre.length() + y_radius);
        // The offsets: `E` the inner sum at the start, `f` how far it gets from it.
        let e = (linear_j.inverse() * sums.shifts).length();
        let mut f = 0.0;
        for t in pair_terms {
            let k = self.joints[t.joint as usize];
            let deviation = *cache.deviations.entry((k, joint)).or_insert_with(|| {
                let ibm_k = DMat3::from_mat4(skin.inverse_bind[k as usize].as_dmat4());
                motions.deviation(skeleton, skin.joints[k as usize], node_j, at)
                    * spectral_bound(&ibm_k)
                    * spectral_bound(&DMat3::from_mat4(bind_j))
            });
            f += times(deviation, t.offset.length());
        }
        let offsets = sums.offsets.min(times(norm_j, f) + times(*deviation_j, e + f));
        // `σ tⱼ`: weights summing to 1 up to rounding leave a little of `Tⱼ`'s translation.
        let translation = *cache.translations.entry(joint).or_insert_with(|| {
            let b = motions.carry(skeleton, node_j, r, Aabb::point(ibm_j.w_axis.truncate()));
            b.min.abs().max(b.max.abs()).length()
        });
        by_box.min(by_ball) + offsets + sums.reach + times(sigma.abs(), translation)
    }
}

/// One pair's sums over its terms: the offsets' parts at the start (`Σₖ Lin Tₖ(start) offₖ`)
/// and their deviation, and the morph deltas' reach.
struct PairSums {
    shifts: DVec3,
    offsets: f64,
    reach: f64,
}

/// A ball: centre and radius.
type Ball = (DVec3, f64);

/// What [`Terms::relative_bound`] computes once per interval: `Uⱼₖ m₀` per (vertex, k, j) as
/// a box and a ball, the deviation of `Lin Uⱼₖ` per (k, j), `|tⱼ|` per j.
#[derive(Default)]
struct RelativeCache {
    carried: HashMap<(u32, u16, u16), (Aabb, Ball)>,
    deviations: HashMap<(u16, u16), f64>,
    translations: HashMap<u16, f64>,
}

/// `a · b` for bounds ≥ 0, where a zero factor wins over an unbounded one.
fn times(a: f64, b: f64) -> f64 {
    if a == 0.0 || b == 0.0 { 0.0 } else { a * b }
}

/// A triangle of the side matched against, in the rest pose.
struct Target {
    vertices: [u32; 3],
    corners: [DVec3; 3],
    bounds: Aabb,
}

/// Covers every triangle of `from` by sub-triangles matched with triangles of `to` and
/// appends each sub-triangle corner's pair as coefficients over mesh vertices (`P − Q`).
fn match_pairs(ctx: &Ctx, from: &[u32], to: &[u32], out: &mut Vec<Vec<(u32, f64)>>) {
    let targets: Vec<Target> = to
        .chunks_exact(3)
        .map(|t| {
            let corners = [ctx.posed(t[0], 0), ctx.posed(t[1], 0), ctx.posed(t[2], 0)];
            let mut bounds = Aabb::point(corners[0]);
            bounds.extend(corners[1]);
            bounds.extend(corners[2]);
            Target { vertices: [t[0], t[1], t[2]], corners, bounds }
        })
        .collect();
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for t in from.chunks_exact(3) {
        subdivide(ctx, &targets, &[t[0], t[1], t[2]], identity, 0, out);
    }
}

/// Matches the sub-triangle with barycentric corners `bary` (over `source`) or splits it.
/// Each corner is paired with its nearest point of the target in the rest pose, and the
/// target is the one whose pairs stay nearest over the sampled poses ([`Ctx::posed`]): the
/// bound holds for any pairing, and pairs that part in motion make it loose.
fn subdivide(
    ctx: &Ctx,
    targets: &[Target],
    source: &[u32; 3],
    bary: [[f64; 3]; 3],
    depth: u32,
    out: &mut Vec<Vec<(u32, f64)>>,
) {
    let at = |b: [f64; 3], p: usize| {
        b[0] * ctx.posed(source[0], p) + b[1] * ctx.posed(source[1], p) + b[2] * ctx.posed(source[2], p)
    };
    // The corners at every pose (pose after pose).
    let posed: Vec<[DVec3; 3]> = (0..ctx.poses).map(|p| bary.map(|b| at(b, p))).collect();
    let points = posed[0];
    // The target whose farthest pair over the poses is nearest, and each corner's own
    // nearest such pair. Any pose's distance bounds that from below: the rest pose's boxes
    // skip targets.
    let (mut best, mut best_far) = (None, f64::INFINITY);
    let mut nearest = [f64::INFINITY; 3];
    for t in targets {
        let gaps = points.map(|p| box_distance(&t.bounds, p));
        let skip =
            gaps.iter().zip(&nearest).all(|(g, n)| g >= n) && gaps.iter().copied().fold(0.0, f64::max) >= best_far;
        if skip && best.is_some() {
            continue;
        }
        let w = points.map(|p| closest_point(&t.corners, p).1);
        let mut d = [0.0f64; 3];
        for (p, corners) in posed.iter().enumerate() {
            let [a, b, c] = t.vertices.map(|v| ctx.posed(v, p));
            for k in 0..3 {
                let x = (corners[k] - (w[k][0] * a + w[k][1] * b + w[k][2] * c)).length();
                d[k] = if x.is_nan() { f64::INFINITY } else { d[k].max(x) };
            }
            // Distances only grow with more poses: stop once this target improves nothing.
            if d.iter().zip(&nearest).all(|(d, n)| d >= n) && d.iter().copied().fold(0.0, f64::max) >= best_far {
                break;
            }
        }
        for k in 0..3 {
            nearest[k] = nearest[k].min(d[k]);
        }
        let far = d.iter().copied().fold(0.0, f64::max);
        // Every sub-triangle gets a target, whatever its distances (even infinite, from a
        // degenerate pose): the bound holds for any pairing, and a missing pair would not.
        if far < best_far || best.is_none() {
            (best, best_far) = (Some((t, w)), far);
        }
    }
    let own = nearest.iter().copied().fold(0.0, f64::max);
    let size = (points[1] - points[0]).length().max((points[2] - points[0]).length());
    if depth < MAX_DEPTH && best_far > own * LOOSE + 1e-9 * size {
        let mid = |a: [f64; 3], b: [f64; 3]| [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0, (a[2] + b[2]) / 2.0];
        let [a, b, c] = bary;
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        for piece in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
            subdivide(ctx, targets, source, piece, depth + 1, out);
        }
        return;
    }
    let Some((target, w)) = best else { return };
    for (b, w) in bary.iter().zip(w) {
        let mut coefficients: Vec<(u32, f64)> = Vec::with_capacity(6);
        let mut add = |v: u32, c: f64| match coefficients.iter_mut().find(|e| e.0 == v) {
            Some(e) => e.1 += c,
            None => coefficients.push((v, c)),
        };
        (0..3).for_each(|k| add(source[k], b[k]));
        (0..3).for_each(|k| add(target.vertices[k], -w[k]));
        coefficients.retain(|e| e.1 != 0.0);
        // A corner paired with itself (a vertex both sides keep) is 0 at every pose.
        if !coefficients.is_empty() {
            out.push(coefficients);
        }
    }
}

/// The distance from `p` to the box (0 inside).
fn box_distance(b: &Aabb, p: DVec3) -> f64 {
    (b.min - p).max(p - b.max).max(DVec3::ZERO).length()
}

/// The point of triangle `t` nearest `p` and its barycentric coordinates (Ericson,
/// "Real-Time Collision Detection", 5.1.5).
pub(crate) fn closest_point(t: &[DVec3; 3], p: DVec3) -> (DVec3, [f64; 3]) {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + v * ab, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + w * ac, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + w * (c - b), [0.0, 1.0 - w, w]);
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate triangle: its nearest corner.
        let d = [a, b, c].map(|q| (q - p).length_squared());
        let k = (0..3).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap_or(0);
        let mut w = [0.0; 3];
        w[k] = 1.0;
        return (t[k], w);
    }
    let (v, w) = (vb / denom, vc / denom);
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_match_the_triangle_that_stays_near_in_motion() {
        // A source triangle, a copy 0.1 above it that slides away at the second pose, and one
        // 0.2 below that stays: at the rest pose alone the first is nearer, over both the second.
        let triangle = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let rest: Vec<DVec3> = [0.0, 0.1, -0.2].iter().flat_map(|&z| triangle.map(|p| p + DVec3::Z * z)).collect();
        let moved: Vec<DVec3> =
            (rest.iter().enumerate()).map(|(v, &p)| if (3..6).contains(&v) { p + 5.0 * DVec3::X } else { p }).collect();
        let mesh = SkinnedMesh { positions: rest.iter().map(|p| p.as_vec3()).collect(), ..SkinnedMesh::default() };
        let (skeleton, skin) =
            (Skeleton::default(), Skin { name: String::new(), joints: Vec::new(), inverse_bind: Vec::new() });
        let matched = |poses: &[&[DVec3]], to: [u32; 6]| -> Vec<u32> {
            let posed = (0..rest.len()).flat_map(|v| poses.iter().map(move |p| p[v])).collect();
            let ctx = Ctx {
                skeleton: &skeleton,
                skin: &skin,
                mesh: &mesh,
                reach: Vec::new(),
                envelope: None,
                posed,
                poses: poses.len(),
            };
            let mut pairs = Vec::new();
            match_pairs(&ctx, &[0, 1, 2], &to, &mut pairs);
            let mut targets: Vec<u32> = pairs.iter().flatten().filter(|e| e.1 < 0.0).map(|e| e.0).collect();
            targets.sort_unstable();
            targets.dedup();
            targets
        };
        assert_eq!(matched(&[&rest], [3, 4, 5, 6, 7, 8]), [3, 4, 5]);
        assert_eq!(matched(&[&rest, &moved], [3, 4, 5, 6, 7, 8]), [6, 7, 8]);
        // Either order of the targets (the first seen is no favourite) and of the poses (the
        // rest pose last: a rule reading one pose, the first or the last, would fail one).
        assert_eq!(matched(&[&rest, &moved], [6, 7, 8, 3, 4, 5]), [6, 7, 8]);
        assert_eq!(matched(&[&moved, &rest], [3, 4, 5, 6, 7, 8]), [6, 7, 8]);
    }

    #[test]
    fn closest_point_barycentrics_reproduce_the_point() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        for p in [
            DVec3::new(0.2, 0.2, 1.0),
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(2.0, 0.5, 0.0),
            DVec3::new(0.6, 0.6, -3.0),
        ] {
            let (q, w) = closest_point(&t, p);
            let back = w[0] * t[0] + w[1] * t[1] + w[2] * t[2];
            assert!((q - back).length() < 1e-12, "{p}: {q} against {back}");
            assert!(w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)));
        }
        assert!((closest_point(&t, DVec3::new(0.6, 0.6, 0.0)).0 - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12);
    }
}
