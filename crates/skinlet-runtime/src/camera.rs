//! The camera culling needs: a view-projection matrix, its six frustum planes (Gribb &
//! Hartmann's extraction, normalized), and the eye position (perspective) or view direction
//! (orthographic) that backface tests need. [`Camera::from_view_proj`] takes the matrix of
//! any projection with depth in [0, 1] (wgpu's, Vulkan's, D3D's, Metal's: every 3D camera of
//! Bevy's): finite or infinite far plane, reverse-Z, left- or right-handed, perspective or
//! orthographic; [`Camera::from_gl_view_proj`] takes OpenGL's depth in [-1, 1].
//! [`Camera::perspective`] and [`Camera::orthographic`] build glam's right-handed ones.
//!
//! An infinite far plane (and a reverse-Z near plane at infinity) comes out of the extraction
//! as `(0, 0, 0, w)` with `w > 0`: a plane every point is inside. It is stored as a copy of
//! another plane of the frustum, which culls exactly what the other five do and keeps every
//! plane a unit normal for the tests (and the GPU's).

use crate::{Error, Result};
use glam::{Mat4, Vec3, Vec4};

/// A camera for culling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub view_proj: Mat4,
    /// Frustum planes `(n, w)` with unit `n` pointing inside: a point `p` is inside a plane
    /// when `n·p + w ≥ 0`. Order: left, right, bottom, top, near, far.
    pub planes: [Vec4; 6],
    pub projection: Projection,
}

/// What a backface test needs from the projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from the eye: a face is back-facing when `(p − eye)·n ≥ 0`.
    Perspective { eye: Vec3 },
    /// Parallel rays along the unit `dir`: a face is back-facing when `dir·n ≥ 0`.
    Orthographic { dir: Vec3 },
}

impl Camera {
    /// A perspective camera at `eye` looking at `target` (`fov_y` in radians). Errors unless
    /// every value is finite, `0 < fov_y < π`, `aspect > 0`, `0 < near < far`, and `up` is
    /// not along the view direction.
    pub fn perspective(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y: f32,
        aspect: f32,
        near: f32,
        far: f32,
    ) -> Result<Camera> {
        check_view(eye, target, up)?;
        if !(fov_y > 0.0 && fov_y < std::f32::consts::PI && aspect > 0.0 && near > 0.0 && far > near && far.is_finite())
        {
            return Err(Error::invalid(
                "perspective camera",
                format!(
                    "fov_y {fov_y}, aspect {aspect}, near {near}, far {far} (need 0 < fov_y < π, aspect > 0, 0 < near < far)"
                ),
            ));
        }
        let view_proj = Mat4::perspective_rh(fov_y, aspect, near, far) * Mat4::look_at_rh(eye, target, up);
        Camera::from_view_proj(view_proj, Projection::Perspective { eye })
    }

    /// An orthographic camera at `eye` looking at `target`, seeing `half_width` × `half_height`
    /// around the view axis. Errors unless every value is finite, both half sizes are
    /// positive, `near < far`, and `up` is not along the view direction.
    pub fn orthographic(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        half_width: f32,
        half_height: f32,
        near: f32,
        far: f32,
    ) -> Result<Camera> {
        check_view(eye, target, up)?;
        if !(half_width > 0.0 && half_height > 0.0 && far > near && near.is_finite() && far.is_finite())
            || !(half_width.is_finite() && half_height.is_finite())
        {
            return Err(Error::invalid(
                "orthographic camera",
                format!(
                    "half size {half_width} × {half_height}, near {near}, far {far} (need positive sizes, near < far)"
                ),
            ));
        }
        let proj = Mat4::orthographic_rh(-half_width, half_width, -half_height, half_height, near, far);
        let view_proj = proj * Mat4::look_at_rh(eye, target, up);
        Camera::from_view_proj(view_proj, Projection::Orthographic { dir: (target - eye).normalize() })
    }

