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
//! - [`cull`]: the baker's side of culling (any-pose and per-joint boxes, per-triangle tests),
//!   the crowd scene; the run-time culler is `skinlet_runtime`'s (the Bevy baseline is in
//!   `skinlet-lab`).
//! - [`meshlet`]: meshlet layout, four builders (incl. skin-aware), flat GPU form, metrics.
//! - [`contour`]: mesh contour extraction with patch decomposition (and its baselines).
//! - [`overdraw`]: triangle orders for low overdraw over animation (measures, clustering,
//!   run-time lookup).
//! - [`weld`]: merging vertices that are equal in position, skin data and morph deltas.
//! - [`demo`]: the built-in procedural demo character (and a UV sphere).
//!
//! Baking the demo character and reading the bake back the way a game does, with
//! `skinlet-runtime`'s checked view of the bytes:
//!
//! ```
//! use skinlet::bake::{bake, to_bytes};
//! use skinlet::bounds::refine::Refinement;
//! use skinlet::demo::{DemoParams, demo_character};
//! use skinlet::meshlet::{Builder, MeshletLimits};
//!
//! let asset = demo_character(&DemoParams { triangles: 1000, ..DemoParams::default() });
//! let character = asset.character()?; // every mesh-drawing node of the scene, one palette
//! let clips: Vec<_> = asset.clips.iter().collect();
//! let limits = MeshletLimits::NVIDIA;
//! let (baked, _stats) =
//!     bake(&asset, &character, &clips, Builder::SkinAware, limits, &Refinement::NONE, &mut |_| {})?;
//! let bytes = to_bytes(&baked); // what `skinlet::bake::write` stores
//! let view = skinlet_runtime::bake_view::BakeView::new(&bytes)?;
//! assert_eq!(view.meshlet_count()?, baked.meshlets.len());
//! let culler = view.culler()?; // what a game culls with, frame after frame
//! assert_eq!(culler.len(), baked.meshlets.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

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
pub mod weld;

pub use character::{Character, Part, PartKind};

pub use error::{Error, Result};
pub use model::{Asset, Influences, Instance, Mesh, Node, Skeleton, Skin, SkinnedMesh, Trs};
