//! Patch decomposition (Tsiapkolis & Bénard 2024, section 3.3, algorithm 1): edges grouped
//! into patches bounded by spatialized normal cones so that the expected extraction time
//! `Σ E(P)` is low, and the run-time extraction that culls them.
//!
//! Greedy bottom-up fusion: one patch per edge, then repeatedly merge the pair with the
//! largest gain `G = E(a) + E(b) − E(a ∪ b)` until no gain is positive. Each patch caches its
//! `k` best fusions (k = 50); the cache never misses a better fusion: a fusion is only
//! dropped when `k` better ones are stored, and a cache that lost every entry while some were
//! dropped is rebuilt. Edges are first split into groups of at most `c_max` (median splits of
//! the longest axis of their midpoints' box), fused independently and in parallel.
//!
//! Beyond the paper: candidate gains use O(1) upper bounds of the merged sphere radius and
//! cone angle (triangle inequality from both parents' bounds around the merged center and
//! mean axis), so one candidate costs the same for any patch size; the exact bounds are
//! computed once, on merge. Candidates are never over-estimated, so a fusion taken always
//! gains at least what was predicted. Finally a patch is kept only if it beats testing its
//! edges directly (`ξ·t_e > E`); its edges are tested every frame otherwise.
//!
//! Guarantee (see [`super`]): extraction returns exactly the brute-force contour set.

use super::Edges;
use super::bound::{
    EdgeGeometry, PatchBounds, acceptance, cone_angle, edge_geometry, line_distance, mean_axis, mean_sphere,
    reduced_sphere,
};
use crate::bounds::cone::reference_axis;
use crate::bounds::sphere_cone::round_up;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Patches as extraction reads them, and the extraction, live in the runtime crate.
pub use skinlet_runtime::contour_patches::{Patches, test_quads};

/// Which bounding sphere patches use (section 3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SphereKind {
    Mean,
    Reduced,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchParams {
    pub sphere: SphereKind,
    /// Viewing distance of the acceptance metric, in model sizes (largest box side): 10 in
    /// the paper, for models at unit scale.
    pub d_cam: f64,
    /// `t_P / t_e`: cost of a patch test in edge tests (calibrated per machine, section 4.2).
    pub cost_ratio: f64,
    /// Best fusions cached per patch (k).
    pub cache: usize,
    /// Largest group of edges fused together (c_max).
    pub group: usize,
    /// Optional GPU limits per patch (e.g. 126 edges, 64 vertices).
    pub max_edges: Option<usize>,
    pub max_vertices: Option<usize>,
}

impl Default for PatchParams {
    fn default() -> Self {
        PatchParams {
            sphere: SphereKind::Reduced,
            d_cam: 10.0,
            cost_ratio: DEFAULT_COST_RATIO,
            cache: 50,
            group: 4096,
            max_edges: None,
            max_vertices: None,
        }
    }
}

/// `t_P / t_e` measured with `skinlet_lab::contour_eval::calibrate` (`skinlet contours --calibrate`)
/// on the 2-core EPYC VM of docs/PERFORMANCE.md: bunny 0.32, armadillo 0.36 (the paper's
/// CPUs: 1.4 and 2.0; our patch test is branch-free and batched).
pub const DEFAULT_COST_RATIO: f64 = 0.35;

/// One patch being built (f64).
#[derive(Clone, Debug)]
struct Node {
    edges: Vec<u32>,
    center: DVec3,
    radius: f64,
    axis: DVec3,
    angle: f64,
    cost: f64,
    /// Sorted distinct vertices (kept only with a vertex limit).
    verts: Vec<u32>,
    alive: bool,
    /// Bumped on every merge into this slot (stale cache entries carry an older one).
    generation: u32,
    cache: Vec<Fusion>,
    /// No positive fusion was left out of `cache`.
    complete: bool,
}

/// What candidate gains read of a node, packed for the all-pairs loops.
#[derive(Clone, Copy, Debug)]
struct Key {
    center: Vec3,
    radius: f32,
    axis: Vec3,
    cos: f32,
    sin: f32,
    cost: f32,
    xi: u32,
}

impl Key {
    fn of(n: &Node) -> Key {
        let finite = |v: DVec3| if v.is_finite() { v.as_vec3() } else { Vec3::ZERO };
        Key {
            center: n.center.as_vec3(),
            // Rounded up: the estimate must not shrink below the exact f64 bound.
            radius: round_up(n.radius),
            axis: finite(n.axis),
            cos: n.angle.cos() as f32,
            sin: n.angle.sin() as f32,
            cost: n.cost as f32,
            xi: n.edges.len() as u32,
        }
    }
}

