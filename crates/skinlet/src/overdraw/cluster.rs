//! Index buffers for animated meshes by clustering (keyframe, viewpoint) nodes (Han & Sander
//! 2016, section 3.2), and the run-time lookup that picks one (section 3.3).
//!
//! The triangles are first cut into patches, each in vertex-cache order: the paper's linear
//! clustering of the Tipsify order ([`super::tipsify`], λ) or, beyond the paper and the
//! default, compact patches ([`super::compact`]). Bootstrapping: `k` random nodes, each with its patches sorted front to back (patch
//! centroid distance to the node's eye). Then k-means: (1) every node goes to the buffer that
//! renders it with the least overdraw ([`super::measure::Raster`]); (2) every cluster's
//! buffer becomes its patches sorted by their distance to the eye, averaged over the
//! cluster's nodes in which the patch has a front-facing triangle (patches never seen keep
//! their order, at the end). Stops when no node changes cluster or after `iterations`.
//!
//! Beyond the paper ([`PatchOrder::Occlusion`], the default): step 2 also orders the patches
//! by the occlusion measured between them on the cluster's nodes ([`super::occlusion`]) and
//! keeps that order, the distance order or the cluster's current buffer, whichever shades the
//! fewest fragments over those nodes.
//!
//! Guarantees: every buffer is a permutation of the input triangles with windings kept
//! (patches are moved whole); the output is deterministic for a seed (nodes are rendered in
//! parallel, but each result lands in its own slot).

use super::compact::compact_patches;
use super::measure::{Fragments, Raster};
use super::occlusion::Occlusion;
use super::tipsify::{patches as linear_patches, tipsify};
use super::viewpoints::icosphere;
use glam::Vec3;
use rayon::prelude::*;
pub use skinlet_runtime::overdraw_orders::{Framing, Lookup, Orders, Patches, direction};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClusterParams {
    /// Index buffers to make.
    pub k: usize,
    /// How the triangles are cut into the patches the orders move whole: compact (ours,
    /// size 32) or the paper's linear clustering at λ (0.85 in the paper; 3 ignores the cache).
    pub patches: Patches,
    pub cache_size: u32,
    /// Raster resolution used to measure overdraw while clustering.
    pub resolution: u32,
    /// Icosahedron subdivisions for the viewpoints (2: the paper's 162).
    pub view_levels: u32,
    pub iterations: usize,
    pub seed: u64,
    /// Most bytes of node fragments kept between k-means iterations (beyond: rasterized
    /// again in every iteration; same result, slower).
    pub cache_bytes: usize,
    /// How each cluster orders its patches (step 2).
    pub order: PatchOrder,
}

/// How a cluster's patches are ordered in k-means step 2.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PatchOrder {
    /// The paper's: by centroid distance to the eye, averaged over the nodes that see them.
    Distance,
    /// Ours: by measured occlusion between patches over the cluster's nodes
    /// ([`super::occlusion`]), ties by distance; the distance order or the current buffer is
    /// kept instead where it shades fewer fragments on those nodes.
    #[default]
    Occlusion,
}

impl Default for ClusterParams {
    fn default() -> Self {
        ClusterParams {
            k: 5,
            patches: Patches::default(),
            cache_size: 16,
            resolution: 64,
            view_levels: 2,
            iterations: 4,
            seed: 1,
            cache_bytes: 1 << 30,
            order: PatchOrder::default(),
        }
    }
}

/// The result of clustering.
#[derive(Clone, Debug, PartialEq)]
pub struct Clustering {
    /// The `k` index buffers (fewer when there were fewer nodes).
    pub buffers: Vec<Vec<[u32; 3]>>,
    /// The patch rule the buffers were cut with (compact patches may have grown).
    pub patches: Patches,
    /// Viewpoint directions (unit) used as nodes.
    pub views: Vec<Vec3>,
    /// Buffer of each node, node = keyframe × views + view.
    pub assignment: Vec<u8>,
    /// Overdraw ratio of each node with its buffer, at the clustering resolution.
    pub node_overdraw: Vec<f32>,
    pub framing: Framing,
    /// k-means iterations run.
    pub iterations: usize,
}

struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 33) % n.max(1) as u64) as usize
    }
}

/// The triangles patch after patch, the start of each patch and the patch rule used (compact
/// patches may grow, [`super::compact::compact_patches`]): `patches` over `positions` (e.g.
/// the first keyframe; compact patches are built on it).
pub fn cut(
    triangles: &[[u32; 3]],
    positions: &[Vec3],
    patches: Patches,
    cache_size: u32,
) -> (Vec<[u32; 3]>, Vec<u32>, Patches) {
    match patches {
        Patches::Linear { lambda } => {
            let order = tipsify(triangles, positions.len(), cache_size);
            let starts = linear_patches(&order, positions.len(), cache_size, lambda);
            (order, starts, patches)
        }
        Patches::Compact { size } => {
            let (order, starts, size) = compact_patches(triangles, positions, size, cache_size);
            (order, starts, Patches::Compact { size })
        }
    }
}

