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