/// A finished patch: its quads and exact f64 bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct BuiltPatch {
    pub edges: Vec<u32>,
    pub center: DVec3,
    pub radius: f64,
    pub axis: DVec3,
    pub angle: f64,
}

/// Decomposes the quads of `edges` into patches over `positions` (rest or static geometry).
pub fn build(positions: &[Vec3], edges: &Edges, params: &PatchParams) -> Patches {
    let all: Vec<u32> = (0..edges.quads.len() as u32).collect();
    let size = size_of(positions, edges);
    let (built, always) = fuse(positions, edges, &all, params, size);
    Patches { cost_ratio: params.cost_ratio, ..assemble(edges, built, always, size) }
}

/// Largest side of the box around the quads' vertices (1 when empty or flat).
pub fn size_of(positions: &[Vec3], edges: &Edges) -> f64 {
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    for q in &edges.quads {
        for &v in q {
            lo = lo.min(positions[v as usize].as_dvec3());
            hi = hi.max(positions[v as usize].as_dvec3());
        }
    }
    let s = (hi - lo).max_element();
    if s.is_finite() && s > 0.0 { s } else { 1.0 }
}

/// Fuses the quads `candidates` (one set, split by `params.group`): the patches worth
/// keeping and the quads left to test every time.
pub fn fuse(
    positions: &[Vec3],
    edges: &Edges,
    candidates: &[u32],
    params: &PatchParams,
    size: f64,
) -> (Vec<BuiltPatch>, Vec<u32>) {
    let mut always = Vec::new();
    let mut cullable = Vec::with_capacity(candidates.len());
    let mut geo = Vec::with_capacity(candidates.len());
    for &e in candidates {
        match edge_geometry(positions, edges.quads[e as usize]) {
            Some(g) => {
                cullable.push(e);
                geo.push(g);
            }
            None => always.push(e),
        }
    }
    let mut groups = Vec::new();
    split(&geo, (0..geo.len() as u32).collect(), params.group.max(1), &mut groups);
    let ctx = Ctx { quads: &edges.quads, geo: &geo, ids: &cullable, p: params, d_cam: params.d_cam * size };
    let results: Vec<(Vec<BuiltPatch>, Vec<u32>)> = groups.par_iter().map(|g| ctx.fuse_group(g)).collect();
    let mut built = Vec::new();
    for (b, a) in results {
        built.extend(b);
        always.extend(a);
    }
    (built, always)
}

/// Median splits along the longest axis of the midpoints' box until groups hold ≤ `max`.
fn split(geo: &[EdgeGeometry], mut ids: Vec<u32>, max: usize, out: &mut Vec<Vec<u32>>) {
    if ids.len() <= max {
        if !ids.is_empty() {
            out.push(ids);
        }
        return;
    }
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for &i in &ids {
        lo = lo.min(geo[i as usize].midpoint());
        hi = hi.max(geo[i as usize].midpoint());
    }
    let axis = (hi - lo).max_position();
    let half = ids.len() / 2;
    ids.select_nth_unstable_by(half, |&x, &y| {
        let (a, b) = (geo[x as usize].midpoint()[axis], geo[y as usize].midpoint()[axis]);
        a.total_cmp(&b).then(x.cmp(&y))
    });
    let right = ids.split_off(half);
    split(geo, ids, max, out);
    split(geo, right, max, out);
}

struct Ctx<'a> {
    quads: &'a [[u32; 4]],
    geo: &'a [EdgeGeometry],
    /// Quad identifier of each `geo` entry.
    ids: &'a [u32],
    p: &'a PatchParams,
    d_cam: f64,
}

