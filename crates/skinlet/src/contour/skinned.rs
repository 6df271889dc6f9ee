//! Contours of skinned characters: patches whose bounds hold over whole animation clips.
//!
//! Tsiapkolis & Bénard 2024 (section 4.1) split a character into rigid parts — quads whose
//! four vertices all follow one bone — build patches per part in the bone's space and move
//! the viewer into that space at run time; every other edge goes to a group that is never
//! culled ([`SkinnedMethod::Rigid`]; the paper counts a quad rigid when its two edge vertices
//! are, but the faces' opposite vertices move the normals too, so we require all four).
//!
//! Beyond the paper ([`SkinnedMethod::Animated`]): non-rigid quads are fused too, per
//! principal joint, and bounded with the conservative animated sphere and normal cone of
//! Unterguggenberger et al. 2021 ([`crate::bounds`]) over the clips: a patch's "meshlet" is
//! the set of faces adjacent to its edges, so the sphere holds every edge point and the cone
//! every adjacent face normal, at every time of every clip, in the principal joint's space.
//!
//! Run time: per joint, the eye moves into the joint's space (`G⁻¹·eye`; orthographic:
//! `A⁻¹·dir`). Facing is invariant under that affine map (`(A·u)×(A·v) = cof(A)(u×v)` and
//! `cof(A)ᵀA = det(A)·I`: every face's sign flips together when `det < 0`), so the
//! contour set is the same in either space, and the static cone test applies unchanged.
//!
//! Guarantee: the extracted set equals brute force on the f32 skinned positions at any time
//! of the clips. The bounds hold for exact skinning; the f32 rounding of skinning (at most
//! [`SKIN_ROUNDING`] of the model's extent per vertex) turns a face normal by at most that
//! times its `2(|e1| + |e2|)/|n|`, and each patch's cone is widened by four times the
//! largest such turn among its faces. Tested on every shared asset over sampled frames.

use super::Edges;
use super::bound::{EdgeGeometry, quad_geometry};
use super::patches::{BuiltPatch, PatchParams, Patches, assemble, fuse, patch_around, size_of};
use crate::bounds::cone::reference_axis;
use crate::bounds::refine::{PieceExtent, Refinement, refine};
use crate::clip::Clip;
use crate::meshlet::Meshlets;
use crate::meshlet::stats::principal_joint;
use crate::model::{Skeleton, Skin, SkinnedMesh};
use crate::{Error, Result};
use glam::{DMat4, DVec3, Vec3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Skinned patches as extraction reads them, and the extraction, live in the runtime crate.
pub use skinlet_runtime::contour_patches::{ClipWindows, SkinnedPatches, joint_view, rigid_quad};

/// Relative f32 rounding of skinned positions, as the bounds module allows for it.
pub const SKIN_ROUNDING: f64 = crate::bounds::INFLATE;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SkinnedMethod {
    /// The paper: patches on rigid parts only.
    Rigid,
    /// Ours: every quad, non-rigid ones with animated bounds.
    Animated,
}

impl SkinnedMethod {
    pub fn name(self) -> &'static str {
        match self {
            SkinnedMethod::Rigid => "rigid",
            SkinnedMethod::Animated => "animated",
        }
    }
}

/// How to build skinned patches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinnedParams {
    pub method: SkinnedMethod,
    pub patches: PatchParams,
    /// Refinement of the animated bounds ([`refinement`]).
    pub refine: Refinement,
    /// Time windows per clip with their own bounds (1: one bound over each whole clip set).
    pub windows: usize,
}

impl SkinnedParams {
    pub fn new(method: SkinnedMethod, refine: Refinement) -> SkinnedParams {
        SkinnedParams { method, patches: PatchParams::default(), refine, windows: DEFAULT_WINDOWS }
    }
}

/// Windows per clip by default: bounds over an eighth of a clip are much tighter than over
/// all clips (Fox: ×1.35 → ×2.0 over brute force) for 8× the bound memory.
pub const DEFAULT_WINDOWS: usize = 8;

