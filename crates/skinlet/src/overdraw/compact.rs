//! Compact patches for overdraw orders (ours; Han & Sander 2016 and Sander et al. 2007 cut
//! the Tipsify order into linear patches instead, [`super::tipsify::patches`]).
//!
//! An overdraw order moves patches whole, so their shape bounds what any order can do. Fast
//! linear clustering cuts Tipsify's sweep where the cache runs cold: its patches are strips
//! that can wrap around a limb, so one part of a patch hides another whatever the order.
//! Here the patches are meshoptimizer meshlets of at most `size` vertices and triangles with
//! cone weight 0.5 (small, round, facing one way), each in Tipsify order. At size 32 their
//! ACMR (16-entry FIFO) equals λ = 0.85's on the shared characters, and orders built from
//! them remove more overdraw (`docs/OVERDRAW.md`).
//!
//! Guarantee: the patches hold every input triangle exactly once, windings kept (a triangle
//! the meshlet builder leaves out, such as a degenerate one, goes into a last patch).

use super::measure::FifoCache;
use super::tipsify::tipsify;
use crate::meshlet::MeshletLimits;
use crate::meshlet::greedy::{Method, build_with};
use glam::Vec3;
use skinlet_runtime::overdraw_orders::canonical;

/// The cone weight of the meshlet builder: patches that face one way hide less of themselves.
const CONE_WEIGHT: f32 = 0.5;

/// Patches whose ACMR is above this with the cache emptied at every patch grow (by a quarter,
/// up to 256; smaller patches leave orders more freedom): 32-triangle patches cost 0.92 on
/// RiggedSimple's cylinder, whose vertex-cache order alone costs 0.60.
pub const MAX_ACMR: f32 = 0.9;

/// Cuts `triangles` (over `positions`, e.g. the first keyframe) into compact patches of at
/// most `size` vertices and triangles (clamped to 4..=256, meshoptimizer's range), each in
/// Tipsify order for a FIFO cache of `cache_size`; the size grows by a quarter while the
/// patches' ACMR (cache emptied at every patch) is above [`MAX_ACMR`] (up to 256). Returns the triangles patch after patch, the start of
/// every patch in that list, as [`super::tipsify::patches`] does, and the size used.
pub fn compact_patches(
    triangles: &[[u32; 3]],
    positions: &[Vec3],
    size: u32,
    cache_size: u32,
) -> (Vec<[u32; 3]>, Vec<u32>, u32) {
    let mut size = size.clamp(4, 256);
    loop {
        let (order, starts) = cut(triangles, positions, size, cache_size);
        if size >= 256 || cold_acmr(&order, &starts, positions.len(), cache_size) <= MAX_ACMR {
            return (order, starts, size);
        }
        size = (size + size.div_ceil(4)).min(256);
    }
}

/// ACMR with the cache emptied at every patch start: what the patches cost in any order
/// (a cache still warm from the previous patch rarely adds misses).
fn cold_acmr(order: &[[u32; 3]], starts: &[u32], vertex_count: usize, cache_size: u32) -> f32 {
    let mut cache = FifoCache::new(vertex_count, cache_size);
    let mut next = starts.iter().peekable();
    let mut misses = 0usize;
    for (i, t) in order.iter().enumerate() {
        if next.peek().is_some_and(|&&s| s as usize == i) {
            next.next();
            cache.flush();
        }
        misses += t.iter().filter(|&&v| cache.miss(v)).count();
    }
    misses as f32 / order.len().max(1) as f32
}

