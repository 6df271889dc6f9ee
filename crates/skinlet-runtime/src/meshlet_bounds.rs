//! What the baker stores per meshlet for culling (conservative-bounds paper, sections 4–6): a
//! sphere and a normal cone in the bind space of the meshlet's principal joint, valid over the
//! baked clips (or over a pose envelope), and the culling class that says which tests may use
//! them. The baker (`skinlet::bounds::sphere_cone`) computes them; [`crate::meshlet_cull`] tests them.

use glam::Vec3;

/// One meshlet's bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshletBounds {
    /// Principal joint (index into the skin's joints).
    pub joint: u16,
    /// Sphere center in the joint's bind space.
    pub center: Vec3,
    /// Radius that holds over every interval of the clips the bounds were computed for.
    pub radius: f32,
    /// Radius of the rest-pose sphere.
    pub rest_radius: f32,
    /// Normal cone axis (unit, joint space).
    pub cone_axis: Vec3,
    /// Normal cone half-angle in radians; ≥ π/2 means no useful cone.
    pub cone_angle: f32,
    /// Half-angle of the rest-pose normals alone.
    pub rest_cone_angle: f32,
}

/// Culling class of a meshlet (paper section 6, table 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Class {
    /// Frustum- and backface-cullable.
    Both,
    /// Frustum-cullable only.
    FrustumOnly,
    /// Drawn without culling code.
    None,
}

impl Class {
    pub fn name(self) -> &'static str {
        match self {
            Class::Both => "both",
            Class::FrustumOnly => "frustum-only",
            Class::None => "none",
        }
    }
}

/// The smallest `f32` at least `x` (bounds are stored rounded outward: radii, angles, box
/// maxima; `-round_up(-x)` rounds minima down). Any sign; NaN stays NaN.
pub fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) >= x || x.is_nan() { f } else { f.next_up() }
}

#[cfg(test)]
mod tests {
    use super::round_up;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn round_up_is_the_nearest_f32_not_below(x in prop::num::f64::ANY) {
            let f = round_up(x);
            if x.is_nan() {
                prop_assert!(f.is_nan());
            } else {
                prop_assert!(f as f64 >= x, "{x} rounded to {f}");
                // Nothing smaller is also at least x.
                prop_assert!((f.next_down() as f64) < x || f == f32::NEG_INFINITY, "{x} rounded to {f}");
            }
        }
    }

    #[test]
    fn negative_values_round_toward_zero() {
        // -1 - 0.75 ulp: the nearest f32 is below it; the bound must be -1.
        let x = -1.0 - 0.75 * f32::EPSILON as f64;
        assert_eq!(round_up(x), -1.0);
        assert_eq!(round_up(1.0 + 0.25 * f32::EPSILON as f64), 1.0 + f32::EPSILON);
        assert_eq!(round_up(f64::MAX), f32::INFINITY);
    }
}
