//! A validated, zero-copy view over the bytes of a bake file (`docs/FORMAT.md`), the one
//! reader of the format: [`BakeView::new`] checks the header, the section table and every
//! section once, each against what it depends on, and keeps typed slices of the file's own
//! bytes (every section starts 16-byte aligned in the file, so a memory-mapped file or a
//! `Vec<u8>` read from disk serves them directly; its records are little-endian, as the
//! format is). What it hands out has been checked, and its accessors cannot fail: a culler
//! built from it never indexes out of range and never sees a non-finite number.
//!
//! Every section: the bake settings and clip names (`INFO`), the drivers' inverse bind
//! matrices, nodes and node names (`SKIN`), vertices (`VERT`), triangles (`TRIS`), meshlets
//! (`MLET`), meshlet bounds with their classes (`BNDS`), parts (`PART`), morph targets
//! (`MRPH`), the pose envelope with its bounds, any-pose boxes and node names (`ENVL`) as
//! typed slices; the parts' boxes per clip window (`PWIN`), the overdraw orders (`OVDR`) and
//! contour patches (`CONT`, with the edges it indexes, which the file does not store) read
//! into arrays; the cluster LOD hierarchy (`LODC`) as typed slices. The baker's reader (`skinlet::bake::from_bytes`) builds its types from this
//! view.

use crate::any_pose::AnyPoseBoxes;
use crate::contour_edges::Edges;
use crate::contour_patches::{BakedContours, ClipWindows, rigid_vertices, skinned_edges};
use crate::meshlet_bounds::{Class, MeshletBounds};
use crate::meshlet_cull::MeshletCuller;
use crate::overdraw_orders::Orders;
use crate::pose_guard::{NodeRange, PoseGuard, check_ranges};
use crate::{Error, Result};
use glam::{Quat, Vec3};

/// The first eight bytes of every bake file.
pub const MAGIC: [u8; 8] = *b"SKINLET\0";
/// The format version this view reads.
pub const VERSION: u32 = 3;
/// Bytes per section table entry: tag, zero, offset (u64), length (u64).
const ENTRY: usize = 24;
/// Most drivers a bake can have: `VERT` numbers them in 16 bits.
pub const MAX_DRIVERS: usize = 1 << 16;
/// How far from 1 a stored unit quantity may be (a cone axis's squared length, `sin² + cos²`
/// of a stored angle): f32 rounding is off by a few ulps; the culling tests' margins cover far
/// more.
pub(crate) const UNIT: f32 = 1e-5;

/// One meshlet's record in `BNDS` (48 bytes, `docs/FORMAT.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BakedBounds {
    pub center: [f32; 3],
    pub radius: f32,
    pub cone_axis: [f32; 3],
    pub cone_angle: f32,
    pub rest_radius: f32,
    pub rest_cone_angle: f32,
    pub joint: u32,
    /// 0 both tests, 1 frustum only, 2 none.
    pub class: u32,
}

// SAFETY: `repr(C)`, twelve 4-byte fields of plain numbers (48 bytes, no padding): every bit
// pattern is a value, and zero is one.
unsafe impl bytemuck::Zeroable for BakedBounds {}
// SAFETY: as above; `Copy` and `'static`.
unsafe impl bytemuck::Pod for BakedBounds {}

impl BakedBounds {
    /// The bounds (the joint is below 2¹⁶ in any record [`check_bounds`] accepts).
    pub fn bounds(&self) -> MeshletBounds {
        MeshletBounds {
            joint: self.joint as u16,
            center: Vec3::from(self.center),
            radius: self.radius,
            rest_radius: self.rest_radius,
            cone_axis: Vec3::from(self.cone_axis),
            cone_angle: self.cone_angle,
            rest_cone_angle: self.rest_cone_angle,
        }
    }

    /// The class (a code above 2, which [`check_bounds`] refuses, reads as "none").
    pub fn class(&self) -> Class {
        match self.class {
            0 => Class::Both,
            1 => Class::FrustumOnly,
            _ => Class::None,
        }
    }
}

/// Checks bounds records for `joints` joints: finite numbers, principal joints below
/// `joints`, known classes, radii not negative, `|center| + radius` finite in f32, cone angles
/// in [0, π], unit axes for cones below π/2. Errors name the meshlet; `location` says where the records came from.
pub fn check_bounds(records: &[BakedBounds], joints: usize, location: &str) -> Result<()> {
    for (i, r) in records.iter().enumerate() {
        let bad = |what: String| Err(Error::invalid(location, format!("meshlet {i}: {what}")));
        // The first ten words are the floats.
        let words: [f32; 12] = bytemuck::cast(*r);
        if words[..10].iter().any(|x| !x.is_finite()) {
            return bad("a number is not finite".into());
        }
        if r.joint as usize >= joints {
            return bad(format!("principal joint {} is not one of {joints} joints", r.joint));
        }
        if r.class > 2 {
            return bad(format!("unknown class {}", r.class));
        }
        if r.radius < 0.0 || r.rest_radius < 0.0 || !(0.0..=std::f32::consts::PI).contains(&r.cone_angle) {
            return bad("a negative radius or a cone angle outside [0, π]".into());
        }
        // The culler sizes its margins by |center| + radius: in f32's range.
        let reach = Vec3::from(r.center).length() + r.radius.max(r.rest_radius);
        if !reach.is_finite() {
            return bad(format!("|center| + radius {reach} is past f32's range"));
        }
        if !(0.0..=std::f32::consts::PI).contains(&r.rest_cone_angle) {
            return bad(format!("rest cone angle {} outside [0, π]", r.rest_cone_angle));
        }
        // The axis of a cone the culler uses (below π/2) is a unit vector.
        let axis = Vec3::from(r.cone_axis);
        if r.cone_angle < std::f32::consts::FRAC_PI_2 && (axis.length_squared() - 1.0).abs() > UNIT {
            return bad(format!("cone axis {axis} is not a unit vector"));
        }
    }
    Ok(())
}

/// Records as the culler takes them: the bounds and the classes.
pub fn bounds_and_classes(records: &[BakedBounds]) -> (Vec<MeshletBounds>, Vec<Class>) {
    records.iter().map(|r| (r.bounds(), r.class())).unzip()
}

/// One node range's record in `ENVL` (72 bytes, `docs/FORMAT.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BakedNodeRange {
    pub node: u32,
    /// x, y, z, w.
    pub centre: [f32; 4],
    pub angle: f32,
    pub translation_min: [f32; 3],
    pub translation_max: [f32; 3],
    pub scale_min: [f32; 3],
    pub scale_max: [f32; 3],
}

// SAFETY: `repr(C)`, eighteen 4-byte fields of plain numbers (72 bytes, no padding): every bit
// pattern is a value, and zero is one.
unsafe impl bytemuck::Zeroable for BakedNodeRange {}
// SAFETY: as above; `Copy` and `'static`.
unsafe impl bytemuck::Pod for BakedNodeRange {}

impl BakedNodeRange {
    /// The range as the pose guard takes it.
    pub fn range(&self) -> NodeRange {
        NodeRange {
            node: self.node,
            centre: Quat::from_array(self.centre),
            angle: self.angle,
            translation: (Vec3::from(self.translation_min), Vec3::from(self.translation_max)),
            scale: (Vec3::from(self.scale_min), Vec3::from(self.scale_max)),
        }
    }
}

/// The `ENVL` section, checked: the pose envelope's node and morph weight ranges, one
/// envelope bounds record per meshlet, the any-pose boxes (slices of the file's bytes) and
/// the ranges' nodes' names.
#[derive(Clone, Debug)]
pub struct EnvelopeView<'a> {
    pub nodes: &'a [BakedNodeRange],
    /// Per morph weight, its range (min, max).
    pub weights: &'a [[f32; 2]],
    pub bounds: &'a [BakedBounds],
    /// Boxes of meshlet `m`: `box_offsets[m]..box_offsets[m + 1]`.
    pub box_offsets: &'a [u32],
    /// Per box its joint, then its center and half extents.
    pub box_joints: &'a [u32],
    pub boxes: &'a [[f32; 6]],
    /// The names of the ranges' nodes, in range order.
    pub names: Vec<&'a str>,
}

impl EnvelopeView<'_> {
    /// The node ranges as [`NodeRange`]s.
    pub fn ranges(&self) -> Vec<NodeRange> {
        self.nodes.iter().map(BakedNodeRange::range).collect()
    }

    /// The morph weight ranges as pairs.
    pub fn weight_ranges(&self) -> Vec<(f32, f32)> {
        self.weights.iter().map(|w| (w[0], w[1])).collect()
    }

    /// The run-time pose guard of the envelope.
    pub fn guard(&self) -> Result<PoseGuard> {
        PoseGuard::new(&self.ranges(), &self.weight_ranges())
    }

    /// The any-pose boxes, owned.
    pub fn any_pose(&self) -> AnyPoseBoxes {
        AnyPoseBoxes {
            offsets: self.box_offsets.to_vec(),
            // A joint past u16 (only a hand-made view has one) becomes one no culler accepts.
            joints: self.box_joints.iter().map(|&j| u16::try_from(j).unwrap_or(u16::MAX)).collect(),
            center: self.boxes.iter().map(|b| Vec3::new(b[0], b[1], b[2])).collect(),
            half: self.boxes.iter().map(|b| Vec3::new(b[3], b[4], b[5])).collect(),
        }
    }

    /// The culler for poses inside the envelope, holding the any-pose boxes for the rest
    /// ([`MeshletCuller::prepare_with_boxes`], [`MeshletCuller::prepare_boxes_only`]).
    pub fn culler(&self, joints: usize) -> Result<MeshletCuller> {
        let (bounds, classes) = bounds_and_classes(self.bounds);
        MeshletCuller::new(&bounds, &classes, joints)?.with_any_pose(&self.any_pose())
    }
}

