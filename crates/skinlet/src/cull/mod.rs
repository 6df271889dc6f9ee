//! CPU culling in the baker and its tools: any-pose boxes built from a mesh ([`any_pose`]),
//! per-joint whole-mesh boxes built from a mesh and folded over clips ([`joint_aabb`]),
//! per-triangle culling inside visible meshlets ([`triangle`]; the crowd scene that measures
//! them and the Bevy baseline are in `skinlet-lab`). The
//! run-time culler, camera, joint-box update and pose guard are in `skinlet-runtime`
//! (re-exported here where the baker uses them).

pub mod any_pose;
pub mod joint_aabb;
pub mod triangle;

pub use skinlet_runtime::camera::{Camera, Projection, planes};
