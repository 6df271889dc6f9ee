//! Static meshes of sizes and shapes `../shared/assets` lacks, for the contour targets
//! (Tsiapkolis & Bénard 2024 measure on scans): a scan-like noisy sphere (a geodesic sphere
//! with a few broad bumps and band-limited noise along the normal, like a reconstructed
//! scan), a thin-shelled cup (a surface of revolution whose wall is a small fraction of its
//! height thick, rim included), and decimations of any mesh by meshoptimizer's simplifier.
//! Every mesh is closed and consistently wound outward; the same parameters give the same
//! mesh.

use crate::demo::Rng;
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// A mesh as positions and triangles.
pub type Geometry = (Vec<Vec3>, Vec<[u32; 3]>);

/// A geodesic sphere of unit radius: each face of an icosahedron cut into `frequency²`
/// triangles and projected onto the sphere (`20 · frequency²` triangles).
pub fn geodesic_sphere(frequency: u32) -> Geometry {
    let n = frequency.max(1);
    let phi = (1.0 + 5f32.sqrt()) / 2.0;
    let mut ico = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            ico.extend([Vec3::new(a, b, 0.0), Vec3::new(0.0, a, b), Vec3::new(b, 0.0, a)]);
        }
    }
    // The faces: triples at mutual distance 2, wound outward.
    let mut faces = Vec::new();
    for a in 0..12 {
        for b in a + 1..12 {
            for c in b + 1..12 {
                let near = |i: usize, j: usize| (ico[i].distance_squared(ico[j]) - 4.0).abs() < 1e-3;
                if near(a, b) && near(b, c) && near(a, c) {
                    let out = (ico[b] - ico[a]).cross(ico[c] - ico[a]).dot(ico[a]) > 0.0;
                    faces.push(if out { [a, b, c] } else { [a, c, b] });
                }
            }
        }
    }
    // Vertices are keyed by their integer barycentric weights over icosahedron vertices, so
    // the faces sharing an edge share its vertices, computed in one order.
    let mut index: HashMap<[(usize, u32); 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut vertex = |weights: [(usize, u32); 3]| -> u32 {
        let mut key = weights.map(|(v, w)| if w == 0 { (usize::MAX, 0) } else { (v, w) });
        key.sort_unstable();
        *index.entry(key).or_insert_with(|| {
            let p = key.iter().filter(|(_, w)| *w > 0).fold(Vec3::ZERO, |s, &(v, w)| s + ico[v] * w as f32);
            positions.push(p.normalize());
            positions.len() as u32 - 1
        })
    };
    let mut triangles = Vec::new();
    for [a, b, c] in faces {
        let mut at = |i: u32, j: u32| vertex([(a, n - i - j), (b, i), (c, j)]);
        for i in 0..n {
            for j in 0..n - i {
                triangles.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                if i + j + 1 < n {
                    triangles.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    (positions, triangles)
}

/// Scanner-like noise: white noise per vertex, averaged with its neighbours `smoothing`
/// times (scanner noise is correlated over a few samples), scaled to a standard deviation of
/// `amount` mean edge lengths, along the vertex normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    pub amount: f32,
    pub smoothing: usize,
    pub seed: u64,
}

impl Default for Noise {
    /// Dihedral angles like the Stanford bunny's on a sphere (median 4.8° against 4.1°).
    fn default() -> Self {
        Noise { amount: 0.1, smoothing: 1, seed: 1 }
    }
}

/// Moves each vertex along its normal (the area-weighted mean of its faces') by [`Noise`].
pub fn add_noise(positions: &mut [Vec3], triangles: &[[u32; 3]], noise: &Noise) {
    let mut rng = Rng(noise.seed);
    let neighbours = neighbours(positions.len(), triangles);
    let mut field: Vec<f32> = (0..positions.len()).map(|_| 2.0 * rng.unit() - 1.0).collect();
    for _ in 0..noise.smoothing {
        field = (neighbours.iter().enumerate())
            .map(|(v, ns)| (field[v] + ns.iter().map(|&u| field[u as usize]).sum::<f32>()) / (1 + ns.len()) as f32)
            .collect();
    }
    let std = (field.iter().map(|x| x * x).sum::<f32>() / field.len().max(1) as f32).sqrt().max(f32::MIN_POSITIVE);
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in triangles {
        let [pa, pb, pc] = [a, b, c].map(|v| positions[v as usize]);
        let n = (pb - pa).cross(pc - pa);
        for v in [a, b, c] {
            normals[v as usize] += n;
        }
    }
    let scale = noise.amount * mean_edge(positions, triangles) / std;
    for ((p, n), e) in positions.iter_mut().zip(&normals).zip(&field) {
        *p += n.normalize_or_zero() * scale * e;
    }
}

/// A scan-like sphere: [`geodesic_sphere`] at about `triangles`, displaced along the radius
/// by ten broad bumps (up to ±12% of the radius), then by [`Noise`].
pub fn noisy_sphere(triangles: usize, noise: &Noise) -> Geometry {
    let frequency = ((triangles as f32 / 20.0).sqrt().round() as u32).max(1);
    let (mut positions, triangles) = geodesic_sphere(frequency);
    let mut rng = Rng(noise.seed ^ 0x5EED);
    let bumps: Vec<(Vec3, f32, f32)> = (0..10)
        .map(|_| {
            let z = 2.0 * rng.unit() - 1.0;
            let a = std::f32::consts::TAU * rng.unit();
            let s = (1.0 - z * z).sqrt();
            (Vec3::new(s * a.cos(), s * a.sin(), z), 0.12 * (2.0 * rng.unit() - 1.0), 0.05 + 0.35 * rng.unit())
        })
        .collect();
    for p in &mut positions {
        let d = *p;
        *p = d * (1.0 + bumps.iter().map(|&(c, a, w)| a * (-(1.0 - d.dot(c)) / w).exp()).sum::<f32>());
    }
    add_noise(&mut positions, &triangles, noise);
    (positions, triangles)
}

/// A cup 1 high and 1 wide whose wall, bottom and rounded rim are `thickness` thick (a
/// fraction of the height), with rounded bottom corners, revolved into about `triangles`
/// triangles of even size (the rim gets at least 4 segments across), then [`Noise`]
/// (keep it well under the thickness).
pub fn thin_shell_cup(triangles: usize, thickness: f32, noise: &Noise) -> Geometry {
    let (r, h, t) = (0.5, 1.0, thickness.clamp(1e-4, 0.2));
    let c = 0.08f32.max(2.0 * t);
    enum Piece {
        Line(Vec2, Vec2),
        Arc { center: Vec2, radius: f32, from: f32, to: f32 },
    }
    use std::f32::consts::{FRAC_PI_2, PI};
    let arc =
        |x: f32, y: f32, radius: f32, from: f32, to: f32| Piece::Arc { center: Vec2::new(x, y), radius, from, to };
    // The profile in (radius, height), from the outer bottom center to the inner one.
    let profile = [
        Piece::Line(Vec2::new(0.0, 0.0), Vec2::new(r - c, 0.0)),
        arc(r - c, c, c, -FRAC_PI_2, 0.0),
        Piece::Line(Vec2::new(r, c), Vec2::new(r, h)),
        arc(r - t / 2.0, h, t / 2.0, 0.0, PI),
        Piece::Line(Vec2::new(r - t, h), Vec2::new(r - t, c)),
        arc(r - c, c, c - t, 0.0, -FRAC_PI_2),
        Piece::Line(Vec2::new(r - c, t), Vec2::new(0.0, t)),
    ];
    let length = |p: &Piece| match p {
        Piece::Line(a, b) => a.distance(*b),
        Piece::Arc { radius, from, to, .. } => radius * (to - from).abs(),
    };
    let total: f32 = profile.iter().map(length).sum();
    // 2 · (total / step) · (2π r / step) triangles.
    let step = (4.0 * PI * r * total / triangles.max(64) as f32).sqrt();
    let mut points = vec![Vec2::ZERO];
    for p in &profile {
        let min = if matches!(p, Piece::Arc { .. }) { 4 } else { 1 };
        let k = ((length(p) / step).ceil() as usize).max(min);
        points.extend((1..=k).map(|i| {
            let s = i as f32 / k as f32;
            match p {
                Piece::Line(a, b) => a.lerp(*b, s),
                Piece::Arc { center, radius, from, to } => {
                    let a = from + (to - from) * s;
                    *center + Vec2::new(a.cos(), a.sin()) * *radius
                }
            }
        }));
    }
    let segments = ((2.0 * PI * r / step).round() as u32).max(8);
    let rings = points.len() - 2;
    let mut positions = vec![Vec3::new(0.0, points[0].y, 0.0)];
    for q in &points[1..=rings] {
        positions.extend((0..segments).map(|s| {
            let a = std::f32::consts::TAU * s as f32 / segments as f32;
            Vec3::new(q.x * a.cos(), q.y, q.x * a.sin())
        }));
    }
    positions.push(Vec3::new(0.0, points[rings + 1].y, 0.0));
    let last = positions.len() as u32 - 1;
    let v = |ring: usize, s: u32| 1 + ring as u32 * segments + s % segments;
    let mut tris = Vec::new();
    for s in 0..segments {
        tris.push([0, v(0, s), v(0, s + 1)]);
        for k in 0..rings - 1 {
            tris.push([v(k, s), v(k + 1, s), v(k + 1, s + 1)]);
            tris.push([v(k, s), v(k + 1, s + 1), v(k, s + 1)]);
        }
        tris.push([last, v(rings - 1, s + 1), v(rings - 1, s)]);
    }
    // Wind outward: the enclosed volume is positive.
    let volume: f32 = tris
        .iter()
        .map(|&[a, b, c]| positions[a as usize].dot(positions[b as usize].cross(positions[c as usize])))
        .sum();
    if volume < 0.0 {
        tris.iter_mut().for_each(|t| t.swap(1, 2));
    }
    add_noise(&mut positions, &tris, noise);
    (positions, tris)
}

/// The mesh simplified by meshoptimizer to about `ratio` of its triangles (its error bound
/// lifted so that the count decides), unused vertices dropped.
pub fn decimate(positions: &[Vec3], triangles: &[[u32; 3]], ratio: f32) -> Geometry {
    let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
    let vertices: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let target = ((flat.len() as f32 * ratio.clamp(0.0, 1.0)) as usize / 3) * 3;
    let kept = meshopt::simplify_decoder(&flat, &vertices, target, 1.0, meshopt::SimplifyOptions::None, None);
    let mut remap = vec![u32::MAX; positions.len()];
    let mut out = Vec::new();
    let tris = kept
        .chunks_exact(3)
        .map(|t| {
            [0, 1, 2].map(|k| {
                let v = t[k] as usize;
                if remap[v] == u32::MAX {
                    remap[v] = out.len() as u32;
                    out.push(positions[v]);
                }
                remap[v]
            })
        })
        .collect();
    (out, tris)
}

/// Each vertex's neighbours along edges, sorted.
fn neighbours(vertices: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut n = vec![Vec::new(); vertices];
    for t in triangles {
        for k in 0..3 {
            n[t[k] as usize].extend([t[(k + 1) % 3], t[(k + 2) % 3]]);
        }
    }
    for list in &mut n {
        list.sort_unstable();
        list.dedup();
    }
    n
}

fn mean_edge(positions: &[Vec3], triangles: &[[u32; 3]]) -> f32 {
    let sum: f32 = (triangles.iter())
        .map(|t| (0..3).map(|k| positions[t[k] as usize].distance(positions[t[(k + 1) % 3] as usize])).sum::<f32>())
        .sum();
    sum / (3 * triangles.len()).max(1) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// How often each directed edge appears.
    fn directed_edges(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), usize> {
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for t in triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        directed
    }

    /// Closed and consistently wound: every directed edge appears once, and its reverse once.
    fn assert_closed(name: &str, (p, t): &Geometry) {
        let directed = directed_edges(t);
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1, "{name}: edge {a}-{b} used {n} times the same way");
            assert_eq!(directed.get(&(b, a)), Some(&1), "{name}: edge {a}-{b} has no opposite");
        }
        let volume: f32 =
            t.iter().map(|&[a, b, c]| p[a as usize].dot(p[b as usize].cross(p[c as usize]))).sum::<f32>() / 6.0;
        assert!(volume > 0.0, "{name}: wound inward (volume {volume})");
        assert!(p.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn generated_scans_are_closed_outward_and_sized() {
        let sphere = geodesic_sphere(8);
        assert_eq!(sphere.1.len(), 20 * 64);
        assert_eq!(sphere.0.len(), 10 * 64 + 2, "Euler: V = T/2 + 2");
        assert_closed("geodesic", &sphere);
        let noisy = noisy_sphere(20_000, &Noise::default());
        assert_closed("noisy sphere", &noisy);
        assert!((noisy.1.len() as f32 / 20_000.0 - 1.0).abs() < 0.05, "{} triangles", noisy.1.len());
        assert_eq!(noisy, noisy_sphere(20_000, &Noise::default()), "deterministic");
        let cup = thin_shell_cup(20_000, 0.02, &Noise { amount: 0.0, ..Noise::default() });
        assert_closed("cup", &cup);
        assert!((cup.1.len() as f32 / 20_000.0 - 1.0).abs() < 0.1, "{} triangles", cup.1.len());
        // The wall is as thick as asked: the inner and outer walls are 0.02 apart.
        let radii = cup.0.iter().filter(|p| (p.y - 0.6).abs() < 0.05).map(|p| p.x.hypot(p.z));
        let (lo, hi) = radii.fold((f32::MAX, 0f32), |(lo, hi), r| (lo.min(r), hi.max(r)));
        assert!((hi - lo - 0.02).abs() < 1e-3 && (hi - 0.5).abs() < 1e-3, "wall {lo}..{hi}");
        // meshoptimizer's simplifier may fold a few faces over (the contour code tests such
        // irregular edges every time): nearly all edges stay manifold.
        let half = decimate(&noisy.0, &noisy.1, 0.25);
        let directed = directed_edges(&half.1);
        let manifold = directed.iter().filter(|&(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1)).count();
        assert!(manifold as f32 > 0.99 * directed.len() as f32, "{manifold} of {} edges manifold", directed.len());
        assert!(half.1.iter().flatten().all(|&v| (v as usize) < half.0.len()));
        assert!((half.1.len() as f32 / 5_000.0 - 1.0).abs() < 0.05, "{} triangles", half.1.len());
    }
}