/// The checked view: every section the format defines, read and checked once by
/// [`BakeView::new`]; the accessors hand out what was checked and cannot fail.
#[derive(Clone, Debug)]
pub struct BakeView<'a> {
    sections: Vec<([u8; 4], &'a [u8])>,
    info: InfoView<'a>,
    inverse_bind: &'a [[f32; 16]],
    joint_nodes: &'a [u32],
    joint_names: Vec<&'a str>,
    vertices: VertexView<'a>,
    triangles: &'a [[u32; 3]],
    meshlets: MeshletView<'a>,
    bounds: &'a [BakedBounds],
    morphs: Option<MorphView<'a>>,
    parts: &'a [BakedPartRecord],
    envelope: Option<EnvelopeView<'a>>,
    part_windows: Option<BakedPartWindows>,
    overdraw: Option<Orders>,
    contours: Option<(BakedContours, Edges)>,
    sources: Option<&'a [u32]>,
    lod: Option<LodView<'a>>,
}

/// The little-endian `u32` at byte `at` of `b`, or `None` past its end.
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?))
}

impl<'a> BakeView<'a> {
    /// Checks the header (magic, version), the section table (every section inside the file,
    /// no tag twice) and every section `docs/FORMAT.md` defines, each against the ones it
    /// depends on. `bytes` must start at a 4-byte aligned address, as a memory map or a
    /// buffer from the allocator does. Errors say what is wrong and where. Allocates what is
    /// read into arrays (`PWIN`, `OVDR`, `CONT` with its edges): run it once, at load.
    pub fn new(bytes: &'a [u8]) -> Result<BakeView<'a>> {
        let sections = read_table(bytes)?;
        let find = |tag: &[u8; 4]| sections.iter().find(|(t, _)| t == tag).map(|(_, b)| *b);
        let required = |tag: &[u8; 4]| {
            find(tag).ok_or_else(|| Error::invalid("bake file", format!("section {} is missing", tag_name(tag))))
        };
        let info = read_info(required(b"INFO")?)?;
        let (inverse_bind, joint_nodes, joint_names) = read_skin(required(b"SKIN")?)?;
        let drivers = inverse_bind.len();
        let vertices = read_vertices(required(b"VERT")?, drivers)?;
        let n = vertices.positions.len();
        let triangles = read_triangles(required(b"TRIS")?, n)?;
        let meshlets = read_meshlets(required(b"MLET")?, n, &info)?;
        let bounds = read_bounds(required(b"BNDS")?, meshlets.len(), drivers)?;
        let morphs = find(b"MRPH").map(|s| read_morphs(s, n)).transpose()?;
        let parts = read_parts(required(b"PART")?, n, triangles, &meshlets)?;
        // A rigid part (or every part of a bake without skin weights) is weight 1 on its
        // node's driver.
        let rigid = |p: &BakedPartRecord| vertices.stride == 0 || p.skin == u32::MAX;
        if let Some((i, p)) = parts.iter().enumerate().find(|(_, p)| rigid(p) && !joint_nodes.contains(&p.node)) {
            return Err(Error::invalid("bake section PART", format!("part {i}: no driver for node {}", p.node)));
        }
        let weights = morphs.map_or(0, |m| m.weights.len());
        let envelope = find(b"ENVL").map(|s| read_envelope(s, meshlets.len(), weights, drivers)).transpose()?;
        let part_windows =
            find(b"PWIN").map(|s| read_part_windows(s, parts.len(), info.clips.len(), drivers)).transpose()?;
        let overdraw = find(b"OVDR").map(|s| Orders::read(s, triangles, parts, info.clips.len())).transpose()?;
        let contours = (find(b"CONT"))
            .map(|s| read_contours(s, &vertices, morphs, triangles, drivers, info.clips.len()))
            .transpose()?;
        let sources = find(b"SRCT").map(|s| read_sources(s, &meshlets)).transpose()?;
        let mut lod = find(b"LODC").map(|s| read_lod(s, n, &info, parts, drivers)).transpose()?;
        if let Some(s) = find(b"LODE") {
            let (Some(l), Some(_)) = (&mut lod, &envelope) else {
                return Err(Error::invalid("bake section LODE", "the bake has no LODC or no ENVL section"));
            };
            l.envelope = Some(read_lod_envelope(s, l, drivers)?);
        }
        Ok(BakeView {
            sections,
            info,
            inverse_bind,
            joint_nodes,
            joint_names,
            vertices,
            triangles,
            meshlets,
            bounds,
            morphs,
            parts,
            envelope,
            part_windows,
            overdraw,
            contours,
            sources,
            lod,
        })
    }

    /// The bytes of section `tag`, if the file has it (sections a later version adds, or a
    /// section's bytes for a GPU upload as they are).
    pub fn section(&self, tag: &[u8; 4]) -> Option<&'a [u8]> {
        self.sections.iter().find(|(t, _)| t == tag).map(|(_, b)| *b)
    }

    /// `INFO`: how the bake was made, and the baked clips' names.
    pub fn info(&self) -> &InfoView<'a> {
        &self.info
    }

    /// The number of drivers (joints), from `SKIN` (at most [`MAX_DRIVERS`]).
    pub fn joint_count(&self) -> usize {
        self.inverse_bind.len()
    }

    /// Each driver's inverse bind matrix (16 `f32`, column-major), finite.
    pub fn inverse_bind(&self) -> &'a [[f32; 16]] {
        self.inverse_bind
    }

    /// Each driver's node (index into the source file's nodes).
    pub fn joint_nodes(&self) -> &'a [u32] {
        self.joint_nodes
    }

    /// Each driver's node name (empty for unnamed nodes).
    pub fn joint_names(&self) -> &[&'a str] {
        &self.joint_names
    }

    /// The vertices of `VERT`: finite positions and normals; per vertex, joint numbers below
    /// the driver count and weights as `docs/FORMAT.md` says (in [0, 1], non-zero ones first,
    /// summing to 1).
    pub fn vertices(&self) -> VertexView<'a> {
        self.vertices
    }

    /// The triangles of `TRIS` (vertex indices below the vertex count, counter-clockwise
    /// front faces).
    pub fn triangles(&self) -> &'a [[u32; 3]] {
        self.triangles
    }

    /// The meshlets of `MLET` ([`MeshletView::check`] against the vertices and `INFO`'s
    /// limits).
    pub fn meshlets(&self) -> MeshletView<'a> {
        self.meshlets
    }

    /// The meshlet count.
    pub fn meshlet_count(&self) -> usize {
        self.meshlets.len()
    }

    /// The meshlet bounds and classes of `BNDS`, one per meshlet ([`check_bounds`] for the
    /// file's drivers).
    pub fn meshlet_bounds(&self) -> &'a [BakedBounds] {
        self.bounds
    }

    /// The run-time culler for the clip bounds of `BNDS`.
    pub fn culler(&self) -> Result<MeshletCuller> {
        let (bounds, classes) = bounds_and_classes(self.bounds);
        MeshletCuller::new(&bounds, &classes, self.joint_count())
    }

    /// Per meshlet, whether its part is marked in `parts` (one flag per part of `PART`;
    /// missing flags are false): e.g. the parts whose material is double-sided.
    pub fn meshlets_of_parts(&self, parts: &[bool]) -> Vec<bool> {
        let mut out = vec![false; self.meshlets.len()];
        for (p, &marked) in self.parts.iter().zip(parts) {
            out[p.meshlets[0] as usize..p.meshlets[1] as usize].fill(marked);
        }
        out
    }

    /// [`BakeView::culler`] for a draw that shows the back faces of the parts `two_sided`
    /// marks (one flag per part: a double-sided material): their meshlets are frustum-culled
    /// only, never backface-culled.
    pub fn two_sided_culler(&self, two_sided: &[bool]) -> Result<MeshletCuller> {
        let (bounds, mut classes) = bounds_and_classes(self.bounds);
        for (class, two_sided) in classes.iter_mut().zip(self.meshlets_of_parts(two_sided)) {
            if two_sided && *class == Class::Both {
                *class = Class::FrustumOnly;
            }
        }
        MeshletCuller::new(&bounds, &classes, self.joint_count())
    }

    /// The run-time culler for the clip bounds of `BNDS`' meshlets, then `LODC`'s clusters
    /// (numbered as [`LodView::cluster_errors`] numbers them): to cull a cut. `None` without
    /// `LODC`.
    pub fn lod_culler(&self) -> Result<Option<MeshletCuller>> {
        let Some(lod) = &self.lod else { return Ok(None) };
        let (bounds, classes) = bounds_and_classes(&[self.bounds, lod.bounds].concat());
        MeshletCuller::new(&bounds, &classes, self.joint_count()).map(Some)
    }

    /// [`Self::lod_culler`] for the poses inside the pose envelope: `ENVL`'s meshlet bounds,
    /// then `LODE`'s cluster bounds ([`LodView::envelope`]). `None` without `LODE`.
    pub fn lod_envelope_culler(&self) -> Result<Option<MeshletCuller>> {
        let (Some(lod), Some(e)) = (self.lod.and_then(|l| l.envelope()), &self.envelope) else { return Ok(None) };
        let (bounds, classes) = bounds_and_classes(&[e.bounds, lod.bounds].concat());
        MeshletCuller::new(&bounds, &classes, self.joint_count()).map(Some)
    }

    /// The morph targets of `MRPH` ([`MorphView::check`]), if the file has the section.
    pub fn morphs(&self) -> Option<MorphView<'a>> {
        self.morphs
    }

    /// The vertices, triangles, morph targets and meshlets: what a GPU upload reads.
    pub fn mesh_data(&self) -> MeshData<'a> {
        MeshData {
            vertices: self.vertices,
            triangles: self.triangles,
            morphs: self.morphs,
            meshlets: Some(self.meshlets),
        }
    }

    /// The parts of `PART`: consecutive ranges from 0 covering every vertex, triangle and
    /// meshlet, each part's triangles and meshlets using only its own vertices (so one
    /// material per part range holds).
    pub fn parts(&self) -> &'a [BakedPartRecord] {
        self.parts
    }

    /// The optional `ENVL` section: node ranges ([`check_ranges`], each node once), one morph
    /// weight range per morph weight, envelope bounds for every meshlet ([`check_bounds`]),
    /// any-pose boxes ([`AnyPoseBoxes::check`] rules), the nodes' names.
    pub fn envelope(&self) -> Option<&EnvelopeView<'a>> {
        self.envelope.as_ref()
    }

    /// The optional `PWIN` section: its part and clip counts are `PART`'s and `INFO`'s, the
    /// clips' windows are numbered in order from 0, every anchor is a driver, every number is
    /// finite, every box has `min ≤ max`.
    pub fn part_windows(&self) -> Option<&BakedPartWindows> {
        self.part_windows.as_ref()
    }

    /// The optional `OVDR` section ([`Orders::read`]): the overdraw orders' buffers and their
    /// run-time lookup.
    pub fn overdraw_orders(&self) -> Option<&Orders> {
        self.overdraw.as_ref()
    }

    /// The optional `CONT` section ([`BakedContours::read`]), with the edges its quads index
    /// (rebuilt from `VERT` and `TRIS`: [`skinned_edges`], without the concave rigid quads
    /// when the patches are visible-only).
    pub fn contours(&self) -> Option<(&BakedContours, &Edges)> {
        self.contours.as_ref().map(|(c, e)| (c, e))
    }

    /// The optional `LODC` section: the cluster LOD hierarchy ([`LodView`], checked).
    pub fn lod(&self) -> Option<&LodView<'a>> {
        self.lod.as_ref()
    }

    /// The optional `SRCT` section: per triangle of `MLET` (the one at triangle byte `3·i`
    /// is entry `i`), its source triangle in its part's glTF primitive (bits 0–29) and the
    /// rotation of its corners (bits 30–31: corner `k` is the source triangle's corner
    /// `(k + rotation) % 3`), for drawing meshlets with the source's vertex attributes.
    pub fn sources(&self) -> Option<&'a [u32]> {
        self.sources
    }
}