impl Ctx<'_> {
    fn cost(&self, xi: usize, radius: f64, angle: f64) -> f64 {
        self.p.cost_ratio + acceptance(angle, radius, self.d_cam) * xi as f64
    }

    fn leaf(&self, i: u32) -> Node {
        let g = &self.geo[i as usize];
        let axis = mean_axis(g.n1 + g.n2).unwrap_or(DVec3::NAN);
        let angle = cone_angle(axis, [g.n1, g.n2].into_iter());
        let center = g.midpoint();
        let radius = match self.p.sphere {
            SphereKind::Reduced => 0.0,
            SphereKind::Mean => g.a.distance(g.b) * 0.5,
        };
        let mut verts = Vec::new();
        if self.p.max_vertices.is_some() {
            let q = self.quads[self.ids[i as usize] as usize];
            verts = vec![q[0].min(q[1]), q[0].max(q[1])];
        }
        Node {
            edges: vec![i],
            center,
            radius,
            axis,
            angle,
            cost: self.cost(1, radius, angle),
            verts,
            alive: true,
            generation: 0,
            cache: Vec::new(),
            complete: true,
        }
    }

    /// Estimated cost of merging `a` and `b` (never below the exact one; a lower bound when
    /// that alone shows the fusion does not pay). In f32: it only ranks candidates.
    fn merged_cost(&self, a: &Key, b: &Key) -> f32 {
        let xi = (a.xi + b.xi) as f32;
        let ratio = self.p.cost_ratio as f32;
        // A cone around both cones is at least half the angle between their axes wide: a
        // cheap bound that rejects most candidates.
        let half_sin = ((1.0 - a.axis.dot(b.axis)) * 0.5).max(0.0).sqrt();
        if ratio + half_sin * xi >= a.cost + b.cost {
            return ratio + half_sin * xi;
        }
        // The smallest sphere around both spheres and the smallest cone around both cones:
        // the exact merge ([`Ctx::merge`]) is never wider than these.
        let d = a.center.distance(b.center);
        let radius = if d + b.radius <= a.radius {
            a.radius
        } else if d + a.radius <= b.radius {
            b.radius
        } else {
            (d + a.radius + b.radius) * 0.5
        };
        if a.cos <= 0.0 || b.cos <= 0.0 {
            return ratio + xi;
        }
        // cos/sin of θ (between the axes), θ + α_a, θ + α_b and θ + α_a + α_b, without trigonometry.
        let ct = a.axis.dot(b.axis).clamp(-1.0, 1.0);
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        let add = |(c1, s1): (f32, f32), (c2, s2): (f32, f32)| (c1 * c2 - s1 * s2, s1 * c2 + c1 * s2);
        let (ta, tb) = (add((ct, st), (a.cos, a.sin)), add((ct, st), (b.cos, b.sin)));
        let (ca, sa) = if tb.0 >= a.cos {
            (a.cos, a.sin) // b's cone lies inside a's
        } else if ta.0 >= b.cos {
            (b.cos, b.sin)
        } else {
            let (cx, sx) = add(ta, (b.cos, b.sin));
            if sx < 0.0 {
                return ratio + xi; // θ + α_a + α_b > π: the merged cone passes 90°
            }
            (((1.0 + cx) * 0.5).max(0.0).sqrt(), ((1.0 - cx) * 0.5).max(0.0).sqrt())
        };
        let sb = (radius / self.d_cam as f32).min(1.0);
        let cb = (1.0 - sb * sb).sqrt();
        let h = if ca * cb - sa * sb <= 0.0 { 1.0 } else { sa * cb + ca * sb };
        ratio + h * xi
    }

    /// Estimated gain of merging nodes `i` and `j`; −∞ when a limit forbids it.
    fn gain(&self, nodes: &[Node], keys: &[Key], i: usize, j: usize) -> f32 {
        let (a, b) = (&keys[i], &keys[j]);
        if self.p.max_edges.is_some_and(|m| (a.xi + b.xi) as usize > m)
            || self.p.max_vertices.is_some_and(|m| union_len(&nodes[i].verts, &nodes[j].verts) > m)
        {
            return f32::NEG_INFINITY;
        }
        a.cost + b.cost - self.merged_cost(a, b)
    }

    /// The exact bounds of `a ∪ b`.
    fn merge(&self, a: &Node, b: &Node) -> Node {
        let mut edges = a.edges.clone();
        edges.extend_from_slice(&b.edges);
        let geo: Vec<EdgeGeometry> = edges.iter().map(|&i| self.geo[i as usize]).collect();
        let normals: Vec<DVec3> = geo.iter().flat_map(|g| [g.n1, g.n2]).collect();
        // Cone: the narrower of the mean axis / smallest cap ([`reference_axis`]) and the axis
        // of the smallest cone around both parents' cones.
        let (ref_axis, _) = reference_axis(&normals);
        let (axis, angle) = [ref_axis, enclosing_axis(a, b)]
            .into_iter()
            .map(|x| (x, cone_angle(x, normals.iter().copied())))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .unwrap_or((DVec3::NAN, PI));
        let (center, radius) = match self.p.sphere {
            SphereKind::Reduced => {
                // The paper's center (mean midpoint) or the one between the parents' centers
                // that balances their radii, whichever needs the smaller radius.
                let (c1, r1) = reduced_sphere(&geo);
                let d = a.center.distance(b.center);
                let t = if d > 0.0 { ((d + b.radius - a.radius) / (2.0 * d)).clamp(0.0, 1.0) } else { 0.0 };
                let c2 = a.center.lerp(b.center, t);
                let r2 = geo.iter().map(|g| line_distance(c2, g.a, g.b)).fold(0.0, f64::max);
                if r2 < r1 { (c2, r2) } else { (c1, r1) }
            }
            SphereKind::Mean => mean_sphere(&mut geo.iter().flat_map(|g| [g.a, g.b]).collect()),
        };
        let mut verts = Vec::new();
        if self.p.max_vertices.is_some() {
            verts = a.verts.iter().chain(&b.verts).copied().collect();
            verts.sort_unstable();
            verts.dedup();
        }
        Node {
            cost: self.cost(edges.len(), radius, angle),
            edges,
            center,
            radius,
            axis,
            angle,
            verts,
            alive: true,
            generation: 0,
            cache: Vec::new(),
            complete: true,
        }
    }

    fn build_cache(&self, nodes: &mut [Node], keys: &[Key], alive: &[u32], i: usize) {
        let mut cache = Vec::new();
        let mut complete = true;
        for &j in alive {
            if j as usize != i {
                let gain = self.gain(nodes, keys, i, j as usize);
                if gain > 0.0 {
                    let f = Fusion { partner: j, generation: nodes[j as usize].generation, gain };
                    complete &= insert(&mut cache, f, self.p.cache, true);
                }
            }
        }
        nodes[i].cache = cache;
        nodes[i].complete = complete;
    }

    /// Algorithm 1. Cache entries of merged patches are dropped lazily: an entry whose
    /// partner died or changed (generation) is removed when it reaches the head.
    fn fuse_group(&self, group: &[u32]) -> (Vec<BuiltPatch>, Vec<u32>) {
        let mut nodes: Vec<Node> = group.iter().map(|&i| self.leaf(i)).collect();
        let mut keys: Vec<Key> = nodes.iter().map(Key::of).collect();
        let mut alive: Vec<u32> = (0..nodes.len() as u32).collect();
        for i in 0..nodes.len() {
            self.build_cache(&mut nodes, &keys, &alive, i);
        }
        loop {
            let mut best: Option<(usize, usize, f32)> = None;
            for k in 0..alive.len() {
                let i = alive[k] as usize;
                while let Some(f) = nodes[i].cache.first().copied() {
                    let p = &nodes[f.partner as usize];
                    if p.alive && p.generation == f.generation {
                        break;
                    }
                    nodes[i].cache.remove(0);
                }
                if nodes[i].cache.is_empty() && !nodes[i].complete {
                    self.build_cache(&mut nodes, &keys, &alive, i);
                }
                if let Some(f) = nodes[i].cache.first()
                    && best.is_none_or(|b| f.gain > b.2)
                {
                    best = Some((i, f.partner as usize, f.gain));
                }
            }
            let Some((a, b, _)) = best else { break };
            let mut merged = self.merge(&nodes[a], &nodes[b]);
            merged.generation = nodes[a].generation + 1;
            keys[a] = Key::of(&merged);
            nodes[a] = merged;
            nodes[b].alive = false;
            nodes[b].edges = Vec::new();
            nodes[b].cache = Vec::new();
            alive.retain(|&x| x as usize != b);
            for &m in &alive {
                let m = m as usize;
                if m == a {
                    continue;
                }
                let gain = self.gain(&nodes, &keys, m, a);
                if gain > 0.0 {
                    let f = Fusion { partner: a as u32, generation: nodes[a].generation, gain };
                    let node = &mut nodes[m];
                    node.complete &= insert(&mut node.cache, f, self.p.cache, node.complete);
                }
            }
            self.build_cache(&mut nodes, &keys, &alive, a);
        }
        let mut built = Vec::new();
        let mut always = Vec::new();
        for n in nodes.into_iter().filter(|n| n.alive) {
            let ids = n.edges.iter().map(|&i| self.ids[i as usize]);
            // Keep a patch only if culling it beats testing its edges (ξ·t_e > E).
            if (n.edges.len() as f64) > n.cost && n.angle.is_finite() {
                built.push(BuiltPatch {
                    edges: ids.collect(),
                    center: n.center,
                    radius: n.radius,
                    axis: n.axis,
                    angle: n.angle,
                });
            } else {
                always.extend(ids);
            }
        }
        (built, always)
    }
}

