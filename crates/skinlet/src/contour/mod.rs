//! Mesh contour extraction (Tsiapkolis & Bénard 2024, "Patch Decomposition for Efficient Mesh
//! Contours Extraction"), for static meshes and skinned characters.
//!
//! A mesh contour edge joins a front-facing face to one that is not (section 1): with the
//! viewer at `e`, face `(a, b, c)` is front-facing when `((b − a) × (c − a)) · (e − a) > 0`
//! (orthographic views: `−dir` instead of `e − a`). Modules:
//! - [`edges`] (in `skinlet_runtime`): the edge structure (quads `a, b, c, d`, boundary and
//!   irregular edges, the concave filter) and the per-edge test.
//! - [`bound`]: spatialized normal cones — Mean and Reduced Sphere (section 3.1), the cone
//!   test `|n·s| ≤ sin(α + β)` (eq. 1) — and the acceptance metric and cost (section 3.2).
//! - [`patches`]: greedy patch fusion with the k-best cache and space partition (3.3).
//! - [`skinned`]: skinned characters — the paper's rigid parts, and patches bounded over the
//!   clips with the conservative animated bounds of [`crate::bounds`], per time window.
//!
//! The baselines (Johnson & Cohen 2001's hierarchy, meshoptimizer meshlets used as patches)
//! and the paper's evaluation protocol are tools: `skinlet_lab::{snch, meshlet_patches,
//! contour_eval}`.
//!
//! Guarantee, for every extractor: the extracted edge set equals [`brute_force`]'s. All of
//! them run the same per-edge test ([`quad_is_contour`], in f64 on the f32 positions), and
//! every culling test keeps a margin ([`bound::MARGIN`]) far above the rounding of that test,
//! so a culled edge is one whose computed test is certainly negative. Edges whose faces are
//! too thin for their normal to have a reliable direction are never culled.

pub mod bound;
pub mod patches;
pub mod skinned;

pub use skinlet_runtime::camera::Projection;
/// The edge structure and the per-edge test live in the runtime crate (what a game ships).
pub use skinlet_runtime::contour_edges as edges;
pub use skinlet_runtime::contour_edges::{
    Edges, Irregular, Tested, Viewer, brute_force, extract_uncullable, irregular_is_contour, quad_is_contour,
};