/// The header and the section table: the magic, the version, every section inside the file,
/// no tag twice.
fn read_table(bytes: &[u8]) -> Result<Vec<([u8; 4], &[u8])>> {
    let head = |message: String| Error::invalid("bake header", message);
    if cfg!(target_endian = "big") {
        return Err(head("bake files are little-endian; this target is big-endian".into()));
    }
    if !(bytes.as_ptr() as usize).is_multiple_of(4) {
        return Err(head("the bytes must start at a 4-byte aligned address (copy them into an aligned buffer)".into()));
    }
    if bytes.get(..8) != Some(&MAGIC[..]) {
        return Err(head("not a skinlet bake file (wrong magic bytes)".into()));
    }
    let version = u32_at(bytes, 8).ok_or_else(|| head("truncated (no version)".into()))?;
    if version != VERSION {
        return Err(Error::unsupported("bake header", format!("version {version}; this skinlet reads {VERSION}")));
    }
    let n = u32_at(bytes, 12).ok_or_else(|| head("truncated (no section count)".into()))? as usize;
    if n.saturating_mul(ENTRY) > bytes.len() - 16 {
        return Err(head(format!("byte 12: {n} sections do not fit in the file")));
    }
    let mut sections = Vec::with_capacity(n);
    for k in 0..n {
        let e = &bytes[16 + k * ENTRY..16 + (k + 1) * ENTRY];
        let tag: [u8; 4] = e[..4].try_into().expect("4 bytes");
        let (offset, len) = (
            u64::from_le_bytes(e[8..16].try_into().expect("8 bytes")),
            u64::from_le_bytes(e[16..24].try_into().expect("8 bytes")),
        );
        let body = usize::try_from(offset)
            .ok()
            .zip(usize::try_from(len).ok())
            .and_then(|(o, l)| bytes.get(o..o.checked_add(l)?))
            .ok_or_else(|| {
                head(format!("byte {}: section {} lies outside the file", 16 + k * ENTRY, tag_name(&tag)))
            })?;
        sections.push((tag, body));
    }
    // No tag twice: sorted by tag (then entry), equal neighbours are a repeat.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| (sections[k].0, k));
    if let Some(w) = order.windows(2).filter(|w| sections[w[0]].0 == sections[w[1]].0).min_by_key(|w| w[1]) {
        let (first, k) = (w[0], w[1]);
        return Err(head(format!(
            "byte {}: section {} appears twice in the table (entries {first} and {k})",
            16 + k * ENTRY,
            tag_name(&sections[k].0)
        )));
    }
    Ok(sections)
}

/// `INFO`: the whole section read, a known builder and stop reason, meshlet limits the
/// builders accept (3 to 256 vertices, 1 to 512 triangles), names in UTF-8.
fn read_info(b: &[u8]) -> Result<InfoView<'_>> {
    let mut s = Cursor::new("INFO", b);
    let builder = s.u32()?;
    if builder > 6 {
        return Err(s.err(format!("unknown meshlet builder {builder}")));
    }
    let (max_vertices, max_triangles) = (s.u32()?, s.u32()?);
    if !(3..=256).contains(&max_vertices) || !(1..=512).contains(&max_triangles) {
        return Err(s.err(format!(
            "meshlet limits {max_vertices} vertices / {max_triangles} triangles (need 3 to 256 and 1 to 512)"
        )));
    }
    let (s_r, alpha_t, rounds, stop) = (s.f32()?, s.f32()?, s.u32()?, s.u32()?);
    if stop > 2 {
        return Err(s.err(format!("unknown stop reason {stop}")));
    }
    let n = s.u32()? as usize;
    if n.saturating_mul(4) > s.remaining() {
        return Err(s.err(format!("{n} clip names do not fit in the section")));
    }
    let clips = (0..n).map(|_| s.str()).collect::<Result<Vec<_>>>()?;
    s.end()?;
    Ok(InfoView { builder, max_vertices, max_triangles, s_r, alpha_t, rounds, stop, clips })
}

/// `SKIN`: at most [`MAX_DRIVERS`] drivers, finite inverse bind matrices, nodes, UTF-8 names,
/// the section read to its end.
#[allow(clippy::type_complexity)]
fn read_skin(b: &[u8]) -> Result<(&[[f32; 16]], &[u32], Vec<&str>)> {
    let mut s = Cursor::new("SKIN", b);
    let n = s.u32()? as usize;
    if n > MAX_DRIVERS {
        return Err(s.err(format!("{n} drivers; the format numbers them in 16 bits (at most 65,536)")));
    }
    if n.saturating_mul(68) > s.remaining() {
        return Err(s.err(format!("{n} joints do not fit in the section")));
    }
    let inverse_bind: &[[f32; 16]] = cast(s.bytes(64 * n)?, "SKIN")?;
    if let Some(j) = inverse_bind.iter().position(|m| m.iter().any(|x| !x.is_finite())) {
        return Err(s.err(format!("joint {j}'s inverse bind matrix is not finite")));
    }
    let nodes: &[u32] = cast(s.bytes(4 * n)?, "SKIN")?;
    let names = (0..n).map(|_| s.str()).collect::<Result<Vec<_>>>()?;
    s.end()?;
    Ok((inverse_bind, nodes, names))
}

/// `VERT`: the section's exact length, finite positions and normals, influences as
/// [`check_influences`] says.
fn read_vertices(s: &[u8], drivers: usize) -> Result<VertexView<'_>> {
    let location = "bake section VERT";
    let word = |at: usize| u32_at(s, at).ok_or_else(|| Error::invalid(location, format!("byte {at}: truncated")));
    let (n, stride, flag) = (word(0)? as usize, word(4)? as usize, word(8)?);
    if !matches!(stride, 0 | 4 | 8) || flag > 1 {
        return Err(Error::invalid(location, format!("byte 4: influence stride {stride} and normals flag {flag}")));
    }
    let slots = n.checked_mul(stride).filter(|&k| k <= s.len() / 6);
    let slots = slots.ok_or_else(|| Error::invalid(location, format!("byte 0: {n} vertices do not fit")))?;
    let after_positions = n.checked_mul(12).and_then(|b| b.checked_add(12)).filter(|&e| e <= s.len());
    let after_positions =
        after_positions.ok_or_else(|| Error::invalid(location, format!("byte 0: {n} vertices do not fit")))?;
    let after_normals = after_positions + 12 * n * flag as usize;
    let joints_end = after_normals + (2 * slots).next_multiple_of(4);
    if joints_end + 4 * slots != s.len() {
        return Err(Error::invalid(
            location,
            format!("{} bytes for {n} vertices of {stride} influences (expected {})", s.len(), joints_end + 4 * slots),
        ));
    }
    let positions: &[Vec3] = cast(&s[12..after_positions], "VERT")?;
    let normals: &[Vec3] = cast(&s[after_positions..after_normals], "VERT")?;
    let joints: &[u16] = cast(&s[after_normals..after_normals + 2 * slots], "VERT")?;
    let weights: &[f32] = cast(&s[joints_end..], "VERT")?;
    if let Some(v) = positions.iter().chain(normals).position(|p| !p.is_finite()) {
        let what = if v < n { "position" } else { "normal" };
        return Err(Error::invalid(location, format!("vertex {}'s {what} is not finite", v % n.max(1))));
    }
    if stride > 0 {
        check_influences(stride, joints, weights, drivers).map_err(|e| Error::invalid(location, e.to_string()))?;
    }
    Ok(VertexView { positions, normals, stride, joints, weights })
}

