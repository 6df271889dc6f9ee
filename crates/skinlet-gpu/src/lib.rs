//! skinlet's GPU runtime on wgpu (exact version pinned) with WGSL shaders.
//!
//! In progress (issue 8). Done: the device ([`Gpu`]: Vulkan, headless, optional features
//! picked from what the adapter offers: mesh shaders, timestamps, subgroups) and
//! compute-shader skinning ([`skinning`]), checked against skinlet's reference skinning;
//! offscreen rendering by vertex-shader, compute-shader and mesh-shader skinning
//! ([`render`]), checked to give the same image; per-meshlet culling of many instances in a
//! compute pass ([`cull`]) and in a task shader ([`render::Renderer::render_culled`]), checked
//! against the CPU; per-meshlet colored views. Not yet: common-influences slim-vertex mesh
//! shading, per-triangle culling, indirect draws, GPU contours, `gpu-bench`.
//!
//! Errors (no adapter, a failed device request, a validation error, bad input) come back as
//! [`GpuError`]; nothing here panics on user data.

mod context;
pub mod contours;
pub mod cull;
pub mod mesh;
pub mod render;
pub mod skinning;

pub use context::{Gpu, GpuOptions};

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