    /// A camera from an engine's own view-projection matrix, with clip volume
    /// `-w ≤ x, y ≤ w`, `0 ≤ z ≤ w` (wgpu's: any glam projection but the `_gl` ones, Bevy's
    /// `Projection`s), and what the backface test needs: the eye, or the unit view direction.
    /// Errors when the matrix is not finite, a frustum plane is degenerate (a zero normal
    /// that no point is inside), or the eye or direction is not finite (a direction must have
    /// unit length).
    pub fn from_view_proj(view_proj: Mat4, projection: Projection) -> Result<Camera> {
        let planes = planes(&view_proj).ok_or_else(|| {
            Error::invalid("camera", "the view-projection matrix is not finite or has a plane no point is inside")
        })?;
        let ok = match projection {
            Projection::Perspective { eye } => eye.is_finite(),
            Projection::Orthographic { dir } => dir.is_finite() && (dir.length() - 1.0).abs() < 1e-3,
        };
        if !ok {
            return Err(Error::invalid("camera", format!("{projection:?}: need a finite eye or a unit direction")));
        }
        Ok(Camera { view_proj, planes, projection })
    }

    /// [`Camera::from_view_proj`] for OpenGL's clip volume, `-w ≤ z ≤ w` (glam's
    /// `perspective_rh_gl`, `orthographic_rh_gl`, …): the matrix is remapped to depth in
    /// [0, 1] (`z' = (z + w) / 2`), which keeps the same frustum.
    pub fn from_gl_view_proj(view_proj: Mat4, projection: Projection) -> Result<Camera> {
        let to_zero_one =
            Mat4::from_cols(Vec4::X, Vec4::Y, Vec4::new(0.0, 0.0, 0.5, 0.0), Vec4::new(0.0, 0.0, 0.5, 1.0));
        Camera::from_view_proj(to_zero_one * view_proj, projection)
    }

    /// The world-space position the backface test measures from (the eye; for orthographic
    /// cameras none exists and `None` is returned).
    pub fn eye(&self) -> Option<Vec3> {
        match self.projection {
            Projection::Perspective { eye } => Some(eye),
            Projection::Orthographic { .. } => None,
        }
    }
}

/// Eye, target and up of a view: finite, apart, and `up` not along the view direction.
fn check_view(eye: Vec3, target: Vec3, up: Vec3) -> Result<()> {
    let dir = target - eye;
    if !(eye.is_finite() && target.is_finite() && up.is_finite())
        || dir.length_squared() == 0.0
        || dir.cross(up).length_squared() <= 1e-12 * dir.length_squared() * up.length_squared()
    {
        return Err(Error::invalid(
            "camera",
            format!("eye {eye}, target {target}, up {up}: need finite values, eye ≠ target, up not along the view"),
        ));
    }
    Ok(())
}

/// The six planes of `view_proj`'s clip volume (`-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`), normalized,
/// in the order left, right, bottom, top, near, far. A plane at infinity (a zero normal, or
/// one so small against its offset that normalizing overflows) with a non-negative offset
/// holds every point, and is replaced by a copy of the first proper plane. `None` when the
/// matrix is not finite, or such a plane holds no point, or no plane is proper.
pub fn planes(view_proj: &Mat4) -> Option<[Vec4; 6]> {
    if !view_proj.is_finite() {
        return None;
    }
    let r = |i: usize| view_proj.row(i);
    let raw = [r(3) + r(0), r(3) - r(0), r(3) + r(1), r(3) - r(1), r(2), r(3) - r(2)];
    if !raw.iter().all(|p| p.is_finite()) {
        return None;
    }
    let unit = raw.map(|p| Some(p / p.truncate().length()).filter(|u| u.is_finite()));
    let proper = unit.iter().flatten().next().copied()?;
    let mut out = [proper; 6];
    for ((o, u), p) in out.iter_mut().zip(unit).zip(raw) {
        match u {
            Some(u) => *o = u,
            None if p.w >= 0.0 => {}
            None => return None,
        }
    }
    Some(out)
}

