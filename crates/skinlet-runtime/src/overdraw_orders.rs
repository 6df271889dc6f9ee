//! The run-time half of animated overdraw orders (Han & Sander 2016, section 3.3): a bake
//! stores a few index buffers, each ordered for low overdraw over a cluster of (keyframe,
//! viewpoint) nodes, and a table that names the buffer for each keyframe and view direction;
//! [`Orders::select`] picks the one to draw. The baker (`skinlet::overdraw`) clusters the
//! nodes and orders the buffers.

use glam::{Mat4, Vec3};

/// Where viewpoints sit: on the sphere of `3 × radius` around `center`, looking at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Framing {
    pub center: Vec3,
    pub radius: f32,
}

impl Framing {
    /// The bounding sphere (box center, farthest point) of every keyframe's positions.
    pub fn of(keyframes: &[Vec<Vec3>]) -> Framing {
        let all = keyframes.iter().flatten();
        let (lo, hi) = all.clone().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
        let center = if lo.x <= hi.x { (lo + hi) / 2.0 } else { Vec3::ZERO };
        let radius = all.map(|p| p.distance(center)).fold(0.0f32, f32::max).max(1e-6);
        Framing { center, radius }
    }

    /// The eye for a unit direction `dir` at `distance` radii.
    pub fn eye(&self, dir: Vec3, distance: f32) -> Vec3 {
        self.center + dir * self.radius * distance
    }

    /// A perspective view-projection from `eye` that frames the bounding sphere.
    pub fn view_proj(&self, eye: Vec3) -> Mat4 {
        let d = eye.distance(self.center).max(self.radius * 1.01);
        let fov = 2.0 * (self.radius / d).clamp(-1.0, 1.0).asin() * 1.05;
        let up = if (eye - self.center).normalize_or_zero().y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        Mat4::perspective_rh(fov, 1.0, (d - self.radius) * 0.5, d + self.radius * 2.0)
            * Mat4::look_at_rh(eye, self.center, up)
    }
}

/// The run-time table (section 3.3): for each keyframe and each (polar, azimuth) cell, the
/// buffer of the nearest stored viewpoint.
#[derive(Clone, Debug, PartialEq)]
pub struct Lookup {
    pub keyframes: usize,
    pub polar: usize,
    pub azimuth: usize,
    pub table: Vec<u8>,
}

impl Lookup {
    /// The buffer for keyframe `f` seen from unit direction `dir` (model space, from the
    /// model's center toward the eye), both rounded to the nearest stored value.
    pub fn get(&self, f: usize, dir: Vec3) -> u8 {
        let dir = dir.normalize_or(Vec3::Z);
        let theta = dir.z.clamp(-1.0, 1.0).acos();
        let phi = dir.y.atan2(dir.x).rem_euclid(std::f32::consts::TAU);
        let i = (theta / std::f32::consts::PI * (self.polar - 1).max(1) as f32).round() as usize;
        let j = (phi / std::f32::consts::TAU * self.azimuth as f32).round() as usize % self.azimuth.max(1);
        let f = f.min(self.keyframes.saturating_sub(1));
        // An empty table (no keyframes) selects buffer 0.
        let cell = (f * self.polar + i.min(self.polar.saturating_sub(1))) * self.azimuth + j;
        self.table.get(cell).copied().unwrap_or(0)
    }
}

/// What a bake stores for run-time selection: the buffers, the keyframes they were
/// clustered for, the framing the viewpoints were placed with, and the lookup table.
#[derive(Clone, Debug, PartialEq)]
pub struct Orders {
    pub lambda: f32,
    /// (clip index among the baked clips, time) of each keyframe.
    pub keyframes: Vec<(u32, f32)>,
    pub framing: Framing,
    pub buffers: Vec<Vec<[u32; 3]>>,
    pub lookup: Lookup,
}

impl Orders {
    /// Lookup cells per keyframe the baker stores: 37 polar × 72 azimuth (5°).
    pub const CELLS: (usize, usize) = (37, 72);

    /// The buffer to draw for `clip` at `time` seen from `eye` (model space): the nearest
    /// stored keyframe of that clip (the first keyframe when the clip has none), then the
    /// lookup by the direction from the model's center to the eye.
    pub fn select(&self, clip: u32, time: f32, eye: Vec3) -> usize {
        let f = (0..self.keyframes.len())
            .filter(|&f| self.keyframes[f].0 == clip)
            .min_by(|&a, &b| (self.keyframes[a].1 - time).abs().total_cmp(&(self.keyframes[b].1 - time).abs()))
            .unwrap_or(0);
        self.lookup.get(f, (eye - self.framing.center).normalize_or(Vec3::Z)) as usize
    }
}

/// The unit direction at polar angle `theta` from +z and azimuth `phi` from +x toward +y.
pub fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}
