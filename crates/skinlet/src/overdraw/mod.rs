//! Overdraw-reducing triangle orders for animated meshes (Han & Sander 2016), built on the
//! static-mesh methods of Sander, Nehab & Barczak 2007. In progress: [`measure`] (ACMR and
//! a software rasterizer for overdraw) is done; cache-efficient patches, viewpoint and
//! keyframe clustering and run-time selection are not yet.

pub mod measure;
