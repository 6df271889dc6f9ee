//! A validated, zero-copy view over the bytes of a bake file (`docs/FORMAT.md`): the header
//! and section table are checked once, and sections come out as typed slices of the file's
//! own bytes (every section starts 16-byte aligned in the file, so a memory-mapped file or a
//! `Vec<u8>` read from disk serves them directly; its records are little-endian, as the
//! format is). What it hands out has been checked: a culler built from it never indexes out
//! of range and never sees a non-finite number.
//!
//! Every section: the bake settings and clip names (`INFO`), the drivers' inverse bind
//! matrices, nodes and node names (`SKIN`), vertices (`VERT`), triangles (`TRIS`), meshlets (`MLET`),
//! meshlet bounds with their classes (`BNDS`), parts (`PART`), morph targets (`MRPH`), the
//! pose envelope with its bounds and any-pose boxes (`ENVL`) as typed slices; the parts'
//! boxes per clip window (`PWIN`), the overdraw orders (`OVDR`) and contour patches (`CONT`,
//! with the edges it indexes, which the file does not store) read into arrays once, at load. The baker's reader
//! (`skinlet::bake::from_bytes`) goes through this view for every section but `SKIN`'s names,
//! `VERT`, `TRIS` and `MLET`, which it parses into its own types.

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
/// `joints`, known classes, radii not negative, cone angles in [0, π], unit axes for cones
/// below π/2. Errors name the meshlet; `location` says where the records came from.
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
/// envelope bounds record per meshlet, the any-pose boxes; slices of the file's bytes. The
/// nodes' names that follow are not read (a game needs none).
#[derive(Clone, Copy, Debug)]
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
    /// Where the nodes' names start in the section.
    pub names_at: usize,
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

/// The checked view.
#[derive(Clone, Debug)]
pub struct BakeView<'a> {
    sections: Vec<([u8; 4], &'a [u8])>,
}

/// The little-endian `u32` at byte `at` of `b`, or `None` past its end.
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?))
}

impl<'a> BakeView<'a> {
    /// Checks the header (magic, version) and the section table (every section inside the
    /// file, no tag twice). `bytes` must start at a 4-byte aligned address, as a memory map or a buffer
    /// from the allocator does. Errors say what is wrong and where.
    pub fn new(bytes: &'a [u8]) -> Result<BakeView<'a>> {
        let head = |message: String| Error::invalid("bake header", message);
        if cfg!(target_endian = "big") {
            return Err(head("bake files are little-endian; this target is big-endian".into()));
        }
        if !(bytes.as_ptr() as usize).is_multiple_of(4) {
            return Err(head(
                "the bytes must start at a 4-byte aligned address (copy them into an aligned buffer)".into(),
            ));
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
        Ok(BakeView { sections })
    }

    /// The bytes of section `tag`, if the file has it.
    pub fn section(&self, tag: &[u8; 4]) -> Option<&'a [u8]> {
        self.sections.iter().find(|(t, _)| t == tag).map(|(_, b)| *b)
    }

    /// The bytes of a section the format requires.
    pub fn required(&self, tag: &[u8; 4]) -> Result<&'a [u8]> {
        self.section(tag).ok_or_else(|| Error::invalid("bake file", format!("section {} is missing", tag_name(tag))))
    }

    /// The number of drivers (joints), from `SKIN`.
    pub fn joint_count(&self) -> Result<usize> {
        let s = self.required(b"SKIN")?;
        let n = u32_at(s, 0).ok_or_else(|| Error::invalid("bake section SKIN", "byte 0: truncated"))? as usize;
        if n > MAX_DRIVERS {
            return Err(Error::invalid(
                "bake section SKIN",
                format!("byte 0: {n} drivers; the format numbers them in 16 bits (at most 65,536)"),
            ));
        }
        if n.saturating_mul(68) > s.len() - 4 {
            return Err(Error::invalid("bake section SKIN", format!("byte 0: {n} joints do not fit in the section")));
        }
        Ok(n)
    }

