//! The two measures triangle orders are judged by (Sander, Nehab & Barczak 2007; Han &
//! Sander 2016, section 1):
//!
//! - ACMR, the average cache miss ratio: vertices transformed per triangle with a FIFO
//!   post-transform cache of `cache_size` entries (a vertex hits when it was one of the last
//!   `cache_size` vertices inserted).
//! - OVR, the overdraw ratio: fragments that pass the depth test (early-z, "less") divided by
//!   the visible pixels, for an ordered triangle list seen through a view-projection matrix.
//!
//! The rasterizer is exact and deterministic: vertices snap to 1/256 pixel, edge functions are
//! evaluated in 64-bit integers at pixel centers with the top-left fill rule (two triangles
//! sharing an edge never both cover a pixel, and leave no gap), back faces are culled, depth is
//! interpolated from the snapped barycentrics in f64. Triangles with a vertex at or behind the
//! eye (`w ≤ 0`) are skipped (the viewpoints used lie outside the model's bounding sphere).

use glam::{Mat4, Vec3};

/// A FIFO post-transform vertex cache: a vertex hits when it was one of the last `size`
/// vertices inserted.
pub struct FifoCache {
    /// The insertion count when each vertex last entered the cache (0: never).
    inserted: Vec<u64>,
    insertions: u64,
    size: u64,
}

impl FifoCache {
    pub fn new(vertex_count: usize, size: u32) -> FifoCache {
        FifoCache { inserted: vec![0; vertex_count], insertions: 0, size: size as u64 }
    }

    /// Looks `v` up, inserting it on a miss; true on a miss.
    pub fn miss(&mut self, v: u32) -> bool {
        let at = self.inserted[v as usize];
        let miss = at == 0 || self.insertions - at >= self.size;
        if miss {
            self.insertions += 1;
            self.inserted[v as usize] = self.insertions;
        }
        miss
    }

    /// Empties the cache.
    pub fn flush(&mut self) {
        self.insertions += self.size + 1;
    }
}

/// ACMR of `triangles` (in order) for a FIFO cache of `cache_size` vertices.
pub fn acmr(triangles: &[[u32; 3]], vertex_count: usize, cache_size: u32) -> f32 {
    let mut cache = FifoCache::new(vertex_count, cache_size);
    let misses = triangles.iter().flatten().filter(|&&v| cache.miss(v)).count();
    misses as f32 / triangles.len().max(1) as f32
}

/// What one render measured (the runtime crate holds the type, which the GPU renderer fills too).
pub use skinlet_runtime::overdraw_orders::Overdraw;

/// A depth buffer and per-pixel counters, reused across renders.
#[derive(Clone, Debug)]
pub struct Raster {
    pub width: u32,
    pub height: u32,
    depth: Vec<f64>,
    /// Fragments that passed the depth test, per pixel (for heat maps).
    pub shaded: Vec<u32>,
}

const SUB: i64 = 256;

impl Raster {
    pub fn new(width: u32, height: u32) -> Raster {
        let n = width as usize * height as usize;
        Raster { width, height, depth: vec![f64::INFINITY; n], shaded: vec![0; n] }
    }

    /// Renders `triangles` in order (counter-clockwise front faces, back faces culled) and
    /// returns the overdraw counts. Clears the buffers first.
    pub fn render(&mut self, positions: &[Vec3], triangles: &[[u32; 3]], view_proj: &Mat4) -> Overdraw {
        self.depth.fill(f64::INFINITY);
        self.shaded.fill(0);
        let screen = self.project(positions, view_proj);
        let mut shaded = 0u64;
        let (depth, counts, width) = (&mut self.depth, &mut self.shaded, self.width as i64);
        for t in triangles {
            if let (Some(a), Some(b), Some(c)) = (screen[t[0] as usize], screen[t[1] as usize], screen[t[2] as usize]) {
                rasterize(a, b, c, width, self.height as i64, |i, z| {
                    if z < depth[i] {
                        depth[i] = z;
                        counts[i] += 1;
                        shaded += 1;
                    }
                });
            }
        }
        let covered = self.depth.iter().filter(|d| d.is_finite()).count() as u64;
        Overdraw { shaded, covered }
    }

