//! skinlet-lab: what only skinlet's tools and tests need, built on the public API of
//! `skinlet-gpu` like any other user of it; nothing a game ships.
//!
//! - [`render`]: skinlet's own offscreen renderer: vertex-, compute-, mesh- and slim
//!   mesh-shader skinning drawing the same image, culled drawing (task shaders, or a compute
//!   pass and indirect draws), crowds timed by timestamp queries, colored, contour and
//!   overdraw views, every image read back. `skinlet render` and `skinlet gpu-bench` draw
//!   with it; tests/render.rs checks that every pipeline draws the same pixels.

pub mod render;