/// Clusters the nodes of `keyframes` (skinned positions per keyframe, all the same length)
/// and returns `k` index buffers with the assignment.
pub fn cluster(keyframes: &[Vec<Vec3>], triangles: &[[u32; 3]], params: &ClusterParams) -> Clustering {
    let (order, starts, rule) =
        cut(triangles, keyframes.first().map_or(&[][..], |k| k), params.patches, params.cache_size);
    let patches = starts.len();
    let patch = |p: usize| &order[starts[p] as usize..starts.get(p + 1).map_or(order.len(), |&e| e as usize)];
    let framing = Framing::of(keyframes);
    let views = icosphere(params.view_levels);
    let nodes = keyframes.len() * views.len();
    // Per keyframe: patch centroids.
    let centroids: Vec<Vec<Vec3>> = keyframes
        .iter()
        .map(|pos| {
            (0..patches)
                .map(|p| {
                    let tris = patch(p);
                    tris.iter()
                        .map(|t| (pos[t[0] as usize] + pos[t[1] as usize] + pos[t[2] as usize]) / 3.0)
                        .sum::<Vec3>()
                        / tris.len().max(1) as f32
                })
                .collect()
        })
        .collect();
    let node = |n: usize| (n / views.len(), framing.eye(views[n % views.len()], 3.0));
    // Buffers are patch orders while clustering. Patches sorted by a key (None: never seen,
    // last), ties in patch order.
    let by_key = |key: &dyn Fn(usize) -> Option<f32>| -> Vec<u32> {
        let mut keyed: Vec<(f32, u32)> = (0..patches).map(|p| (key(p).unwrap_or(f32::INFINITY), p as u32)).collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        keyed.into_iter().map(|(_, p)| p).collect()
    };
    // Bootstrap: k distinct random nodes, patches front to back from each.
    let mut rng = Rng(params.seed ^ 0x00DD_BA11);
    let mut seeds: Vec<usize> = Vec::new();
    while seeds.len() < params.k.min(nodes) {
        let n = rng.below(nodes);
        if !seeds.contains(&n) {
            seeds.push(n);
        }
    }
    let mut buffers: Vec<Vec<u32>> = seeds
        .iter()
        .map(|&n| {
            let (f, eye) = node(n);
            by_key(&|p| Some(centroids[f][p].distance(eye)))
        })
        .collect();
    // Each node's fragments by patch, rasterized once (orders change, the geometry does not)
    // while they fit in `cache_bytes`; beyond it (many keyframes of a large mesh) they are
    // rasterized again in every iteration instead. And what does not depend on the order:
    // the patches each node sees, its covered pixels and its occlusion weights.
    let rasterize = |raster: &mut Raster, n: usize, frags: &mut Fragments| {
        let (f, eye) = node(n);
        raster.fragments(&keyframes[f], &order, &starts, &framing.view_proj(eye), frags);
    };
    let new_raster = || Raster::new(params.resolution, params.resolution);
    let sample: usize = (0..nodes.min(16))
        .map(|i| {
            let mut frags = Fragments::default();
            rasterize(&mut new_raster(), i * nodes / nodes.clamp(1, 16), &mut frags);
            frags.bytes()
        })
        .sum();
    let cache = sample / nodes.clamp(1, 16) * nodes <= params.cache_bytes;
    struct Node {
        fragments: Option<Fragments>,
        visible: Vec<bool>,
        covered: u64,
        occlusion: Vec<(u64, u32)>,
    }
    let rendered: Vec<Node> = (0..nodes)
        .into_par_iter()
        .map_init(
            || (new_raster(), Vec::new()),
            |(raster, scratch), n| {
                let mut frags = Fragments::default();
                rasterize(raster, n, &mut frags);
                let visible = (0..patches).map(|p| frags.seen(p)).collect();
                let occlusion = match params.order {
                    PatchOrder::Occlusion => Occlusion::of_view(&frags, scratch),
                    PatchOrder::Distance => Vec::new(),
                };
                Node { covered: frags.covered, fragments: cache.then_some(frags), visible, occlusion }
            },
        )
        .collect();
    // Calls `f` with the fragments of each node in `of`.
    let with_frags = |of: &mut dyn Iterator<Item = usize>, f: &mut dyn FnMut(usize, &Fragments)| {
        let (mut raster, mut scratch) = (None, Fragments::default());
        for n in of {
            match &rendered[n].fragments {
                Some(frags) => f(n, frags),
                None => {
                    rasterize(raster.get_or_insert_with(new_raster), n, &mut scratch);
                    f(n, &scratch);
                }
            }
        }
    };
    // A cluster's order from its nodes: patches by distance averaged over the nodes that see
    // them; beyond the paper ([`PatchOrder::Occlusion`]) the occlusion order, the distance
    // order or the `current` one, whichever shades the fewest fragments over the nodes (so
    // no iteration makes a cluster worse for its nodes).
    let order_for = |members: &[usize], current: &Vec<u32>| -> Vec<u32> {
        let mut sum = vec![0.0f64; patches];
        let mut seen = vec![0u32; patches];
        for &n in members {
            let (f, eye) = node(n);
            for p in (0..patches).filter(|&p| rendered[n].visible[p]) {
                sum[p] += centroids[f][p].distance(eye) as f64;
                seen[p] += 1;
            }
        }
        let key: Vec<Option<f32>> =
            (0..patches).map(|p| (seen[p] > 0).then(|| (sum[p] / seen[p] as f64) as f32)).collect();
        let distance = by_key(&|p| key[p]);
        if params.order == PatchOrder::Distance {
            return distance;
        }
        let mut occlusion = Occlusion::default();
        for &n in members {
            occlusion.add(&rendered[n].occlusion);
        }
        let candidates = [occlusion.order(&key), distance, current.clone()];
        let mut shaded = [0u64; 3];
        let mut scratch = Vec::new();
        with_frags(&mut members.iter().copied(), &mut |_, frags| {
            for (s, c) in shaded.iter_mut().zip(&candidates) {
                *s = s.saturating_add(frags.shade(c.iter().copied(), u64::MAX, &mut scratch).unwrap_or(u64::MAX));
            }
        });
        let best = (0..3).min_by_key(|&i| shaded[i]).unwrap_or(0);
        candidates.into_iter().nth(best).unwrap_or_default()
    };
    let mut assignment = vec![u8::MAX; nodes];
    let mut node_overdraw = vec![0.0f32; nodes];
    let mut iterations = 0;
    while iterations < params.iterations && !buffers.is_empty() {
        iterations += 1;
        // Step 1: each node to the buffer with the least overdraw: a depth-tested pass over
        // the node's fragments per buffer, abandoned as soon as it shades more than the best
        // so far (coverage is the same for every order).
        let mut best = vec![(0u8, 0.0f32); nodes];
        best.par_chunks_mut(64).enumerate().for_each(|(chunk, out)| {
            let mut depth = Vec::new();
            with_frags(&mut (chunk * 64..chunk * 64 + out.len()), &mut |n, frags| {
                let mut pick = (0u8, u64::MAX);
                for (b, buf) in buffers.iter().enumerate() {
                    if let Some(shaded) = frags.shade(buf.iter().copied(), pick.1.saturating_sub(1), &mut depth) {
                        pick = (b as u8, shaded);
                    }
                }
                let covered = rendered[n].covered;
                out[n - chunk * 64] = (pick.0, if covered == 0 { 0.0 } else { pick.1 as f32 / covered as f32 });
            });
        });
        let changed = best.iter().zip(&assignment).any(|(b, &a)| b.0 != a);
        for (n, (b, r)) in best.into_iter().enumerate() {
            assignment[n] = b;
            node_overdraw[n] = r;
        }
        if !changed {
            break;
        }
        // Step 2: each cluster's order from its nodes.
        buffers = (0..buffers.len())
            .into_par_iter()
            .map(|b| {
                let members: Vec<usize> = (0..nodes).filter(|&n| assignment[n] as usize == b).collect();
                if members.is_empty() { buffers[b].clone() } else { order_for(&members, &buffers[b]) }
            })
            .collect();
    }
    let buffers = buffers.iter().map(|b| b.iter().flat_map(|&p| patch(p as usize)).copied().collect()).collect();
    Clustering { buffers, patches: rule, views, assignment, node_overdraw, framing, iterations }
}

