//! The bake file: everything the runtime needs to draw and cull one skinned character, in
//! one versioned little-endian binary file (layout in `docs/FORMAT.md`): the prepared
//! vertices and skin weights, the inverse bind matrices, the triangles, the meshlets (the
//! flat layout of [`crate::meshlet::flat`]) and their conservative bounds and classes, per
//! part a box per clip window ([`crate::bounds::part_windows`]), and optionally
//! overdraw-reducing index buffers with their lookup table ([`add_overdraw`]), contour patches
//! with bounds over the clips ([`add_contours`]) and a pose envelope ([`add_envelope`]).
//!
//! Guarantees: [`to_bytes`] is a pure function of the [`Baked`] value (same input and
//! options, same bytes); [`from_bytes`] accepts exactly what `to_bytes` can produce and
//! reports anything else (wrong magic, newer version, truncation, out-of-range indices,
//! non-finite numbers) as an error naming the section and byte; [`write()`] replaces the
//! destination atomically (temporary file in the same folder, then rename). Readers skip
//! sections with tags they do not know, so later versions can add sections.

use crate::bounds::envelope::{Envelope, envelope_bounds};
use crate::bounds::part_windows::{PartWindows, part_windows};
use crate::bounds::refine::{Progress, Refinement, Stop, refine_with_progress};
use crate::bounds::sphere_cone::{Class, MeshletBounds, classify};
use crate::character::{Character, PartKind};
use crate::clip::Clip;
use crate::contour::skinned::{SkinnedParams, skinned_edges};
use crate::cull::any_pose::AnyPoseBoxes;
use crate::meshlet::lod::{LodHierarchy, LodParams};
use crate::meshlet::sources::source_triangles;
use crate::meshlet::{
    Builder, MeshletLimits, Meshlets, PartRange, PreparedMesh, build_moving, flat, motion_for, prepare_parts,
};
use crate::model::{Asset, Influences, Morphs, Skin, SkinnedMesh};
use crate::overdraw::cluster::{ClusterParams, Orders, cluster};
use crate::overdraw::evaluate::keyframes;
use crate::{Error, Result};
use glam::{Mat4, Vec3};
use skinlet_runtime::bake_view::{BakeView, NO_GROUP, bounds_and_classes};
use skinlet_runtime::part_bounds::{PartBounds, PoseBounds};
use std::io::Write;
use std::ops::Range;
use std::path::Path;

pub use skinlet_runtime::bake_view::{MAGIC, VERSION};
/// Contour patches of a bake's mesh; their quads index the edges that
/// [`skinned_edges`]`(mesh, visible_only)` rebuilds from the stored triangles.
pub use skinlet_runtime::contour_patches::BakedContours;

/// How a bake was made (enough to reproduce it from the same source file).
#[derive(Clone, Debug, PartialEq)]
pub struct BakeSettings {
    pub builder: Builder,
    pub limits: MeshletLimits,
    /// Classification thresholds: radius growth and normal deviation (radians).
    pub s_r: f32,
    pub alpha_t: f32,
    /// Refinement rounds done and why they stopped.
    pub rounds: u32,
    pub stop: Stop,
    /// Names of the clips the bounds hold for (their union).
    pub clips: Vec<String>,
}

/// One part of a baked character (see [`crate::character`]): which node draws which
/// primitive, and where its vertices, triangles and meshlets lie in the bake.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BakedPart {
    pub node: u32,
    pub mesh: u32,
    pub primitive: u32,
    pub kind: PartKind,
    pub vertices: Range<u32>,
    pub triangles: Range<u32>,
    pub meshlets: Range<u32>,
}

/// A baked character.
#[derive(Clone, Debug, PartialEq)]
pub struct Baked {
    pub settings: BakeSettings,
    /// The character's drivers (its palette): node index, name (empty for unnamed nodes) and
    /// inverse bind matrix of each; skinning matrix `d` is `global(joint_nodes[d]) × inverse_bind[d]`.
    pub joint_nodes: Vec<u32>,
    pub joint_names: Vec<String>,
    pub inverse_bind: Vec<Mat4>,
    /// The parts, in mesh order; their ranges cover the vertices, triangles and meshlets.
    pub parts: Vec<BakedPart>,
    /// Welded, cache-ordered vertices with influences; its triangles are the meshlets'.
    pub mesh: SkinnedMesh,
    pub meshlets: Meshlets,
    pub bounds: Vec<MeshletBounds>,
    pub classes: Vec<Class>,
    /// Overdraw-reducing index buffers with their run-time lookup (optional section OVDR).
    pub overdraw: Option<Orders>,
    /// Contour patches of the mesh (optional section CONT).
    pub contours: Option<BakedContours>,
    /// A pose envelope with its bounds, and the any-pose boxes (optional section ENVL).
    pub envelope: Option<BakedEnvelope>,
    /// Per part, a box per time window of each clip (section PWIN; none without clips).
    pub part_windows: Option<PartWindows>,
    /// Per meshlet triangle, its source triangle and corner rotation
    /// ([`crate::meshlet::sources`]; section SRCT, written by [`bake`]).
    pub sources: Option<Vec<u32>>,
    /// The cluster LOD hierarchy (optional section LODC, [`add_lod`]).
    pub lod: Option<BakedLod>,
}

