//! Conservative spatio-temporal bounds of skinned vertices (Unterguggenberger et al. 2021,
//! "Conservative Meshlet Bounds for Robust Culling of Skinned Meshes", sections 3.1–3.3).
//!
//! [`motion`] bounds one node's local transform over a time interval inside one key
//! segment (LINEAR: translation and scale intervals and the exact slerp arc; STEP: both key
//! values; CUBICSPLINE: exact cubic ranges and interval arithmetic on the rotation).
//! [`vertex`] carries a vertex through the hierarchy, step by step from each influencing
//! bone to a target bone (up to the common ancestor, then down with inverse transforms,
//! eq. 2), and takes the weighted Minkowski sum over influences (section 3.3).
//!
//! Guarantee: for every time t in the interval, the reference-skinned position of the
//! vertex, expressed in the target bone's space (`global(target, t)⁻¹ · p(t)`), lies in the
//! returned box, including the f32 rounding of the sampled pose ([`motion::SAMPLING_ROUNDING`]
//! per step); [`sphere_cone`] then adds [`INFLATE`] for the rounding of the skinning itself.
//! [`sphere_cone`] builds spheres and normal cones from these boxes, [`verify`] checks them
//! against dense sampling. Tested on random hierarchies and clips and on the shared assets.

pub mod cone;
pub mod envelope;
pub mod lod_error;
pub mod lod_verify;
pub mod motion;
pub mod part_windows;
pub mod refine;
pub mod sphere_cone;
pub mod verify;
pub mod vertex;

use glam::DVec3;

/// Relative margin for f32 rounding (of stored boxes and of skinning itself).
pub use skinlet_runtime::joint_boxes::INFLATE;

/// An axis-aligned box in f64. Empty boxes have `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: DVec3::INFINITY, max: DVec3::NEG_INFINITY };
    pub const EVERYWHERE: Aabb = Aabb { min: DVec3::NEG_INFINITY, max: DVec3::INFINITY };

    pub fn point(p: DVec3) -> Aabb {
        Aabb { min: p, max: p }
    }

    pub fn extend(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    pub fn corners(&self) -> [DVec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            DVec3::new(a.x, a.y, a.z),
            DVec3::new(b.x, a.y, a.z),
            DVec3::new(a.x, b.y, a.z),
            DVec3::new(b.x, b.y, a.z),
            DVec3::new(a.x, a.y, b.z),
            DVec3::new(b.x, a.y, b.z),
            DVec3::new(a.x, b.y, b.z),
            DVec3::new(b.x, b.y, b.z),
        ]
    }

    /// The box of the points `m·x`, x in the box (the affine image of a box is spanned by
    /// its corners); a point maps to a point.
    pub fn transformed(&self, m: &glam::DMat4) -> Aabb {
        if self.min == self.max {
            return Aabb::point(m.transform_point3(self.min));
        }
        self.corners().iter().fold(Aabb::EMPTY, |mut acc, &c| {
            acc.extend(m.transform_point3(c));
            acc
        })
    }

    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Grown by `rel` times its largest coordinate magnitude (at least an absolute `rel`).
    pub fn inflated(&self, rel: f64) -> Aabb {
        let m = self.min.abs().max(self.max.abs()).max_element().max(1.0);
        let d = DVec3::splat(rel * m);
        Aabb { min: self.min - d, max: self.max + d }
    }

    /// Largest distance from `c` to any point of the box.
    pub fn max_distance(&self, c: DVec3) -> f64 {
        let far = (self.min - c).abs().max((self.max - c).abs());
        far.length()
    }
}