/// Checks skin influences of `stride` (4 or 8) slots per vertex over `drivers` drivers, as
/// `docs/FORMAT.md` says: as many weights as joint numbers, a whole number of vertices, every
/// joint number below `drivers`, weights finite and in [0, 1], non-zero ones first, each
/// vertex's summing to 1 (within 1e-3).
pub fn check_influences(stride: usize, joints: &[u16], weights: &[f32], drivers: usize) -> Result<()> {
    let bad = |what: String| Err(Error::invalid("skin influences", what));
    if !matches!(stride, 4 | 8) || joints.len() != weights.len() || !joints.len().is_multiple_of(stride) {
        return bad(format!("stride {stride} with {} joints and {} weights", joints.len(), weights.len()));
    }
    if let Some(i) = joints.iter().position(|&j| j as usize >= drivers) {
        return bad(format!("vertex {} uses joint {} of {drivers}", i / stride, joints[i]));
    }
    for (v, w) in weights.chunks_exact(stride).enumerate() {
        if let Some(x) = w.iter().find(|x| !(0.0..=1.0).contains(*x)) {
            return bad(format!("vertex {v} has weight {x}"));
        }
        let used = w.iter().position(|&x| x == 0.0).unwrap_or(stride);
        if w[used..].iter().any(|&x| x != 0.0) {
            return bad(format!("vertex {v} has a non-zero weight after a zero one"));
        }
        let sum: f32 = w.iter().sum();
        if (sum - 1.0).abs() > 1e-3 {
            return bad(format!("vertex {v}'s weights sum to {sum}"));
        }
    }
    Ok(())
}

/// `TRIS`: the section's exact length, vertex indices below `vertices`.
fn read_triangles(s: &[u8], vertices: usize) -> Result<&[[u32; 3]]> {
    let location = "bake section TRIS";
    let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
    if n.checked_mul(12).and_then(|b| b.checked_add(4)) != Some(s.len()) {
        return Err(Error::invalid(location, format!("{} bytes for {n} triangles", s.len())));
    }
    let triangles: &[[u32; 3]] = cast(&s[4..], "TRIS")?;
    if let Some(t) = triangles.iter().position(|t| t.iter().any(|&i| i as usize >= vertices)) {
        return Err(Error::invalid(
            location,
            format!("triangle {t} {:?} indexes past {vertices} vertices", triangles[t]),
        ));
    }
    Ok(triangles)
}

/// `SRCT`: one entry per triangle byte triple of `MLET`, every rotation below 3.
fn read_sources<'a>(s: &'a [u8], meshlets: &MeshletView) -> Result<&'a [u32]> {
    let location = "bake section SRCT";
    let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
    if n != meshlets.triangles.len() / 3 || n.checked_mul(4).and_then(|b| b.checked_add(4)) != Some(s.len()) {
        let m = meshlets.triangles.len() / 3;
        return Err(Error::invalid(
            location,
            format!("{} bytes for {n} entries, where MLET has {m} triangles", s.len()),
        ));
    }
    let sources: &[u32] = cast(&s[4..], "SRCT")?;
    if let Some(i) = sources.iter().position(|&x| x >> 30 == 3) {
        return Err(Error::invalid(location, format!("entry {i}: rotation 3 (at most 2)")));
    }
    Ok(sources)
}

/// One group of the cluster LOD hierarchy (`LODC`): the level of the clusters it made (≥ 1)
/// and its error, in scene units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BakedLodGroup {
    pub level: u32,
    pub error: f32,
}

// SAFETY: `repr(C)`, a `u32` and an `f32` (8 bytes, no padding): every bit pattern is a
// value, and zero is one; `Copy` and `'static`.
unsafe impl bytemuck::Zeroable for BakedLodGroup {}
unsafe impl bytemuck::Pod for BakedLodGroup {}

/// No group: a root cluster's parent.
pub const NO_GROUP: u32 = u32::MAX;

/// The cluster LOD hierarchy of `LODC` (`docs/FORMAT.md`, `skinlet::meshlet::lod`): the
/// clusters above level 0 in `MLET`'s layout with their bounds in `BNDS`'s, per cluster its
/// own group and its parent group, per `MLET` meshlet (level 0) its parent group, per part the
/// range of its clusters. Checked at load: indices in range, each parent group above its
/// child's level with an error at least its child's, finite errors ≥ 0, each cluster inside its
/// part's vertices, every group with clusters it simplified and clusters it made, all of one
/// part. That a cut covers each part once is the baker's guarantee (tested), not re-proved
/// here: a file that passes is safe to read and draw.
#[derive(Clone, Copy, Debug)]
pub struct LodView<'a> {
    pub groups: &'a [BakedLodGroup],
    /// Per `MLET` meshlet, its parent group ([`NO_GROUP`]: it is a root).
    pub base_parents: &'a [u32],
    /// Per cluster, its own group and its parent group ([`NO_GROUP`]: a root).
    pub clusters: &'a [[u32; 2]],
    pub bounds: &'a [BakedBounds],
    /// Per part, its clusters' range (parts in order, covering every cluster).
    pub part_clusters: &'a [[u32; 2]],
    pub meshlets: MeshletView<'a>,
    /// `LODE`: the groups (same levels) with their errors within the pose envelope, and the
    /// clusters' bounds there, checked like `LODC`'s ([`Self::envelope`]).
    pub envelope: Option<(&'a [BakedLodGroup], &'a [BakedBounds])>,
}

impl<'a> LodView<'a> {
    /// The hierarchy for the poses inside the bake's pose envelope (the pose guard admits
    /// them): the same clusters with `LODE`'s errors and bounds. `None` without `LODE`.
    pub fn envelope(&self) -> Option<LodView<'a>> {
        let (groups, bounds) = self.envelope?;
        Some(LodView { groups, bounds, envelope: None, ..*self })
    }

    /// The errors of a cluster's own group (0 at level 0) and parent group (infinite for a
    /// root): `cluster` counts `MLET`'s meshlets first, then this section's clusters.
    pub fn cluster_errors(&self, cluster: usize) -> (f32, f32) {
        let error = |g: u32| if g == NO_GROUP { f32::INFINITY } else { self.groups[g as usize].error };
        match cluster.checked_sub(self.base_parents.len()) {
            None => (0.0, error(self.base_parents[cluster])),
            Some(c) => (self.groups[self.clusters[c][0] as usize].error, error(self.clusters[c][1])),
        }
    }

    /// Every cluster's errors ([`Self::cluster_errors`]), `MLET`'s meshlets first: the
    /// `errors` of `skinlet_gpu::crowd_culling::GpuCharacter::with_lod`.
    pub fn errors(&self) -> Vec<[f32; 2]> {
        (0..self.base_parents.len() + self.clusters.len()).map(|c| self.cluster_errors(c).into()).collect()
    }

    /// The cut at error `threshold` (the clusters whose own group's error is at most it and
    /// whose parent group's is above it), numbered as in [`Self::cluster_errors`], into `out`
    /// (cleared first; no allocation once it has grown). Full detail (`MLET`'s meshlets) where
    /// `threshold` is negative or NaN; an infinite one cuts at the roots.
    pub fn cut(&self, threshold: f32, out: &mut Vec<u32>) {
        out.clear();
        if threshold.is_nan() || threshold < 0.0 {
            out.extend(0..self.base_parents.len() as u32);
            return;
        }
        let threshold = threshold.min(f32::MAX);
        out.extend((0..self.base_parents.len() + self.clusters.len()).filter_map(|c| {
            let (own, parent) = self.cluster_errors(c);
            (own <= threshold && threshold < parent).then_some(c as u32)
        }));
    }
}

