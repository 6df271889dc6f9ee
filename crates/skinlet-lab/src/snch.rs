//! Baseline: the Spatialized Normal Cone Hierarchy (Johnson & Cohen 2001, as Tsiapkolis &
//! Bénard 2024 section 4 compare against it): a binary bounding-volume hierarchy over the
//! edges, built from their positions only (median split of the longest axis of the edge
//! midpoints' box, leaves of at most [`LEAF`] edges); each node bounds its edges' vertices
//! with a Mean Sphere and their faces' normals with a mean-axis cone. Extraction walks the
//! tree, skipping a subtree whose node fails the cone test (eq. 1).
//!
//! Layout: nodes in depth-first order with an escape index, so traversal needs no stack.
//! Guarantee (see [`super`]): the same edge set as brute force.

use glam::{DVec3, Vec3};
use skinlet::contour::bound::{EdgeGeometry, PatchBounds, cone_angle, edge_geometry, mean_axis, mean_sphere, viewers};
use skinlet::contour::patches::test_quads;
use skinlet::contour::{Edges, Projection, Tested, extract_uncullable};

/// Most edges in a leaf.
pub const LEAF: usize = 4;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Snch {
    pub bounds: Vec<PatchBounds>,
    /// Per node: the index of the next node after its subtree.
    pub skip: Vec<u32>,
    /// Per node: range of its edges in `order` when it is a leaf (count 0 otherwise).
    pub leaves: Vec<[u32; 2]>,
    pub order: Vec<u32>,
    pub quads: Vec<[u32; 4]>,
    /// Quads too thin to bound, tested every time (from here in `order`).
    pub always_from: usize,
}

impl Snch {
    pub fn build(positions: &[Vec3], edges: &Edges) -> Snch {
        let mut items = Vec::new();
        let mut geo = Vec::new();
        let mut always = Vec::new();
        for (i, q) in edges.quads.iter().enumerate() {
            match edge_geometry(positions, *q) {
                Some(g) => {
                    items.push(i as u32);
                    geo.push(g);
                }
                None => always.push(i as u32),
            }
        }
        let mut t = Snch::default();
        let mut idx: Vec<u32> = (0..geo.len() as u32).collect();
        if !idx.is_empty() {
            t.node(&geo, &items, &mut idx);
        }
        t.always_from = t.order.len();
        t.order.extend(always);
        t.quads = t.order.iter().map(|&i| edges.quads[i as usize]).collect();
        t
    }

    fn node(&mut self, geo: &[EdgeGeometry], items: &[u32], idx: &mut [u32]) {
        let me = self.bounds.len();
        let g: Vec<&EdgeGeometry> = idx.iter().map(|&i| &geo[i as usize]).collect();
        let axis = mean_axis(g.iter().map(|g| g.n1 + g.n2).sum()).unwrap_or(DVec3::NAN);
        let angle = cone_angle(axis, g.iter().flat_map(|g| [g.n1, g.n2]));
        let (center, radius) = mean_sphere(&mut g.iter().flat_map(|g| [g.a, g.b]).collect());
        self.bounds.push(PatchBounds::new(center, radius, axis, angle));
        self.skip.push(0);
        self.leaves.push([0, 0]);
        if idx.len() <= LEAF {
            self.leaves[me] = [self.order.len() as u32, idx.len() as u32];
            self.order.extend(idx.iter().map(|&i| items[i as usize]));
        } else {
            let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            for x in &g {
                lo = lo.min(x.midpoint());
                hi = hi.max(x.midpoint());
            }
            let axis = (hi - lo).max_position();
            let half = idx.len() / 2;
            idx.select_nth_unstable_by(half, |&x, &y| {
                let (a, b) = (geo[x as usize].midpoint()[axis], geo[y as usize].midpoint()[axis]);
                a.total_cmp(&b).then(x.cmp(&y))
            });
            let (left, right) = idx.split_at_mut(half);
            self.node(geo, items, left);
            self.node(geo, items, right);
        }
        self.skip[me] = self.bounds.len() as u32;
    }

    /// Contour edges for one view (identifiers of [`Edges`]).
    pub fn extract(&self, positions: &[Vec3], edges: &Edges, projection: Projection, out: &mut Vec<u32>) -> Tested {
        let (viewer, view) = viewers(projection);
        out.clear();
        let (mut tested, mut visited) = (0, 0);
        let mut i = 0;
        while i < self.bounds.len() {
            visited += 1;
            if self.bounds[i].accepts(&view) {
                let [first, count] = self.leaves[i];
                if count > 0 {
                    let r = first as usize..(first + count) as usize;
                    test_quads(positions, &self.quads[r.clone()], &self.order[r], &viewer, out);
                    tested += count as usize;
                }
                i += 1;
            } else {
                i = self.skip[i] as usize;
            }
        }
        let rest = self.always_from..self.order.len();
        test_quads(positions, &self.quads[rest.clone()], &self.order[rest.clone()], &viewer, out);
        tested += rest.len() + extract_uncullable(positions, edges, &viewer, out);
        Tested { edges: tested, bounds: visited }
    }

    pub fn len(&self) -> usize {
        self.bounds.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bounds.is_empty()
    }
}
