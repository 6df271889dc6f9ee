//! Which clusters of a bake's LOD hierarchy (`LODC`, [`crate::bake_view::LodView`]) an
//! instance draws: the pixel threshold, projected at the nearest depth of a sphere or box
//! holding the whole instance, gives the instance one error threshold in scene units, and the
//! cut at that threshold is drawn (Nanite's rule with one distance per instance).
//!
//! Guarantee: a group's error bounds how far its clusters get from the full detail mesh at
//! every pose of the baked clips. Two points `e` apart, both at view depth at least `z`, land
//! at most `f·k·e / z` pixels apart on screen inside the frustum of a perspective camera of
//! focal length `f` pixels (the projection's Jacobian has norm `f/z · √(1 + x² + y²)` at view
//! direction `(x, y, 1)`, that is `f/z` times the point's distance from the eye over its
//! depth; `k` bounds that ratio over the segment: at the frustum's corners, or over the
//! instance's sphere grown by the error where that is less). A point of the cut is within `e`
//! of the full detail mesh, so at depth at least `z − e`, `z` the nearest depth of the
//! instance's sphere or box (the box's is nearer the instance where it is known); with
//! `e = pixels · z / (f·k + pixels)` no point of the cut is displaced by more than `pixels`
//! from where full detail draws it. One threshold per instance makes the cut
//! crack-free whatever the distances: every cluster decides with its own group's error and its
//! parent group's, both monotone up the hierarchy.

use glam::Vec3;

/// What the threshold needs of a perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodCamera {
    pub eye: Vec3,
    /// The unit view direction.
    pub forward: Vec3,
    /// Focal length in pixels: `viewport height / (2 tan(fov_y / 2))`.
    pub focal_px: f32,
    /// `√(1 + tan²(fov_x / 2) + tan²(fov_y / 2))`: how much more a displacement moves on
    /// screen at the frustum's corners than on its axis, at the same depth.
    pub corner: f32,
}

impl LodCamera {
    /// A camera at `eye` looking along `forward` (normalized here) with vertical field of view
    /// `fov_y` (radians), `aspect` = width / height, over an image `height` pixels tall.
    pub fn perspective(eye: Vec3, forward: Vec3, fov_y: f32, aspect: f32, height: u32) -> LodCamera {
        let t = (fov_y / 2.0).tan();
        let corner = (1.0 + t * t * (1.0 + aspect * aspect)).sqrt();
        LodCamera { eye, forward: forward.normalize_or_zero(), focal_px: height as f32 / (2.0 * t), corner }
    }

    /// The error threshold, in the scene units of the bake, at which an instance draws its
    /// cut: `pixels` (the largest screen displacement allowed) at the nearest view depth of the
    /// sphere (`center`, `radius`, world space) that holds the instance, drawn at `scale` times
    /// the bake's size (its world matrix's largest column length). 0 (full detail) where the
    /// sphere reaches the eye's plane, and for inputs that are not finite and positive where
    /// they must be.
    pub fn threshold(&self, pixels: f32, center: Vec3, radius: f32, scale: f32) -> f32 {
        let radius = radius.max(0.0);
        self.threshold_at(pixels, self.forward.dot(center - self.eye) - radius, center, radius, scale)
    }

    /// [`Self::threshold`] for an instance inside the world-space box `min`..`max`: at the
    /// box's nearest view depth, which is nearer the instance than its bounding sphere's
    /// (a character seen from the front is much shallower than it is tall). 0 for a box whose
    /// `min` is not at most its `max`.
    pub fn threshold_box(&self, pixels: f32, min: Vec3, max: Vec3, scale: f32) -> f32 {
        if !min.cmple(max).all() {
            return 0.0;
        }
        let (center, half) = ((min + max) / 2.0, (max - min) / 2.0);
        let depth = self.forward.dot(center - self.eye) - self.forward.abs().dot(half);
        self.threshold_at(pixels, depth, center, half.length(), scale)
    }

