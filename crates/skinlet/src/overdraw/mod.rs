//! Overdraw-reducing triangle orders for animated meshes (Han & Sander 2016), built on the
//! static-mesh methods of Sander, Nehab & Barczak 2007. In progress (issue 6): done are
//! [`measure`] (ACMR, equal to meshoptimizer's, and an exact software rasterizer for
//! overdraw), [`tipsify`] (vertex cache order and fast linear clustering into patches),
//! [`viewpoints`] (the subdivided icosahedron), [`cluster`] (k-means over keyframe ×
//! viewpoint nodes, the run-time lookup table); not yet: the "tipsify per frame" baseline
//! (Sander 2007's view-independent overdraw sort), the evaluation table, `skinlet overdraw`,
//! heat maps, the bake-file section.

pub mod cluster;
pub mod evaluate;
pub mod measure;
pub mod tipsify;
pub mod viewpoints;