/// `LODC`: counts, groups, parents, bounds, part ranges and the clusters' meshlet layout,
/// each checked against the bake (see [`LodView`]).
fn read_lod<'a>(
    s: &'a [u8],
    vertices: usize,
    info: &InfoView,
    parts: &[BakedPartRecord],
    drivers: usize,
) -> Result<LodView<'a>> {
    let location = "bake section LODC";
    let bad = |what: String| Error::invalid(location, what);
    let word = |at: usize| u32_at(s, at).ok_or_else(|| bad(format!("byte {at}: truncated")));
    let [g, c, m, p] = [word(0)?, word(4)?, word(8)?, word(12)?].map(|x| x as usize);
    let base = parts.last().map_or(0, |p| p.meshlets[1] as usize);
    if m != base || p != parts.len() {
        return Err(bad(format!("byte 8: {m} meshlets and {p} parts, where the bake has {base} and {}", parts.len())));
    }
    // Each array's end, checked against the section's length before any cast.
    let mut at = 16usize;
    // The next `bytes`, after zero padding to a multiple of `align`.
    let mut take = |bytes: Option<usize>, align: usize| -> Result<std::ops::Range<usize>> {
        let start = at.next_multiple_of(align);
        if s.get(at..start).is_none_or(|pad| pad.iter().any(|&b| b != 0)) {
            return Err(bad(format!("byte {at}: the padding is cut or not zero")));
        }
        let end = bytes.and_then(|b| start.checked_add(b)).filter(|&e| e <= s.len());
        let end = end.ok_or_else(|| bad(format!("byte {start}: the counts do not fit in the section")))?;
        at = end;
        Ok(start..end)
    };
    let groups: &[BakedLodGroup] = cast(&s[take(g.checked_mul(8), 4)?], "LODC")?;
    let base_parents: &[u32] = cast(&s[take(m.checked_mul(4), 4)?], "LODC")?;
    let clusters: &[[u32; 2]] = cast(&s[take(c.checked_mul(8), 4)?], "LODC")?;
    // The bounds records start 16-byte aligned, as in BNDS.
    let bounds: &[BakedBounds] = cast(&s[take(c.checked_mul(48), 16)?], "LODC")?;
    let part_clusters: &[[u32; 2]] = cast(&s[take(p.checked_mul(8), 4)?], "LODC")?;
    let meshlets = MeshletView::new(&s[at..]).map_err(|e| bad(format!("clusters: {e}")))?;
    if meshlets.len() != c {
        return Err(bad(format!("{} clusters in the meshlet layout, where the header says {c}", meshlets.len())));
    }
    let limits = [info.max_vertices as usize, info.max_triangles as usize];
    meshlets.check(vertices, limits).map_err(|e| bad(format!("clusters: {e}")))?;
    check_bounds(bounds, drivers, location)?;
    if let Some((i, x)) =
        groups.iter().enumerate().find(|(_, x)| x.level == 0 || !(x.error >= 0.0 && x.error.is_finite()))
    {
        return Err(bad(format!("group {i}: level {} (≥ 1) and error {} (finite, ≥ 0)", x.level, x.error)));
    }
    let group = |k: u32| groups.get(k as usize).copied();
    // A parent group lies above its child's level with at least its error.
    let parent_ok = |own: BakedLodGroup, parent: u32| {
        parent == NO_GROUP || group(parent).is_some_and(|p| p.level > own.level && p.error >= own.error)
    };
    let level_zero = BakedLodGroup { level: 0, error: 0.0 };
    if let Some(i) = (0..m).find(|&i| !parent_ok(level_zero, base_parents[i])) {
        return Err(bad(format!("meshlet {i}: parent group {} does not exist", base_parents[i])));
    }
    for (i, &[own, parent]) in clusters.iter().enumerate() {
        let Some(own) = group(own) else { return Err(bad(format!("cluster {i}: group {own} does not exist"))) };
        if !parent_ok(own, parent) {
            return Err(bad(format!(
                "cluster {i}: parent group {parent} is missing, not above its level or below its error"
            )));
        }
    }
    let mut end = 0u32;
    for (i, (r, part)) in part_clusters.iter().zip(parts).enumerate() {
        let own = |v: &u32| (part.vertices[0]..part.vertices[1]).contains(v);
        if r[0] != end
            || r[1] < r[0]
            || r[1] as usize > c
            || !(r[0]..r[1]).all(|k| meshlets.vertices_of(k as usize).iter().all(own))
        {
            return Err(bad(format!("part {i}: clusters {r:?} are not the next range of its own vertices")));
        }
        end = r[1];
    }
    if end as usize != c {
        return Err(bad("the parts do not cover every cluster".into()));
    }
    // Every group simplified some clusters into others, all of one part.
    let mut seen = vec![(u32::MAX, false, false); g];
    let mut mark = |group: u32, part: u32, made: bool| -> Result<()> {
        let Some(x) = seen.get_mut(group as usize) else { return Ok(()) };
        if x.0 != u32::MAX && x.0 != part {
            return Err(bad(format!("group {group}: clusters of parts {} and {part}", x.0)));
        }
        x.0 = part;
        if made {
            x.2 = true
        } else {
            x.1 = true
        }
        Ok(())
    };
    for (p, part) in parts.iter().enumerate() {
        for m in part.meshlets[0]..part.meshlets[1] {
            mark(base_parents[m as usize], p as u32, false)?;
        }
        for k in part_clusters[p][0]..part_clusters[p][1] {
            let [own, parent] = clusters[k as usize];
            mark(own, p as u32, true)?;
            mark(parent, p as u32, false)?;
        }
    }
    if let Some(i) = seen.iter().position(|x| !(x.1 && x.2)) {
        return Err(bad(format!("group {i}: no clusters it simplified, or none it made")));
    }
    Ok(LodView { groups, base_parents, clusters, bounds, part_clusters, meshlets, envelope: None })
}

/// `LODE`: per group of `lod` (same levels) its error within the envelope, finite, ≥ 0 and
/// growing up the hierarchy as `LODC`'s; per cluster its bounds ([`check_bounds`]).
fn read_lod_envelope<'a>(
    s: &'a [u8],
    lod: &LodView,
    drivers: usize,
) -> Result<(&'a [BakedLodGroup], &'a [BakedBounds])> {
    let location = "bake section LODE";
    let bad = |what: String| Error::invalid(location, what);
    let word = |at: usize| u32_at(s, at).ok_or_else(|| bad(format!("byte {at}: truncated")));
    let [g, c] = [word(0)?, word(4)?].map(|x| x as usize);
    if g != lod.groups.len() || c != lod.clusters.len() {
        return Err(bad(format!(
            "byte 0: {g} groups and {c} clusters, where LODC has {} and {}",
            lod.groups.len(),
            lod.clusters.len()
        )));
    }
    let bounds_at = (16 + 8 * g).next_multiple_of(16);
    if s.len() != bounds_at + 48 * c
        || s[16 + 8 * g..bounds_at].iter().any(|&b| b != 0)
        || word(8)? != 0
        || word(12)? != 0
    {
        return Err(bad(format!(
            "{} bytes, reserved words or padding not zero, for {g} groups and {c} clusters",
            s.len()
        )));
    }
    let groups: &[BakedLodGroup] = cast(&s[16..16 + 8 * g], "LODE")?;
    let bounds: &[BakedBounds] = cast(&s[bounds_at..], "LODE")?;
    check_bounds(bounds, drivers, location)?;
    for (i, (x, y)) in groups.iter().zip(lod.groups).enumerate() {
        if x.level != y.level || !(x.error >= 0.0 && x.error.is_finite()) {
            return Err(bad(format!(
                "group {i}: level {} (LODC's: {}) and error {} (finite, ≥ 0)",
                x.level, y.level, x.error
            )));
        }
    }
    let parent_ok = |own: f32, parent: u32| parent == NO_GROUP || groups[parent as usize].error >= own;
    let below = lod.base_parents.iter().map(|&p| (0.0, p));
    let above = lod.clusters.iter().map(|&[own, parent]| (groups[own as usize].error, parent));
    if let Some((i, _)) = below.chain(above).enumerate().find(|(_, (own, parent))| !parent_ok(*own, *parent)) {
        return Err(bad(format!("cluster {i} (meshlets first): its parent group's error is below its own")));
    }
    Ok((groups, bounds))
}

/// `MLET`: the layout ([`MeshletView::new`]) and every meshlet ([`MeshletView::check`]).
fn read_meshlets<'a>(s: &'a [u8], vertices: usize, info: &InfoView) -> Result<MeshletView<'a>> {
    let view = MeshletView::new(s).map_err(|e| Error::invalid("bake section MLET", e.to_string()))?;
    let limits = [info.max_vertices as usize, info.max_triangles as usize];
    view.check(vertices, limits).map_err(|e| Error::invalid("bake section MLET", e.to_string()))?;
    Ok(view)
}

/// `BNDS`: one record per meshlet, the section's exact length, [`check_bounds`].
fn read_bounds(s: &[u8], meshlets: usize, drivers: usize) -> Result<&[BakedBounds]> {
    let location = "bake section BNDS";
    let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
    if n != meshlets {
        return Err(Error::invalid(location, format!("byte 0: {n} bounds for {meshlets} meshlets")));
    }
    let end = n.checked_mul(48).and_then(|b| b.checked_add(16)).filter(|&e| e <= s.len());
    let end =
        end.ok_or_else(|| Error::invalid(location, format!("byte 0: {n} meshlet bounds do not fit in the section")))?;
    if end != s.len() {
        return Err(Error::invalid(location, format!("byte {end}: unexpected bytes after the section's data")));
    }
    let records: &[BakedBounds] = cast(&s[16..end], "BNDS")?;
    check_bounds(records, drivers, location)?;
    Ok(records)
}

/// `MRPH`: the section's exact length, then [`MorphView::check`].
fn read_morphs(s: &[u8], vertices: usize) -> Result<MorphView<'_>> {
    let location = "bake section MRPH";
    let err = |at: usize, what: String| Error::invalid(location, format!("byte {at}: {what}"));
    let word = |at: usize| u32_at(s, at).map(|x| x as u64).ok_or_else(|| err(at, "truncated".into()));
    let (w, d, v) = (word(0)?, word(4)?, vertices as u64);
    let offsets_at = 8 + 12 * w;
    let deltas_at = offsets_at + 4 * (v + 1);
    if deltas_at + 28 * d != s.len() as u64 {
        return Err(err(0, format!("{} bytes for {w} weights, {v} vertices and {d} deltas", s.len())));
    }
    let (o, e) = (offsets_at as usize, deltas_at as usize);
    let view = MorphView {
        weights: cast(&s[8..o], "MRPH")?,
        offsets: cast(&s[o..e], "MRPH")?,
        deltas: cast(&s[e..], "MRPH")?,
    };
    view.check(vertices).map_err(|e| Error::invalid(location, e.to_string()))?;
    Ok(view)
}

/// `PART`: consecutive ranges from 0 covering every vertex, triangle and meshlet, each part's
/// triangles and meshlets using only its own vertices.
fn read_parts<'a>(
    s: &'a [u8],
    vertices: usize,
    triangles: &[[u32; 3]],
    meshlets: &MeshletView,
) -> Result<&'a [BakedPartRecord]> {
    let location = "bake section PART";
    let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
    if n.checked_mul(40).and_then(|b| b.checked_add(4)) != Some(s.len()) {
        return Err(Error::invalid(location, format!("{} bytes for {n} parts", s.len())));
    }
    let parts: &[BakedPartRecord] = cast(&s[4..], "PART")?;
    let totals = [vertices, triangles.len(), meshlets.len()];
    let mut ends = [0u32; 3];
    for (i, p) in parts.iter().enumerate() {
        let ranges = [p.vertices, p.triangles, p.meshlets];
        let next = ranges.iter().zip(ends).zip(totals).all(|((r, e), t)| r[0] == e && r[1] >= e && r[1] as usize <= t);
        let own = |v: &u32| (p.vertices[0]..p.vertices[1]).contains(v);
        let ok = next
            && triangles[p.triangles[0] as usize..p.triangles[1] as usize].iter().flatten().all(own)
            && (p.meshlets[0] as usize..p.meshlets[1] as usize).all(|m| meshlets.vertices_of(m).iter().all(own));
        if !ok {
            return Err(Error::invalid(
                location,
                format!(
                    "part {i}: vertices {:?}, triangles {:?}, meshlets {:?} are not the next ranges of its own data",
                    p.vertices, p.triangles, p.meshlets
                ),
            ));
        }
        ends = ranges.map(|r| r[1]);
    }
    if ends.map(|e| e as usize) != totals {
        return Err(Error::invalid(location, "the parts do not cover every vertex, triangle and meshlet"));
    }
    Ok(parts)
}