/// Every projection glam builds, for the tests: a [`GlamCamera`] for kind `0..GLAM_KINDS` at
/// `eye` looking at `target` (right-handed projections with `look_at_rh`, left-handed ones
/// with `look_at_lh`). `None` where no view exists (the eye at the target, or looking along
/// +Y).
#[cfg(test)]
pub(crate) fn glam_camera(kind: usize, eye: Vec3, target: Vec3) -> Option<GlamCamera> {
    check_view(eye, target, Vec3::Y).ok()?;
    let (rh, lh) = (Mat4::look_at_rh(eye, target, Vec3::Y), Mat4::look_at_lh(eye, target, Vec3::Y));
    let (fov, aspect, near, far) = (1.0, 1.5, 0.1, 30.0);
    let (name, proj, view, ortho, gl) = match kind {
        0 => ("perspective_rh", Mat4::perspective_rh(fov, aspect, near, far), rh, false, false),
        1 => ("perspective_lh", Mat4::perspective_lh(fov, aspect, near, far), lh, false, false),
        2 => ("perspective_rh reverse-Z", Mat4::perspective_rh(fov, aspect, far, near), rh, false, false),
        3 => ("perspective_infinite_rh", Mat4::perspective_infinite_rh(fov, aspect, near), rh, false, false),
        4 => ("perspective_infinite_lh", Mat4::perspective_infinite_lh(fov, aspect, near), lh, false, false),
        5 => (
            "perspective_infinite_reverse_rh",
            Mat4::perspective_infinite_reverse_rh(fov, aspect, near),
            rh,
            false,
            false,
        ),
        6 => (
            "perspective_infinite_reverse_lh",
            Mat4::perspective_infinite_reverse_lh(fov, aspect, near),
            lh,
            false,
            false,
        ),
        7 => ("frustum_rh", Mat4::frustum_rh(-0.05, 0.2, -0.1, 0.08, near, far), rh, false, false),
        8 => ("frustum_lh", Mat4::frustum_lh(-0.2, 0.05, -0.08, 0.1, near, far), lh, false, false),
        9 => ("orthographic_rh", Mat4::orthographic_rh(-3.0, 3.0, -2.0, 2.0, near, far), rh, true, false),
        10 => ("orthographic_lh", Mat4::orthographic_lh(-3.0, 2.0, -2.0, 1.0, near, far), lh, true, false),
        11 => ("orthographic_rh reverse-Z", Mat4::orthographic_rh(-3.0, 3.0, -2.0, 2.0, far, near), rh, true, false),
        12 => ("perspective_rh_gl", Mat4::perspective_rh_gl(fov, aspect, near, far), rh, false, true),
        13 => ("frustum_rh_gl", Mat4::frustum_rh_gl(-0.05, 0.2, -0.1, 0.08, near, far), rh, false, true),
        14 => ("orthographic_rh_gl", Mat4::orthographic_rh_gl(-3.0, 3.0, -2.0, 2.0, near, far), rh, true, true),
        _ => return None,
    };
    let projection = if ortho {
        Projection::Orthographic { dir: (target - eye).normalize() }
    } else {
        Projection::Perspective { eye }
    };
    let view_proj = proj * view;
    let camera = if gl {
        Camera::from_gl_view_proj(view_proj, projection)
    } else {
        Camera::from_view_proj(view_proj, projection)
    };
    Some(GlamCamera { name, camera: camera.ok()?, view_proj, gl })
}

/// A camera from one of glam's projections, with the matrix as glam built it.
#[cfg(test)]
pub(crate) struct GlamCamera {
    pub name: &'static str,
    pub camera: Camera,
    pub view_proj: Mat4,
    /// Clip depth in [-1, 1] (OpenGL's), else [0, 1].
    pub gl: bool,
}

#[cfg(test)]
impl GlamCamera {
    /// How deep `p` is inside the clip volume of the matrix glam built (f64): the smallest of
    /// its clip coordinates' margins `w ± x`, `w ± y`, `z` (`z + w` for OpenGL's depth) and
    /// `w − z`, over the magnitude of the coordinates. Positive inside, negative outside.
    pub(crate) fn clip_depth(&self, p: glam::DVec3) -> f64 {
        let c = self.view_proj.as_dmat4() * p.extend(1.0);
        let near = if self.gl { c.z + c.w } else { c.z };
        let m = [c.w + c.x, c.w - c.x, c.w + c.y, c.w - c.y, near, c.w - c.z].into_iter().fold(f64::INFINITY, f64::min);
        m / c.abs().max_element().max(f64::MIN_POSITIVE)
    }
}