/// Builds the patches of `mesh` (welded, skinned by `skin`) for `clips`.
pub fn build(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    edges: &Edges,
    sp: &SkinnedParams,
) -> Result<SkinnedPatches> {
    let (method, params, how) = (sp.method, &sp.patches, &sp.refine);
    if mesh.influences.is_none() {
        return Err(Error::invalid("contours", "the mesh has no skin weights"));
    }
    let p = &mesh.positions;
    let rigid_vertex = rigid_vertices(mesh);
    // Group quads by (joint, rigid); rigid quads keep the joint their vertices follow.
    let mut groups: BTreeMap<(u16, bool), Vec<u32>> = BTreeMap::new();
    for (i, q) in edges.quads.iter().enumerate() {
        let r = rigid_vertex[q[0] as usize];
        let rigid = rigid_quad(&rigid_vertex, q);
        let joint = match r {
            Some(j) if rigid => j,
            _ => principal_joint(mesh, q).map_or(0, |(j, _)| j),
        };
        groups.entry((joint, rigid)).or_default().push(i as u32);
    }
    let size = size_of(p, edges);
    let mut always = Vec::new();
    let work: Vec<(u16, bool, &Vec<u32>)> = groups
        .iter()
        .filter_map(|(&(j, rigid), q)| {
            if rigid || method == SkinnedMethod::Animated {
                Some((j, rigid, q))
            } else {
                always.extend_from_slice(q);
                None
            }
        })
        .collect();
    // Fusion on the bind pose; bounds per patch below.
    let fused: Vec<(u16, bool, Vec<BuiltPatch>, Vec<u32>)> = work
        .par_iter()
        .map(|&(j, rigid, q)| {
            let (b, a) = fuse(p, edges, q, params, size);
            (j, rigid, b, a)
        })
        .collect();
    let magnitude = model_extent(skeleton, skin, clips, mesh)?;
    let eta = SKIN_ROUNDING * magnitude;
    let mut out: Vec<(u16, bool, BuiltPatch, Vec<PieceExtent>)> = Vec::new();
    let mut animated: Vec<BuiltPatch> = Vec::new();
    for (j, rigid, built, a) in fused {
        always.extend(a);
        for b in built {
            if rigid {
                // Rigid vertices sit still in the joint's space at their bind position there.
                let to_joint = skin.inverse_bind[j as usize].as_dmat4();
                match rigid_bounds(p, edges, &b.edges, &to_joint) {
                    Some(x) => out.push((j, true, x, Vec::new())),
                    None => always.extend(b.edges),
                }
            } else {
                animated.push(b);
            }
        }
    }
    // Animated bounds of the non-rigid patches, each as the "meshlet" of its adjacent faces.
    let mut meshlets = Meshlets::default();
    let mut kept = Vec::new();
    for b in animated {
        match faces_meshlet(mesh, edges, &b.edges) {
            Some((verts, tris)) => {
                meshlets.push(&verts, &tris);
                kept.push(b);
            }
            None => always.extend(b.edges),
        }
    }
    if !kept.is_empty() {
        let refined = refine(skeleton, skin, clips, mesh, &meshlets, how)?;
        for ((b, mb), ext) in kept.into_iter().zip(refined.bounds).zip(refined.extents) {
            let x = BuiltPatch {
                edges: b.edges,
                center: mb.center.as_dvec3(),
                radius: mb.radius as f64,
                axis: mb.cone_axis.as_dvec3(),
                angle: mb.cone_angle as f64,
            };
            out.push((mb.joint, false, x, ext));
        }
    }
    // Windows of each clip.
    let mut windows = Vec::new();
    let mut first = 0;
    for c in clips {
        let keys = c.key_times();
        let (start, end) = (keys.first().copied().unwrap_or(0.0), keys.last().copied().unwrap_or(0.0));
        let count = if end > start { sp.windows.max(1) as u32 } else { 1 };
        windows.push(ClipWindows { start, end, count, first });
        first += count;
    }
    // Widen for the rounding of skinning, then keep only patches that still pay.
    // (joint, patch, (radius, angle) per window)
    type Final = (u16, BuiltPatch, Vec<(f64, f64)>);
    let mut final_patches: Vec<Final> = Vec::new();
    let (mut rigid_quads, mut animated_quads) = (0, 0);
    for (j, rigid, mut b, ext) in out {
        let widen = 4.0 * eta * thinness(p, edges, &b.edges);
        b.angle += widen;
        // Keep a patch when culling it pays on average over the windows it will be tested in.
        let per_window = window_extents(&windows, &b, &ext, widen);
        let xi = b.edges.len() as f64;
        let cost = per_window
            .iter()
            .map(|&(r, a)| params.cost_ratio + super::bound::acceptance(a, r, params.d_cam * size) * xi)
            .sum::<f64>()
            / per_window.len().max(1) as f64;
        if xi > cost {
            *(if rigid { &mut rigid_quads } else { &mut animated_quads }) += b.edges.len();
            final_patches.push((j, b, per_window));
        } else {
            always.extend(b.edges);
        }
    }
    final_patches.sort_by_key(|(j, _, _)| *j);
    let (mut joints, mut built, mut extents) = (Vec::new(), Vec::new(), Vec::new());
    for (j, b, w) in final_patches {
        joints.push(j);
        extents.push((b.center, w));
        built.push(b);
    }
    let patches = Patches { cost_ratio: params.cost_ratio, ..assemble(edges, built, always, size) };
    let total = first as usize;
    let mut window_bounds = Vec::with_capacity(total * patches.len());
    for w in 0..total {
        for (b, (center, ext)) in patches.bounds.iter().zip(&extents) {
            let (r, a) = ext[w];
            window_bounds.push(b.with_extent(*center, r, a));
        }
    }
    Ok(SkinnedPatches { patches, joints, rigid_quads, animated_quads, clips: windows, window_bounds })
}

