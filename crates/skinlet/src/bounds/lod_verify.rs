//! Ground-truth check of cluster LOD errors ([`super::lod_error`]): at given poses, reference
//! skinning of every vertex, then per part: every point sampled on every group's clusters
//! (corners, edge midpoints, centroid) within the group's error of the full detail part, and
//! every point of the full detail part within the largest error of three cuts (fine to
//! coarse) of the cut; exact point-triangle distances (a nearest-point routine of its own, not
//! the bound's), found through a uniform grid. The tolerance is the f32 rounding of skinning,
//! 4e-6 of the posed part's largest coordinate. Also measures how tight the errors are.

use crate::clip::Clip;
use crate::meshlet::lod::LodHierarchy;
use crate::model::{Skeleton, Skin, SkinnedMesh, Trs};
use crate::{Error, Result};
use glam::{Affine3A, DVec3, Vec3};
use std::ops::Range;

/// Sample points of a triangle, as barycentric coordinates.
const SAMPLES: [[f64; 3]; 7] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
];

#[derive(Clone, Debug, Default, PartialEq)]
pub struct LodReport {
    pub poses: usize,
    pub points: usize,
    /// Points farther from the other surface than the error allows.
    pub violations: usize,
    /// Largest distance found ÷ the error that bounds it.
    pub max_ratio: f64,
    /// Median over groups: the largest distance from its clusters to the full detail part ÷
    /// its stored error.
    pub median_ratio: f64,
}

/// The poses of clips at times (`None`: the rest pose), as [`verify_errors`] takes them: every
/// node's local transform and the morph weights' values.
pub fn clip_poses(
    skeleton: &Skeleton,
    mesh: &SkinnedMesh,
    times: &[(Option<&Clip>, f32)],
) -> Vec<(Vec<Trs>, Vec<f32>)> {
    (times.iter())
        .map(|&(clip, t)| {
            let (mut locals, mut weights) = (Vec::new(), Vec::new());
            match clip {
                Some(c) => c.sample_locals(skeleton, t, &mut locals),
                None => locals.extend(skeleton.nodes.iter().map(|n| n.rest)),
            }
            mesh.morphs.weights_at(clip, t, &mut weights);
            (locals, weights)
        })
        .collect()
}

/// Checks the hierarchies `parts` (each with the range of its part's triangles in `mesh`) at
/// `poses`: every node's local transform and the morph weights' values ([`clip_poses`]; or
/// poses inside a pose envelope, against the errors within it). Errors when a pose has not
/// one transform per node and one value per morph weight.
pub fn verify_errors(
    skeleton: &Skeleton,
    skin: &Skin,
    poses: &[(Vec<Trs>, Vec<f32>)],
    mesh: &SkinnedMesh,
    parts: &[(Range<u32>, &LodHierarchy)],
) -> Result<LodReport> {
    let n = mesh.positions.len();
    if let Some(k) =
        poses.iter().position(|(l, w)| l.len() != skeleton.nodes.len() || w.len() != mesh.morphs.weights.len())
    {
        return Err(Error::invalid(
            "verify cluster LOD",
            format!("pose {k} has {} local transforms and {} morph weight values", poses[k].0.len(), poses[k].1.len()),
        ));
    }
    for (range, lod) in parts {
        let inside = range.end as usize <= mesh.triangles.len()
            && lod.clusters.iter().all(|c| c.triangles.iter().all(|&v| (v as usize) < n));
        if !inside
            || lod.groups.iter().any(|g| g.made.iter().chain(&g.children).any(|&c| c as usize >= lod.clusters.len()))
        {
            return Err(Error::invalid("verify cluster LOD", "a hierarchy indexes past the mesh or its clusters"));
        }
    }
    let mut report = LodReport { poses: poses.len(), ..LodReport::default() };
    // Per group over all poses: (largest distance to full, error).
    let mut groups: Vec<(f64, f64)> = Vec::new();
    let (mut matrices, mut globals) = (Vec::new(), Vec::new());
    for (pose, (locals, weights)) in poses.iter().enumerate() {
        crate::pose::global_transforms(skeleton, locals, &mut globals);
        crate::pose::skinning_matrices(skin, &globals, &mut matrices);
        let mut posed = vec![Vec3::ZERO; n];
        crate::skinning::skin_mesh(mesh, weights, &matrices as &[Affine3A], &mut posed, &mut [])?;
        let posed: Vec<DVec3> = posed.iter().map(|p| p.as_dvec3()).collect();
        let mut at = 0;
        for (range, lod) in parts {
            let full = as_triangles(&mesh.triangles[range.start as usize..range.end as usize].concat());
            let largest = full.iter().flatten().map(|&v| posed[v as usize].abs().max_element()).fold(0.0, f64::max);
            let rounding = 4e-6 * largest;
            let grid = Grid::new(&posed, full.clone(), 48.0);
            let mut measure = |from: &[[u32; 3]], to: &Grid, bound: f64| -> f64 {
                let mut far = 0.0f64;
                for t in from {
                    let corners = t.map(|v| posed[v as usize]);
                    for b in SAMPLES {
                        let p = b[0] * corners[0] + b[1] * corners[1] + b[2] * corners[2];
                        report.points += 1;
                        match to.nearest_within(p, bound + rounding) {
                            Some(d) => {
                                far = far.max(d);
                                if bound > 0.0 {
                                    report.max_ratio = report.max_ratio.max(d / bound);
                                }
                            }
                            None => report.violations += 1,
                        }
                    }
                }
                far
            };
            let triangles = |clusters: &[u32]| {
                let flat: Vec<u32> =
                    clusters.iter().flat_map(|&c| lod.clusters[c as usize].triangles.iter().copied()).collect();
                as_triangles(&flat)
            };
            for g in &lod.groups {
                let far = measure(&triangles(&g.made), &grid, g.error as f64);
                if pose == 0 {
                    groups.push((far, g.error as f64));
                } else {
                    groups[at].0 = groups[at].0.max(far);
                }
                at += 1;
            }
            let mut errors: Vec<f32> = lod.groups.iter().map(|g| g.error).collect();
            errors.sort_by(f32::total_cmp);
            errors.dedup();
            for k in 0..3.min(errors.len()) {
                let cut = lod.cut(errors[k * (errors.len() - 1) / 2]);
                let worst = cut.iter().map(|&c| lod.cluster_errors(c as usize).0).fold(0.0f32, f32::max);
                measure(&full, &Grid::new(&posed, triangles(&cut), 48.0), worst as f64);
            }
        }
    }
    let mut ratios: Vec<f64> = groups.iter().filter(|g| g.1 > 0.0).map(|g| g.0 / g.1).collect();
    ratios.sort_by(f64::total_cmp);
    report.median_ratio = ratios.get(ratios.len() / 2).copied().unwrap_or(0.0);
    Ok(report)
}

