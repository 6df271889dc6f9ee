//! skinlet-runtime: what a game ships to cull skinned characters baked by skinlet.
//!
//! The baker (`skinlet`) turns a glTF character into meshlets with conservative bounds that
//! hold while it animates; this crate uses them every frame, on the CPU, with no allocation
//! once its buffers have grown and no panic on the data it is given: any lengths and values
//! give an `Err` or a conservative answer (`tests/no_panic.rs` holds one property per entry
//! point). It depends on glam and bytemuck only. Modules, one algorithm each:
//! - [`bake_view`]: the format's one reader, a checked, zero-copy view over a bake file's bytes.
//! - [`camera`]: a camera's frustum planes and what backface tests need.
//! - [`meshlet_bounds`]: per-meshlet spheres, normal cones and culling classes, as baked.
//! - [`meshlet_cull`]: per-meshlet frustum and backface culling of skinned instances, in each
//!   meshlet's principal joint space (conservative-bounds paper, section 6), with the
//!   any-pose boxes for poses no stored bound covers; its prepared per-joint values are what
//!   GPU culling passes read.
//! - [`any_pose`]: per-meshlet boxes per influencing joint, valid for any pose.
//! - [`joint_boxes`]: whole-mesh boxes from per-joint boxes (the Bevy PR's method).
//! - [`part_bounds`]: one box per part (an engine's entity) every frame, morph targets
//!   included: per-joint boxes for any pose, narrowed by the clip or envelope bounds.
//! - [`pose_guard`]: whether a pose (blend, additive layer, IK) lies inside a pose envelope.
//! - [`overdraw_orders`]: which of a bake's overdraw-reducing index buffers to draw.
//! - [`contour_edges`]: a mesh's edges and the contour test (Tsiapkolis & Bénard 2024), brute
//!   force as the reference.
//! - [`contour_patches`]: contour extraction with a bake's patches (static or skinned, per
//!   time window), exactly brute force's edges.
//! - [`lod_select`]: which clusters of a bake's LOD hierarchy an instance draws, from a pixel
//!   threshold projected at its bounding sphere.
//! - [`source_corners`]: each meshlet corner's vertex in its glTF primitive, for drawing the
//!   meshlets with the source's own vertex attributes.
//!
//! Culling one instance of a baked character (one meshlet here, built by hand):
//!
//! ```
//! use glam::{Affine3A, Vec3};
//! use skinlet_runtime::camera::Camera;
//! use skinlet_runtime::meshlet_bounds::{Class, MeshletBounds};
//! use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
//!
//! // A meshlet on joint 0: a unit sphere at the joint's origin, every normal within 0.3 rad of +z.
//! let bounds = [MeshletBounds {
//!     joint: 0,
//!     center: Vec3::ZERO,
//!     radius: 1.0,
//!     rest_radius: 1.0,
//!     cone_axis: Vec3::Z,
//!     cone_angle: 0.3,
//!     rest_cone_angle: 0.3,
//! }];
//! let culler = MeshletCuller::new(&bounds, &[Class::Both], 1)?;
//! let camera = Camera::perspective(Vec3::new(0.0, 0.0, -10.0), Vec3::ZERO, Vec3::Y, 1.0, 1.0, 0.1, 100.0)?;
//! let (mut frame, mut flags, mut visible) = (JointFrame::default(), Vec::new(), Vec::new());
//! // Every frame, per instance: the joints' world matrices (here the joint moved 3 to the side).
//! let joint_to_world = [Affine3A::from_translation(Vec3::new(3.0, 0.0, 0.0))];
//! culler.prepare(&joint_to_world, &camera, Tests::Both, &mut frame);
//! let counts = culler.cull(&frame, &mut flags, &mut visible);
//! // In view, but every normal faces away from the eye: culled by the backface test.
//! assert_eq!((counts.backface, visible.len()), (1, 0));
//! // Turned around, it faces the eye and is drawn.
//! let turned = [Affine3A::from_rotation_translation(glam::Quat::from_rotation_y(std::f32::consts::PI), Vec3::X * 3.0)];
//! culler.prepare(&turned, &camera, Tests::Both, &mut frame);
//! visible.clear();
//! culler.cull(&frame, &mut flags, &mut visible);
//! assert_eq!(visible, [0]);
//! # Ok::<(), skinlet_runtime::Error>(())
//! ```

pub mod any_pose;
pub mod bake_view;
pub mod camera;
pub mod contour_edges;
pub mod contour_patches;
pub mod error;
pub mod joint_boxes;
pub mod lod_select;
pub mod meshlet_bounds;
pub mod meshlet_cull;
pub mod overdraw_orders;
pub mod part_bounds;
pub mod pose_guard;
pub mod source_corners;

pub use error::{Error, Result};
pub use pose_guard::Trs;