    /// Each driver's inverse bind matrix (16 `f32`, column-major), checked finite.
    pub fn inverse_bind(&self) -> Result<&'a [[f32; 16]]> {
        let n = self.joint_count()?;
        let m: &[[f32; 16]] = cast(&self.required(b"SKIN")?[4..4 + 64 * n], "SKIN")?;
        if let Some(j) = m.iter().position(|m| m.iter().any(|x| !x.is_finite())) {
            return Err(Error::invalid("bake section SKIN", format!("joint {j}'s inverse bind matrix is not finite")));
        }
        Ok(m)
    }

    /// Each driver's node (index into the source file's nodes).
    pub fn joint_nodes(&self) -> Result<&'a [u32]> {
        let n = self.joint_count()?;
        cast(&self.required(b"SKIN")?[4 + 64 * n..4 + 68 * n], "SKIN")
    }

    /// Each driver's node name (empty for unnamed nodes), checked: UTF-8, the section read to
    /// its end. Allocates the list: for load-time checks that a scene is the baked one.
    pub fn joint_names(&self) -> Result<Vec<&'a str>> {
        let n = self.joint_count()?;
        let mut s = Cursor::new("SKIN", self.required(b"SKIN")?);
        s.bytes(4 + 68 * n)?;
        let names = (0..n).map(|_| s.str()).collect::<Result<Vec<_>>>()?;
        s.end()?;
        Ok(names)
    }

    /// The meshlet count, from `MLET`'s header.
    pub fn meshlet_count(&self) -> Result<usize> {
        let s = self.required(b"MLET")?;
        Ok(u32_at(s, 0).ok_or_else(|| Error::invalid("bake section MLET", "byte 0: truncated"))? as usize)
    }

    /// The meshlet bounds and classes of `BNDS`, one per meshlet, checked
    /// ([`check_bounds`] for the file's joints).
    pub fn meshlet_bounds(&self) -> Result<&'a [BakedBounds]> {
        let s = self.required(b"BNDS")?;
        let location = "bake section BNDS";
        let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
        let meshlets = self.meshlet_count()?;
        if n != meshlets {
            return Err(Error::invalid(location, format!("byte 0: {n} bounds for {meshlets} meshlets")));
        }
        let end = n.checked_mul(48).and_then(|b| b.checked_add(16)).filter(|&e| e <= s.len());
        let end = end
            .ok_or_else(|| Error::invalid(location, format!("byte 0: {n} meshlet bounds do not fit in the section")))?;
        if end != s.len() {
            return Err(Error::invalid(location, format!("byte {end}: unexpected bytes after the section's data")));
        }
        let records: &[BakedBounds] = cast(&s[16..end], "BNDS")?;
        check_bounds(records, self.joint_count()?, location)?;
        Ok(records)
    }

    /// The run-time culler for the clip bounds of `BNDS`.
    pub fn culler(&self) -> Result<MeshletCuller> {
        let (bounds, classes) = bounds_and_classes(self.meshlet_bounds()?);
        MeshletCuller::new(&bounds, &classes, self.joint_count()?)
    }

    /// The optional `ENVL` section, checked: node ranges ([`check_ranges`], any node index,
    /// each once), morph weight ranges (as many as `weights`, the mesh's morph weights),
    /// envelope bounds for every meshlet ([`check_bounds`]), any-pose boxes
    /// ([`AnyPoseBoxes::check`] rules, box joints below 2¹⁶).
    pub fn envelope(&self, weights: usize) -> Result<Option<EnvelopeView<'a>>> {
        let Some(s) = self.section(b"ENVL") else { return Ok(None) };
        let location = "bake section ENVL";
        let err = |at: usize, what: String| Error::invalid(location, format!("byte {at}: {what}"));
        let word = |at: usize| u32_at(s, at).map(|x| x as usize).ok_or_else(|| err(at, "truncated".into()));
        let (r, w, m, b) = (word(0)?, word(4)?, word(8)?, word(12)?);
        let meshlets = self.meshlet_count()?;
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
        let (names_at, offsets_at, joints_at) = (boxes.end, offsets.start, joints.start);
        let view = EnvelopeView {
            nodes: cast(&s[nodes], "ENVL")?,
            weights: cast(&s[ws], "ENVL")?,
            bounds: cast(&s[bounds], "ENVL")?,
            box_offsets: cast(&s[offsets], "ENVL")?,
            box_joints: cast(&s[joints], "ENVL")?,
            boxes: cast(&s[boxes], "ENVL")?,
            names_at,
        };
        check_ranges(&view.ranges(), &view.weight_ranges(), None, weights).map_err(|e| err(16, e.to_string()))?;
        let j = self.joint_count()?;
        check_bounds(view.bounds, j, location)?;
        if let Some(x) = view.box_joints.iter().find(|&&x| x > u16::MAX as u32) {
            return Err(err(joints_at, format!("box joint {x}")));
        }
        view.any_pose().check(meshlets, j).map_err(|e| err(offsets_at, e.to_string()))?;
        Ok(Some(view))
    }
}

