//! skinlet: make skinned (skeletally animated) meshes cheap to render.
//!
//! This crate holds the algorithms and never prints. Modules, one algorithm each:
//! - [`model`]: the character data model (hierarchy, skins, meshes, instances).
//! - [`character`]: the whole scene as one skinned mesh over a palette of drivers.
//! - [`clip`]: animation clips and their exact glTF sampling.
//! - [`pose`]: global transforms and skinning matrices.
//! - [`skinning`]: reference linear blend skinning, morph targets first (the ground truth of
//!   every bound).
//! - [`import`]: glTF 2.0 and OBJ loading with errors that say what and where.
//! - [`export`]: writing an asset as a glTF binary (.glb).
//! - [`bake`]: the bake file (meshlets, bounds, vertices) the runtime loads.
//! - [`bounds`]: conservative animated meshlet bounds (spheres, normal cones) and their check.
//! - [`cull`]: CPU culling at run time: meshlets, triangles, whole-mesh boxes, the crowd scene.
//! - [`meshlet`]: meshlet layout, four builders (incl. skin-aware), flat GPU form, metrics.
//! - [`contour`]: mesh contour extraction with patch decomposition (and its baselines).
//! - [`overdraw`]: triangle orders for low overdraw over animation (measures, clustering,
//!   run-time lookup).
//! - [`weld`]: merging vertices that are equal in position, skin data and morph deltas.
//! - [`summary`]: the facts `skinlet inspect` reports.
//! - [`demo`]: the built-in procedural demo character.

pub mod bake;
pub mod bounds;
pub mod character;
pub mod clip;
pub mod contour;
pub mod cull;
pub mod demo;
pub mod error;
pub mod export;
pub mod import;
pub mod meshlet;
pub mod model;
pub mod overdraw;
pub mod pose;
pub mod skinning;
pub mod summary;
pub mod weld;

pub use character::{Character, Part, PartKind};

pub use error::{Error, Result};
pub use model::{Asset, Influences, Instance, Mesh, Node, Skeleton, Skin, SkinnedMesh, Trs};
