//! Overdraw-reducing triangle orders for animated meshes (Han & Sander 2016), built on the
//! static-mesh methods of Sander, Nehab & Barczak 2007: [`measure`] (ACMR, equal to
//! meshoptimizer's, and an exact software rasterizer for overdraw), [`tipsify`] (vertex cache
//! order and fast linear clustering into patches), [`compact`] (our compact patches), [`viewpoints`] (the subdivided
//! icosahedron), [`cluster`] (k-means over keyframe × viewpoint nodes, the run-time lookup
//! table), [`occlusion`] (our patch order from measured occlusion), [`evaluate`] (the paper's
//! table 2).

pub mod cluster;
pub mod compact;
pub mod evaluate;
pub mod measure;
pub mod occlusion;
pub mod tipsify;
pub mod viewpoints;