/// Axis of the smallest cone around the cones of `a` and `b` (on the arc between their axes).
fn enclosing_axis(a: &Node, b: &Node) -> DVec3 {
    let theta = a.axis.dot(b.axis).clamp(-1.0, 1.0).acos();
    if !theta.is_finite() || theta < 1e-9 || theta + b.angle <= a.angle {
        return a.axis;
    }
    if theta + a.angle <= b.angle {
        return b.axis;
    }
    // Rotate a's axis toward b's by φ so that φ + α_a = θ − φ + α_b.
    let phi = ((theta + b.angle - a.angle) * 0.5).clamp(0.0, theta);
    ((a.axis * (theta - phi).sin() + b.axis * phi.sin()) / theta.sin()).normalize()
}

/// A cached fusion with `partner` as it was at `generation`.
#[derive(Clone, Copy, Debug)]
struct Fusion {
    partner: u32,
    generation: u32,
    gain: f32,
}

/// Inserts `item` into the cache sorted by gain (ties: lower partner first), keeping at most
/// `k`. An incomplete cache only takes items at least as good as its worst. Returns `false`
/// when a positive fusion was left out.
fn insert(cache: &mut Vec<Fusion>, item: Fusion, k: usize, complete: bool) -> bool {
    let before = |x: &Fusion| x.gain > item.gain || (x.gain == item.gain && x.partner < item.partner);
    if !complete && cache.last().is_none_or(before) {
        return false;
    }
    let pos = cache.partition_point(before);
    if pos >= k {
        return false;
    }
    cache.insert(pos, item);
    if cache.len() > k {
        cache.pop();
        return false;
    }
    true
}

