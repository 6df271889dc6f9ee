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
    // Scratch space: projected vertices, and for [`Raster::fragments`].
    screen: Vec<Option<(i64, i64, f64)>>,
    raw_pixel: Vec<u32>,
    raw_depth: Vec<f64>,
    count: Vec<u32>,
    bucket: Vec<u32>,
    rank: Vec<u32>,
}

const SUB: i64 = 256;

impl Raster {
    pub fn new(width: u32, height: u32) -> Raster {
        let n = width as usize * height as usize;
        Raster {
            width,
            height,
            depth: vec![f64::INFINITY; n],
            shaded: vec![0; n],
            screen: Vec::new(),
            raw_pixel: Vec::new(),
            raw_depth: Vec::new(),
            count: Vec::new(),
            bucket: Vec::new(),
            rank: Vec::new(),
        }
    }

    /// Renders `triangles` in order (counter-clockwise front faces, back faces culled) and
    /// returns the overdraw counts. Clears the buffers first.
    pub fn render(&mut self, positions: &[Vec3], triangles: &[[u32; 3]], view_proj: &Mat4) -> Overdraw {
        self.depth.fill(f64::INFINITY);
        self.shaded.fill(0);
        self.project(positions, view_proj);
        let screen = &self.screen;
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

    /// Rasterizes every front-facing triangle once, without a depth test, keeping the
    /// fragments of each group of triangles (group `g` is `triangles[groups[g]..groups[g + 1]]`,
    /// the last group running to the end; `groups` empty: one group per triangle):
    /// [`Fragments::shade`] then measures any order of the groups without rasterizing again.
    /// Triangles keep their order within a group.
    pub fn fragments(
        &mut self,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        groups: &[u32],
        view_proj: &Mat4,
        out: &mut Fragments,
    ) {
        self.project(positions, view_proj);
        let screen = &self.screen;
        let n = self.width as usize * self.height as usize;
        let group_count = if groups.is_empty() { triangles.len() } else { groups.len() };
        let group_start = |g: usize| if groups.is_empty() { g } else { groups[g] as usize };
        // Every fragment, group after group, with its depth.
        let (pixel, depth) = (&mut self.raw_pixel, &mut self.raw_depth);
        pixel.clear();
        depth.clear();
        let mut raw_start = Vec::with_capacity(group_count + 1);
        out.seen.clear();
        out.seen.resize(group_count.div_ceil(64), 0);
        for g in 0..group_count {
            raw_start.push(pixel.len() as u32);
            let end = if g + 1 < group_count { group_start(g + 1) } else { triangles.len() };
            for t in &triangles[group_start(g)..end] {
                if let (Some(a), Some(b), Some(c)) =
                    (screen[t[0] as usize], screen[t[1] as usize], screen[t[2] as usize])
                {
                    let front = rasterize(a, b, c, self.width as i64, self.height as i64, |i, z| {
                        pixel.push(i as u32);
                        depth.push(z);
                    });
                    out.seen[g / 64] |= (front as u64) << (g % 64);
                }
            }
        }
        raw_start.push(pixel.len() as u32);
        // Fragments per pixel, then each pixel's fragments by depth: their rank (equal depths,
        // equal ranks) orders them exactly as their depths do.
        let count = &mut self.count;
        count.clear();
        count.resize(n + 1, 0);
        for &p in pixel.iter() {
            count[p as usize + 1] += 1;
        }
        out.covered = count.iter().filter(|&&c| c > 0).count() as u64;
        out.single = count.iter().filter(|&&c| c == 1).count() as u64;
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let bucket = &mut self.bucket;
        bucket.clear();
        bucket.resize(pixel.len(), 0);
        let mut fill = count[..n].to_vec();
        for (f, &p) in pixel.iter().enumerate() {
            bucket[fill[p as usize] as usize] = f as u32;
            fill[p as usize] += 1;
        }
        let rank = &mut self.rank;
        rank.clear();
        rank.resize(pixel.len(), 0);
        for p in 0..n {
            let of_pixel = &mut bucket[count[p] as usize..count[p + 1] as usize];
            if of_pixel.len() < 2 {
                continue;
            }
            of_pixel.sort_by(|&a, &b| depth[a as usize].total_cmp(&depth[b as usize]).then(a.cmp(&b)));
            let mut r = 0;
            for w in 0..of_pixel.len() {
                if w > 0 && depth[of_pixel[w] as usize] > depth[of_pixel[w - 1] as usize] {
                    r += 1;
                }
                rank[of_pixel[w] as usize] = r;
            }
        }
        // Kept: fragments on pixels that more than one fragment covers (a pixel covered once is
        // shaded once whatever the order).
        let kept: u32 = count.windows(2).map(|c| c[1] - c[0]).filter(|&c| c > 1).sum();
        out.start.clear();
        out.start.reserve_exact(group_count + 1);
        out.fragments.clear();
        out.fragments.reserve_exact(kept as usize);
        out.pixels = n;
        for g in 0..group_count {
            out.start.push(out.fragments.len() as u32);
            for f in raw_start[g] as usize..raw_start[g + 1] as usize {
                let p = pixel[f] as usize;
                if count[p + 1] - count[p] > 1 {
                    out.fragments.push((pixel[f], rank[f]));
                }
            }
        }
        out.start.push(out.fragments.len() as u32);
    }

    /// Screen positions (1/256 pixel, y down) and depth into `self.screen`; `None` at or
    /// behind the eye.
    fn project(&mut self, positions: &[Vec3], view_proj: &Mat4) {
        let (w, h) = (self.width as f64, self.height as f64);
        self.screen.clear();
        self.screen.extend(positions.iter().map(|p| {
            let c = *view_proj * p.extend(1.0);
            (c.w > 0.0).then(|| {
                let inv = 1.0 / c.w as f64;
                let (x, y, z) = (c.x as f64 * inv, c.y as f64 * inv, c.z as f64 * inv);
                let sx = round((x + 1.0) * 0.5 * w * SUB as f64);
                let sy = round((1.0 - y) * 0.5 * h * SUB as f64);
                (sx, sy, z)
            })
        }));
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

/// The fragments of one view, by group of triangles (see [`Raster::fragments`]).
#[derive(Clone, Debug, Default)]
pub struct Fragments {
    /// Fragments of group `g`: `start[g]..start[g + 1]`.
    start: Vec<u32>,
    /// (pixel, depth rank among that pixel's fragments: 0 nearest, equal depths equal ranks)
    /// of the fragments on pixels covered more than once.
    fragments: Vec<(u32, u32)>,
    pixels: usize,
    /// Pixels covered exactly once: shaded once whatever the order (their fragments are not kept).
    single: u64,
    /// Groups with a triangle facing the eye (all its vertices before it), a bit each.
    seen: Vec<u64>,
    /// Pixels covered by any triangle: the same for every order.
    pub covered: u64,
}

impl Fragments {
    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        4 * self.start.capacity() + 8 * self.fragments.capacity() + 8 * self.seen.capacity()
    }

    /// Whether group `g` has a triangle facing the eye (covering a pixel center or not).
    pub fn seen(&self, g: usize) -> bool {
        self.seen.get(g / 64).is_some_and(|w| w >> (g % 64) & 1 == 1)
    }

    fn of(&self, g: u32) -> &[(u32, u32)] {
        &self.fragments[self.start[g as usize] as usize..self.start[g as usize + 1] as usize]
    }

    /// Fragments passing the depth test when the groups are drawn in `order` (each group once);
    /// `None` as soon as they exceed `limit`. `nearest` is scratch space, reused.
    pub fn shade(&self, order: impl IntoIterator<Item = u32>, limit: u64, nearest: &mut Vec<u32>) -> Option<u64> {
        nearest.clear();
        nearest.resize(self.pixels, u32::MAX);
        let mut shaded = self.single;
        for g in order {
            for &(p, r) in self.of(g) {
                if r < nearest[p as usize] {
                    nearest[p as usize] = r;
                    shaded += 1;
                }
            }
            if shaded > limit {
                return None;
            }
        }
        (shaded <= limit).then_some(shaded)
    }

    /// Calls `emit(front, back)` for the nearest fragment of every pixel and each other
    /// fragment on that pixel in another group: the pairs a draw order should keep in that
    /// order to shade each pixel once (once the nearest is drawn, the order of those behind
    /// it no longer matters). Fragments as near as the nearest pair with nothing (never
    /// shaded a second time). `front` is scratch space, reused.
    pub fn occlusions(&self, front: &mut Vec<u32>, mut emit: impl FnMut(u32, u32)) {
        front.clear();
        front.resize(self.pixels, u32::MAX);
        let groups = self.start.len().saturating_sub(1) as u32;
        for g in 0..groups {
            for &(p, r) in self.of(g) {
                if r == 0 && front[p as usize] == u32::MAX {
                    front[p as usize] = g;
                }
            }
        }
        for g in 0..groups {
            for &(p, r) in self.of(g) {
                let f = front[p as usize];
                if r > 0 && f != g {
                    emit(f, g);
                }
            }
        }
    }
}

/// `v.round() as i64` without the library call (`round` is one on baseline x86-64):
/// `v − trunc(v)` is exact below 2^52, beyond which every f64 is an integer.
fn round(v: f64) -> i64 {
    if v.abs() < 4.0e15 {
        let t = v as i64;
        let f = v - t as f64;
        t + (f >= 0.5) as i64 - (f <= -0.5) as i64
    } else {
        v as i64
    }
}

/// Rasterizes one triangle (screen coordinates in 1/256 pixel, y down), calling `emit`
/// with the pixel index and depth of every covered pixel center. Returns whether it faces
/// the viewer (covering a pixel center or not).
fn rasterize(
    a: (i64, i64, f64),
    b: (i64, i64, f64),
    c: (i64, i64, f64),
    width: i64,
    height: i64,
    mut emit: impl FnMut(usize, f64),
) -> bool {
    let edge =
        |p: (i64, i64, f64), q: (i64, i64, f64), x: i64, y: i64| (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0);
    // Counter-clockwise in NDC (y up) is clockwise on screen (y down), where this edge
    // function is negative: front faces have area < 0. Swap two vertices so that the
    // inside is positive for every edge.
    let area = edge(a, b, c.0, c.1);
    if area >= 0 {
        return false; // back-facing or degenerate
    }
    let (b, c, area) = (c, b, -area);
    // Top-left rule for this orientation: a top edge runs right (dy = 0, dx > 0), a left
    // edge runs up (dy < 0). Pixels exactly on other edges belong to the neighbour.
    let bias = |p: (i64, i64, f64), q: (i64, i64, f64)| {
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        if (dy == 0 && dx > 0) || dy < 0 { 0 } else { -1 }
    };
    let (bab, bbc, bca) = (bias(a, b), bias(b, c), bias(c, a));
    // The pixels whose centers (`p * SUB + SUB / 2`) lie in the bounding box: a triangle
    // smaller than a pixel often has none.
    let first = |lo: i64| -(-(lo - SUB / 2)).div_euclid(SUB);
    let last = |hi: i64| (hi - SUB / 2).div_euclid(SUB);
    let minx = first(a.0.min(b.0).min(c.0)).max(0);
    let maxx = last(a.0.max(b.0).max(c.0)).min(width - 1);
    let miny = first(a.1.min(b.1).min(c.1)).max(0);
    let maxy = last(a.1.max(b.1).max(c.1)).min(height - 1);
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
    true
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
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Fragments grouped and ranked measure any group order exactly as rendering that
        /// order does: random triangles on a coarse grid (so depths tie, triangles repeat and
        /// cover one another), random groups, a random order of the groups.
        #[test]
        fn grouped_fragments_shade_like_a_render(
            points in prop::collection::vec((0i32..9, 0i32..9, -3i32..4), 3..24),
            tris in prop::collection::vec((0usize..24, 0usize..24, 0usize..24), 1..60),
            cuts in prop::collection::vec(any::<bool>(), 60),
            keys in prop::collection::vec(any::<u32>(), 60),
        ) {
            let positions: Vec<Vec3> =
                points.iter().map(|&(x, y, z)| Vec3::new(x as f32 * 2.0, y as f32 * 2.0, z as f32)).collect();
            let n = positions.len();
            let triangles: Vec<[u32; 3]> = tris.iter().map(|&(a, b, c)| [(a % n) as u32, (b % n) as u32, (c % n) as u32]).collect();
            let groups: Vec<u32> =
                (0..triangles.len() as u32).filter(|&t| t == 0 || cuts[t as usize]).collect();
            let mut order: Vec<u32> = (0..groups.len() as u32).collect();
            order.sort_by_key(|&g| keys[g as usize]);
            let end = |g: u32| groups.get(g as usize + 1).map_or(triangles.len(), |&e| e as usize);
            let drawn: Vec<[u32; 3]> =
                order.iter().flat_map(|&g| &triangles[groups[g as usize] as usize..end(g)]).copied().collect();
            let vp = Mat4::orthographic_rh(0.0, 16.0, 0.0, 16.0, -10.0, 10.0);
            let mut r = Raster::new(16, 16);
            let mut frags = Fragments::default();
            r.fragments(&positions, &triangles, &groups, &vp, &mut frags);
            let full = r.render(&positions, &drawn, &vp);
            prop_assert_eq!(frags.covered, full.covered);
            prop_assert_eq!(frags.shade(order.iter().copied(), u64::MAX, &mut Vec::new()), Some(full.shaded));
        }
    }

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
    fn round_matches_the_library() {
        let mut v = 0.37f64;
        for i in 0..20_000 {
            v = (v * 1.3 + 0.71).rem_euclid(1e6) * if i % 2 == 0 { 1.0 } else { -1.0 };
            for x in [v, v.trunc() + 0.5, v.trunc() - 0.5, 3.0e15 + 0.5, -7.0e15, 1e300, f64::NAN] {
                assert_eq!(round(x), x.round() as i64, "{x}");
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
        r.fragments(&pts, &tris, &[0, 2], &vp, &mut frags);
        assert!(frags.seen(0) && frags.seen(1) && !frags.seen(2));
        let mut pairs = std::collections::HashMap::new();
        frags.occlusions(&mut Vec::new(), |a, b| *pairs.entry((a, b)).or_insert(0) += 1);
        assert_eq!(pairs, std::collections::HashMap::from([((0, 1), 128)]));
        // A third, farthest quad over everything: only the nearest fragment of a pixel
        // pairs, so (1, 2) counts the right half alone (all pairs would count it twice).
        pts.extend(quad(16.0, -3.0));
        let tris = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 9, 10], [8, 10, 11]];
        r.fragments(&pts, &tris, &[0, 2, 4], &vp, &mut frags);
        pairs.clear();
        frags.occlusions(&mut Vec::new(), |a, b| *pairs.entry((a, b)).or_insert(0) += 1);
        assert_eq!(pairs, std::collections::HashMap::from([((0, 1), 128), ((0, 2), 128), ((1, 2), 128)]));
    }
}