/// The tag as text (lossy for non-ASCII bytes).
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

impl MeshletView<'_> {
    /// Checks the meshlets of a mesh of `vertices` vertices: every meshlet's ranges inside
    /// the arrays, its local indices below its vertex count, its vertex indices below
    /// `vertices`. What [`Self::index_buffer`] and a GPU upload need.
    pub fn check(&self, vertices: usize) -> Result<()> {
        for (i, h) in self.headers.iter().enumerate() {
            let (vc, tc) = self.counts(i);
            let verts = self.vertices.get(h[0] as usize..).and_then(|r| r.get(..vc));
            let tris = self.triangles.get(h[1] as usize..).and_then(|r| r.get(..3 * tc));
            let (Some(verts), Some(tris), Some(_)) = (verts, tris, self.joints_of(i)) else {
                return Err(Error::invalid(format!("meshlet {i}"), "points past the meshlet arrays"));
            };
            if tris.iter().any(|&l| l as usize >= vc) || verts.iter().any(|&x| x as usize >= vertices) {
                return Err(Error::invalid(format!("meshlet {i}"), "indexes past its or the mesh's vertices"));
            }
        }
        Ok(())
    }

    /// Meshlet `i`'s joint list (single-joint-set meshlets; empty for the others), or `None`
    /// when it points past the array.
    pub fn joints_of(&self, i: usize) -> Option<&[u16]> {
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
    /// Panics unless [`Self::check`] passes (a view from [`BakeView::meshlets`] does).
    pub fn index_buffer(&self) -> (Vec<u32>, Vec<[u32; 2]>) {
        let (mut indices, mut draws) = (Vec::with_capacity(self.triangles.len()), Vec::with_capacity(self.len()));
        for (i, h) in self.headers.iter().enumerate() {
            let (vc, tc) = self.counts(i);
            let local = &self.vertices[h[0] as usize..][..vc];
            draws.push([3 * tc as u32, indices.len() as u32]);
            indices.extend(self.triangles[h[1] as usize..][..3 * tc].iter().map(|&l| local[l as usize]));
        }
        (indices, draws)
    }
}

