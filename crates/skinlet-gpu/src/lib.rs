//! skinlet's GPU runtime on wgpu 29 (Bevy 0.19's) with WGSL shaders.
//!
//! - [`Gpu`]: the device skinlet's objects live on, yours ([`Gpu::from_device`]): this crate
//!   creates no device, forces no wgpu backend and blocks on no executor (skinlet's own tools
//!   make a headless Vulkan device in `skinlet-lab`), with the buffer and pipeline helpers the
//!   modules share.
//! - [`mesh`]: a skinned mesh (morph target deltas included) and its meshlets on the GPU,
//!   uploaded from a bake's `skinlet_runtime::bake_view::MeshData`; a [`mesh::Pose`] is one
//!   draw's skinning matrices and morph weights.
//! - [`skinning`]: compute-shader skinning, checked against skinlet's reference skinning, and
//!   the shared skinning WGSL with its bindings for your own skinning shaders.
//! - [`crowd_culling`]: culling a crowd on the caller's own device, recorded into the caller's
//!   own encoder: per-joint preparation and per-meshlet tests in one compute pass, indexed
//!   indirect draws out, nothing read back (the library API an engine links).
//! - [`crowd_skinning`]: a crowd's skinning as one WGSL function of (instance, vertex), for
//!   the triangle pass and the caller's draw alike.
//! - [`triangle_culling`]: per-triangle culling of crowd culling's survivors with the caller's
//!   own skinning function (back faces, triangles between pixel centers, the depth pyramid),
//!   one compacted index list and one indexed indirect draw out.
//! - [`contours`]: contour extraction (patch culling and edge test passes), equal to brute
//!   force.
//!
//! skinlet's own offscreen renderer (every skinning and culling pipeline, timed crowds,
//! readbacks) is not here: it is a user of this API in the `skinlet-lab` crate, for the tools
//! and tests.
//!
//! Errors (no adapter, a failed device request, a validation error, bad input) come back as
//! [`GpuError`]; nothing here panics on user data.
//!
//! Skinning a baked character on your own device (the bake read by `skinlet-runtime`'s view;
//! crowd culling on the same device: [`crowd_culling`]):
//!
//! ```no_run
//! use skinlet_gpu::mesh::{GpuMesh, Pose};
//! use skinlet_gpu::{Gpu, skinning::ComputeSkinning};
//!
//! fn skin(device: &wgpu::Device, queue: &wgpu::Queue, adapter: &wgpu::Adapter) -> Result<(), Box<dyn std::error::Error>> {
//!     let gpu = Gpu::from_device(device.clone(), queue.clone(), adapter.get_info());
//!     let bytes = std::fs::read("character.skinlet")?;
//!     let view = skinlet_runtime::bake_view::BakeView::new(&bytes)?;
//!     let mesh = GpuMesh::new(&gpu, &view.mesh_data())?; // once
//!     let skinning = ComputeSkinning::new(&gpu)?;
//!     // Every frame: your pose's skinning matrices (one per driver) and morph weights.
//!     let matrices = vec![glam::Affine3A::IDENTITY; view.joint_count()];
//!     let morph_weights = vec![0.0; mesh.morph_weights];
//!     skinning.skin(&gpu, &mesh, Pose { matrices: &matrices, morph_weights: &morph_weights })?;
//!     // `mesh.out_positions` and `mesh.out_normals` now hold the skinned vertices.
//!     Ok(())
//! }
//! ```

mod context;
pub mod contours;
pub mod crowd_culling;
pub mod crowd_skinning;
pub mod mesh;
pub mod skinning;
pub mod triangle_culling;

pub use context::Gpu;

/// What went wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0} (on a machine without a GPU, install Mesa's lavapipe: mesa-vulkan-drivers)")]
    NoAdapter(String),
    #[error("the GPU device could not be created: {0}")]
    Device(String),
    #[error("GPU error in {location}: {message}")]
    Gpu { location: &'static str, message: String },
    #[error("invalid input to {location}: {message}")]
    Invalid { location: &'static str, message: String },
}

pub type Result<T> = std::result::Result<T, GpuError>;
