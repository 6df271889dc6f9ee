//! Patch orders from measured occlusion: our replacement for Han & Sander 2016's per-cluster
//! sort by mean view distance (section 3.2, step 2).
//!
//! The paper sorts a cluster's patches by the distance of their centroids to the eye,
//! averaged over the cluster's nodes. A centroid says little about a large or curved patch,
//! so instead we count, over the cluster's nodes, how often the nearest fragment of a pixel
//! is patch `a`'s while patch `b` has a fragment behind it (`w(a, b)`, from the fragments
//! each node already rasterized for measuring). A pixel is shaded once when its nearest
//! patch comes first, so a good order is one that violates little weight: the weighted
//! linear ordering problem. (Counting every pair of a pixel's fragments instead also weighs
//! the order among hidden layers, which shades nothing once the nearest is drawn: measured,
//! it removes less overdraw.) We solve it greedily (Eades, Lin & Smyth 1993, weighted): repeatedly
//! place the patch with the largest (weight in front of remaining patches − weight behind
//! them), ties by the paper's mean distance. Patches no node sees go last in their old order.
//!
//! Guarantee: the result is a permutation of the patches (so buffers stay permutations of
//! the triangles with windings kept); it is deterministic.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Occlusion weights between patches, accumulated over nodes.
#[derive(Clone, Debug, Default)]
pub struct Occlusion {
    /// `(front << 32) | back` per occluding fragment pair.
    pairs: Vec<u64>,
}

impl Occlusion {
    pub fn add(&mut self, front: u32, back: u32) {
        self.pairs.push((front as u64) << 32 | back as u64);
    }

    /// A patch order (`patches` patches). `key[p]`: the tie-break, smaller first (`None`:
    /// never seen, placed last in patch order).
    pub fn order(mut self, key: &[Option<f32>]) -> Vec<u32> {
        let n = key.len();
        self.pairs.sort_unstable();
        // Weighted edges front → back, both ways.
        let mut succ: Vec<Vec<(u32, i64)>> = vec![Vec::new(); n];
        let mut pred: Vec<Vec<(u32, i64)>> = vec![Vec::new(); n];
        let mut delta = vec![0i64; n];
        for run in self.pairs.chunk_by(|a, b| a == b) {
            let (a, b, w) = ((run[0] >> 32) as usize, (run[0] & 0xFFFF_FFFF) as usize, run.len() as i64);
            if a < n && b < n {
                succ[a].push((b as u32, w));
                pred[b].push((a as u32, w));
                delta[a] += w;
                delta[b] -= w;
            }
        }
        let tie = |p: usize| key[p].unwrap_or(f32::INFINITY);
        let mut heap: BinaryHeap<Entry> = (0..n)
            .filter(|&p| key[p].is_some())
            .map(|p| Entry { delta: delta[p], tie: tie(p), patch: p as u32 })
            .collect();
        let mut placed = vec![false; n];
        let mut out = Vec::with_capacity(n);
        while let Some(e) = heap.pop() {
            let p = e.patch as usize;
            if placed[p] || e.delta != delta[p] {
                continue;
            }
            placed[p] = true;
            out.push(p as u32);
            // p leaves: patches behind it lose weight behind (their delta rises), patches in
            // front of it lose weight in front (their delta falls).
            for &(q, w) in &succ[p] {
                if !placed[q as usize] {
                    delta[q as usize] += w;
                    heap.push(Entry { delta: delta[q as usize], tie: tie(q as usize), patch: q });
                }
            }
            for &(q, w) in &pred[p] {
                if !placed[q as usize] {
                    delta[q as usize] -= w;
                    heap.push(Entry { delta: delta[q as usize], tie: tie(q as usize), patch: q });
                }
            }
        }
        out.extend((0..n as u32).filter(|&p| !placed[p as usize]));
        out
    }
}

/// A heap entry: largest delta first, then smallest tie key, then smallest patch.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    delta: i64,
    tie: f32,
    patch: u32,
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        self.delta.cmp(&o.delta).then(o.tie.total_cmp(&self.tie)).then(o.patch.cmp(&self.patch))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_follows_occlusion_and_is_a_permutation() {
        // 0 occludes 1 a lot, 1 occludes 2, 2 occludes 0 a little (a cycle): 0, 1, 2.
        let mut o = Occlusion::default();
        for _ in 0..10 {
            o.add(0, 1);
        }
        for _ in 0..5 {
            o.add(1, 2);
        }
        o.add(2, 0);
        // Patch 3 is never occluded nor occluding: placed by its key; patch 4 never seen.
        let key = [Some(5.0), Some(1.0), Some(0.5), Some(0.1), None];
        let order = o.order(&key);
        let pos = |p: u32| order.iter().position(|&x| x == p).unwrap();
        assert!(pos(0) < pos(1) && pos(1) < pos(2), "{order:?}");
        assert_eq!(pos(4), 4, "unseen patches last");
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, vec![0, 1, 2, 3, 4]);
    }
}