/// The cluster LOD hierarchy of a bake ([`crate::meshlet::lod`], errors from
/// [`crate::bounds::lod_error`]): `MLET`'s meshlets are level 0; the clusters above them are
/// meshlets of their own (same layout and limits) with conservative bounds over the bake's
/// clips. Groups are numbered over the whole character; a part's clusters and groups are its
/// own.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLod {
    /// Per group: the level of the clusters it made and its error (scene units).
    pub groups: Vec<(u32, f32)>,
    /// Per `MLET` meshlet, its parent group ([`NO_GROUP`]: a root).
    pub base_parents: Vec<u32>,
    /// Per cluster above level 0: its own group and its parent group ([`NO_GROUP`]: a root).
    pub clusters: Vec<[u32; 2]>,
    pub meshlets: Meshlets,
    pub bounds: Vec<MeshletBounds>,
    pub classes: Vec<Class>,
    /// Per part, the range of its clusters.
    pub part_clusters: Vec<Range<u32>>,
    /// Errors and cluster bounds for the poses inside the bake's pose envelope (optional
    /// section LODE): present when the bake has both.
    pub envelope: Option<BakedLodEnvelope>,
}

/// A LOD hierarchy's errors and cluster bounds within a pose envelope
/// ([`crate::bounds::lod_error::bound_errors`], [`envelope_bounds`]): what an instance the
/// pose guard admits selects and culls its cut with.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLodEnvelope {
    /// Per group (as [`BakedLod::groups`]), its error within the envelope (scene units).
    pub errors: Vec<f32>,
    pub bounds: Vec<MeshletBounds>,
    pub classes: Vec<Class>,
}

impl BakedLod {
    /// Each part's hierarchy, with the range of the part's triangles: its clusters are the
    /// part's `MLET` meshlets (level 0), then its own clusters; its groups are numbered from 0.
    pub fn hierarchies(&self, meshlets: &Meshlets, parts: &[BakedPart]) -> Vec<(Range<u32>, LodHierarchy)> {
        use crate::meshlet::lod::{LodCluster, LodGroup};
        let triangles = |m: &Meshlets, i: usize| -> Vec<u32> { m.mesh_triangles(&m.meshlets[i]).flatten().collect() };
        let mut out = Vec::with_capacity(parts.len());
        for (part, range) in parts.iter().zip(&self.part_clusters) {
            let base = part.meshlets.start as usize..part.meshlets.end as usize;
            let own = range.start as usize..range.end as usize;
            // The part's groups: a contiguous range (add_lod numbers them part by part).
            let used = own.clone().map(|c| self.clusters[c][0]).chain(base.clone().map(|m| self.base_parents[m]));
            let used: Vec<u32> = used.filter(|&g| g != NO_GROUP).collect();
            let first = used.iter().copied().min().unwrap_or(0);
            let end = used.iter().copied().max().map_or(first, |g| g + 1);
            let local = |g: u32| (g != NO_GROUP && (first..end).contains(&g)).then(|| g - first);
            let mut lod = LodHierarchy::default();
            for m in base.clone() {
                let (triangles, parent) = (triangles(meshlets, m), local(self.base_parents[m]));
                lod.clusters.push(LodCluster { triangles, level: 0, group: None, parent });
            }
            for c in own.clone() {
                let [group, parent] = self.clusters[c];
                let level = self.groups[group as usize].0;
                let (triangles, group, parent) = (triangles(&self.meshlets, c), local(group), local(parent));
                lod.clusters.push(LodCluster { triangles, level, group, parent });
            }
            lod.groups = (first..end)
                .map(|g| {
                    let (level, error) = self.groups[g as usize];
                    LodGroup { level, children: Vec::new(), made: Vec::new(), error }
                })
                .collect();
            for (c, cluster) in lod.clusters.iter().enumerate() {
                if let Some(g) = cluster.parent {
                    lod.groups[g as usize].children.push(c as u32);
                }
                if let Some(g) = cluster.group {
                    lod.groups[g as usize].made.push(c as u32);
                }
            }
            out.push((part.triangles.clone(), lod));
        }
        out
    }

    /// [`Self::hierarchies`] with the errors within the pose envelope (`None` without them).
    pub fn envelope_hierarchies(
        &self,
        meshlets: &Meshlets,
        parts: &[BakedPart],
    ) -> Option<Vec<(Range<u32>, LodHierarchy)>> {
        let errors = &self.envelope.as_ref()?.errors;
        let mut out = self.hierarchies(meshlets, parts);
        let mut next = errors.iter();
        for (_, lod) in &mut out {
            lod.groups.iter_mut().zip(&mut next).for_each(|(g, &e)| g.error = e);
        }
        Some(out)
    }
}

/// Bounds for the poses games make: a pose envelope with meshlet bounds (and their classes)
/// that hold for every pose inside it, and per-meshlet any-pose boxes for the poses outside
/// (see [`crate::bounds::envelope`], [`crate::cull::any_pose`]). The any-pose boxes hold for
/// any joint matrices with morph weights inside the envelope's ranges.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedEnvelope {
    pub envelope: Envelope,
    /// Name of each range's node (empty for unnamed nodes), in `envelope.nodes` order.
    pub names: Vec<String>,
    pub bounds: Vec<MeshletBounds>,
    pub classes: Vec<Class>,
    pub any_pose: AnyPoseBoxes,
}

/// Precomputation figures of a bake (not stored: they depend on the machine).
#[derive(Clone, Copy, Debug)]
pub struct BakeStats {
    /// Wall-clock time of the bounds (key intervals and refinement).
    pub precompute: std::time::Duration,
    /// Vertex-influence-intervals evaluated ([`crate::bounds::refine::Refined::work`]).
    pub work: u64,
}

/// The character prepared for meshlets, its parts kept apart.
pub fn prepare_character(character: &Character) -> Result<PreparedMesh> {
    let ranges: Vec<PartRange> = (character.parts.iter())
        .map(|p| PartRange { vertices: p.vertices.clone(), triangles: p.triangles.clone() })
        .collect();
    prepare_parts(&character.mesh, &ranges)
}

