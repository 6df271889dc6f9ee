//! The evaluation protocol of Tsiapkolis & Bénard 2024 (section 4.3): every extractor runs
//! from 42 directions (a once-subdivided icosahedron's vertices) at 6 distances (5, 10, 25,
//! 50, 75, 100 model sizes from the model's box center; the paper scales models to unit
//! size); reported: share of edges tested, time per view against brute force in the same
//! run, build time, patch count, mean radius and cone angle, and every view whose edge set
//! differs from brute force's. Also the hardware calibration of `t_P / t_e` (section 4.2).

use crate::meshlet_patches;
use crate::snch::Snch;
use glam::{DVec3, Vec3};
use skinlet::contour::patches::{self, BuiltPatch, PatchParams, Patches, SphereKind};
use skinlet::contour::{Edges, Projection, Tested, brute_force};
use skinlet::overdraw::viewpoints::icosphere;
use std::time::Instant;

/// Viewing distances, in model sizes.
pub const DISTANCES: [f64; 6] = [5.0, 10.0, 25.0, 50.0, 75.0, 100.0];

/// The contour extractors compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Brute,
    /// Patch decomposition with the Reduced Sphere.
    Patches,
    /// Patch decomposition with the Mean Sphere.
    PatchesMean,
    Snch,
    /// meshoptimizer 16-face meshlets as patches.
    Meshlets,
}

impl Method {
    pub const ALL: [Method; 5] = [Method::Brute, Method::Patches, Method::PatchesMean, Method::Snch, Method::Meshlets];

    pub fn name(self) -> &'static str {
        match self {
            Method::Brute => "brute",
            Method::Patches => "patches",
            Method::PatchesMean => "patches-mean",
            Method::Snch => "snch",
            Method::Meshlets => "meshlets",
        }
    }

    pub fn from_name(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// A built extractor.
#[derive(Clone, Debug)]
pub enum Extractor {
    Brute,
    Patches(Patches),
    Snch(Snch),
}

impl Extractor {
    pub fn build(
        method: Method,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        edges: &Edges,
        params: &PatchParams,
    ) -> Extractor {
        match method {
            Method::Brute => Extractor::Brute,
            Method::Patches => Extractor::Patches(patches::build(positions, edges, params)),
            Method::PatchesMean => Extractor::Patches(patches::build(
                positions,
                edges,
                &PatchParams { sphere: SphereKind::Mean, ..*params },
            )),
            Method::Snch => Extractor::Snch(Snch::build(positions, edges)),
            Method::Meshlets => Extractor::Patches(meshlet_patches::build(positions, triangles, edges, 16)),
        }
    }

    pub fn extract(&self, positions: &[Vec3], edges: &Edges, projection: Projection, out: &mut Vec<u32>) -> Tested {
        match self {
            Extractor::Brute => brute_force(positions, edges, projection, out),
            Extractor::Patches(p) => p.extract(positions, edges, projection, out),
            Extractor::Snch(s) => s.extract(positions, edges, projection, out),
        }
    }

    /// Patches or hierarchy nodes.
    pub fn bounds(&self) -> usize {
        match self {
            Extractor::Brute => 0,
            Extractor::Patches(p) => p.len(),
            Extractor::Snch(s) => s.len(),
        }
    }
}

/// The 42 × 6 perspective views around the box of `positions`.
pub fn views(positions: &[Vec3]) -> Vec<Projection> {
    let (center, size) = frame(positions);
    views_around(center, size)
}

/// Eyes in the 42 directions at each of [`DISTANCES`] model sizes `size` from `center`.
pub fn views_around(center: Vec3, size: f64) -> Vec<Projection> {
    let dirs = icosphere(1);
    DISTANCES
        .iter()
        .flat_map(|&d| dirs.iter().map(move |&dir| Projection::Perspective { eye: center + dir * (d * size) as f32 }))
        .collect()
}

/// Center and largest side of the box around `positions` (size 1 when empty or flat).
pub fn frame(positions: &[Vec3]) -> (Vec3, f64) {
    let lo = positions.iter().fold(DVec3::INFINITY, |a, p| a.min(p.as_dvec3()));
    let hi = positions.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(p.as_dvec3()));
    let size = (hi - lo).max_element();
    if size.is_finite() && size > 0.0 { (((lo + hi) * 0.5).as_vec3(), size) } else { (Vec3::ZERO, 1.0) }
}