/// `ENVL`: node ranges, `weights` morph weight ranges, `meshlets` envelope bounds for
/// `drivers` drivers, any-pose boxes, the nodes' names, the section read to its end.
fn read_envelope(s: &[u8], meshlets: usize, weights: usize, drivers: usize) -> Result<EnvelopeView<'_>> {
    let location = "bake section ENVL";
    let err = |at: usize, what: String| Error::invalid(location, format!("byte {at}: {what}"));
    let word = |at: usize| u32_at(s, at).map(|x| x as usize).ok_or_else(|| err(at, "truncated".into()));
    let (r, w, m, b) = (word(0)?, word(4)?, word(8)?, word(12)?);
    if m != meshlets {
        return Err(err(8, format!("{m} envelope bounds for {meshlets} meshlets")));
    }
    if w != weights {
        return Err(err(4, format!("{w} morph weight ranges for {weights} morph weights")));
    }
    // Byte ranges, in u64 so that no count overflows.
    let mut at = 16u64;
    let mut take = |bytes: u64, align: u64| {
        let start = at.next_multiple_of(align);
        at = start + bytes;
        (at <= s.len() as u64).then_some(start as usize..at as usize)
    };
    let (r64, w64, m64, b64) = (r as u64, w as u64, m as u64, b as u64);
    let spans = [
        take(72 * r64, 4),
        take(8 * w64, 4),
        take(48 * m64, 16),
        take(4 * (m64 + 1), 4),
        take(4 * b64, 4),
        take(24 * b64, 4),
    ];
    let [Some(nodes), Some(ws), Some(bounds), Some(offsets), Some(joints), Some(boxes)] = spans else {
        return Err(err(
            0,
            format!("{r} node ranges, {w} weight ranges, {m} bounds and {b} boxes do not fit in the section"),
        ));
    };
    let (offsets_at, joints_at) = (offsets.start, joints.start);
    let mut names = Cursor::new("ENVL", s);
    names.at = boxes.end;
    let mut view = EnvelopeView {
        nodes: cast(&s[nodes], "ENVL")?,
        weights: cast(&s[ws], "ENVL")?,
        bounds: cast(&s[bounds], "ENVL")?,
        box_offsets: cast(&s[offsets], "ENVL")?,
        box_joints: cast(&s[joints], "ENVL")?,
        boxes: cast(&s[boxes], "ENVL")?,
        names: Vec::new(),
    };
    check_ranges(&view.ranges(), &view.weight_ranges(), None, weights).map_err(|e| err(16, e.to_string()))?;
    check_bounds(view.bounds, drivers, location)?;
    if let Some(x) = view.box_joints.iter().find(|&&x| x > u16::MAX as u32) {
        return Err(err(joints_at, format!("box joint {x}")));
    }
    view.any_pose().check(meshlets, drivers).map_err(|e| err(offsets_at, e.to_string()))?;
    view.names = (0..r).map(|_| names.str()).collect::<Result<Vec<_>>>()?;
    names.align(4)?;
    names.end()?;
    Ok(view)
}

/// `PWIN`: `parts` parts and `clips` clips, windows numbered in order from 0, anchors below
/// `drivers`, finite numbers, `min ≤ max`.
fn read_part_windows(b: &[u8], parts_want: usize, clips_want: usize, drivers: usize) -> Result<BakedPartWindows> {
    let mut s = Cursor::new("PWIN", b);
    let (parts, clips, windows) = (s.u32()? as usize, s.u32()? as usize, s.u32()? as usize);
    s.u32()?;
    if (parts, clips) != (parts_want, clips_want) {
        return Err(
            s.err(format!("{parts} parts and {clips} clips, where PART has {parts_want} and INFO {clips_want}"))
        );
    }
    let size = (parts.checked_mul(windows).and_then(|n| n.checked_mul(24)))
        .and_then(|n| n.checked_add(16 + 16 * clips + 4 * parts));
    if size != Some(b.len()) {
        return Err(s.err(format!("{} bytes for {parts} parts, {clips} clips and {windows} windows", b.len())));
    }
    let mut list = Vec::with_capacity(clips);
    for c in 0..clips {
        let w = ClipWindows { start: s.f32()?, end: s.f32()?, count: s.u32()?, first: s.u32()? };
        // Every earlier clip's windows end within `windows` (checked below), so this adds.
        let first = list.last().map_or(0, |p: &ClipWindows| p.first + p.count);
        let end = w.first.checked_add(w.count).filter(|&e| e as usize <= windows);
        if !(w.start <= w.end && w.count >= 1 && w.first == first && end.is_some()) {
            return Err(s.err(format!("clip {c}: windows {w:?} (the next window is {first})")));
        }
        list.push(w);
    }
    if list.last().map_or(0, |w| w.first + w.count) as usize != windows {
        return Err(s.err(format!("the clips' windows do not add up to {windows}")));
    }
    let anchors = (0..parts)
        .map(|p| match s.u32()? {
            a if (a as usize) < drivers => Ok(a),
            a => Err(s.err(format!("part {p}: anchor {a} of {drivers} drivers"))),
        })
        .collect::<Result<Vec<_>>>()?;
    let boxes = (0..parts * windows)
        .map(|i| {
            let (min, max) = (s.vec3()?, s.vec3()?);
            if min.cmple(max).all() {
                Ok([min, max])
            } else {
                Err(s.err(format!("part {}, window {}: box {min} to {max}", i / windows, i % windows)))
            }
        })
        .collect::<Result<Vec<_>>>()?;
    s.end()?;
    Ok(BakedPartWindows { clips: list, anchors, boxes })
}

/// `CONT` with the edges its quads index, rebuilt from the vertices and triangles; one set of
/// windows per baked clip.
fn read_contours(
    s: &[u8],
    vertices: &VertexView,
    morphs: Option<MorphView>,
    triangles: &[[u32; 3]],
    drivers: usize,
    clips: usize,
) -> Result<(BakedContours, Edges)> {
    let rigid = if BakedContours::visible_only(s)? {
        let morphed = |v: usize| morphs.is_some_and(|m| !m.of(v).is_empty());
        Some(rigid_vertices(vertices.positions.len(), vertices.stride, vertices.joints, vertices.weights, morphed))
    } else {
        None
    };
    let edges = skinned_edges(vertices.positions, triangles, rigid.as_deref())
        .map_err(|e| Error::invalid("bake section CONT", e.to_string()))?;
    let contours = BakedContours::read(s, &edges, drivers)?;
    if contours.patches.clips.len() != clips {
        let n = contours.patches.clips.len();
        return Err(Error::invalid("bake section CONT", format!("{n} clips, where INFO has {clips}")));
    }
    Ok((contours, edges))
}

/// The prepared vertices of `VERT`, as slices of the file's bytes.
#[derive(Clone, Copy, Debug)]
pub struct VertexView<'a> {
    /// Bind-pose positions (mesh space of skinned parts, node space of rigid ones).
    pub positions: &'a [Vec3],
    /// Unit normals, or empty when the bake has none.
    pub normals: &'a [Vec3],
    /// Influences per vertex: 4 or 8 (0: no skin weights); vertex `v`'s are
    /// `joints[v * stride..][..stride]` (driver numbers) and the same range of `weights`.
    pub stride: usize,
    pub joints: &'a [u16],
    pub weights: &'a [f32],
}

/// The meshlets of `MLET` (the flat layout of `docs/FORMAT.md`), as slices of the file's bytes.
#[derive(Clone, Copy, Debug)]
pub struct MeshletView<'a> {
    /// Per meshlet: first vertex index, first triangle byte, first joint, and `packed`
    /// (vertex count in bits 0–8, triangle count in bits 9–18, joint count in bits 19–22).
    pub headers: &'a [[u32; 4]],
    /// Indices into the vertices.
    pub vertices: &'a [u32],
    /// Local vertex indices, three per triangle.
    pub triangles: &'a [u8],
    /// Joint numbers of single-joint-set meshlets.
    pub joints: &'a [u16],
}

