//! Overdraw-reducing triangle orders for animated meshes (Han & Sander 2016), built on the
//! static-mesh methods of Sander, Nehab & Barczak 2007. In progress (issue 6): done are
//! [`measure`] (ACMR, equal to meshoptimizer's, and an exact software rasterizer for
//! overdraw), [`tipsify`] (vertex cache order and fast linear clustering into patches) and
//! [`viewpoints`] (the subdivided icosahedron); not yet: the keyframe × viewpoint clustering,
//! run-time selection, the evaluation table and `skinlet overdraw`.

pub mod measure;
pub mod tipsify;
pub mod viewpoints;
