//! skinlet-lab: what only skinlet's tools and tests need, built on the public API of
//! `skinlet-gpu` like any other user of it; nothing a game ships.
//!
//! - [`render`]: skinlet's own offscreen renderer: vertex-, compute-, mesh- and slim
//!   mesh-shader skinning drawing the same image, culled drawing (task shaders on the joint
//!   records GPU crowd culling prepares), crowds timed by timestamp queries, colored, contour and
//!   overdraw views, every image read back. `skinlet render` and `skinlet gpu-bench` draw
//!   with it; tests/render.rs checks that every pipeline draws the same pixels.
//! - [`gpu_crowd`]: a GPU-driven crowd renderer on `skinlet_gpu::crowd_culling` (culling,
//!   survivors drawn with one call, the unculled image and the ID-buffer oracle of visible
//!   meshlets); `skinlet gpu-bench --crowd` draws with it.
//! - [`occlusion_limits`]: what a box test against a frame's depth can cull at best (full
//!   resolution, or as `crowd_culling`'s pyramid), on boxes of the frame's own pose.
//! - [`contour_eval`]: the contour paper's evaluation protocol (42 directions × 6 distances,
//!   frames of clips) over every extractor, and the calibration of `t_P / t_e`.
//! - [`snch`], [`meshlet_patches`]: the contour baselines (Johnson & Cohen 2001's hierarchy;
//!   meshoptimizer meshlets used as patches, with a correct cone).
//! - [`demo`]: the built-in demo character `skinlet demo` bakes (a whole character: two skins,
//!   rigid, animated and instanced parts, a morph face, three clips), and a UV sphere.
//! - [`scans`]: static meshes of sizes and shapes the shared scans lack (a scan-like noisy
//!   sphere, a thin-shelled cup, decimations), for the contour targets.
//! - [`crowd`]: the crowd scene of the conservative-bounds paper (clips, crossfades, additive
//!   layers, IK), its statistics, and the brute-force check of every culled triangle.
//! - [`backface_views`]: what the backface test alone saves over random views (meshlets,
//!   triangles, skinning) against per-triangle backface culling (`skinlet bounds`).
//! - [`bevy_baseline`]: Bevy's per-joint box update, the baseline skinlet's is measured against.
//! - [`summary`]: the facts `skinlet inspect` reports.
//! - [`headless`]: the headless Vulkan device the tools and tests draw on.

pub mod backface_views;
pub mod bevy_baseline;
pub mod contour_eval;
pub mod crowd;
pub mod crowd_lod;
pub mod demo;
pub mod gpu_crowd;
pub mod headless;
pub mod meshlet_patches;
pub mod occlusion_limits;
pub mod render;
pub mod scans;
pub mod snch;
pub mod summary;