    /// Rasterizes every front-facing triangle once, without a depth test, keeping each
    /// triangle's fragments: [`Fragments::shade`] then measures any order of the same
    /// triangles without rasterizing again.
    pub fn fragments(&mut self, positions: &[Vec3], triangles: &[[u32; 3]], view_proj: &Mat4, out: &mut Fragments) {
        let screen = self.project(positions, view_proj);
        out.start.clear();
        out.pixel.clear();
        out.depth.clear();
        out.pixels = self.width as usize * self.height as usize;
        self.depth.fill(f64::INFINITY);
        for t in triangles {
            out.start.push(out.pixel.len() as u32);
            if let (Some(a), Some(b), Some(c)) = (screen[t[0] as usize], screen[t[1] as usize], screen[t[2] as usize]) {
                let (pixel, depth, seen) = (&mut out.pixel, &mut out.depth, &mut self.depth);
                rasterize(a, b, c, self.width as i64, self.height as i64, |i, z| {
                    pixel.push(i as u32);
                    depth.push(z);
                    seen[i] = 0.0;
                });
            }
        }
        out.start.push(out.pixel.len() as u32);
        out.start.shrink_to_fit();
        out.pixel.shrink_to_fit();
        out.depth.shrink_to_fit();
        out.covered = self.depth.iter().filter(|d| d.is_finite()).count() as u64;
    }

    /// Screen positions (1/256 pixel, y down) and depth; `None` at or behind the eye.
    fn project(&self, positions: &[Vec3], view_proj: &Mat4) -> Vec<Option<(i64, i64, f64)>> {
        let (w, h) = (self.width as f64, self.height as f64);
        positions
            .iter()
            .map(|p| {
                let c = *view_proj * p.extend(1.0);
                (c.w > 0.0).then(|| {
                    let (x, y, z) = (c.x as f64 / c.w as f64, c.y as f64 / c.w as f64, c.z as f64 / c.w as f64);
                    let sx = ((x + 1.0) * 0.5 * w * SUB as f64).round() as i64;
                    let sy = ((1.0 - y) * 0.5 * h * SUB as f64).round() as i64;
                    (sx, sy, z)
                })
            })
            .collect()
    }
}

impl Raster {
    /// The last render's overdraw as an RGB8 image (row-major, top row first): see [`heatmap`].
    pub fn heatmap(&self) -> Vec<u8> {
        heatmap(&self.shaded)
    }
}

/// Shaded fragments per pixel as RGB8: background dark, then blue, green, yellow, orange,
/// red for 1, 2, 3, 4, 5+ fragments.
pub fn heatmap(shaded: &[u32]) -> Vec<u8> {
    const COLORS: [[u8; 3]; 6] =
        [[24, 24, 28], [40, 90, 200], [40, 170, 90], [230, 200, 40], [235, 120, 30], [215, 35, 35]];
    shaded.iter().flat_map(|&n| COLORS[(n as usize).min(5)]).collect()
}

/// The fragments of one view's triangles (see [`Raster::fragments`]).
#[derive(Clone, Debug, Default)]
pub struct Fragments {
    /// Fragments of triangle `t`: `start[t]..start[t + 1]`.
    start: Vec<u32>,
    pixel: Vec<u32>,
    depth: Vec<f64>,
    pixels: usize,
    /// Pixels covered by any triangle: the same for every order.
    pub covered: u64,
}

impl Fragments {
    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        4 * self.start.capacity() + 4 * self.pixel.capacity() + 8 * self.depth.capacity()
    }

    /// Fragments passing the depth test when the triangles (indices into the list given to
    /// [`Raster::fragments`]) are drawn in `order`; `None` as soon as they exceed `limit`.
    pub fn shade(&self, order: impl IntoIterator<Item = u32>, limit: u64, depth: &mut Vec<f64>) -> Option<u64> {
        depth.clear();
        depth.resize(self.pixels, f64::INFINITY);
        let mut shaded = 0u64;
        for t in order {
            let r = self.start[t as usize] as usize..self.start[t as usize + 1] as usize;
            for (&i, &z) in self.pixel[r.clone()].iter().zip(&self.depth[r]) {
                if z < depth[i as usize] {
                    depth[i as usize] = z;
                    shaded += 1;
                }
            }
            if shaded > limit {
                return None;
            }
        }
        Some(shaded)
    }
}

impl Fragments {
    /// Calls `emit(front, back)` for the nearest fragment of every pixel and each other
    /// fragment on that pixel whose triangle (indices into the list given to
    /// [`Raster::fragments`]) is in another group (`group[t]`): the pairs a draw order
    /// should keep in that order to shade each pixel once (once the nearest is drawn, the
    /// order of those behind it no longer matters). `nearest` is scratch space, reused.
    pub fn occlusions(&self, group: &[u32], nearest: &mut Vec<(f64, u32)>, mut emit: impl FnMut(u32, u32)) {
        nearest.clear();
        nearest.resize(self.pixels, (f64::INFINITY, u32::MAX));
        let fragments = || {
            self.start.windows(2).zip(group).flat_map(|(w, &g)| {
                let r = w[0] as usize..w[1] as usize;
                self.pixel[r.clone()].iter().zip(&self.depth[r]).map(move |(&p, &z)| (p as usize, z, g))
            })
        };
        for (p, z, g) in fragments() {
            if z < nearest[p].0 {
                nearest[p] = (z, g);
            }
        }
        // Fragments at the nearest depth are never shaded a second time: no pair.
        for (p, z, g) in fragments() {
            let (front_z, front) = nearest[p];
            if z > front_z && g != front {
                emit(front, g);
            }
        }
    }
}