fn as_triangles(flat: &[u32]) -> Vec<[u32; 3]> {
    flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
}

/// Triangles in a uniform grid over a box, for "how near is the nearest triangle" queries.
struct Grid<'a> {
    positions: &'a [DVec3],
    triangles: Vec<[u32; 3]>,
    origin: DVec3,
    cell: f64,
    dims: [i64; 3],
    cells: Vec<Vec<u32>>,
}

impl<'a> Grid<'a> {
    /// A grid of about `resolution` cells along the triangles' box's longest side.
    fn new(positions: &'a [DVec3], triangles: Vec<[u32; 3]>, resolution: f64) -> Grid<'a> {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in &triangles {
            let (a, b) = bounds(t.map(|v| positions[v as usize]));
            (lo, hi) = (lo.min(a), hi.max(b));
        }
        let cell = ((hi - lo).max_element() / resolution).max(1e-9);
        let dims = ((hi - lo) / cell).floor().as_i64vec3().to_array().map(|d| d + 1);
        let mut grid = Grid { positions, triangles, origin: lo, cell, dims, cells: Vec::new() };
        grid.cells = vec![Vec::new(); (dims[0] * dims[1] * dims[2]) as usize];
        for (i, t) in grid.triangles.iter().enumerate() {
            let (a, b) = bounds(t.map(|v| positions[v as usize]));
            let (a, b) = (grid.key(a), grid.key(b));
            for x in a[0]..=b[0] {
                for y in a[1]..=b[1] {
                    for z in a[2]..=b[2] {
                        let index = grid.index([x, y, z]).expect("inside the grid");
                        grid.cells[index].push(i as u32);
                    }
                }
            }
        }
        grid
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        ((p - self.origin) / self.cell).floor().as_i64vec3().to_array()
    }

    fn index(&self, k: [i64; 3]) -> Option<usize> {
        let inside = (0..3).all(|a| (0..self.dims[a]).contains(&k[a]));
        inside.then(|| ((k[2] * self.dims[1] + k[1]) * self.dims[0] + k[0]) as usize)
    }

    /// The distance from `p` to the nearest triangle when one is within `radius`: cells in
    /// growing shells around `p`'s until the nearest found is nearer than any unseen one.
    fn nearest_within(&self, p: DVec3, radius: f64) -> Option<f64> {
        let c = self.key(p);
        let mut best = f64::INFINITY;
        let reach = self.dims.iter().copied().max().unwrap_or(0) + c.iter().map(|k| k.abs()).max().unwrap_or(0);
        // Shells nearer than the grid hold no cell; only the grid's part of a shell is read.
        let first = (0..3).map(|a| (-c[a]).max(c[a] - (self.dims[a] - 1)).max(0)).max().unwrap_or(0);
        let span = |a: usize, k: i64| (-k).max(-c[a])..=k.min(self.dims[a] - 1 - c[a]);
        for k in first..=reach {
            for x in span(0, k) {
                for y in span(1, k) {
                    for z in span(2, k) {
                        if x.abs().max(y.abs()).max(z.abs()) != k {
                            continue;
                        }
                        let Some(index) = self.index([c[0] + x, c[1] + y, c[2] + z]) else { continue };
                        for &t in &self.cells[index] {
                            let corners = self.triangles[t as usize].map(|v| self.positions[v as usize]);
                            best = best.min((closest(&corners, p) - p).length());
                        }
                    }
                }
            }
            // Every triangle not seen yet is in a cell at least k cells away.
            let unseen = k as f64 * self.cell;
            if best <= unseen || unseen > radius {
                break;
            }
        }
        (best <= radius).then_some(best)
    }
}

fn bounds(points: [DVec3; 3]) -> (DVec3, DVec3) {
    (points[0].min(points[1]).min(points[2]), points[0].max(points[1]).max(points[2]))
}

/// The nearest point of a triangle: its projection onto the plane when inside, else the
/// nearest point of its edges.
fn closest(t: &[DVec3; 3], p: DVec3) -> DVec3 {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if n.length_squared() > 0.0 {
        let q = p - n * (p - t[0]).dot(n) / n.length_squared();
        let inside = (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(q - t[k]).dot(n) >= 0.0);
        if inside {
            return q;
        }
    }
    let on_edge = |a: DVec3, b: DVec3| {
        let ab = b - a;
        let s = if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
        a + s * ab
    };
    let candidates = [on_edge(t[0], t[1]), on_edge(t[1], t[2]), on_edge(t[2], t[0])];
    candidates.into_iter().min_by(|a, b| (*a - p).length_squared().total_cmp(&(*b - p).length_squared())).unwrap()
}