/// Bakes the whole character of `asset` (every part, see [`crate::character`]): prepares
/// its mesh part by part, builds meshlets (none mixes two parts), computes bounds over the
/// union of `clips` refined as `how` allows, and classifies them.
pub fn bake(
    asset: &Asset,
    character: &Character,
    clips: &[&Clip],
    builder: Builder,
    limits: MeshletLimits,
    how: &Refinement,
    progress: &mut dyn FnMut(Progress),
) -> Result<(Baked, BakeStats)> {
    let s = &character.palette;
    let prepared = prepare_character(character)?;
    let motion = motion_for(builder, &asset.skeleton, s, &prepared.mesh, clips)?;
    let meshlets = build_moving(&prepared, builder, limits, motion.as_ref())?;
    let mut parts = Vec::with_capacity(character.parts.len());
    let mut first_meshlet = 0u32;
    for (p, r) in character.parts.iter().zip(&prepared.parts) {
        let end = (first_meshlet as usize..meshlets.len())
            .find(|&m| meshlets.vertices_of(&meshlets.meshlets[m])[0] >= r.vertices.end)
            .unwrap_or(meshlets.len()) as u32;
        parts.push(BakedPart {
            node: p.node,
            mesh: p.mesh,
            primitive: p.primitive,
            kind: p.kind,
            vertices: r.vertices.clone(),
            triangles: r.triangles.clone(),
            meshlets: first_meshlet..end,
        });
        first_meshlet = end;
    }
    let ranges: Vec<Range<u32>> = parts.iter().map(|p| p.meshlets.clone()).collect();
    let sources = source_triangles(character, &prepared, &meshlets, &ranges)?;
    let started = std::time::Instant::now();
    let mut refined = refine_with_progress(&asset.skeleton, s, clips, &prepared.mesh, &meshlets, how, progress)?;
    // A radius past f32's range (a joint that nearly collapses within a key interval): the
    // largest finite one, which never culls, keeps the file's floats finite.
    for b in refined.bounds.iter_mut().filter(|b| !b.radius.is_finite()) {
        b.radius = f32::MAX;
    }
    let part_windows = if clips.is_empty() {
        None
    } else {
        let ranges: Vec<Range<u32>> = parts.iter().map(|p| p.vertices.clone()).collect();
        Some(part_windows(&asset.skeleton, s, clips, &prepared.mesh, &ranges)?)
    };
    let stats = BakeStats { precompute: started.elapsed(), work: refined.work };
    let baked = Baked {
        settings: BakeSettings {
            builder,
            limits,
            s_r: how.s_r,
            alpha_t: how.alpha_t,
            rounds: refined.rounds as u32,
            stop: refined.stop,
            clips: clips.iter().map(|c| c.name.clone()).collect(),
        },
        joint_nodes: s.joints.clone(),
        joint_names: s.joints.iter().map(|&j| asset.skeleton.nodes[j as usize].name.clone()).collect(),
        inverse_bind: s.inverse_bind.clone(),
        parts,
        classes: refined.bounds.iter().map(|b| classify(b, how.s_r, how.alpha_t)).collect(),
        mesh: prepared.mesh,
        meshlets,
        bounds: refined.bounds,
        overdraw: None,
        contours: None,
        envelope: None,
        part_windows,
        sources: Some(sources),
        lod: None,
    };
    Ok((baked, stats))
}

/// Adds overdraw-reducing index buffers to a bake: the "joint" clustering of Han & Sander
/// over up to `max_keyframes` key times of every clip the bounds were baked for. Each buffer
/// keeps every part's triangles in the part's triangle range (a stable partition of the
/// clustered order by part), so a renderer still binds one material per range; the order
/// within a part is the clustering's.
pub fn add_overdraw(baked: &mut Baked, asset: &Asset, params: &ClusterParams, max_keyframes: usize) -> Result<()> {
    if !(1..=255).contains(&params.k) {
        return Err(Error::invalid("bake", format!("{} overdraw buffers (the bake holds 1 to 255)", params.k)));
    }
    let mut keys = Vec::new();
    let mut positions = Vec::new();
    let palette = baked.palette();
    for (i, clip) in baked_clips(baked, asset)?.into_iter().enumerate() {
        let (times, pos) = keyframes(&asset.skeleton, &palette, &baked.mesh, clip, max_keyframes)?;
        keys.extend(times.into_iter().map(|t| (i as u32, t)));
        positions.extend(pos);
    }
    if positions.is_empty() {
        return Err(Error::invalid("bake", "overdraw orders need at least one clip"));
    }
    let c = cluster(&positions, &baked.mesh.triangles, params);
    let mut orders = crate::overdraw::cluster::orders(&c, keys);
    let part_of = |t: &[u32; 3]| baked.parts.partition_point(|p| p.vertices.end <= t[0]);
    for buffer in &mut orders.buffers {
        buffer.sort_by_key(part_of);
    }
    baked.overdraw = Some(orders);
    Ok(())
}

/// Adds contour patches (see [`crate::contour::skinned`]) with bounds over the clips the
/// bake was made for.
pub fn add_contours(baked: &mut Baked, asset: &Asset, params: &SkinnedParams, visible_only: bool) -> Result<()> {
    let clips = baked_clips(baked, asset)?;
    let edges = skinned_edges(&baked.mesh, visible_only)?;
    let patches =
        crate::contour::skinned::build(&asset.skeleton, &baked.palette(), &clips, &baked.mesh, &edges, params)?;
    baked.contours = Some(BakedContours { visible_only, patches });
    Ok(())
}

