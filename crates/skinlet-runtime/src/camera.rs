//! The camera culling needs: a view-projection matrix, its six frustum planes (Gribb &
//! Hartmann's extraction, normalized), and the eye position (perspective) or view direction
//! (orthographic) that backface tests need. Conventions are glam's right-handed ones with
//! depth in [0, 1] (`Mat4::perspective_rh`, `Mat4::orthographic_rh`); an engine's own matrix
//! goes through [`Camera::from_view_proj`].

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

    /// A camera from an engine's own view-projection matrix (glam conventions: clip volume
    /// `-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`) and what the backface test needs: the eye, or the unit
    /// view direction. Errors when the matrix is not finite or a frustum plane is degenerate,
    /// or the eye or direction is not finite (a direction must have unit length).
    pub fn from_view_proj(view_proj: Mat4, projection: Projection) -> Result<Camera> {
        let planes = planes(&view_proj);
        if !view_proj.is_finite() || !planes.iter().all(|p| p.is_finite()) {
            return Err(Error::invalid("camera", "the view-projection matrix is not finite or has a degenerate plane"));
        }
        let ok = match projection {
            Projection::Perspective { eye } => eye.is_finite(),
            Projection::Orthographic { dir } => dir.is_finite() && (dir.length() - 1.0).abs() < 1e-3,
        };
        if !ok {
            return Err(Error::invalid("camera", format!("{projection:?}: need a finite eye or a unit direction")));
        }
        Ok(Camera { view_proj, planes, projection })
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

/// The six planes of `view_proj`'s clip volume (`-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`), normalized.
pub fn planes(view_proj: &Mat4) -> [Vec4; 6] {
    let r = |i: usize| view_proj.row(i);
    let raw = [r(3) + r(0), r(3) - r(0), r(3) + r(1), r(3) - r(1), r(2), r(3) - r(2)];
    raw.map(|p| p / p.truncate().length())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_agree_with_clip_space() {
        // A point is inside every plane exactly when its clip coordinates are in the volume.
        let cams = [
            Camera::perspective(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 1.5, 0.1, 50.0).unwrap(),
            Camera::orthographic(Vec3::new(-3.0, 1.0, 2.0), Vec3::X, Vec3::Y, 4.0, 3.0, 0.5, 20.0).unwrap(),
        ];
        let mut s = 12345u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 * 40.0 - 20.0
        };
        for cam in cams {
            for _ in 0..20_000 {
                let p = Vec3::new(next(), next(), next());
                let c = cam.view_proj * p.extend(1.0);
                let in_clip = c.w > 0.0 && c.x.abs() <= c.w && c.y.abs() <= c.w && c.z >= 0.0 && c.z <= c.w;
                let dists = cam.planes.map(|pl| pl.truncate().dot(p) + pl.w);
                let in_planes = dists.iter().all(|&d| d >= 0.0);
                let margin = dists.iter().map(|d| d.abs()).fold(f32::INFINITY, f32::min);
                if margin > 1e-3 {
                    assert_eq!(in_clip, in_planes, "{p} {c} {dists:?}");
                }
            }
        }
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