/// The median and 90th percentile of the dihedral angles (degrees between the two face
/// normals) over the interior edges: how much a mesh's normals turn from face to face, which
/// bounds how narrow its patches' cones can be (the shared scans: medians 2.2° to 8.5°).
pub fn dihedral_angles(positions: &[Vec3], edges: &Edges) -> (f64, f64) {
    let p = |v: u32| positions[v as usize].as_dvec3();
    let mut angles: Vec<f64> = (edges.quads.iter())
        .map(|&[a, b, c, d]| {
            let n1 = (p(b) - p(a)).cross(p(c) - p(a));
            let n2 = (p(d) - p(a)).cross(p(b) - p(a));
            n1.angle_between(n2).to_degrees()
        })
        .filter(|a| a.is_finite())
        .collect();
    if angles.is_empty() {
        return (0.0, 0.0);
    }
    angles.sort_by(f64::total_cmp);
    let at = |q: f64| angles[((angles.len() - 1) as f64 * q) as usize];
    (at(0.5), at(0.9))
}

/// One row of the evaluation (static or skinned).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodResult {
    pub method: &'static str,
    /// Patches, or tree nodes for the SNCH.
    pub patches: usize,
    /// Edges tested ÷ edges, over all views (and frames), in percent.
    pub tested_edges_pct: f64,
    /// Contour edges ÷ edges over the same views (and frames), in percent, boundary edges
    /// (contours in every view, never tested) left out: every method tests at least these,
    /// so `tested_edges_pct` can never be lower.
    pub contour_edges_pct: f64,
    pub ms_per_view: f64,
    pub speedup_vs_brute: f64,
    pub build_s: f64,
    /// Views (frame-views) whose edge set differs from brute force's.
    pub mismatched_views: usize,
    /// Mean patch radius (model sizes) and cone half-angle (degrees); 0 when not patches.
    pub mean_radius: f64,
    pub mean_angle_deg: f64,
    /// Skinned rows: frames, and quads in rigid and in animated patches (the rest are
    /// tested every time).
    pub frames: usize,
    pub rigid_quads: usize,
    pub animated_quads: usize,
}

/// Runs `methods` over `views` (positions fixed), timing each over `repeats` rounds (the
/// fastest round counts) and checking every view against brute force.
pub fn evaluate(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    edges: &Edges,
    methods: &[Method],
    params: &PatchParams,
    views: &[Projection],
    repeats: usize,
) -> Vec<MethodResult> {
    let built: Vec<(Method, Extractor, f64)> = methods
        .iter()
        .map(|&m| {
            let t = Instant::now();
            let x = Extractor::build(m, positions, triangles, edges, params);
            (m, x, t.elapsed().as_secs_f64())
        })
        .collect();
    let mut reference = Vec::new();
    let mut out = Vec::new();
    let mut tested = vec![0usize; built.len()];
    let mut mismatched = vec![0usize; built.len()];
    let mut contours = 0;
    for &view in views {
        brute_force(positions, edges, view, &mut reference);
        contours += reference.len() - edges.boundary.len();
        for (k, (_, x, _)) in built.iter().enumerate() {
            tested[k] += x.extract(positions, edges, view, &mut out).edges;
            out.sort_unstable();
            mismatched[k] += usize::from(out != reference);
        }
    }
    // Timing: rounds interleave the methods so that machine noise hits them alike.
    let mut best = vec![f64::INFINITY; built.len()];
    for _ in 0..repeats.max(1) {
        for (k, (_, x, _)) in built.iter().enumerate() {
            let t = Instant::now();
            for &view in views {
                x.extract(positions, edges, view, &mut out);
            }
            best[k] = best[k].min(t.elapsed().as_secs_f64());
        }
    }
    // The baseline: brute force timed in the same rounds when it is one of the methods.
    let brute_s = match built.iter().position(|(m, _, _)| *m == Method::Brute) {
        Some(k) => best[k],
        None => time_brute(positions, edges, views, repeats),
    };
    let total = (edges.len() * views.len()).max(1) as f64;
    built
        .iter()
        .enumerate()
        .map(|(k, (m, x, build_s))| {
            let (mean_radius, mean_angle_deg) = match x {
                Extractor::Patches(p) => (p.mean_radius, p.mean_angle_deg),
                _ => (0.0, 0.0),
            };
            MethodResult {
                method: m.name(),
                patches: x.bounds(),
                tested_edges_pct: 100.0 * tested[k] as f64 / total,
                contour_edges_pct: 100.0 * contours as f64 / total,
                ms_per_view: 1e3 * best[k] / views.len().max(1) as f64,
                speedup_vs_brute: brute_s / best[k],
                build_s: *build_s,
                mismatched_views: mismatched[k],
                mean_radius,
                mean_angle_deg,
                ..MethodResult::default()
            }
        })
        .collect()
}