/// The run-time table of a clustering ([`Lookup`]) with `polar` × `azimuth` cells per keyframe.
pub fn lookup(c: &Clustering, polar: usize, azimuth: usize) -> Lookup {
    let keyframes = c.assignment.len() / c.views.len().max(1);
    let mut table = Vec::with_capacity(keyframes * polar * azimuth);
    for f in 0..keyframes {
        for i in 0..polar {
            for j in 0..azimuth {
                let d = direction(
                    i as f32 * std::f32::consts::PI / (polar - 1).max(1) as f32,
                    j as f32 * std::f32::consts::TAU / azimuth as f32,
                );
                let nearest =
                    (0..c.views.len()).max_by(|&a, &b| c.views[a].dot(d).total_cmp(&c.views[b].dot(d))).unwrap_or(0);
                table.push(c.assignment[f * c.views.len() + nearest]);
            }
        }
    }
    Lookup { keyframes, polar, azimuth, table }
}

/// What a bake stores of a clustering for run-time selection ([`Orders`]): its buffers,
/// `keyframes` (clip index and time per keyframe), the patch rule, the framing and the lookup table.
pub fn orders(c: &Clustering, keyframes: Vec<(u32, f32)>) -> Orders {
    let lookup = lookup(c, Orders::CELLS.0, Orders::CELLS.1);
    Orders { patches: c.patches, keyframes, framing: c.framing, buffers: c.buffers.clone(), lookup }
}