/// A patch's (radius, angle) over every window: from the pieces that overlap it (animated
/// patches; rigid ones have no pieces and keep their bounds), widened like the union.
fn window_extents(windows: &[ClipWindows], b: &BuiltPatch, pieces: &[PieceExtent], widen: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for (c, w) in windows.iter().enumerate() {
        for k in 0..w.count {
            if pieces.is_empty() {
                out.push((b.radius, b.angle));
                continue;
            }
            let (a, z) = w.range(k);
            // Pieces touching the closed window, with slack for the rounding of its ends.
            let slack = 1e-4 * (w.end - w.start) / w.count as f32;
            let (mut r, mut min_cos) = (0.0f64, 1.0f64);
            for p in pieces.iter().filter(|p| p.clip as usize == c && p.t1 <= z + slack && p.t2 >= a - slack) {
                r = r.max(p.radius);
                min_cos = min_cos.min(p.min_cos);
            }
            let angle = if min_cos > 0.0 { min_cos.min(1.0).acos() } else { PI };
            // Never wider than the union (which also holds over the window).
            out.push((r.min(b.radius), (angle + widen).min(b.angle)));
        }
    }
    out
}

/// Refinement of the animated bounds aimed at contour culling: pieces are halved until they
/// stay within 1.5× their rest radius and 3° of their rest cone or stop improving (tighter
/// thresholds cost 3× the time for < 1% fewer tested edges on mannequiny).
pub fn refinement(budget: Option<std::time::Duration>, max_rounds: usize) -> Refinement {
    Refinement { s_r: 1.5, alpha_t: 3f32.to_radians(), budget, max_rounds }
}

/// The edges of a skinned mesh; with `visible_only`, minus the concave rigid quads (their
/// concavity cannot change, so their contours are always hidden): what a bake's `CONT`
/// patches index ([`skinlet_runtime::contour_patches::skinned_edges`]).
pub fn skinned_edges(mesh: &SkinnedMesh, visible_only: bool) -> Result<Edges> {
    let rigid = visible_only.then(|| rigid_vertices(mesh));
    Ok(skinlet_runtime::contour_patches::skinned_edges(&mesh.positions, &mesh.triangles, rigid.as_deref())?)
}