/// Adds a cluster LOD hierarchy to a bake, part by part ([`crate::meshlet::lod::build`] with
/// the vertices' positions at sampled poses of the baked clips as attributes), with errors
/// and cluster bounds that hold over those clips, and within the bake's pose envelope where
/// it has one.
pub fn add_lod(baked: &mut Baked, asset: &Asset, params: &LodParams) -> Result<()> {
    let palette = baked.palette();
    let clips = baked_clips(baked, asset)?;
    let mesh = &baked.mesh;
    let attributes = crate::meshlet::lod::posed_attributes(&asset.skeleton, &palette, &clips, mesh, 8)?;
    let mut out = BakedLod {
        groups: Vec::new(),
        base_parents: vec![NO_GROUP; baked.meshlets.len()],
        clusters: Vec::new(),
        meshlets: Meshlets::default(),
        bounds: Vec::new(),
        classes: Vec::new(),
        part_clusters: Vec::new(),
        envelope: None,
    };
    let envelope = baked.envelope.as_ref().map(|e| &e.envelope);
    let mut within_envelope = Vec::new();
    let limits = baked.settings.limits;
    for part in &baked.parts {
        let first = out.clusters.len() as u32;
        let base = part.meshlets.start as usize..part.meshlets.end as usize;
        let mine = baked.meshlets.subset(base.clone());
        let mut lod = crate::meshlet::lod::build(&mesh.positions, &attributes, &mine, limits, *params)?;
        let within =
            crate::bounds::lod_error::bound_errors(&asset.skeleton, &palette, &clips, envelope, mesh, &mut lod)?;
        within_envelope.extend(within.unwrap_or_default().iter().map(|e| e.min(f32::MAX)));
        let group_offset = out.groups.len() as u32;
        let global = |g: Option<u32>| g.map_or(NO_GROUP, |g| g + group_offset);
        // An unbounded error (a scale through zero) as the largest finite one: never coarser.
        out.groups.extend(lod.groups.iter().map(|g| (g.level, g.error.min(f32::MAX))));
        for (i, c) in lod.clusters.iter().enumerate() {
            if i < base.len() {
                out.base_parents[base.start + i] = global(c.parent);
            } else {
                out.clusters.push([global(c.group), global(c.parent)]);
                out.meshlets.push_triangles(&c.triangles);
            }
        }
        out.part_clusters.push(first..out.clusters.len() as u32);
    }
    let bounds = crate::bounds::sphere_cone::meshlet_bounds(&asset.skeleton, &palette, &clips, mesh, &out.meshlets)?;
    out.classes = bounds.iter().map(|b| classify(b, baked.settings.s_r, baked.settings.alpha_t)).collect();
    out.bounds = bounds;
    for b in out.bounds.iter_mut().filter(|b| !b.radius.is_finite()) {
        b.radius = f32::MAX;
    }
    if let Some(e) = envelope {
        out.envelope = Some(lod_envelope(baked, asset, e, &out.meshlets, within_envelope)?);
    }
    baked.lod = Some(out);
    Ok(())
}

/// The clusters' bounds within `envelope`, with the groups' `errors` there.
fn lod_envelope(
    baked: &Baked,
    asset: &Asset,
    envelope: &Envelope,
    clusters: &Meshlets,
    errors: Vec<f32>,
) -> Result<BakedLodEnvelope> {
    let mut bounds = envelope_bounds(&asset.skeleton, &baked.palette(), &baked.mesh, clusters, envelope)?;
    let classes = bounds.iter().map(|b| classify(b, baked.settings.s_r, baked.settings.alpha_t)).collect();
    for b in bounds.iter_mut().filter(|b| !b.radius.is_finite()) {
        b.radius = f32::MAX;
    }
    Ok(BakedLodEnvelope { errors, bounds, classes })
}

/// Adds a pose envelope to a bake: meshlet bounds for every pose inside it, classified with
/// the bake's thresholds, and the any-pose boxes for morph weights inside its ranges. A LOD
/// hierarchy's errors and bounds within an earlier envelope are dropped (they hold for that
/// one): [`add_lod_envelope`] bounds them for this one; adding the envelope before the
/// hierarchy ([`add_lod`]) bounds them once.
pub fn add_envelope(baked: &mut Baked, asset: &Asset, envelope: Envelope) -> Result<()> {
    let palette = baked.palette();
    let bounds = envelope_bounds(&asset.skeleton, &palette, &baked.mesh, &baked.meshlets, &envelope)?;
    let classes = bounds.iter().map(|b| classify(b, baked.settings.s_r, baked.settings.alpha_t)).collect();
    let any_pose = crate::cull::any_pose::build(&palette, &baked.mesh, &baked.meshlets, &envelope.weight_ranges())?;
    let names = envelope.nodes.iter().map(|r| asset.skeleton.nodes[r.node as usize].name.clone()).collect();
    baked.envelope = Some(BakedEnvelope { envelope, names, bounds, classes, any_pose });
    if let Some(lod) = &mut baked.lod {
        lod.envelope = None;
    }
    Ok(())
}

/// Bounds a bake's LOD hierarchy's errors and cluster bounds within its pose envelope
/// (section LODE), for a bake that got its envelope after its hierarchy. Errors without both.
pub fn add_lod_envelope(baked: &mut Baked, asset: &Asset) -> Result<()> {
    let (Some(lod), Some(e)) = (&baked.lod, &baked.envelope) else {
        return Err(Error::invalid("LOD within the envelope", "the bake has no LOD hierarchy or no pose envelope"));
    };
    let (palette, clips) = (baked.palette(), baked_clips(baked, asset)?);
    let mut errors = Vec::with_capacity(lod.groups.len());
    for (_, mut h) in lod.hierarchies(&baked.meshlets, &baked.parts) {
        let bound = crate::bounds::lod_error::bound_errors;
        let within = bound(&asset.skeleton, &palette, &clips, Some(&e.envelope), &baked.mesh, &mut h)?;
        errors.extend(within.unwrap_or_default().iter().map(|e| e.min(f32::MAX)));
    }
    if errors.len() != lod.groups.len() {
        return Err(Error::invalid("LOD within the envelope", "the hierarchies do not cover every group"));
    }
    let within = lod_envelope(baked, asset, &e.envelope, &lod.meshlets, errors)?;
    baked.lod.as_mut().expect("checked above").envelope = Some(within);
    Ok(())
}

