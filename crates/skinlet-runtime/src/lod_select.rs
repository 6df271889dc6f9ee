//! Which clusters of a bake's LOD hierarchy (`LODC`, [`crate::bake_view::LodView`]) an
//! instance draws: the pixel threshold, projected at the nearest point of a sphere holding the
//! whole instance, gives the instance one error threshold in scene units, and the cut at that
//! threshold is drawn (Nanite's rule with one distance per instance).
//!
//! Guarantee: a group's error bounds how far its clusters get from the full detail mesh at
//! every pose of the baked clips, and no point of the instance is nearer the eye than the
//! sphere's nearest point, so no point of the drawn cut is displaced by more than
//! `pixels` pixels on screen from where the full detail mesh would draw it (a displacement `d`
//! at distance `z` covers at most `d · focal / z` pixels, and `z` is at least the distance to
//! the sphere). One threshold per instance makes the cut crack-free whatever the distances:
//! every cluster decides with its own group's error and its parent group's, both monotone up
//! the hierarchy.

use glam::Vec3;

/// The error threshold, in the scene units of the bake, at which an instance draws its cut:
/// `pixels` (the largest screen displacement allowed) projected at the nearest point of the
/// sphere (`center`, `radius`, in world space) that holds the instance, for a camera at `eye`
/// whose focal length is `focal_px` pixels (`viewport height / (2 tan(fov_y / 2))` for a
/// perspective camera), the instance drawn at `scale` times the bake's size (its world
/// matrix's largest column length). 0 (full detail) with the eye inside the sphere, and for
/// inputs that are not finite and positive where they must be.
pub fn error_threshold(pixels: f32, focal_px: f32, eye: Vec3, center: Vec3, radius: f32, scale: f32) -> f32 {
    let distance = eye.distance(center) - radius.max(0.0);
    let t = pixels * distance / (focal_px * scale);
    if distance > 0.0 && t.is_finite() && t > 0.0 && pixels > 0.0 { t } else { 0.0 }
}

/// The focal length in pixels of a perspective projection matrix (`clip_from_view`, any of
/// OpenGL's, Vulkan's, reverse-Z or infinite forms: `m[1][1]` is `1 / tan(fov_y / 2)` in all)
/// for a viewport `height` pixels tall.
pub fn focal_px(clip_from_view: &glam::Mat4, height: u32) -> f32 {
    clip_from_view.y_axis.y.abs() * height as f32 / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_grows_with_distance_and_is_zero_inside() {
        let focal = focal_px(&glam::Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1), 1080);
        assert!((focal - 540.0 / 0.5f32.tan()).abs() < 1e-2, "{focal}");
        let at = |d: f32| error_threshold(1.0, focal, Vec3::ZERO, Vec3::new(0.0, 0.0, -d), 1.0, 1.0);
        assert_eq!(at(0.5), 0.0, "eye inside the sphere");
        assert!(at(10.0) > 0.0 && at(20.0) > at(10.0));
        // A displacement of the threshold at the sphere's nearest point covers one pixel.
        assert!((at(11.0) * focal / 10.0 - 1.0).abs() < 1e-5);
        // Twice as large an instance: half the threshold in the bake's units.
        let big = error_threshold(1.0, focal, Vec3::ZERO, Vec3::new(0.0, 0.0, -11.0), 1.0, 2.0);
        assert!((big * 2.0 - at(11.0)).abs() < 1e-6);
        assert_eq!(error_threshold(f32::NAN, focal, Vec3::ZERO, Vec3::Z * 5.0, 1.0, 1.0), 0.0);
        assert_eq!(error_threshold(1.0, 0.0, Vec3::ZERO, Vec3::Z * 5.0, 1.0, 1.0), 0.0);
    }
}
