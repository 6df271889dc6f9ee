//! How far box-against-depth occlusion culling can go, measured on the CPU from a frame's
//! unculled depth buffer: whether a world-space box is behind the depth over every pixel its
//! projection reaches, tested at full resolution (the limit of any test of a box against the
//! frame's depth) and as `crowd_culling`'s second phase tests it (the farthest depth over at
//! most 8 × 8 texels of a max pyramid). With boxes around a
//! meshlet's skinned vertices of this very pose, the two split the distance between the
//! meshlets occlusion culling draws and the ID-buffer oracle into what the bounds' looseness
//! costs, what the pyramid's coarseness costs, and what no box test can remove (a meshlet
//! whose box reaches past an occluder's silhouette though its triangles do not). Per
//! triangle, the same test says what a per-triangle pass over the survivors could keep.
//!
//! Depth is forward (near 0, far 1), as skinlet-lab draws.

use glam::{Affine3A, Mat4, Vec3};
use rayon::prelude::*;
use skinlet::bake::Baked;
use skinlet::cull::Camera;

/// A depth buffer and its max pyramid (level 0 the buffer; level k + 1 the farthest of the up
/// to 2 × 2 texels of level k, as `pyramid.wgsl` builds it).
pub struct DepthPyramid {
    levels: Vec<(u32, u32, Vec<f32>)>,
}

/// How a box's screen rectangle is tested.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rect {
    /// The pixels whose centers the box's projection covers, at full resolution.
    Exact,
    /// As `crowd_culling.wgsl` does: the pixel centers within the rectangle widened by 1/16
    /// pixel, at the level where they span at most 8 × 8 texels.
    Pyramid,
}

impl DepthPyramid {
    /// `depth`: `width` × `height` values, rows top to bottom.
    pub fn new(width: u32, height: u32, depth: Vec<f32>) -> DepthPyramid {
        let mut levels = vec![(width, height, depth)];
        while let Some((w, h, d)) = levels.last().filter(|l| l.0 > 1 || l.1 > 1) {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let at = |x: u32, y: u32| d[(y.min(h - 1) * w + x.min(w - 1)) as usize];
            let next = (0..nh)
                .flat_map(|y| (0..nw).map(move |x| (x, y)))
                .map(|(x, y)| {
                    at(2 * x, 2 * y).max(at(2 * x + 1, 2 * y)).max(at(2 * x, 2 * y + 1)).max(at(2 * x + 1, 2 * y + 1))
                })
                .collect();
            levels.push((nw, nh, next));
        }
        DepthPyramid { levels }
    }

    /// Whether every point of the box `lo`..`hi` is behind the depth over its screen
    /// rectangle (a box reaching behind the eye's plane is not; a box off screen or covering no
    /// pixel center is).
    pub fn hidden(&self, view_proj: &Mat4, lo: Vec3, hi: Vec3, rect: Rect) -> bool {
        let (mut a, mut b) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 != 0 { hi.x } else { lo.x },
                if k & 2 != 0 { hi.y } else { lo.y },
                if k & 4 != 0 { hi.z } else { lo.z },
            );
            let clip = *view_proj * p.extend(1.0);
            if clip.w <= 0.0 {
                return false;
            }
            let ndc = clip.truncate() / clip.w;
            (a, b) = (a.min(ndc), b.max(ndc));
        }
        let (w, h, _) = &self.levels[0];
        let (w, h) = (*w as f32, *h as f32);
        let (px0, px1) = ((a.x * 0.5 + 0.5) * w, (b.x * 0.5 + 0.5) * w);
        let (py0, py1) = ((0.5 - b.y * 0.5) * h, (0.5 - a.y * 0.5) * h);
        let (x0, x1, y0, y1) = match rect {
            // Pixel centers (i + 0.5) inside [p0, p1].
            Rect::Exact => ((px0 - 0.5).ceil(), (px1 - 0.5).floor(), (py0 - 0.5).ceil(), (py1 - 0.5).floor()),
            // Widened by 1/16 pixel (rasterizers snap vertices to 1/16 pixel or finer).
            Rect::Pyramid => {
                let e = 0.5 + 1.0 / 16.0;
                ((px0 - e).ceil(), (px1 - 0.5 + 1.0 / 16.0).floor(), (py0 - e).ceil(), (py1 - 0.5 + 1.0 / 16.0).floor())
            }
        };
        let (x0, y0) = (x0.max(0.0), y0.max(0.0));
        let (x1, y1) = (x1.min(w - 1.0), y1.min(h - 1.0));
        if x0 > x1 || y0 > y1 {
            return true;
        }
        let (x0, x1, y0, y1) = (x0 as u32, x1 as u32, y0 as u32, y1 as u32);
        let mut level = 0;
        if rect == Rect::Pyramid {
            while level + 1 < self.levels.len()
                && ((x1 >> level) - (x0 >> level) > 7 || (y1 >> level) - (y0 >> level) > 7)
            {
                level += 1;
            }
        }
        let (lw, lh, d) = &self.levels[level];
        let mut far = 0f32;
        for y in (y0 >> level)..=(y1 >> level).min(lh - 1) {
            for x in (x0 >> level)..=(x1 >> level).min(lw - 1) {
                far = far.max(d[(y * lw + x) as usize]);
            }
        }
        a.z > far
    }
}