/// How many projections [`glam_camera`] builds.
#[cfg(test)]
pub(crate) const GLAM_KINDS: usize = 15;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_agree_with_clip_space() {
        // For every projection glam builds: a point is inside every plane exactly when its
        // clip coordinates are in the volume (away from the boundary).
        let mut s = 12345u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 * 40.0 - 20.0
        };
        let views = [(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO), (Vec3::new(-3.0, 1.0, 2.0), Vec3::X)];
        for kind in 0..GLAM_KINDS {
            for (eye, target) in views {
                let glam = glam_camera(kind, eye, target).unwrap();
                let (name, cam) = (glam.name, glam.camera);
                let (mut inside, mut outside) = (0, 0);
                for _ in 0..20_000 {
                    let p = Vec3::new(next(), next(), next());
                    let depth = glam.clip_depth(p.as_dvec3());
                    let dists = cam.planes.map(|pl| pl.truncate().dot(p) + pl.w);
                    let in_planes = dists.iter().all(|&d| d >= 0.0);
                    let margin = dists.iter().map(|d| d.abs()).fold(f32::INFINITY, f32::min);
                    if margin > 1e-3 && depth.abs() > 1e-4 {
                        assert_eq!(depth > 0.0, in_planes, "{name}: {p} {dists:?}");
                        if in_planes { inside += 1 } else { outside += 1 }
                    }
                }
                assert!(inside > 100 && outside > 100, "{name}: {inside} inside, {outside} outside");
                assert!(cam.planes.iter().all(|p| (p.truncate().length() - 1.0).abs() < 1e-5), "{name}");
            }
        }
    }

    #[test]
    fn infinite_planes_hold_every_point() {
        // Bevy's default 3D camera: the reverse-Z near plane at infinity holds everything, and
        // the frustum is the other five planes; the far plane of perspective_infinite_rh too.
        let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y);
        for proj in [Mat4::perspective_infinite_reverse_rh(1.0, 1.0, 0.1), Mat4::perspective_infinite_rh(1.0, 1.0, 0.1)]
        {
            let cam =
                Camera::from_view_proj(proj * view, Projection::Perspective { eye: Vec3::new(0.0, 0.0, 5.0) }).unwrap();
            let far_away = Vec3::new(0.0, 0.0, -1e30);
            assert!(cam.planes.iter().all(|p| p.truncate().dot(far_away) + p.w >= 0.0), "{:?}", cam.planes);
            let behind = Vec3::new(0.0, 0.0, 6.0);
            assert!(cam.planes.iter().any(|p| p.truncate().dot(behind) + p.w < 0.0));
        }
        // A plane at infinity that holds no point is refused.
        let nothing = Mat4::from_cols(Vec4::X, Vec4::Y, Vec4::new(0.0, 0.0, 0.0, 0.0), Vec4::new(0.0, 0.0, -1.0, 1.0));
        assert!(Camera::from_view_proj(nothing, Projection::Perspective { eye: Vec3::ZERO }).is_err());
    }

    #[test]
    fn bad_cameras_are_errors() {
        let (e, t) = (Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO);
        for (fov, aspect, near, far) in [
            (0.0, 1.0, 0.1, 10.0),
            (1.0, 0.0, 0.1, 10.0),
            (1.0, 1.0, 0.0, 10.0),
            (1.0, 1.0, 2.0, 1.0),
            (f32::NAN, 1.0, 0.1, 10.0),
            (1.0, 1.0, 0.1, f32::INFINITY),
        ] {
            assert!(Camera::perspective(e, t, Vec3::Y, fov, aspect, near, far).is_err(), "{fov} {aspect} {near} {far}");
        }
        assert!(Camera::perspective(e, e, Vec3::Y, 1.0, 1.0, 0.1, 10.0).is_err(), "eye at the target");
        assert!(Camera::perspective(e, t, Vec3::Z, 1.0, 1.0, 0.1, 10.0).is_err(), "up along the view");
        assert!(Camera::orthographic(e, t, Vec3::Y, -1.0, 1.0, 0.1, 10.0).is_err());
        assert!(Camera::orthographic(e, t, Vec3::Y, 1.0, 1.0, 5.0, 5.0).is_err());
        assert!(Camera::from_view_proj(Mat4::NAN, Projection::Perspective { eye: e }).is_err());
        assert!(
            Camera::from_view_proj(Mat4::IDENTITY, Projection::Orthographic { dir: Vec3::new(0.0, 0.0, 2.0) }).is_err()
        );
        let cam = Camera::perspective(e, t, Vec3::Y, 1.0, 1.0, 0.1, 10.0).unwrap();
        assert_eq!(Camera::from_view_proj(cam.view_proj, cam.projection).unwrap(), cam);
    }
}