    /// The threshold for an instance whose every point is at view depth `depth` or more,
    /// inside the sphere (`center`, `radius`).
    fn threshold_at(&self, pixels: f32, depth: f32, center: Vec3, radius: f32, scale: f32) -> f32 {
        let z = self.forward.dot(center - self.eye);
        // The segments between the cut and full detail lie in the sphere grown by the error,
        // which is at most `pixels · z / (f · scale)` (k ≥ 1, depth ≤ z): there a point's
        // distance from the eye over its depth is at most (|c − eye| + grown) / (z − grown).
        let grown = radius + pixels * z / (self.focal_px * scale);
        let near = ((center - self.eye).length() + grown) / (z - grown);
        let k = if z - grown > 0.0 && near.is_finite() { self.corner.min(near) } else { self.corner };
        let t = pixels * depth / ((self.focal_px * k + pixels) * scale);
        if depth > 0.0 && t.is_finite() && t > 0.0 && pixels > 0.0 && self.corner >= 1.0 { t } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_grows_with_depth_is_zero_near_and_keeps_within_the_pixels() {
        let cam = LodCamera::perspective(Vec3::ZERO, Vec3::NEG_Z, 1.0, 16.0 / 9.0, 1080);
        assert!((cam.focal_px - 540.0 / 0.5f32.tan()).abs() < 1e-2, "{}", cam.focal_px);
        let at = |d: f32| cam.threshold(1.0, Vec3::new(0.0, 0.0, -d), 1.0, 1.0);
        assert_eq!(at(0.5), 0.0, "the sphere reaches the eye's plane");
        assert!(at(10.0) > 0.0 && at(20.0) > at(10.0));
        // Twice as large an instance: about half the threshold in the bake's units (its grown
        // sphere differs a little).
        let big = cam.threshold(1.0, Vec3::new(0.0, 0.0, -11.0), 1.0, 2.0);
        assert!((big * 2.0 - at(11.0)).abs() < 1e-2 * at(11.0), "{big} {}", at(11.0));
        // A full detail point at a frustum corner in a sphere there, and a cut point the
        // threshold away in any direction: at most a pixel apart on screen.
        let (tx, ty) = ((0.5f32).tan() * 16.0 / 9.0, (0.5f32).tan());
        let e = cam.threshold(1.0, Vec3::new(tx, ty, -1.0) * 11.0, 1.6, 1.0);
        let screen = |p: Vec3| glam::Vec2::new(p.x / -p.z, p.y / -p.z) * cam.focal_px;
        let p = Vec3::new(tx * 10.0, ty * 10.0, -10.0);
        let mut worst = 0.0f32;
        for i in 0..32 {
            for j in 0..64 {
                let (polar, azimuth) =
                    (i as f32 / 31.0 * std::f32::consts::PI, j as f32 / 64.0 * std::f32::consts::TAU);
                let dir = Vec3::new(polar.sin() * azimuth.cos(), polar.sin() * azimuth.sin(), polar.cos());
                worst = worst.max(screen(p).distance(screen(p + dir * e)));
            }
        }
        assert!(worst <= 1.0 + 1e-3 && worst > 0.5, "{worst} pixels");
        // On the axis, far away: about `corner` times the corner's threshold.
        let ratio = at(1000.0) / cam.threshold(1.0, Vec3::new(tx, ty, -1.0) * 1000.0, 1.0, 1.0);
        assert!((ratio - cam.corner).abs() < 0.02 * cam.corner, "{ratio} vs {}", cam.corner);
        assert_eq!(cam.threshold(f32::NAN, Vec3::Z * -5.0, 1.0, 1.0), 0.0);
        assert_eq!(cam.threshold(1.0, Vec3::Z * 5.0, 1.0, 1.0), 0.0, "behind the eye");
    }

    proptest::proptest! {
        /// Random cameras, spheres, scales and pixel counts: a point of the sphere and a point
        /// the threshold away from it, both inside the frustum, land at most `pixels` apart.
        #[test]
        fn a_point_the_threshold_away_moves_at_most_the_pixels(
            fov in 0.2f32..2.2, aspect in 0.4f32..3.0, height in 64u32..4096,
            at in proptest::array::uniform3(-1.0f32..1.0), depth in 0.5f32..300.0, radius in 0.01f32..5.0,
            scale in 0.25f32..4.0, pixels in 0.25f32..8.0,
            inside in proptest::array::uniform3(-1.0f32..1.0), dir in proptest::array::uniform3(-1.0f32..1.0),
        ) {
            let cam = LodCamera::perspective(Vec3::ZERO, Vec3::NEG_Z, fov, aspect, height);
            let (ty, tx) = ((fov / 2.0).tan(), (fov / 2.0).tan() * aspect);
            let center = Vec3::new(at[0] * tx * depth, at[1] * ty * depth, -depth);
            let e = cam.threshold(pixels, center, radius, scale) * scale;
            let p = center + Vec3::from(inside).clamp_length_max(1.0) * radius;
            let q = p + Vec3::from(dir).normalize_or(Vec3::X) * e;
            let in_frustum = |v: Vec3| v.z < 0.0 && v.x.abs() <= tx * -v.z && v.y.abs() <= ty * -v.z;
            if e > 0.0 && in_frustum(p) && in_frustum(q) {
                let screen = |v: Vec3| glam::DVec2::new(v.x as f64 / -v.z as f64, v.y as f64 / -v.z as f64) * cam.focal_px as f64;
                let moved = screen(p).distance(screen(q));
                proptest::prop_assert!(moved <= pixels as f64 * (1.0 + 1e-4), "{moved} px for {pixels}");
            }
        }

        /// The same for boxes (any shape, any camera direction): a point of the box and a
        /// point the box's threshold away land at most `pixels` apart inside the frustum; the
        /// box's threshold is at least its bounding sphere's.
        #[test]
        fn a_point_the_box_threshold_away_moves_at_most_the_pixels(
            fov in 0.2f32..2.2, aspect in 0.4f32..3.0, height in 64u32..4096,
            look in proptest::array::uniform3(-1.0f32..1.0), eye in proptest::array::uniform3(-10.0f32..10.0),
            at in proptest::array::uniform3(-1.0f32..1.0), depth in 0.5f32..300.0,
            half in proptest::array::uniform3(0.0f32..3.0),
            scale in 0.25f32..4.0, pixels in 0.25f32..8.0,
            inside in proptest::array::uniform3(-1.0f32..1.0), dir in proptest::array::uniform3(-1.0f32..1.0),
        ) {
            let forward = Vec3::from(look).normalize_or(Vec3::NEG_Z);
            let eye = Vec3::from(eye);
            let cam = LodCamera::perspective(eye, forward, fov, aspect, height);
            let right = forward.any_orthonormal_vector();
            let up = right.cross(forward);
            let (ty, tx) = ((fov / 2.0).tan(), (fov / 2.0).tan() * aspect);
            let center = eye + forward * depth + right * (at[0] * tx * depth) + up * (at[1] * ty * depth);
            let half = Vec3::from(half);
            let e = cam.threshold_box(pixels, center - half, center + half, scale) * scale;
            proptest::prop_assert!(e >= cam.threshold(pixels, center, half.length(), scale) * scale * (1.0 - 1e-5));
            // View coordinates: x right, y up, z the depth along `forward`.
            let view = |v: Vec3| { let d = v - eye; Vec3::new(d.dot(right), d.dot(up), d.dot(forward)) };
            let in_frustum = |v: Vec3| v.z > 0.0 && v.x.abs() <= tx * v.z && v.y.abs() <= ty * v.z;
            // A point inside the box, and the box's nearest corner (the worst case).
            let nearest = center - forward.signum() * half;
            for p in [center + Vec3::from(inside) * half, nearest] {
                let q = p + Vec3::from(dir).normalize_or(Vec3::X) * e;
                let (vp, vq) = (view(p), view(q));
                if e > 0.0 && in_frustum(vp) && in_frustum(vq) {
                    let screen = |v: Vec3| glam::DVec2::new(v.x as f64 / v.z as f64, v.y as f64 / v.z as f64) * cam.focal_px as f64;
                    let moved = screen(vp).distance(screen(vq));
                    proptest::prop_assert!(moved <= pixels as f64 * (1.0 + 1e-4), "{moved} px for {pixels}");
                }
            }
        }
    }
}