/// Meshlets a box test against a frame's unculled `depth` could keep of `survivors` ((instance,
/// meshlet) pairs of `baked`'s meshlets), instance `i` skinned by `poses[i]` (world-space
/// skinning matrices and morph weights): those whose box around their skinned vertices of this
/// very pose is not hidden at full resolution, the same on the pyramid ([`Rect::Pyramid`]),
/// and those with a front-facing triangle whose box is not hidden at full resolution (what a
/// per-triangle pass could keep at best). The instances are skinned in parallel.
pub fn pose_limits(
    baked: &Baked,
    poses: &[(&[Affine3A], &[f32])],
    survivors: &[[u32; 2]],
    depth: &DepthPyramid,
    camera: &Camera,
) -> skinlet::Result<[usize; 3]> {
    let mut by_instance = survivors.to_vec();
    by_instance.sort_unstable();
    let groups: Vec<&[[u32; 2]]> = by_instance.chunk_by(|a, b| a[0] == b[0]).collect();
    let counts = groups
        .par_iter()
        .map(|group| -> skinlet::Result<[usize; 3]> {
            let (matrices, weights) =
                poses.get(group[0][0] as usize).copied().ok_or_else(|| skinlet::Error::Invalid {
                    location: "occlusion limits".into(),
                    message: format!("no pose for instance {}", group[0][0]),
                })?;
            let mut positions = vec![Vec3::ZERO; baked.mesh.positions.len()];
            skinlet::skinning::skin_mesh(&baked.mesh, weights, matrices, &mut positions, &mut [])?;
            let mut kept = [0; 3];
            for &[_, m] in group.iter() {
                let meshlet = baked.meshlets.meshlets.get(m as usize).ok_or_else(|| skinlet::Error::Invalid {
                    location: "occlusion limits".into(),
                    message: format!("no meshlet {m}"),
                })?;
                let start = meshlet.vertex_offset as usize;
                let indices = &baked.meshlets.vertices[start..start + meshlet.vertex_count as usize];
                let (lo, hi) = bounds(&positions, indices);
                kept[0] += !depth.hidden(&camera.view_proj, lo, hi, Rect::Exact) as usize;
                kept[1] += !depth.hidden(&camera.view_proj, lo, hi, Rect::Pyramid) as usize;
                let seen = baked.meshlets.mesh_triangles(meshlet).any(|t| {
                    let [p0, p1, p2] = t.map(|v| positions[v as usize]);
                    skinlet::cull::triangle::facing(p0, p1, p2, camera.projection) < 0.0
                        && !depth.hidden(&camera.view_proj, p0.min(p1).min(p2), p0.max(p1).max(p2), Rect::Exact)
                });
                kept[2] += seen as usize;
            }
            Ok(kept)
        })
        .collect::<skinlet::Result<Vec<_>>>()?;
    Ok(counts.iter().fold([0; 3], |a, k| [a[0] + k[0], a[1] + k[1], a[2] + k[2]]))
}

/// The box around the points of `positions` that `indices` picks.
pub fn bounds(positions: &[Vec3], indices: &[u32]) -> (Vec3, Vec3) {
    indices.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
        let p = positions[i as usize];
        (lo.min(p), hi.max(p))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall at depth 0.5 over pixels 0..=14 of a 32 × 8 image, far elsewhere; boxes
    /// projected orthographically (view_proj = identity, NDC z = depth; pixel x = 16 (x + 1)).
    fn wall() -> DepthPyramid {
        let depth = (0..8).flat_map(|_| (0..32).map(|x| if x < 15 { 0.5 } else { 1.0 })).collect();
        DepthPyramid::new(32, 8, depth)
    }

    #[test]
    fn a_box_behind_the_wall_is_hidden_only_where_the_wall_covers_it() {
        let (p, m) = (wall(), Mat4::IDENTITY);
        let x = |pixel: f32| pixel / 16.0 - 1.0;
        // Pixels 2.2..12.6: centers 2..=12, behind the wall at full resolution.
        let (lo, hi) = (Vec3::new(x(2.2), -0.5, 0.6), Vec3::new(x(12.6), 0.5, 0.7));
        assert!(p.hidden(&m, lo, hi, Rect::Exact));
        // In front of the wall: not hidden.
        assert!(!p.hidden(&m, lo.with_z(0.4), hi, Rect::Exact));
        // Reaching pixel 15's center: not hidden.
        assert!(!p.hidden(&m, lo, hi.with_x(x(15.8)), Rect::Exact));
        // The pyramid: 11 centers span more than 8 texels, so level 1, texels 1..=6 (pixels
        // 2..=13): all wall.
        assert!(p.hidden(&m, lo, hi, Rect::Pyramid));
        // Centers 2..=14: level 1's texel 7 reaches pixel 15, past the wall.
        assert!(!p.hidden(&m, lo, hi.with_x(x(14.7)), Rect::Pyramid));
        assert!(p.hidden(&m, lo, hi.with_x(x(14.7)), Rect::Exact));
        // Between two pixel centers: covers none, so nothing it could draw is visible.
        assert!(p.hidden(&m, Vec3::new(x(20.6), -0.5, 0.9), Vec3::new(x(21.4), 0.5, 1.0), Rect::Exact));
    }

    #[test]
    fn a_box_behind_the_eye_is_never_hidden() {
        let m = Mat4::perspective_rh(1.0, 2.0, 0.1, 10.0);
        assert!(!wall().hidden(&m, Vec3::new(-1.0, -1.0, -5.0), Vec3::new(1.0, 1.0, 0.5), Rect::Exact));
    }
}