impl<'a> MeshletView<'a> {
    /// The layout of `MLET`'s bytes (4-byte aligned): the header's counts and the section's
    /// exact length. [`Self::check`] checks the meshlets themselves.
    pub fn new(s: &'a [u8]) -> Result<MeshletView<'a>> {
        let word = |at: usize| u32_at(s, at).ok_or_else(|| Error::invalid("meshlets", format!("byte {at}: truncated")));
        let [m, v, t, j] = [word(0)?, word(4)?, word(8)?, word(12)?].map(|x| x as u64);
        let (headers_end, vertices_end) = (16 + 16 * m, 16 + 16 * m + 4 * v);
        let triangles_end = vertices_end + t.next_multiple_of(4);
        let end = triangles_end + (2 * j).next_multiple_of(4);
        if end != s.len() as u64 {
            return Err(Error::invalid("meshlets", format!("{} bytes; the header's counts need {end}", s.len())));
        }
        let (he, ve, te) = (headers_end as usize, vertices_end as usize, triangles_end as usize);
        Ok(MeshletView {
            headers: cast(&s[16..he], "MLET")?,
            vertices: cast(&s[he..ve], "MLET")?,
            triangles: &s[ve..ve + t as usize],
            joints: cast(&s[te..te + 2 * j as usize], "MLET")?,
        })
    }

    /// Checks the meshlets of a mesh of `vertices` vertices, each with at most `limits`
    /// vertices and triangles: every meshlet's ranges inside the arrays, its triangle offset on
    /// a triangle, at least one triangle, its local indices below its vertex count, its vertex
    /// indices below `vertices`, bit 31 of `packed` set exactly when it has a joint set. What
    /// [`Self::index_buffer`] and a GPU upload need.
    pub fn check(&self, vertices: usize, limits: [usize; 2]) -> Result<()> {
        for (i, h) in self.headers.iter().enumerate() {
            let bad = |what: String| Err(Error::invalid(format!("meshlet {i}"), what));
            let (vc, tc) = self.counts(i);
            let verts = self.vertices.get(h[0] as usize..).and_then(|r| r.get(..vc));
            let tris = self.triangles.get(h[1] as usize..).and_then(|r| r.get(..3 * tc));
            let (Some(verts), Some(tris), Some(joints)) = (verts, tris, self.joints_of(i)) else {
                return bad("points past the meshlet arrays".into());
            };
            if !h[1].is_multiple_of(3) || (h[3] >> 31 == 1) == joints.is_empty() {
                return bad("its triangle offset is off a triangle, or its joint-set flag disagrees".into());
            }
            if tc == 0 || vc > limits[0] || tc > limits[1] {
                return bad(format!("{vc} vertices / {tc} triangles (limits {} / {})", limits[0], limits[1]));
            }
            if tris.iter().any(|&l| l as usize >= vc) || verts.iter().any(|&x| x as usize >= vertices) {
                return bad("indexes past its or the mesh's vertices".into());
            }
        }
        Ok(())
    }

    /// Meshlet `i`'s vertex indices (empty past the arrays: see [`Self::check`]).
    pub fn vertices_of(&self, i: usize) -> &'a [u32] {
        let (h, (vc, _)) = (self.headers[i], self.counts(i));
        self.vertices.get(h[0] as usize..).and_then(|r| r.get(..vc)).unwrap_or(&[])
    }

    /// Meshlet `i`'s joint list (single-joint-set meshlets; empty for the others), or `None`
    /// when it points past the array.
    pub fn joints_of(&self, i: usize) -> Option<&'a [u16]> {
        let h = self.headers[i];
        self.joints.get(h[2] as usize..).and_then(|r| r.get(..(h[3] >> 19 & 0xf) as usize))
    }

    pub fn len(&self) -> usize {
        self.headers.len()
    }

    pub fn is_empty(&self) -> bool {
        self.headers.is_empty()
    }

    /// Meshlet `i`'s vertex and triangle counts.
    pub fn counts(&self, i: usize) -> (usize, usize) {
        let packed = self.headers[i][3];
        ((packed & 0x1ff) as usize, (packed >> 9 & 0x3ff) as usize)
    }

    /// An index buffer listing the triangles meshlet by meshlet (vertex indices), and per
    /// meshlet its index count and first index in it: what a renderer binds to draw
    /// meshlets one by one (GPU culling passes write indirect draws over these ranges).
    /// A meshlet that fails [`Self::check`] (a view from [`BakeView::meshlets`] never does)
    /// gets no triangles where its ranges leave the arrays and vertex 0 for a local index past
    /// its vertices.
    pub fn index_buffer(&self) -> (Vec<u32>, Vec<[u32; 2]>) {
        let (mut indices, mut draws) = (Vec::with_capacity(self.triangles.len()), Vec::with_capacity(self.len()));
        for (i, h) in self.headers.iter().enumerate() {
            let (local, tc) = (self.vertices_of(i), self.counts(i).1);
            let tris = self.triangles.get(h[1] as usize..).and_then(|r| r.get(..3 * tc)).unwrap_or(&[]);
            draws.push([tris.len() as u32, indices.len() as u32]);
            indices.extend(tris.iter().map(|&l| local.get(l as usize).copied().unwrap_or(0)));
        }
        (indices, draws)
    }
}

/// A mesh as a bake stores it, as slices: what a GPU upload reads
/// (`skinlet_gpu::mesh::GpuMesh::new`). From a file: [`BakeView::mesh_data`]; the baker
/// builds the same from its in-memory mesh (`skinlet::model::SkinnedMesh::mesh_data`).
#[derive(Clone, Copy, Debug)]
pub struct MeshData<'a> {
    pub vertices: VertexView<'a>,
    /// Vertex indices, counter-clockwise front faces.
    pub triangles: &'a [[u32; 3]],
    /// `None`: no morph targets.
    pub morphs: Option<MorphView<'a>>,
    /// `None`: drawn without meshlets (no mesh shaders, no meshlet culling).
    pub meshlets: Option<MeshletView<'a>>,
}

/// One morph weight of `MRPH`: target `target` of the mesh node `node` draws, and its
/// default weight.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BakedMorphWeight {
    pub node: u32,
    pub target: u32,
    pub default: f32,
}

/// One vertex delta of `MRPH`: the vertex moves by `weight × position` and its normal by
/// `weight × normal`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BakedMorphDelta {
    /// Index into the morph weights.
    pub weight: u32,
    pub position: Vec3,
    /// Zero where the source gives no normal deltas.
    pub normal: Vec3,
}

// SAFETY: `repr(C)`, 4-byte fields of plain numbers (12 and 28 bytes, no padding): every bit
// pattern is a value, and zero is one; `Copy` and `'static`.
unsafe impl bytemuck::Zeroable for BakedMorphWeight {}
unsafe impl bytemuck::Pod for BakedMorphWeight {}
unsafe impl bytemuck::Zeroable for BakedMorphDelta {}
unsafe impl bytemuck::Pod for BakedMorphDelta {}

/// The morph targets of `MRPH`, as slices of the file's bytes: a vertex is drawn at
/// `p + Σ wₖ·dₖ` over its deltas (normals alike), then skinned.
#[derive(Clone, Copy, Debug)]
pub struct MorphView<'a> {
    pub weights: &'a [BakedMorphWeight],
    /// Vertex `v`'s deltas are `deltas[offsets[v]..offsets[v + 1]]`.
    pub offsets: &'a [u32],
    pub deltas: &'a [BakedMorphDelta],
}

impl<'a> MorphView<'a> {
    /// Checks the deltas of a mesh of `vertices` vertices: one offset per vertex and one
    /// more, from 0, never decreasing, ending at the delta count; every delta's weight in
    /// range; finite deltas and defaults.
    pub fn check(&self, vertices: usize) -> Result<()> {
        let bad = |what: String| Err(Error::invalid("morph targets", what));
        let (o, d, w) = (self.offsets, self.deltas.len(), self.weights.len());
        if o.len() != vertices + 1 || o[0] != 0 || o[vertices] as usize != d {
            return bad(format!("{} vertex offsets for {vertices} vertices and {d} deltas", o.len()));
        }
        if let Some(v) = o.windows(2).position(|x| x[1] < x[0]) {
            return bad(format!("vertex {v}: offsets decrease"));
        }
        if let Some(x) = self.deltas.iter().find(|x| x.weight as usize >= w) {
            return bad(format!("a delta uses weight {} of {w}", x.weight));
        }
        if let Some(k) = self.deltas.iter().position(|x| !(x.position.is_finite() && x.normal.is_finite())) {
            return bad(format!("delta {k} is not finite"));
        }
        if let Some(k) = self.weights.iter().position(|x| !x.default.is_finite()) {
            return bad(format!("morph weight {k}'s default is not finite"));
        }
        Ok(())
    }

    /// The deltas of vertex `v` (none past the last vertex).
    pub fn of(&self, v: usize) -> &'a [BakedMorphDelta] {
        let range = self.offsets.get(v..v + 2).and_then(|r| self.deltas.get(r[0] as usize..r[1] as usize));
        range.unwrap_or(&[])
    }
}

/// What `INFO` says about how the bake was made: the meshlet builder (its code in
/// `docs/FORMAT.md`), the meshlet limits, the refinement and why it stopped, and the baked
/// clips' names (clip indices in other sections index this list).
#[derive(Clone, Debug, PartialEq)]
pub struct InfoView<'a> {
    pub builder: u32,
    pub max_vertices: u32,
    pub max_triangles: u32,
    pub s_r: f32,
    pub alpha_t: f32,
    pub rounds: u32,
    /// 0 converged, 1 round limit, 2 time budget.
    pub stop: u32,
    pub clips: Vec<&'a str>,
}

/// `PWIN`: per part, one box per time window of each baked clip, in the skinning space of the
/// part's anchor driver (`inverse_bind⁻¹ · global⁻¹ · p`: mesh space at the bind pose); it
/// holds every vertex of the part at every time of the window, moved by
/// `global(anchor) · inverse_bind(anchor)` (`docs/FORMAT.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct BakedPartWindows {
    /// Per baked clip (`INFO`'s order), its windows, numbered clip after clip.
    pub clips: Vec<ClipWindows>,
    /// Per part, its anchor driver.
    pub anchors: Vec<u32>,
    /// Per part, per window, the box's min and max: `boxes[part * windows + w]`.
    pub boxes: Vec<[Vec3; 2]>,
}

impl BakedPartWindows {
    /// Windows of all clips.
    pub fn windows(&self) -> usize {
        self.clips.last().map_or(0, |c| c.first.saturating_add(c.count) as usize)
    }
}