/// Per vertex, the joint that carries all its weight rigidly, when no morph target moves it
/// ([`skinlet_runtime::contour_patches::rigid_vertices`]).
pub fn rigid_vertices(mesh: &SkinnedMesh) -> Vec<Option<u16>> {
    let Some(inf) = &mesh.influences else { return vec![None; mesh.positions.len()] };
    let morphed = |v: usize| !mesh.morphs.of(v).is_empty();
    skinlet_runtime::contour_patches::rigid_vertices(
        mesh.positions.len(),
        inf.stride,
        &inf.joints,
        &inf.weights,
        morphed,
    )
}

/// Bounds of a rigid patch in its joint's space (`to_joint · x`): Reduced Sphere and the
/// narrower of the mean / smallest-cap cone.
fn rigid_bounds(p: &[Vec3], edges: &Edges, quads: &[u32], to_joint: &DMat4) -> Option<BuiltPatch> {
    let geo: Option<Vec<EdgeGeometry>> = quads
        .iter()
        .map(|&q| {
            let [a, b, c, d] = edges.quads[q as usize].map(|v| to_joint.transform_point3(p[v as usize].as_dvec3()));
            quad_geometry(a, b, c, d)
        })
        .collect();
    let geo = geo?;
    let normals: Vec<DVec3> = geo.iter().flat_map(|g| [g.n1, g.n2]).collect();
    Some(patch_around(quads.to_vec(), &geo, reference_axis(&normals).0))
}

/// The faces adjacent to `quads` as one meshlet (local vertices, local triangles), or
/// `None` past 256 vertices.
fn faces_meshlet(mesh: &SkinnedMesh, edges: &Edges, quads: &[u32]) -> Option<(Vec<u32>, Vec<u8>)> {
    let mut faces: Vec<u32> = quads.iter().flat_map(|&q| edges.quad_faces[q as usize]).collect();
    faces.sort_unstable();
    faces.dedup();
    let mut verts: Vec<u32> = faces.iter().flat_map(|&f| mesh.triangles[f as usize]).collect();
    verts.sort_unstable();
    verts.dedup();
    if verts.len() > 256 {
        return None;
    }
    let local = |v: u32| verts.binary_search(&v).map(|i| i as u8).ok();
    let tris: Vec<u8> = faces.iter().flat_map(|&f| mesh.triangles[f as usize]).map(local).collect::<Option<_>>()?;
    Some((verts, tris))
}

/// Largest `2(|e1| + |e2|)/|n|` over the faces of the quads (bind pose): how far a face
/// normal turns per unit of vertex displacement.
fn thinness(p: &[Vec3], edges: &Edges, quads: &[u32]) -> f64 {
    let mut k: f64 = 0.0;
    for &q in quads {
        let [a, b, c, d] = edges.quads[q as usize].map(|v| p[v as usize].as_dvec3());
        for (x, y) in [(b - a, c - a), (d - a, b - a)] {
            let n = x.cross(y).length();
            k = k.max(if n > 0.0 { 2.0 * (x.length() + y.length()) / n } else { f64::INFINITY });
        }
    }
    k
}

/// An upper bound of |skinned position| over the clips, from the bind pose and the clips'
/// key times (doubled: a margin for the rounding allowance, not a bound the culling relies
/// on for anything but its size).
fn model_extent(skeleton: &Skeleton, skin: &Skin, clips: &[&Clip], mesh: &SkinnedMesh) -> Result<f64> {
    let rest = crate::skinning::posed_positions(skeleton, skin, mesh, None, None)?;
    let mut extent = (mesh.positions.iter().chain(&rest)).map(|p| p.length() as f64).fold(0.0, f64::max);
    for clip in clips {
        for t in clip.key_times() {
            let out = crate::skinning::posed_positions(skeleton, skin, mesh, Some(clip), Some(t))?;
            extent = extent.max(out.iter().map(|p| p.length() as f64).fold(0.0, f64::max));
        }
    }
    Ok(2.0 * extent)
}