impl<'a> BakeView<'a> {
    /// The vertices of `VERT`, checked: the section's exact length, finite positions and
    /// normals, joint numbers below the file's joint count, finite weights.
    pub fn vertices(&self) -> Result<VertexView<'a>> {
        let (s, location) = (self.required(b"VERT")?, "bake section VERT");
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
                format!(
                    "{} bytes for {n} vertices of {stride} influences (expected {})",
                    s.len(),
                    joints_end + 4 * slots
                ),
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
        let drivers = self.joint_count()?;
        if let Some(k) = joints.iter().position(|&j| j as usize >= drivers) {
            return Err(Error::invalid(
                location,
                format!("vertex {}'s joint {} is not one of {drivers}", k / stride, joints[k]),
            ));
        }
        if let Some(k) = weights.iter().position(|w| !w.is_finite()) {
            return Err(Error::invalid(location, format!("vertex {}'s weight is not finite", k / stride)));
        }
        Ok(VertexView { positions, normals, stride, joints, weights })
    }

    /// The triangles of `TRIS` (vertex indices, counter-clockwise front faces), checked
    /// against the vertex count.
    pub fn triangles(&self) -> Result<&'a [[u32; 3]]> {
        let (s, location) = (self.required(b"TRIS")?, "bake section TRIS");
        let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
        if n.checked_mul(12).and_then(|b| b.checked_add(4)) != Some(s.len()) {
            return Err(Error::invalid(location, format!("{} bytes for {n} triangles", s.len())));
        }
        let triangles: &[[u32; 3]] = cast(&s[4..], "TRIS")?;
        let vertices = self.vertices()?.positions.len();
        if let Some(t) = triangles.iter().position(|t| t.iter().any(|&i| i as usize >= vertices)) {
            return Err(Error::invalid(
                location,
                format!("triangle {t} {:?} indexes past {vertices} vertices", triangles[t]),
            ));
        }
        Ok(triangles)
    }

    /// The meshlets of `MLET`, checked: the section's exact length, every meshlet's ranges
    /// inside the arrays, its local indices below its vertex count, its vertex indices below
    /// the vertex count.
    pub fn meshlets(&self) -> Result<MeshletView<'a>> {
        let (s, location) = (self.required(b"MLET")?, "bake section MLET");
        let word = |at: usize| u32_at(s, at).ok_or_else(|| Error::invalid(location, format!("byte {at}: truncated")));
        let [m, v, t, j] = [word(0)?, word(4)?, word(8)?, word(12)?].map(|x| x as u64);
        let (headers_end, vertices_end) = (16 + 16 * m, 16 + 16 * m + 4 * v);
        let triangles_end = vertices_end + t.next_multiple_of(4);
        let end = triangles_end + (2 * j).next_multiple_of(4);
        if end != s.len() as u64 {
            return Err(Error::invalid(location, format!("{} bytes; the header's counts need {end}", s.len())));
        }
        let (he, ve, te) = (headers_end as usize, vertices_end as usize, triangles_end as usize);
        let view = MeshletView {
            headers: cast(&s[16..he], "MLET")?,
            vertices: cast(&s[he..ve], "MLET")?,
            triangles: &s[ve..ve + t as usize],
            joints: cast(&s[te..te + 2 * j as usize], "MLET")?,
        };
        view.check(self.vertices()?.positions.len()).map_err(|e| Error::invalid(location, e.to_string()))?;
        Ok(view)
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

impl<'a> BakeView<'a> {
    /// The vertices, triangles, morph targets and meshlets, each checked
    /// ([`Self::vertices`], [`Self::triangles`], [`Self::morphs`], [`Self::meshlets`]).
    pub fn mesh_data(&self) -> Result<MeshData<'a>> {
        Ok(MeshData {
            vertices: self.vertices()?,
            triangles: self.triangles()?,
            morphs: self.morphs()?,
            meshlets: Some(self.meshlets()?),
        })
    }
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