impl Baked {
    /// The drivers as a skin (joints: their nodes): what the skinning matrices come from.
    pub fn palette(&self) -> Skin {
        Skin { name: String::new(), joints: self.joint_nodes.clone(), inverse_bind: self.inverse_bind.clone() }
    }
}

/// The clips a bake's bounds were computed for, found in `asset` by name.
fn baked_clips<'a>(baked: &Baked, asset: &'a Asset) -> Result<Vec<&'a Clip>> {
    (baked.settings.clips.iter())
        .map(|name| {
            asset
                .clips
                .iter()
                .find(|c| &c.name == name)
                .ok_or_else(|| Error::invalid("bake", format!("no clip {name:?}")))
        })
        .collect()
}

/// Section tags: the seven required ones, then the optional overdraw orders, contours, morph
/// targets, pose envelope, part windows, source triangles, cluster LOD and its errors and
/// bounds within the envelope.
const TAGS: [&[u8; 4]; 15] = [
    b"INFO", b"SKIN", b"VERT", b"TRIS", b"MLET", b"BNDS", b"PART", b"OVDR", b"CONT", b"MRPH", b"ENVL", b"PWIN",
    b"SRCT", b"LODC", b"LODE",
];
const HEADER: usize = 16;
const ENTRY: usize = 24;

fn builder_code(b: Builder) -> u32 {
    Builder::ALL.iter().position(|&x| x == b).expect("every builder is in ALL") as u32
}

fn stop_code(s: Stop) -> u32 {
    match s {
        Stop::Converged => 0,
        Stop::Rounds => 1,
        Stop::Budget => 2,
    }
}

fn class_code(c: Class) -> u32 {
    match c {
        Class::Both => 0,
        Class::FrustumOnly => 1,
        Class::None => 2,
    }
}

#[derive(Default)]
struct Out(Vec<u8>);

