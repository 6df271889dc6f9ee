//! Cluster LOD on a crowd: each instance's error threshold (`skinlet_runtime::lod_select`)
//! from the box around its parts' boxes this frame, and how far the silhouettes of an image
//! drawn with LOD are from those of the same frame at full detail.
//!
//! The threshold holds the screen displacement of every point of the instance's cut within the
//! pixels asked for (`LodCamera::threshold_box`), so a silhouette against the background moves by
//! at most that much plus rasterization: a pixel is covered when its center is, and a
//! displaced edge can uncover a pixel center up to half a pixel's diagonal beyond it.

use glam::{Affine3A, Vec3};
use skinlet::Result;
use skinlet::cull::Camera;
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::lod_select::LodCamera;
use skinlet_runtime::part_bounds::{PartBounds, PoseBounds};

/// Per-instance LOD thresholds for one camera and image size.
pub struct CrowdLod {
    bounds: PartBounds,
    parts: usize,
    camera: LodCamera,
}

impl CrowdLod {
    /// For the bake `view` seen by `camera` (a symmetric perspective camera: its near plane's
    /// inward normal is the view direction, its bottom and top planes' normals are `π − fov_y`
    /// apart) over a `width` × `height` image. Errors for an orthographic camera.
    pub fn new(view: &BakeView, camera: &Camera, width: u32, height: u32) -> Result<CrowdLod> {
        let eye = camera.eye().ok_or_else(|| skinlet::Error::Invalid {
            location: "crowd LOD".into(),
            message: "the camera is orthographic (LOD thresholds need a perspective one)".into(),
        })?;
        let (bottom, top) = (camera.planes[2].truncate(), camera.planes[3].truncate());
        let fov = std::f32::consts::PI - bottom.dot(top).clamp(-1.0, 1.0).acos();
        let aspect = width as f32 / height.max(1) as f32;
        let camera = LodCamera::perspective(eye, camera.planes[4].truncate(), fov, aspect, height);
        Ok(CrowdLod { bounds: PartBounds::new(view)?, parts: view.parts().len(), camera })
    }

    /// The threshold, in the bake's units, of an instance whose drivers' world matrices are
    /// `joints`, with morph weights `weights`, posed as `pose` says: `pixels` projected at the
    /// nearest point of the box around its parts' boxes (0, full detail, where the box
    /// reaches the eye's plane). The instance's model matrix is in `joints` (scale 1).
    pub fn threshold(&self, pixels: f32, joints: &[Affine3A], weights: &[f32], pose: PoseBounds) -> f32 {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for p in 0..self.parts {
            let b = self.bounds.part_box(p, &Affine3A::IDENTITY, joints, weights, pose);
            (lo, hi) = (lo.min(b.min), hi.max(b.max));
        }
        self.camera.threshold_box(pixels, lo, hi, 1.0)
    }
}

/// The largest distance, in pixels, from a pixel covered in one of two `width` × `height`
/// coverage masks (row after row) but not in the other to the nearest pixel the other covers:
/// how far a silhouette moved between them (pixel centers; 0 when they agree, infinite when
/// one is empty and the other not).
pub fn silhouette_displacement(a: &[bool], b: &[bool], width: usize, height: usize) -> f32 {
    let one_way = |from: &[bool], to: &[bool]| {
        let d = squared_distances(to, width, height);
        (from.iter().zip(to).zip(&d)).filter(|((f, t), _)| **f && !**t).map(|(_, &d)| d).fold(0.0f64, f64::max)
    };
    one_way(a, b).max(one_way(b, a)).sqrt() as f32
}

/// Per pixel, the squared distance to the nearest covered pixel (exact Euclidean: a 1D pass
/// along rows, then the lower envelope of parabolas along columns, Felzenszwalb and
/// Huttenlocher 2012).
fn squared_distances(mask: &[bool], width: usize, height: usize) -> Vec<f64> {
    let far = f64::INFINITY;
    let mut d = vec![far; width * height];
    for y in 0..height {
        let row = &mask[y * width..(y + 1) * width];
        let mut last = None;
        for x in 0..width {
            if row[x] {
                last = Some(x);
            }
            if let Some(l) = last {
                d[y * width + x] = ((x - l) * (x - l)) as f64;
            }
        }
        last = None;
        for x in (0..width).rev() {
            if row[x] {
                last = Some(x);
            }
            if let Some(l) = last {
                d[y * width + x] = d[y * width + x].min(((l - x) * (l - x)) as f64);
            }
        }
    }
    let (mut column, mut out) = (vec![far; height], vec![far; height]);
    let (mut sites, mut bounds) = (vec![0usize; height], vec![0f64; height + 1]);
    for x in 0..width {
        for y in 0..height {
            column[y] = d[y * width + x];
        }
        lower_envelope(&column, &mut out, &mut sites, &mut bounds);
        for y in 0..height {
            d[y * width + x] = out[y];
        }
    }
    d
}

/// `out[q] = min over p of f[p] + (q − p)²` (f may be infinite).
fn lower_envelope(f: &[f64], out: &mut [f64], sites: &mut [usize], bounds: &mut [f64]) {
    let finite: Vec<usize> = (0..f.len()).filter(|&p| f[p].is_finite()).collect();
    if finite.is_empty() {
        out.fill(f64::INFINITY);
        return;
    }
    let meet = |p: usize, q: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
    let mut k = 0;
    sites[0] = finite[0];
    bounds[0] = f64::NEG_INFINITY;
    bounds[1] = f64::INFINITY;
    for &q in &finite[1..] {
        let mut s = meet(sites[k], q);
        while s <= bounds[k] {
            k -= 1;
            s = meet(sites[k], q);
        }
        k += 1;
        sites[k] = q;
        bounds[k] = s;
        bounds[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while bounds[k + 1] < q as f64 {
            k += 1;
        }
        let p = sites[k];
        *o = (q as f64 - p as f64).powi(2) + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disk(width: usize, height: usize, cx: f64, cy: f64, r: f64) -> Vec<bool> {
        (0..width * height).map(|i| ((i % width) as f64 - cx).hypot((i / width) as f64 - cy) <= r).collect()
    }

    #[test]
    fn squared_distances_match_brute_force() {
        let (w, h) = (23, 17);
        let mask: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 13 == 0).collect();
        let d = squared_distances(&mask, w, h);
        for (i, &di) in d.iter().enumerate() {
            let brute = (0..w * h)
                .filter(|&j| mask[j])
                .map(|j| ((i % w) as f64 - (j % w) as f64).powi(2) + ((i / w) as f64 - (j / w) as f64).powi(2))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(di, brute, "pixel {i}");
        }
    }

    #[test]
    fn a_shifted_disk_moves_its_silhouette_by_the_shift() {
        let (w, h) = (64, 48);
        let a = disk(w, h, 30.0, 24.0, 10.0);
        assert_eq!(silhouette_displacement(&a, &a, w, h), 0.0);
        let b = disk(w, h, 33.0, 24.0, 10.0);
        let moved = silhouette_displacement(&a, &b, w, h);
        assert!((2.5..=3.5).contains(&moved), "{moved}");
        let grown = disk(w, h, 30.0, 24.0, 12.0);
        let d = silhouette_displacement(&a, &grown, w, h);
        assert!((1.5..=2.5).contains(&d), "{d}");
        assert!(silhouette_displacement(&a, &vec![false; w * h], w, h).is_infinite());
    }
}