/// Rasterizes one triangle (screen coordinates in 1/256 pixel, y down), calling `emit`
/// with the pixel index and depth of every covered pixel center.
fn rasterize(
    a: (i64, i64, f64),
    b: (i64, i64, f64),
    c: (i64, i64, f64),
    width: i64,
    height: i64,
    mut emit: impl FnMut(usize, f64),
) {
    let edge =
        |p: (i64, i64, f64), q: (i64, i64, f64), x: i64, y: i64| (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0);
    // Counter-clockwise in NDC (y up) is clockwise on screen (y down), where this edge
    // function is negative: front faces have area < 0. Swap two vertices so that the
    // inside is positive for every edge.
    let area = edge(a, b, c.0, c.1);
    if area >= 0 {
        return; // back-facing or degenerate
    }
    let (b, c, area) = (c, b, -area);
    // Top-left rule for this orientation: a top edge runs right (dy = 0, dx > 0), a left
    // edge runs up (dy < 0). Pixels exactly on other edges belong to the neighbour.
    let bias = |p: (i64, i64, f64), q: (i64, i64, f64)| {
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        if (dy == 0 && dx > 0) || dy < 0 { 0 } else { -1 }
    };
    let (bab, bbc, bca) = (bias(a, b), bias(b, c), bias(c, a));
    let minx = (a.0.min(b.0).min(c.0) / SUB).max(0);
    let maxx = ((a.0.max(b.0).max(c.0) + SUB - 1) / SUB).min(width - 1);
    let miny = (a.1.min(b.1).min(c.1) / SUB).max(0);
    let maxy = ((a.1.max(b.1).max(c.1) + SUB - 1) / SUB).min(height - 1);
    for py in miny..=maxy {
        let y = py * SUB + SUB / 2;
        for px in minx..=maxx {
            let x = px * SUB + SUB / 2;
            let (e0, e1, e2) = (edge(b, c, x, y), edge(c, a, x, y), edge(a, b, x, y));
            if e0 + bbc < 0 || e1 + bca < 0 || e2 + bab < 0 {
                continue;
            }
            let z = (e0 as f64 * a.2 + e1 as f64 * b.2 + e2 as f64 * c.2) / area as f64;
            emit(py as usize * width as usize + px as usize, z);
        }
    }
}