fn union_len(a: &[u32], b: &[u32]) -> usize {
    let (mut i, mut j, mut n) = (0, 0, 0);
    while i < a.len() && j < b.len() {
        n += 1;
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    n + (a.len() - i) + (b.len() - j)
}

/// Lays built patches out for extraction.
pub fn assemble(edges: &Edges, built: Vec<BuiltPatch>, always: Vec<u32>, size: f64) -> Patches {
    let mut p = Patches { size, ..Patches::default() };
    let n = built.len().max(1) as f64;
    p.mean_radius = built.iter().map(|b| b.radius).sum::<f64>() / n / size;
    p.mean_angle_deg = built.iter().map(|b| b.angle.to_degrees()).sum::<f64>() / n;
    for b in built {
        p.ranges.push([p.order.len() as u32, b.edges.len() as u32]);
        p.bounds.push(PatchBounds::new(b.center, b.radius, b.axis, b.angle));
        p.order.extend_from_slice(&b.edges);
    }
    p.always_from = p.order.len();
    p.order.extend(always);
    p.quads = p.order.iter().map(|&i| edges.quads[i as usize]).collect();
    p
}

/// Exact bounds of arbitrary quads (for baselines and checks): Reduced Sphere and mean cone.
pub fn bounds_of(positions: &[Vec3], edges: &Edges, quads: &[u32]) -> Option<BuiltPatch> {
    let geo: Option<Vec<EdgeGeometry>> =
        quads.iter().map(|&q| edge_geometry(positions, edges.quads[q as usize])).collect();
    let geo = geo?;
    let axis = mean_axis(geo.iter().map(|g| g.n1 + g.n2).sum())?;
    Some(patch_around(quads.to_vec(), &geo, axis))
}

/// The patch of `quads` (geometry `geo`) with its cone around `axis`: Reduced Sphere, and
/// the angle of the widest face normal.
pub(crate) fn patch_around(quads: Vec<u32>, geo: &[EdgeGeometry], axis: DVec3) -> BuiltPatch {
    let (center, radius) = reduced_sphere(geo);
    BuiltPatch { edges: quads, center, radius, axis, angle: cone_angle(axis, geo.iter().flat_map(|g| [g.n1, g.n2])) }
}