impl<'a> BakeView<'a> {
    /// The optional `MRPH` section, checked: exact length, one offset per vertex and one
    /// more, from 0, never decreasing, ending at the delta count; every delta's weight in
    /// range; finite deltas and defaults.
    pub fn morphs(&self) -> Result<Option<MorphView<'a>>> {
        let Some(s) = self.section(b"MRPH") else { return Ok(None) };
        let location = "bake section MRPH";
        let err = |at: usize, what: String| Error::invalid(location, format!("byte {at}: {what}"));
        let word = |at: usize| u32_at(s, at).map(|x| x as u64).ok_or_else(|| err(at, "truncated".into()));
        let (w, d) = (word(0)?, word(4)?);
        let vertices = self.vertices()?.positions.len() as u64;
        let offsets_at = 8 + 12 * w;
        let deltas_at = offsets_at + 4 * (vertices + 1);
        if deltas_at + 28 * d != s.len() as u64 {
            return Err(err(0, format!("{} bytes for {w} weights, {vertices} vertices and {d} deltas", s.len())));
        }
        let (o, e) = (offsets_at as usize, deltas_at as usize);
        let view = MorphView {
            weights: cast(&s[8..o], "MRPH")?,
            offsets: cast(&s[o..e], "MRPH")?,
            deltas: cast(&s[e..], "MRPH")?,
        };
        view.check(vertices as usize).map_err(|e| Error::invalid(location, e.to_string()))?;
        Ok(Some(view))
    }

    /// The optional `CONT` section, read and checked, with the edges its quads index (rebuilt
    /// from `VERT` and `TRIS`: [`skinned_edges`], without the concave rigid quads when the
    /// patches are visible-only). Allocates: run it once, at load.
    pub fn contours(&self) -> Result<Option<(BakedContours, Edges)>> {
        let Some(s) = self.section(b"CONT") else { return Ok(None) };
        let vertices = self.vertices()?;
        let rigid = if BakedContours::visible_only(s)? {
            let morphs = self.morphs()?;
            let morphed = |v: usize| morphs.is_some_and(|m| !m.of(v).is_empty());
            Some(rigid_vertices(vertices.positions.len(), vertices.stride, vertices.joints, vertices.weights, morphed))
        } else {
            None
        };
        let edges = skinned_edges(vertices.positions, self.triangles()?, rigid.as_deref())
            .map_err(|e| Error::invalid("bake section CONT", e.to_string()))?;
        Ok(Some((BakedContours::read(s, &edges, self.joint_count()?)?, edges)))
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
        self.clips.last().map_or(0, |c| (c.first + c.count) as usize)
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

impl<'a> BakeView<'a> {
    /// `INFO`, checked: the whole section read, names in UTF-8.
    pub fn info(&self) -> Result<InfoView<'a>> {
        let mut s = Cursor::new("INFO", self.required(b"INFO")?);
        let (builder, max_vertices, max_triangles) = (s.u32()?, s.u32()?, s.u32()?);
        let (s_r, alpha_t, rounds, stop) = (s.f32()?, s.f32()?, s.u32()?, s.u32()?);
        let n = s.u32()? as usize;
        if n.saturating_mul(4) > s.remaining() {
            return Err(s.err(format!("{n} clip names do not fit in the section")));
        }
        let clips = (0..n).map(|_| s.str()).collect::<Result<Vec<_>>>()?;
        s.end()?;
        Ok(InfoView { builder, max_vertices, max_triangles, s_r, alpha_t, rounds, stop, clips })
    }

    /// `PART`, checked: consecutive ranges from 0 covering every vertex, triangle and meshlet,
    /// each part's triangles and meshlets using only its own vertices (so one material per
    /// part range holds).
    pub fn parts(&self) -> Result<&'a [BakedPartRecord]> {
        let (s, location) = (self.required(b"PART")?, "bake section PART");
        let n = u32_at(s, 0).ok_or_else(|| Error::invalid(location, "byte 0: truncated"))? as usize;
        if n.checked_mul(40).and_then(|b| b.checked_add(4)) != Some(s.len()) {
            return Err(Error::invalid(location, format!("{} bytes for {n} parts", s.len())));
        }
        let parts: &[BakedPartRecord] = cast(&s[4..], "PART")?;
        let (triangles, meshlets) = (self.triangles()?, self.meshlets()?);
        let totals = [self.vertices()?.positions.len(), triangles.len(), meshlets.len()];
        let mut ends = [0u32; 3];
        for (i, p) in parts.iter().enumerate() {
            let ranges = [p.vertices, p.triangles, p.meshlets];
            let next =
                ranges.iter().zip(ends).zip(totals).all(|((r, e), t)| r[0] == e && r[1] >= e && r[1] as usize <= t);
            let own = |v: &u32| (p.vertices[0]..p.vertices[1]).contains(v);
            let ok = next
                && triangles[p.triangles[0] as usize..p.triangles[1] as usize].iter().flatten().all(own)
                && (p.meshlets[0] as usize..p.meshlets[1] as usize).all(|m| {
                    let (h, (vc, _)) = (meshlets.headers[m], meshlets.counts(m));
                    meshlets.vertices[h[0] as usize..][..vc].iter().all(own)
                });
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

    /// The optional `PWIN` section, read and checked: its part and clip counts are `PART`'s
    /// and `INFO`'s, the clips' windows are numbered in order from 0, every anchor is a
    /// driver, every number is finite, every box has `min ≤ max`. Allocates: run it once, at load.
    pub fn part_windows(&self) -> Result<Option<BakedPartWindows>> {
        let Some(b) = self.section(b"PWIN") else { return Ok(None) };
        let mut s = Cursor::new("PWIN", b);
        let (parts, clips, windows) = (s.u32()? as usize, s.u32()? as usize, s.u32()? as usize);
        s.u32()?;
        let (want_parts, want_clips) = (self.parts()?.len(), self.info()?.clips.len());
        if (parts, clips) != (want_parts, want_clips) {
            return Err(
                s.err(format!("{parts} parts and {clips} clips, where PART has {want_parts} and INFO {want_clips}"))
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
            let first = list.last().map_or(0, |p: &ClipWindows| p.first + p.count);
            if !(w.start <= w.end && w.count >= 1 && w.first == first) {
                return Err(s.err(format!("clip {c}: windows {w:?} (the next window is {first})")));
            }
            list.push(w);
        }
        if list.last().map_or(0, |w| w.first + w.count) as usize != windows {
            return Err(s.err(format!("the clips' windows do not add up to {windows}")));
        }
        let drivers = self.joint_count()?;
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
        Ok(Some(BakedPartWindows { clips: list, anchors, boxes }))
    }

    /// The optional `OVDR` section, read and checked ([`Orders::read`]): the overdraw orders'
    /// buffers and their run-time lookup.
    pub fn overdraw_orders(&self) -> Result<Option<Orders>> {
        let Some(s) = self.section(b"OVDR") else { return Ok(None) };
        Ok(Some(Orders::read(s, self.triangles()?, self.parts()?, self.info()?.clips.len())?))
    }
}

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

    /// A header with `sections` (tag, offset, length) and `len` bytes in all, in u32 storage
    /// (4-byte aligned).
    fn file(sections: &[(&[u8; 4], u64, u64)], len: usize) -> Vec<u32> {
        let mut b = vec![0u8; len.max(16 + 24 * sections.len())];
        b[..8].copy_from_slice(&MAGIC);
        b[8..12].copy_from_slice(&VERSION.to_le_bytes());
        b[12..16].copy_from_slice(&(sections.len() as u32).to_le_bytes());
        for (k, (tag, offset, length)) in sections.iter().enumerate() {
            let e = 16 + 24 * k;
            b[e..e + 4].copy_from_slice(*tag);
            b[e + 8..e + 16].copy_from_slice(&offset.to_le_bytes());
            b[e + 16..e + 24].copy_from_slice(&length.to_le_bytes());
        }
        b.resize(b.len().next_multiple_of(4), 0);
        b.chunks_exact(4).map(|w| u32::from_ne_bytes(w.try_into().unwrap())).collect()
    }

    fn error(bytes: &[u8]) -> String {
        BakeView::new(bytes).and_then(|v| v.meshlet_bounds().map(|_| ())).unwrap_err().to_string()
    }

    #[test]
    fn bad_headers_and_tables_are_errors_that_say_where() {
        let ok = file(&[(b"SKIN", 96, 4), (b"MLET", 112, 16), (b"BNDS", 128, 16)], 144);
        let bytes: &[u8] = bytemuck::cast_slice(&ok);
        let view = BakeView::new(bytes).unwrap();
        assert_eq!((view.joint_count().unwrap(), view.meshlet_count().unwrap()), (0, 0));
        assert!(view.meshlet_bounds().unwrap().is_empty());
        assert!(view.envelope(0).unwrap().is_none());
        let mut wrong = bytes.to_vec();
        wrong[0] = b'X';
        assert!(BakeView::new(&wrong).unwrap_err().to_string().contains("magic"));
        let mut newer = bytes.to_vec();
        newer[8] = VERSION as u8 + 1;
        assert!(matches!(BakeView::new(&newer), Err(Error::Unsupported { .. })));
        let outside = file(&[(b"BNDS", 96, 64)], 144);
        assert!(error(bytemuck::cast_slice(&outside)).contains("section BNDS lies outside the file"));
        let twice = file(&[(b"SKIN", 96, 4), (b"MLET", 112, 16), (b"SKIN", 128, 16)], 144);
        assert!(error(bytemuck::cast_slice(&twice)).contains("byte 64: section SKIN appears twice"));
        let missing = file(&[(b"SKIN", 96, 4)], 144);
        assert!(error(bytemuck::cast_slice(&missing)).contains("section BNDS is missing"));
        let words = file(&[(b"SKIN", 96, 4), (b"MLET", 112, 16), (b"BNDS", 128, 16)], 148);
        let shifted: &[u8] = &bytemuck::cast_slice::<u32, u8>(&words)[1..];
        assert!(BakeView::new(shifted).unwrap_err().to_string().contains("aligned"));
        for cut in 0..bytes.len() {
            // Every truncation is an error or a view whose sections all lie inside.
            if let Ok(v) = BakeView::new(&bytes[..cut]) {
                assert!(v.meshlet_bounds().is_err() || cut >= 144);
            }
        }
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