/// The six axis-aligned orthographic views meshoptimizer's `analyzeOverdraw` uses (it
/// rasterizes front faces from one side and back faces from the other), each framing the
/// mesh's bounding cube. Rendered at 256 × 256 and summed, our overdraw ratio agrees with
/// meshoptimizer's within 0.1% on the demo character (the rest: its 1/16-pixel snapping and
/// depth ties counted as passing).
pub fn axis_views(positions: &[Vec3]) -> [Mat4; 6] {
    let (lo, hi) = positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
    let center = (lo + hi) / 2.0;
    let half = ((hi - lo).max_element() / 2.0).max(f32::MIN_POSITIVE);
    let proj = Mat4::orthographic_rh(-half, half, -half, half, 0.0, 4.0 * half);
    [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z].map(|d| {
        let up = if d.y.abs() > 0.5 { Vec3::Z } else { Vec3::Y };
        proj * Mat4::look_at_rh(center + d * 2.0 * half, center, up)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ortho() -> Mat4 {
        // Maps [0, 64] × [0, 64] to the 64 × 64 viewport, looking down −z.
        Mat4::orthographic_rh(0.0, 64.0, 0.0, 64.0, -10.0, 10.0)
    }

    #[test]
    fn acmr_equals_meshoptimizer() {
        let mut s = 7u32;
        let mut next = |n: u32| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s % n
        };
        for case in 0..40 {
            let verts = 5 + next(300);
            let tris: Vec<[u32; 3]> = (0..(1 + next(900))).map(|_| [next(verts), next(verts), next(verts)]).collect();
            let flat: Vec<u32> = tris.iter().flatten().copied().collect();
            for cache in [3, 16, 32] {
                let ours = acmr(&tris, verts as usize, cache);
                let theirs = meshopt::analyze_vertex_cache(&flat, verts as usize, cache, 0, 0).acmr;
                assert!((ours - theirs).abs() < 1e-6, "case {case}, cache {cache}: {ours} vs {theirs}");
            }
        }
    }

    #[test]
    fn coverage_equals_analytic_area() {
        let mut r = Raster::new(64, 64);
        // An axis-aligned rectangle with corners on pixel boundaries: exactly its area.
        let rect = [
            Vec3::new(3.0, 5.0, 0.0),
            Vec3::new(40.0, 5.0, 0.0),
            Vec3::new(40.0, 30.0, 0.0),
            Vec3::new(3.0, 30.0, 0.0),
        ];
        let o = r.render(&rect, &[[0, 1, 2], [0, 2, 3]], &ortho());
        assert_eq!((o.covered, o.shaded), (37 * 25, 37 * 25));
        // A disc as a fan of 64 thin triangles: every pixel once (no double counting along
        // the shared edges), and the area within the perimeter of the exact one.
        let (cx, cy, rad) = (32.3, 31.7, 20.2);
        let mut pts = vec![Vec3::new(cx, cy, 0.0)];
        let n = 64;
        pts.extend((0..n).map(|k| {
            let a = k as f32 / n as f32 * std::f32::consts::TAU;
            Vec3::new(cx + rad * a.cos(), cy + rad * a.sin(), 0.0)
        }));
        let fan: Vec<[u32; 3]> = (0..n).map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
        let o = r.render(&pts, &fan, &ortho());
        assert_eq!(o.shaded, o.covered, "a pixel was covered twice");
        let polygon = 0.5 * n as f64 * (rad as f64).powi(2) * (std::f64::consts::TAU / n as f64).sin();
        let perimeter = std::f64::consts::TAU * rad as f64;
        assert!((o.covered as f64 - polygon).abs() < perimeter / 2.0, "{} vs {polygon}", o.covered);
        // Back faces are culled: the same fan reversed draws nothing.
        let back: Vec<[u32; 3]> = fan.iter().map(|t| [t[0], t[2], t[1]]).collect();
        assert_eq!(r.render(&pts, &back, &ortho()).covered, 0);
    }

    #[test]
    fn overdraw_counts_depth_order() {
        // Two full-screen quads at different depths: front to back shades each pixel once,
        // back to front twice.
        let mut r = Raster::new(16, 16);
        let vp = Mat4::orthographic_rh(0.0, 16.0, 0.0, 16.0, -10.0, 10.0);
        let quad = |z: f32| {
            [Vec3::new(0.0, 0.0, z), Vec3::new(16.0, 0.0, z), Vec3::new(16.0, 16.0, z), Vec3::new(0.0, 16.0, z)]
        };
        let mut pts = quad(1.0).to_vec(); // near (looking down −z, larger z is nearer)
        pts.extend(quad(-1.0));
        let near = [[0, 1, 2], [0, 2, 3]];
        let far = [[4, 5, 6], [4, 6, 7]];
        let front_to_back: Vec<[u32; 3]> = near.iter().chain(&far).copied().collect();
        let back_to_front: Vec<[u32; 3]> = far.iter().chain(&near).copied().collect();
        assert_eq!(r.render(&pts, &front_to_back, &vp).ratio(), 1.0);
        assert_eq!(r.render(&pts, &back_to_front, &vp).ratio(), 2.0);
        let img = r.heatmap();
        assert_eq!(img.len(), 16 * 16 * 3);
        assert!(img.chunks(3).all(|c| c == [40, 170, 90]), "every pixel shaded twice: green");
    }

    #[test]
    fn occlusions_pair_the_nearer_group_first() {
        // A near quad over the left half, a far quad over everything: 128 pixels where the
        // near group (0) occludes the far one (1), none the other way.
        let mut r = Raster::new(16, 16);
        let vp = Mat4::orthographic_rh(0.0, 16.0, 0.0, 16.0, -10.0, 10.0);
        let quad = |x: f32, z: f32| {
            [Vec3::new(0.0, 0.0, z), Vec3::new(x, 0.0, z), Vec3::new(x, 16.0, z), Vec3::new(0.0, 16.0, z)]
        };
        let mut pts = quad(8.0, 1.0).to_vec();
        pts.extend(quad(16.0, -1.0));
        let tris = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let mut frags = Fragments::default();
        r.fragments(&pts, &tris, &vp, &mut frags);
        let mut pairs = std::collections::HashMap::new();
        frags.occlusions(&[0, 0, 1, 1], &mut Vec::new(), |a, b| *pairs.entry((a, b)).or_insert(0) += 1);
        assert_eq!(pairs, std::collections::HashMap::from([((0, 1), 128)]));
        // A third, farthest quad over everything: only the nearest fragment of a pixel
        // pairs, so (1, 2) counts the right half alone (all pairs would count it twice).
        pts.extend(quad(16.0, -3.0));
        let tris = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 9, 10], [8, 10, 11]];
        r.fragments(&pts, &tris, &vp, &mut frags);
        pairs.clear();
        frags.occlusions(&[0, 0, 1, 1, 2, 2], &mut Vec::new(), |a, b| *pairs.entry((a, b)).or_insert(0) += 1);
        assert_eq!(pairs, std::collections::HashMap::from([((0, 1), 128), ((0, 2), 128), ((1, 2), 128)]));
    }
}