fn cut(triangles: &[[u32; 3]], positions: &[Vec3], size: u32, cache_size: u32) -> (Vec<[u32; 3]>, Vec<u32>) {
    let size = size as usize;
    let meshlets = build_with(
        triangles,
        positions,
        MeshletLimits { max_vertices: size, max_triangles: size },
        Method::Greedy { cone_weight: CONE_WEIGHT },
    );
    let (mut order, mut starts) = (Vec::with_capacity(triangles.len()), Vec::with_capacity(meshlets.len() + 1));
    for m in &meshlets.meshlets {
        let tris: Vec<[u32; 3]> = meshlets.mesh_triangles(m).collect();
        starts.push(order.len() as u32);
        order.extend(tipsify(&tris, positions.len(), cache_size));
    }
    // Whatever the builder left out, as one last patch.
    let (mut want, mut got): (Vec<_>, Vec<_>) =
        (triangles.iter().map(|&t| canonical(t)).collect(), order.iter().map(|&t| canonical(t)).collect());
    want.sort_unstable();
    got.sort_unstable();
    let mut missing = Vec::new();
    let mut g = got.iter().peekable();
    for t in want {
        if g.peek() == Some(&&t) {
            g.next();
        } else {
            missing.push(t);
        }
    }
    if !missing.is_empty() {
        starts.push(order.len() as u32);
        order.extend(missing);
    }
    (order, starts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::overdraw::measure::acmr;

    #[test]
    fn patches_hold_every_triangle_once_and_are_small() {
        // A 40 × 40 grid with one degenerate triangle.
        let n = 41u32;
        let positions: Vec<Vec3> = (0..n * n).map(|i| Vec3::new((i % n) as f32, (i / n) as f32, 0.0)).collect();
        let mut triangles: Vec<[u32; 3]> = (0..n - 1)
            .flat_map(|y| {
                (0..n - 1).flat_map(move |x| {
                    let v = y * n + x;
                    [[v, v + 1, v + n], [v + 1, v + n + 1, v + n]]
                })
            })
            .collect();
        triangles.push([5, 5, 6]);
        let (order, starts, size) = compact_patches(&triangles, &positions, 32, 16);
        assert_eq!(size, 32, "a grid's 32-triangle patches need not grow");
        let mut a: Vec<_> = triangles.iter().map(|&t| canonical(t)).collect();
        let mut b: Vec<_> = order.iter().map(|&t| canonical(t)).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "a permutation with windings kept");
        assert_eq!(starts[0], 0);
        assert!(starts.windows(2).all(|w| w[0] < w[1]));
        let ends: Vec<usize> = starts.iter().skip(1).map(|&s| s as usize).chain([order.len()]).collect();
        for (&s, &e) in starts.iter().zip(&ends) {
            let verts: std::collections::HashSet<u32> = order[s as usize..e].iter().flatten().copied().collect();
            assert!(
                e - s as usize <= 32 && verts.len() <= 32,
                "patch of {} triangles, {} vertices",
                e - s as usize,
                verts.len()
            );
        }
        assert!(acmr(&order, positions.len(), 16) < 0.9);
    }

    #[test]
    fn patches_grow_while_their_acmr_is_high() {
        // A cylinder of 6 segments and 60 rings (the vertex-cache floor, vertices per
        // triangle, is about 0.5) and a strip of 200 quads (floor about 1: no size helps).
        let ring = 6u32;
        let positions: Vec<Vec3> = (0..61 * ring)
            .map(|i| {
                let a = (i % ring) as f32 / ring as f32 * std::f32::consts::TAU;
                Vec3::new(a.cos(), a.sin(), (i / ring) as f32 * 0.3)
            })
            .collect();
        let cylinder: Vec<[u32; 3]> = (0..60)
            .flat_map(|r| {
                (0..ring).flat_map(move |j| {
                    let (a, b) = (r * ring + j, r * ring + (j + 1) % ring);
                    [[a, b, a + ring], [b, b + ring, a + ring]]
                })
            })
            .collect();
        let (order, _, _) = compact_patches(&cylinder, &positions, 4, 16);
        assert!(acmr(&order, positions.len(), 16) <= MAX_ACMR);
        let strip_pos: Vec<Vec3> = (0..402).map(|i| Vec3::new((i / 2) as f32, (i % 2) as f32, 0.0)).collect();
        let strip: Vec<[u32; 3]> =
            (0..200u32).flat_map(|q| [[2 * q, 2 * q + 2, 2 * q + 1], [2 * q + 1, 2 * q + 2, 2 * q + 3]]).collect();
        let (order, _, size) = compact_patches(&strip, &strip_pos, 32, 16);
        assert_eq!(size, 256, "grows to the cap");
        assert!(acmr(&order, strip_pos.len(), 16) > MAX_ACMR);
    }
}