impl Out {
    fn u32(&mut self, x: u32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f32(&mut self, x: f32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn vec3(&mut self, v: Vec3) {
        v.to_array().iter().for_each(|&x| self.f32(x));
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    /// Meshlet bounds with their classes, 48 bytes each ([`skinlet_runtime::bake_view::BakedBounds`]).
    fn bounds(&mut self, bounds: &[MeshletBounds], classes: &[Class]) {
        for (x, c) in bounds.iter().zip(classes) {
            self.vec3(x.center);
            self.f32(x.radius);
            self.vec3(x.cone_axis);
            self.f32(x.cone_angle);
            self.f32(x.rest_radius);
            self.f32(x.rest_cone_angle);
            self.u32(x.joint as u32);
            self.u32(class_code(*c));
        }
    }
}

/// The file's bytes.
pub fn to_bytes(b: &Baked) -> Vec<u8> {
    let s = &b.settings;
    let mut info = Out::default();
    for x in [builder_code(s.builder), s.limits.max_vertices as u32, s.limits.max_triangles as u32] {
        info.u32(x);
    }
    info.f32(s.s_r);
    info.f32(s.alpha_t);
    info.u32(s.rounds);
    info.u32(stop_code(s.stop));
    info.u32(s.clips.len() as u32);
    s.clips.iter().for_each(|c| info.str(c));

    let mut skin = Out::default();
    skin.u32(b.inverse_bind.len() as u32);
    b.inverse_bind.iter().flat_map(|m| m.to_cols_array()).for_each(|x| skin.f32(x));
    b.joint_nodes.iter().for_each(|&n| skin.u32(n));
    b.joint_names.iter().for_each(|n| skin.str(n));

    let mut part = Out::default();
    part.u32(b.parts.len() as u32);
    for p in &b.parts {
        let skin = match p.kind {
            PartKind::Skinned { skin } => skin,
            PartKind::Rigid => u32::MAX,
        };
        for x in [p.node, p.mesh, p.primitive, skin] {
            part.u32(x);
        }
        for r in [&p.vertices, &p.triangles, &p.meshlets] {
            part.u32(r.start);
            part.u32(r.end);
        }
    }

    let m = &b.mesh;
    let (stride, joints, weights) =
        m.influences.as_ref().map_or((0, &[][..], &[][..]), |i| (i.stride, &i.joints[..], &i.weights[..]));
    let mut vert = Out::default();
    vert.u32(m.positions.len() as u32);
    vert.u32(stride as u32);
    vert.u32(!m.normals.is_empty() as u32);
    m.positions.iter().chain(&m.normals).for_each(|&p| vert.vec3(p));
    joints.iter().for_each(|j| vert.0.extend_from_slice(&j.to_le_bytes()));
    vert.0.resize(vert.0.len().next_multiple_of(4), 0);
    weights.iter().for_each(|&w| vert.f32(w));

    let mut tris = Out::default();
    tris.u32(m.triangles.len() as u32);
    m.triangles.iter().flatten().for_each(|&i| tris.u32(i));

    let mut bnds = Out::default();
    bnds.u32(b.bounds.len() as u32);
    bnds.0.resize(16, 0);
    bnds.bounds(&b.bounds, &b.classes);

    let mut sections = vec![info.0, skin.0, vert.0, tris.0, flat::to_bytes(&b.meshlets), bnds.0, part.0];
    let mut tags: Vec<&[u8; 4]> = TAGS[..7].to_vec();
    if let Some(o) = &b.overdraw {
        tags.push(TAGS[7]);
        let mut ov = Out::default();
        let l = &o.lookup;
        for x in [o.buffers.len(), o.keyframes.len(), l.polar, l.azimuth] {
            ov.u32(x as u32);
        }
        ov.f32(o.patches.to_f32());
        ov.vec3(o.framing.center);
        ov.f32(o.framing.radius);
        for &(clip, t) in &o.keyframes {
            ov.u32(clip);
            ov.f32(t);
        }
        for buf in &o.buffers {
            ov.u32(buf.len() as u32);
            buf.iter().flatten().for_each(|&i| ov.u32(i));
        }
        ov.0.extend_from_slice(&l.table);
        ov.0.resize(ov.0.len().next_multiple_of(4), 0);
        sections.push(ov.0);
    }
    if !m.morphs.is_empty() {
        tags.push(TAGS[9]);
        let mut mr = Out::default();
        let mo = &m.morphs;
        mr.u32(mo.weights.len() as u32);
        mr.u32(mo.deltas.len() as u32);
        for w in &mo.weights {
            mr.u32(w.node);
            mr.u32(w.target);
            mr.f32(w.default);
        }
        mo.offsets.iter().for_each(|&o| mr.u32(o));
        for d in &mo.deltas {
            mr.u32(d.weight);
            mr.vec3(d.position);
            mr.vec3(d.normal);
        }
        sections.push(mr.0);
    }
    if let Some(c) = &b.contours {
        tags.push(TAGS[8]);
        let (sp, p) = (&c.patches, &c.patches.patches);
        let mut ct = Out::default();
        for x in [c.visible_only as usize, p.order.len(), p.len(), p.always_from, sp.rigid_quads, sp.animated_quads] {
            ct.u32(x as u32);
        }
        for x in [p.size, p.mean_radius, p.mean_angle_deg, p.cost_ratio] {
            ct.f64(x);
        }
        ct.0.resize(64, 0);
        for ((x, r), j) in p.bounds.iter().zip(&p.ranges).zip(&sp.joints) {
            ct.vec3(x.center);
            ct.f32(x.radius);
            ct.vec3(x.axis);
            ct.f32(x.sin_angle);
            ct.f32(x.cos_angle);
            ct.u32(*j as u32);
            ct.u32(r[0]);
            ct.u32(r[1]);
        }
        p.order.iter().for_each(|&i| ct.u32(i));
        ct.u32(sp.clips.len() as u32);
        for w in &sp.clips {
            ct.f32(w.start);
            ct.f32(w.end);
            ct.u32(w.count);
            ct.u32(w.first);
        }
        for x in &sp.window_bounds {
            ct.f32(x.radius);
            ct.f32(x.sin_angle);
            ct.f32(x.cos_angle);
        }
        sections.push(ct.0);
    }
    if let Some(e) = &b.envelope {
        tags.push(TAGS[10]);
        let (env, any) = (&e.envelope, &e.any_pose);
        let mut ev = Out::default();
        for x in [env.nodes.len(), env.weights.len(), e.bounds.len(), any.joints.len()] {
            ev.u32(x as u32);
        }
        for r in &env.nodes {
            ev.u32(r.node);
            r.centre.to_array().iter().for_each(|&x| ev.f32(x));
            ev.f32(r.angle);
            for v in [r.translation.0, r.translation.1, r.scale.0, r.scale.1] {
                ev.vec3(v);
            }
        }
        for &(lo, hi) in &env.weights {
            ev.f32(lo);
            ev.f32(hi);
        }
        ev.0.resize(ev.0.len().next_multiple_of(16), 0);
        ev.bounds(&e.bounds, &e.classes);
        any.offsets.iter().for_each(|&o| ev.u32(o));
        any.joints.iter().for_each(|&j| ev.u32(j as u32));
        for (c, h) in any.center.iter().zip(&any.half) {
            ev.vec3(*c);
            ev.vec3(*h);
        }
        e.names.iter().for_each(|n| ev.str(n));
        ev.0.resize(ev.0.len().next_multiple_of(4), 0);
        sections.push(ev.0);
    }
    if let Some(w) = &b.part_windows {
        tags.push(TAGS[11]);
        let mut pw = Out::default();
        for x in [w.anchors.len(), w.clips.len(), w.windows(), 0] {
            pw.u32(x as u32);
        }
        for c in &w.clips {
            pw.f32(c.start);
            pw.f32(c.end);
            pw.u32(c.count);
            pw.u32(c.first);
        }
        w.anchors.iter().for_each(|&a| pw.u32(a));
        w.boxes.iter().flatten().for_each(|&v| pw.vec3(v));
        sections.push(pw.0);
    }
    if let Some(sources) = &b.sources {
        tags.push(TAGS[12]);
        let mut st = Out::default();
        st.u32(sources.len() as u32);
        sources.iter().for_each(|&x| st.u32(x));
        sections.push(st.0);
    }
    if let Some(l) = &b.lod {
        tags.push(TAGS[13]);
        let mut lo = Out::default();
        for x in [l.groups.len(), l.clusters.len(), l.base_parents.len(), l.part_clusters.len()] {
            lo.u32(x as u32);
        }
        for &(level, error) in &l.groups {
            lo.u32(level);
            lo.f32(error);
        }
        l.base_parents.iter().for_each(|&p| lo.u32(p));
        l.clusters.iter().flatten().for_each(|&x| lo.u32(x));
        lo.0.resize(lo.0.len().next_multiple_of(16), 0);
        lo.bounds(&l.bounds, &l.classes);
        for r in &l.part_clusters {
            lo.u32(r.start);
            lo.u32(r.end);
        }
        lo.0.extend_from_slice(&flat::to_bytes(&l.meshlets));
        sections.push(lo.0);
        // Written only beside the envelope it holds within (a reader refuses it alone).
        if let (Some(e), Some(_)) = (&l.envelope, &b.envelope) {
            tags.push(TAGS[14]);
            let mut le = Out::default();
            for x in [l.groups.len(), l.clusters.len(), 0, 0] {
                le.u32(x as u32);
            }
            for (&(level, _), &error) in l.groups.iter().zip(&e.errors) {
                le.u32(level);
                le.f32(error);
            }
            le.0.resize(le.0.len().next_multiple_of(16), 0);
            le.bounds(&e.bounds, &e.classes);
            sections.push(le.0);
        }
    }
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(sections.len() as u32).to_le_bytes());
    let mut offset = (HEADER + ENTRY * sections.len()).next_multiple_of(16);
    for (tag, body) in tags.iter().zip(&sections) {
        out.extend_from_slice(*tag);
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(offset as u64).to_le_bytes());
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        offset = (offset + body.len()).next_multiple_of(16);
    }
    for body in &sections {
        out.resize(out.len().next_multiple_of(16), 0);
        out.extend_from_slice(body);
    }
    out
}

/// Writes the file atomically: a temporary file beside `path`, flushed to disk, then renamed.
pub fn write(path: &Path, b: &Baked) -> Result<()> {
    let bytes = to_bytes(b);
    let name = path.file_name().ok_or_else(|| Error::invalid(path.display().to_string(), "not a file path"))?;
    let tmp = path.with_file_name(format!(".{}.tmp-{}", name.to_string_lossy(), std::process::id()));
    let io = |e: std::io::Error, what: &Path| Error::Write { path: what.to_path_buf(), source: e };
    let result = (|| {
        let mut f = std::fs::File::create(&tmp).map_err(|e| io(e, &tmp))?;
        f.write_all(&bytes).map_err(|e| io(e, &tmp))?;
        f.sync_all().map_err(|e| io(e, &tmp))?;
        std::fs::rename(&tmp, path).map_err(|e| io(e, path))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Reads and checks a bake file.
pub fn read(path: &Path) -> Result<Baked> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io { path: path.to_path_buf(), source: e })?;
    from_bytes(&bytes).map_err(|e| match e {
        Error::Invalid { location, message } => Error::invalid(format!("{}: {location}", path.display()), message),
        Error::Unsupported { location, message } => {
            Error::unsupported(format!("{}: {location}", path.display()), message)
        }
        e => e,
    })
}

/// Runs every run-time consumer of a bake once, on the rest pose: the meshlet culler (built,
/// prepared and culled for a camera; also with the envelope bounds), the any-pose boxes and
/// the envelope guard, the overdraw lookup, joint boxes, skinning with morphs, contour
/// extraction with every bound set, and the per-part boxes for every kind of pose. Whatever [`from_bytes`] accepts must pass:
/// the bake tests and the `bake` fuzz target (`fuzz/`) call it on corrupted files; an error
/// names the consumer that refused.
pub fn check_consumers(b: &Baked) -> Result<()> {
    use crate::cull::{Camera, Projection};
    use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
    let palette = b.palette();
    let camera = Camera::perspective(Vec3::new(0.0, 1.0, 4.0), Vec3::ZERO, Vec3::Y, 1.0, 1.0, 0.1, 100.0)?;
    let joints = vec![glam::Affine3A::IDENTITY; palette.joints.len()];
    let cull = |bounds: &[MeshletBounds], classes: &[Class], boxes: Option<&AnyPoseBoxes>| -> Result<()> {
        let mut culler = MeshletCuller::new(bounds, classes, palette.joints.len())?;
        if let Some(boxes) = boxes {
            culler = culler.with_any_pose(boxes)?;
        }
        let mut frame = JointFrame::default();
        culler.prepare_with_boxes(&joints, &camera, Tests::Both, &mut frame);
        culler.cull(&frame, &mut Vec::new(), &mut Vec::new());
        culler.prepare_boxes_only(&joints, &camera, Tests::Both, &mut frame);
        culler.cull(&frame, &mut Vec::new(), &mut Vec::new());
        Ok(())
    };
    cull(&b.bounds, &b.classes, None)?;
    if let Some(o) = &b.overdraw
        && o.select(0, 0.0, Vec3::Z) >= o.buffers.len()
    {
        return Err(Error::invalid("overdraw lookup", "selected a buffer that does not exist"));
    }
    crate::cull::joint_aabb::joint_boxes(&b.mesh, &palette, crate::cull::joint_aabb::JointSpace::Joint, &[])?;
    let mut weights = Vec::new();
    b.mesh.morphs.weights_at(None, 0.0, &mut weights);
    let mut posed = vec![Vec3::ZERO; b.mesh.positions.len()];
    if b.mesh.influences.is_some() {
        crate::skinning::skin_mesh(&b.mesh, &weights, &joints, &mut posed, &mut [])?;
    }
    if let Some(e) = &b.envelope {
        cull(&e.bounds, &e.classes, Some(&e.any_pose))?;
        let rest: Vec<f32> = e.envelope.weights.iter().map(|w| w.0).collect();
        e.envelope.guard()?.admits(&[], &rest);
    }
    if let Some(l) = &b.lod {
        cull(&l.bounds, &l.classes, None)?;
        if let Some(e) = &l.envelope {
            cull(&e.bounds, &e.classes, None)?;
        }
    }
    if let Some(c) = &b.contours {
        let edges = skinned_edges(&b.mesh, c.visible_only)?;
        if edges.quads.len() != c.patches.patches.order.len() {
            return Err(Error::invalid("contours", "the patches do not cover the mesh's edges"));
        }
        let globals = vec![glam::DMat4::IDENTITY; palette.joints.len()];
        let eye = Projection::Perspective { eye: Vec3::new(0.0, 1.0, 4.0) };
        for at in std::iter::once(None).chain((0..c.patches.clips.len()).map(|k| Some((k, 0.0)))) {
            c.patches.extract(&posed, &edges, &globals, at, eye, &mut Vec::new());
        }
    }
    // The per-part boxes an engine culls entities with, as a game reads them, for every kind
    // of pose (every clip at its start and past its end).
    with_view(b, |view| {
        if let Some(l) = view.lod() {
            let mut cut = Vec::new();
            for threshold in [0.0, 1e-3, f32::MAX] {
                l.cut(threshold, &mut cut);
            }
        }
        let parts = PartBounds::new(view)?;
        let clips = (0..b.settings.clips.len() as u32)
            .flat_map(|clip| [0.0, f32::MAX].map(|time| PoseBounds::ClipAt { clip, time }));
        for pose in [PoseBounds::Any, PoseBounds::Clips, PoseBounds::Envelope].into_iter().chain(clips) {
            for i in 0..b.parts.len() {
                parts.part_box(i, &glam::Affine3A::IDENTITY, &joints, &weights, pose);
            }
        }
        Ok(())
    })
}

/// Runs `f` on the run-time view of the bake's bytes (what a game reads from the file).
pub fn with_view<R>(b: &Baked, f: impl FnOnce(&BakeView) -> Result<R>) -> Result<R> {
    let bytes = to_bytes(b);
    let words = aligned_words(&bytes);
    f(&BakeView::new(&bytemuck::cast_slice::<u32, u8>(&words)[..bytes.len()])?)
}

/// `bytes` in 4-byte aligned storage, zero-padded to whole words: what the runtime's views
/// read.
pub(crate) fn aligned_words(bytes: &[u8]) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(&[bytes, &[0; 3][..(4 - bytes.len() % 4) % 4]].concat())
}

/// Parses and checks bake file bytes: everything [`BakeView::new`] checks, then the baker's
/// own rules (the meshlets hold exactly the triangles).
pub fn from_bytes(bytes: &[u8]) -> Result<Baked> {
    // The view needs 4-byte aligned bytes; a slice that is not (only a caller's sub-slice
    // can be) is read from an aligned copy.
    let copy: Vec<u32>;
    let bytes = if (bytes.as_ptr() as usize).is_multiple_of(4) {
        bytes
    } else {
        copy = aligned_words(bytes);
        &bytemuck::cast_slice::<u32, u8>(&copy)[..bytes.len()]
    };
    let view = BakeView::new(bytes)?;
    let info = view.info();
    let location = "bake section INFO";
    let builder =
        *Builder::ALL.get(info.builder as usize).ok_or_else(|| Error::invalid(location, "unknown meshlet builder"))?;
    let limits = MeshletLimits { max_vertices: info.max_vertices as usize, max_triangles: info.max_triangles as usize };
    let stop = [Stop::Converged, Stop::Rounds, Stop::Budget][info.stop.min(2) as usize];
    let clips = info.clips.iter().map(|c| c.to_string()).collect();
    let settings =
        BakeSettings { builder, limits, s_r: info.s_r, alpha_t: info.alpha_t, rounds: info.rounds, stop, clips };

    let v = view.vertices();
    let influences =
        (v.stride > 0).then(|| Influences { stride: v.stride, joints: v.joints.to_vec(), weights: v.weights.to_vec() });
    let morphs = view.morphs().map_or_else(Morphs::default, |m| Morphs {
        weights: m.weights.to_vec(),
        offsets: m.offsets.to_vec(),
        deltas: m.deltas.to_vec(),
    });
    let mesh = SkinnedMesh {
        positions: v.positions.to_vec(),
        normals: v.normals.to_vec(),
        triangles: view.triangles().to_vec(),
        influences,
        morphs,
    };
    let meshlets = Meshlets::from_view(&view.meshlets());
    meshlets.validate(&mesh.triangles, limits).map_err(|e| Error::invalid("bake section MLET", e.to_string()))?;

    let (bounds, classes) = bounds_and_classes(view.meshlet_bounds());
    let range = |r: [u32; 2]| r[0]..r[1];
    let parts = (view.parts().iter())
        .map(|p| BakedPart {
            node: p.node,
            mesh: p.mesh,
            primitive: p.primitive,
            kind: if p.skin == u32::MAX { PartKind::Rigid } else { PartKind::Skinned { skin: p.skin } },
            vertices: range(p.vertices),
            triangles: range(p.triangles),
            meshlets: range(p.meshlets),
        })
        .collect();
    let envelope = view.envelope().map(|e| {
        let (bounds, classes) = bounds_and_classes(e.bounds);
        BakedEnvelope {
            envelope: Envelope { nodes: e.ranges(), weights: e.weight_ranges() },
            names: e.names.iter().map(|n| n.to_string()).collect(),
            bounds,
            classes,
            any_pose: e.any_pose(),
        }
    });
    Ok(Baked {
        settings,
        joint_nodes: view.joint_nodes().to_vec(),
        joint_names: view.joint_names().iter().map(|n| n.to_string()).collect(),
        inverse_bind: view.inverse_bind().iter().map(Mat4::from_cols_array).collect(),
        parts,
        mesh,
        meshlets,
        bounds,
        classes,
        overdraw: view.overdraw_orders().cloned(),
        contours: view.contours().map(|(c, _)| c.clone()),
        envelope,
        part_windows: view.part_windows().cloned(),
        sources: view.sources().map(<[u32]>::to_vec),
        lod: view.lod().map(|l| {
            let (bounds, classes) = bounds_and_classes(l.bounds);
            BakedLod {
                groups: l.groups.iter().map(|g| (g.level, g.error)).collect(),
                base_parents: l.base_parents.to_vec(),
                clusters: l.clusters.to_vec(),
                meshlets: Meshlets::from_view(&l.meshlets),
                bounds,
                classes,
                part_clusters: l.part_clusters.iter().map(|r| r[0]..r[1]).collect(),
                envelope: l.envelope().map(|e| {
                    let (bounds, classes) = bounds_and_classes(e.bounds);
                    BakedLodEnvelope { errors: e.groups.iter().map(|g| g.error).collect(), bounds, classes }
                }),
            }
        }),
    })
}
