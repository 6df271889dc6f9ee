//! Which clusters of a bake's LOD hierarchy (`LODC`, [`crate::bake_view::LodView`]) an
//! instance draws: the pixel threshold, projected at the nearest depth of a sphere holding the
//! whole instance, gives the instance one error threshold in scene units, and the cut at that
//! threshold is drawn (Nanite's rule with one distance per instance).
//!
//! Guarantee: a group's error bounds how far its clusters get from the full detail mesh at
//! every pose of the baked clips. Two points `e` apart, both at view depth at least `z`, land
//! at most `f·k·e / z` pixels apart on screen inside the frustum of a perspective camera of
//! focal length `f` pixels (the projection's Jacobian has norm `f/z · √(1 + x² + y²)` at view
//! direction `(x, y, 1)`; `k` is that root at the frustum's corners). A point of the cut is
//! within `e` of the full detail mesh, so at depth at least `z − e`, `z` the sphere's nearest
//! depth; with `e = pixels · z / (f·k + pixels)` no point of the cut is displaced by more than
//! `pixels` from where full detail draws it. One threshold per instance makes the cut
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
        let depth = self.forward.dot(center - self.eye) - radius.max(0.0);
        let t = pixels * depth / ((self.focal_px * self.corner + pixels) * scale);
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
        // Twice as large an instance: half the threshold in the bake's units.
        let big = cam.threshold(1.0, Vec3::new(0.0, 0.0, -11.0), 1.0, 2.0);
        assert!((big * 2.0 - at(11.0)).abs() < 1e-6);
        // A full detail point at the sphere's nearest depth, at a frustum corner, and a cut
        // point the threshold away in any direction: at most a pixel apart on screen.
        let e = at(11.0);
        let (tx, ty) = ((0.5f32).tan() * 16.0 / 9.0, (0.5f32).tan());
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
        assert_eq!(cam.threshold(f32::NAN, Vec3::Z * -5.0, 1.0, 1.0), 0.0);
        assert_eq!(cam.threshold(1.0, Vec3::Z * 5.0, 1.0, 1.0), 0.0, "behind the eye");
    }
}