fn time_brute(positions: &[Vec3], edges: &Edges, views: &[Projection], repeats: usize) -> f64 {
    let mut out = Vec::new();
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        for &view in views {
            brute_force(positions, edges, view, &mut out);
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

/// Hardware calibration (section 4.2): `t_e` from brute force, `t_P` from one patch per
/// edge, `t_P = (t − τ·t_e) / ξ`. Returns `(t_e, t_P)` in nanoseconds.
pub fn calibrate(positions: &[Vec3], edges: &Edges, views: &[Projection], repeats: usize) -> (f64, f64) {
    let xi = edges.quads.len().max(1) as f64;
    let t_e = time_brute(positions, edges, views, repeats) / (xi * views.len().max(1) as f64);
    let singles: Vec<BuiltPatch> =
        (0..edges.quads.len() as u32).filter_map(|q| patches::bounds_of(positions, edges, &[q])).collect();
    let kept: std::collections::HashSet<u32> = singles.iter().map(|b| b.edges[0]).collect();
    let always = (0..edges.quads.len() as u32).filter(|q| !kept.contains(q)).collect();
    let one_each = patches::assemble(edges, singles, always, patches::size_of(positions, edges));
    let mut out = Vec::new();
    let mut best = f64::INFINITY;
    let mut tau = 0;
    for _ in 0..repeats.max(1) {
        tau = 0;
        let t = Instant::now();
        for &view in views {
            tau += one_each.extract(positions, edges, view, &mut out).edges;
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    let per_view = views.len().max(1) as f64;
    let t_p = (best - tau as f64 * t_e) / (xi * per_view);
    (t_e * 1e9, t_p * 1e9)
}

/// A skinned character for [`evaluate_skinned`].
pub struct SkinnedInput<'a> {
    pub skeleton: &'a skinlet::model::Skeleton,
    pub skin: &'a skinlet::model::Skin,
    pub clips: &'a [&'a skinlet::clip::Clip],
    /// Welded mesh with skin weights.
    pub mesh: &'a skinlet::model::SkinnedMesh,
    /// Sample times per clip (evenly spread over its key range).
    pub frames_per_clip: usize,
}

/// The skinned rows: brute force, the paper's rigid parts and ours (animated bounds), each
/// over every sampled frame × 42 directions × 6 distances around the frame's box center.
pub fn evaluate_skinned(
    input: &SkinnedInput,
    edges: &Edges,
    methods: &[skinlet::contour::skinned::SkinnedMethod],
    params: &skinlet::contour::skinned::SkinnedParams,
    repeats: usize,
) -> skinlet::Result<Vec<MethodResult>> {
    use skinlet::contour::skinned::{SkinnedPatches, build};
    let built: Vec<(skinlet::contour::skinned::SkinnedMethod, SkinnedPatches, f64)> = methods
        .iter()
        .map(|&m| {
            let t = Instant::now();
            let sp = skinlet::contour::skinned::SkinnedParams { method: m, ..*params };
            let b = build(input.skeleton, input.skin, input.clips, input.mesh, edges, &sp)?;
            Ok((m, b, t.elapsed().as_secs_f64()))
        })
        .collect::<skinlet::Result<_>>()?;
    // Frames: positions and the joints' inverse global matrices (once per frame).
    let mut poser = skinlet::pose::Poser::default();
    let (mut matrices, mut weights) = (Vec::new(), Vec::new());
    // (skinned positions, inverse joint globals, (clip, time)) per frame.
    type Frame = (Vec<Vec3>, Vec<glam::DMat4>, (usize, f32));
    let mut frames: Vec<Frame> = Vec::new();
    for (c, clip) in input.clips.iter().enumerate() {
        let keys = clip.key_times();
        let (t0, t1) = (keys.first().copied().unwrap_or(0.0), keys.last().copied().unwrap_or(0.0));
        let n = input.frames_per_clip.max(1);
        for k in 0..n {
            let t = t0 + (t1 - t0) * (k as f32 + 0.5) / n as f32;
            let globals = poser.globals(input.skeleton, Some(clip), t).to_vec();
            skinlet::pose::skinning_matrices(input.skin, &globals, &mut matrices);
            input.mesh.morphs.weights_at(Some(clip), t, &mut weights);
            let mut p = vec![Vec3::ZERO; input.mesh.positions.len()];
            skinlet::skinning::skin_mesh(input.mesh, &weights, &matrices, &mut p, &mut [])?;
            let inverses = input.skin.joints.iter().map(|&j| globals[j as usize].inverse()).collect();
            frames.push((p, inverses, (c, t)));
        }
    }
    let size = frame(&input.mesh.positions).1;
    let frame_views: Vec<Vec<Projection>> = frames.iter().map(|(p, _, _)| views_around(frame(p).0, size)).collect();
    let (mut reference, mut out) = (Vec::new(), Vec::new());
    let mut tested = vec![0usize; built.len() + 1];
    let mut mismatched = vec![0usize; built.len() + 1];
    let mut contours = 0;
    for ((p, joints, at), views) in frames.iter().zip(&frame_views) {
        for &view in views {
            tested[0] += brute_force(p, edges, view, &mut reference).edges;
            contours += reference.len() - edges.boundary.len();
            for (k, (_, b, _)) in built.iter().enumerate() {
                tested[k + 1] += b.extract_prepared(p, edges, joints, Some(*at), view, &mut out).edges;
                out.sort_unstable();
                mismatched[k + 1] += usize::from(out != reference);
            }
        }
    }
    let mut best = vec![f64::INFINITY; built.len() + 1];
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        for ((p, _, _), views) in frames.iter().zip(&frame_views) {
            for &view in views {
                brute_force(p, edges, view, &mut out);
            }
        }
        best[0] = best[0].min(t.elapsed().as_secs_f64());
        for (k, (_, b, _)) in built.iter().enumerate() {
            let t = Instant::now();
            for ((p, joints, at), views) in frames.iter().zip(&frame_views) {
                for &view in views {
                    b.extract_prepared(p, edges, joints, Some(*at), view, &mut out);
                }
            }
            best[k + 1] = best[k + 1].min(t.elapsed().as_secs_f64());
        }
    }
    let n_views: usize = frame_views.iter().map(Vec::len).sum();
    let total = (edges.len() * n_views).max(1) as f64;
    let row = |k: usize, name: &'static str, patches: usize, build_s: f64, quads: (usize, usize)| MethodResult {
        method: name,
        patches,
        tested_edges_pct: 100.0 * tested[k] as f64 / total,
        contour_edges_pct: 100.0 * contours as f64 / total,
        ms_per_view: 1e3 * best[k] / n_views.max(1) as f64,
        speedup_vs_brute: best[0] / best[k],
        build_s,
        mismatched_views: mismatched[k],
        frames: frames.len(),
        rigid_quads: quads.0,
        animated_quads: quads.1,
        ..MethodResult::default()
    };
    let mut rows = vec![row(0, "brute", 0, 0.0, (0, 0))];
    for (k, (m, b, s)) in built.iter().enumerate() {
        rows.push(row(k + 1, m.name(), b.patches.len(), *s, (b.rigid_quads, b.animated_quads)));
    }
    Ok(rows)
}