/// One part of a baked character in `PART` (40 bytes): which node draws which glTF mesh
/// primitive, its skin (`u32::MAX`: a rigid part), and its `[start, end)` ranges of vertices,
/// triangles and meshlets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct BakedPartRecord {
    pub node: u32,
    pub mesh: u32,
    pub primitive: u32,
    pub skin: u32,
    pub vertices: [u32; 2],
    pub triangles: [u32; 2],
    pub meshlets: [u32; 2],
}

// SAFETY: `repr(C)`, ten `u32`s (40 bytes, no padding): every bit pattern is a value, and zero
// is one; `Copy` and `'static`.
unsafe impl bytemuck::Zeroable for BakedPartRecord {}
unsafe impl bytemuck::Pod for BakedPartRecord {}

/// A cursor over one section's bytes that names the section and the byte in its errors (for
/// the sections read into arrays rather than viewed in place).
pub(crate) struct Cursor<'a> {
    tag: &'static str,
    b: &'a [u8],
    pub(crate) at: usize,
}

impl<'a> Cursor<'a> {
    pub(crate) fn new(tag: &'static str, b: &'a [u8]) -> Cursor<'a> {
        Cursor { tag, b, at: 0 }
    }
    pub(crate) fn err(&self, msg: impl std::fmt::Display) -> Error {
        Error::invalid(format!("bake section {}", self.tag), format!("byte {}: {msg}", self.at))
    }
    pub(crate) fn bytes(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        let end = end.ok_or_else(|| self.err(format!("truncated (needs {n} more bytes)")))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub(crate) fn remaining(&self) -> usize {
        self.b.len() - self.at
    }
    /// A length-prefixed UTF-8 string.
    pub(crate) fn str(&mut self) -> Result<&'a str> {
        let n = self.u32()? as usize;
        let b = self.bytes(n)?;
        std::str::from_utf8(b).map_err(|_| self.err("a name is not UTF-8"))
    }
    pub(crate) fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.bytes(4)?.try_into().expect("4 bytes")))
    }
    /// A finite `f32`.
    pub(crate) fn f32(&mut self) -> Result<f32> {
        let x = f32::from_le_bytes(self.bytes(4)?.try_into().expect("4 bytes"));
        if x.is_finite() { Ok(x) } else { Err(self.err(format!("non-finite number {x}"))) }
    }
    pub(crate) fn vec3(&mut self) -> Result<glam::Vec3> {
        Ok(glam::Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    pub(crate) fn align(&mut self, to: usize) -> Result<()> {
        let pad = self.at.next_multiple_of(to) - self.at;
        self.bytes(pad).map(|_| ())
    }
    pub(crate) fn end(&self) -> Result<()> {
        if self.at == self.b.len() { Ok(()) } else { Err(self.err("unexpected bytes after the section's data")) }
    }
}

fn tag_name(tag: &[u8; 4]) -> String {
    String::from_utf8_lossy(tag).into_owned()
}

/// Section bytes as typed records (the view checked the file's start alignment; sections and
/// their records are aligned within the file).
fn cast<'a, T: bytemuck::Pod>(b: &'a [u8], tag: &str) -> Result<&'a [T]> {
    bytemuck::try_cast_slice(b)
        .map_err(|e| Error::invalid(format!("bake section {tag}"), format!("records misaligned or cut: {e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of `sections` (tag, body), each at the next 16-byte aligned offset, in u32
    /// storage (4-byte aligned).
    fn file(sections: &[(&[u8; 4], Vec<u8>)]) -> Vec<u32> {
        let mut b = vec![0u8; 16 + 24 * sections.len()];
        b[..8].copy_from_slice(&MAGIC);
        b[8..12].copy_from_slice(&VERSION.to_le_bytes());
        b[12..16].copy_from_slice(&(sections.len() as u32).to_le_bytes());
        for (k, (tag, body)) in sections.iter().enumerate() {
            b.resize(b.len().next_multiple_of(16), 0);
            let e = 16 + 24 * k;
            let offset = b.len() as u64;
            b[e..e + 4].copy_from_slice(*tag);
            b[e + 8..e + 16].copy_from_slice(&offset.to_le_bytes());
            b[e + 16..e + 24].copy_from_slice(&(body.len() as u64).to_le_bytes());
            b.extend_from_slice(body);
        }
        b.resize(b.len().next_multiple_of(4), 0);
        b.chunks_exact(4).map(|w| u32::from_ne_bytes(w.try_into().unwrap())).collect()
    }

    fn words(w: &[u32]) -> Vec<u8> {
        w.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    /// The sections of an empty character: no drivers, vertices, triangles, meshlets or parts.
    fn empty() -> Vec<(&'static [u8; 4], Vec<u8>)> {
        vec![
            (b"INFO", words(&[2, 64, 124, 0, 0, 0, 0, 0])),
            (b"SKIN", words(&[0])),
            (b"VERT", words(&[0, 0, 0])),
            (b"TRIS", words(&[0])),
            (b"MLET", words(&[0; 4])),
            (b"BNDS", words(&[0; 4])),
            (b"PART", words(&[0])),
        ]
    }

    fn error(bytes: &[u8]) -> String {
        BakeView::new(bytes).unwrap_err().to_string()
    }

    #[test]
    fn bad_headers_and_tables_are_errors_that_say_where() {
        let ok = file(&empty());
        let bytes: &[u8] = bytemuck::cast_slice(&ok);
        let view = BakeView::new(bytes).unwrap();
        assert_eq!((view.joint_count(), view.meshlet_count()), (0, 0));
        assert!(view.meshlet_bounds().is_empty() && view.envelope().is_none());
        let mut wrong = bytes.to_vec();
        wrong[0] = b'X';
        assert!(error(&wrong).contains("magic"));
        let mut newer = bytes.to_vec();
        newer[8] = VERSION as u8 + 1;
        assert!(matches!(BakeView::new(&newer), Err(Error::Unsupported { .. })));
        let mut outside = bytes.to_vec();
        // The first entry's length (INFO) made longer than the file.
        outside[32..40].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
        assert!(error(&outside).contains("byte 16: section INFO lies outside the file"));
        let mut sections = empty();
        sections[3].0 = b"SKIN";
        assert!(error(bytemuck::cast_slice(&file(&sections))).contains("byte 88: section SKIN appears twice"));
        let mut sections = empty();
        sections.remove(5);
        assert!(error(bytemuck::cast_slice(&file(&sections))).contains("section BNDS is missing"));
        let mut words = ok.clone();
        words.push(0);
        let shifted: &[u8] = &bytemuck::cast_slice::<u32, u8>(&words)[1..];
        assert!(error(&shifted[..bytes.len()]).contains("aligned"));
        for cut in 0..bytes.len() {
            // Every truncation cuts the last section (PART) or more: an error.
            assert!(BakeView::new(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn section_rules_are_checked() {
        let check = |tag: &[u8; 4], body: Vec<u8>, want: &str| {
            let mut sections = empty();
            sections.iter_mut().find(|(t, _)| *t == tag).unwrap().1 = body;
            let e = error(bytemuck::cast_slice(&file(&sections)));
            assert!(e.contains(want), "{}: {e}", tag_name(tag));
        };
        check(b"INFO", words(&[7, 64, 124, 0, 0, 0, 0, 0]), "unknown meshlet builder 7");
        check(b"INFO", words(&[2, 300, 124, 0, 0, 0, 0, 0]), "meshlet limits 300 vertices");
        check(b"INFO", words(&[2, 64, 124, 0, 0, 0, 3, 0]), "unknown stop reason 3");
        check(b"SKIN", words(&[70_000]), "70000 drivers");
        // One vertex with four influences on driver 0 (of none), then weights that break
        // the rules with a driver to spare.
        let vert = |w: [f32; 4]| {
            let mut b = words(&[1, 4, 0, 0, 0, 0, 0, 0]);
            b.extend(w.iter().flat_map(|x| x.to_le_bytes()));
            b
        };
        check(b"VERT", vert([1.0, 0.0, 0.0, 0.0]), "uses joint 0 of 0");
        let mut sections = empty();
        sections[1].1 = [&words(&[1])[..], &[0; 64], &words(&[3, 0])].concat();
        for (w, want) in [
            ([0.5, 0.0, 0.0, 0.0], "sum to 0.5"),
            ([0.0, 1.0, 0.0, 0.0], "non-zero weight after a zero one"),
            ([1.5, -0.5, 0.0, 0.0], "weight 1.5"),
        ] {
            sections[2].1 = vert(w);
            let e = error(bytemuck::cast_slice(&file(&sections)));
            assert!(e.contains("VERT") && e.contains(want), "{want}: {e}");
        }
        // Good weights: the vertices are fine, and the next section checked is PART's, which
        // covers none of them.
        sections[2].1 = vert([1.0, 0.0, 0.0, 0.0]);
        assert!(error(bytemuck::cast_slice(&file(&sections))).contains("PART"));
    }

    #[test]
    fn bounds_records_are_checked() {
        let good = BakedBounds {
            radius: 1.0,
            rest_radius: 1.0,
            cone_axis: [0.0, 0.0, 1.0],
            cone_angle: 0.5,
            ..Default::default()
        };
        assert!(check_bounds(&[good], 1, "t").is_ok());
        for (what, bad) in [
            ("principal joint", BakedBounds { joint: 1, ..good }),
            ("class", BakedBounds { class: 3, ..good }),
            ("finite", BakedBounds { radius: f32::NAN, ..good }),
            ("negative", BakedBounds { radius: -1.0, ..good }),
            ("cone angle", BakedBounds { cone_angle: 4.0, ..good }),
        ] {
            let e = check_bounds(&[good, bad], 1, "t").unwrap_err().to_string();
            assert!(e.contains("meshlet 1") && e.contains(what), "{what}: {e}");
        }
    }
}
