//! glTF 2.0 import (.glb, and .gltf with embedded data URIs or external buffers) into the
//! [`Asset`] model. Follows the spec's rules for skins (missing inverse bind matrices mean
//! identity), animation (key times non-decreasing; CUBICSPLINE outputs as in-tangent,
//! value, out-tangent triples), and primitives (strips and fans become lists; points and
//! lines are skipped with a warning). Weights are normalized and every change is reported
//! in [`ImportReport`]; malformed data is an [`Error`] naming where it is.

use super::accessor::{Buffers, read_floats, read_uints};
use crate::clip::{Channel, Clip, Interpolation, WeightChannel};
use crate::model::{
    Asset, ImportReport, Influences, Instance, Mesh, MorphTarget, Node, Primitive, Skeleton, Skin, SkinnedMesh, Trs,
};
use crate::{Error, Result};
use base64::Engine as _;
use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::mesh::Mode;
use std::collections::HashSet;
use std::path::Path;

/// Extensions that do not change geometry, skins or animation: safe to ignore when required
/// (names, or prefixes ending in `_`). Textures and their image formats, materials (variants
/// included), lights and metadata; quantization only widens the accessor types, which the
/// accessor reader handles. Any other required extension is refused by name: skinlet cannot
/// know that it leaves the geometry alone.
const HARMLESS_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "MSFT_texture_dds",
    "KHR_materials_",
    "KHR_lights_punctual",
    "EXT_lights_image_based",
    "KHR_xmp_json_ld",
    "KHR_mesh_quantization",
];

/// True for a validation error's JSON path inside what only says how a surface looks
/// (textures, images, samplers, materials) or where it is seen from (cameras), or in a
/// reference to them: skinlet never reads these, so an error there (a texture whose image
/// is only in an extension, as `KHR_texture_basisu` writes it; a dangling material index)
/// cannot change what it bakes.
fn appearance_only(path: &str) -> bool {
    let top = ["textures[", "images[", "samplers[", "materials[", "cameras["];
    top.iter().any(|t| path.starts_with(t))
        || (path.starts_with("meshes[") && path.ends_with(".material"))
        || (path.starts_with("nodes[") && path.ends_with(".camera"))
}

/// Parses a .glb or .gltf file held in memory. `base_dir` resolves external buffer URIs.
pub fn load_gltf_slice(bytes: &[u8], base_dir: Option<&Path>) -> Result<Asset> {
    let gltf = parse(bytes)?;
    let data = load_buffers(&gltf, base_dir)?;
    let decoded = super::meshopt::decode_views(&gltf.document, &data)?;
    let draco = super::draco::decode_primitives(&gltf.document, &data)?;
    let buffers = Buffers::new(data, decoded, draco);
    let doc = &gltf.document;
    let mut report = ImportReport::default();

    let animated: HashSet<usize> =
        doc.animations().flat_map(|a| a.channels().map(|c| c.target().node().index())).collect();
    let skeleton = load_nodes(doc, &animated, &mut report)?;
    let skins = doc.skins().map(|s| load_skin(&s, &buffers, &mut report)).collect::<Result<Vec<_>>>()?;
    let meshes = doc.meshes().map(|m| load_mesh(&m, &buffers, &mut report)).collect::<Result<Vec<_>>>()?;
    let instances = load_instances(doc, &skins, &meshes, &mut report)?;
    let clips = doc.animations().map(|a| load_clip(&a, &meshes, &buffers, &mut report)).collect::<Result<Vec<_>>>()?;
    let node_weights = load_node_weights(doc, &meshes)?;
    let scenes = doc.scenes().map(|s| s.nodes().map(|n| n.index() as u32).collect()).collect();
    let default_scene = doc.default_scene().map(|s| s.index());
    Ok(Asset { skeleton, skins, meshes, instances, clips, scenes, default_scene, node_weights, report })
}

/// Parses and validates the document. The gltf crate's own checks are run here rather than
/// by `Gltf::from_slice`, with what they miss added around them: the GLB container (its
/// parser panics on a header length below 12 and says little about truncation), POSITION
/// accessor indices (its validator indexes with them unchecked), animation channel targets
/// (not validated at all, and unwrapped by its accessors) and required extensions (it
/// rejects the harmless ones skinlet accepts). Its errors about textures, images, samplers,
/// materials and cameras are dropped ([`appearance_only`]).
fn parse(bytes: &[u8]) -> Result<gltf::Gltf> {
    use gltf::json::validation::{Checked, Validate};
    if bytes.is_empty() {
        return Err(Error::invalid("glTF", "the file is empty"));
    }
    // A GLB cut inside its magic is a truncated GLB too.
    let bytes = if bytes.starts_with(b"glTF") || b"glTF".starts_with(bytes) { glb_body(bytes)? } else { bytes };
    // Third-party code fed with untrusted bytes: contain any panic that is left.
    let contained = |_| Error::invalid("glTF", "the file is malformed (the glTF parser could not read it)");
    let gltf = std::panic::catch_unwind(|| gltf::Gltf::from_slice_without_validation(bytes))
        .map_err(contained)?
        .map_err(|e| Error::invalid("glTF", e.to_string()))?;
    let root = gltf.document.as_json();
    for ext in &root.extensions_required {
        let decoded = super::meshopt::EXTENSIONS.iter().chain([&super::draco::EXTENSION]);
        if !HARMLESS_EXTENSIONS.iter().chain(decoded).any(|h| ext.starts_with(h)) {
            return Err(Error::unsupported("glTF extensionsRequired", format!("extension {ext}")));
        }
    }
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(i) = prim.attributes.get(&Checked::Valid(gltf::Semantic::Positions))
                && i.value() >= root.accessors.len()
            {
                return Err(Error::invalid(
                    format!("mesh {m} primitive {p}"),
                    format!("POSITION accessor {} does not exist (there are {})", i.value(), root.accessors.len()),
                ));
            }
        }
    }
    let mut errors = Vec::new();
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        root.validate(root, gltf::json::Path::new, &mut |path, e| {
            let path = path().to_string();
            // Already decided above: the required extensions left are harmless. The gltf
            // crate wants a bufferView on every accessor that is not sparse, but glTF says
            // an accessor without one is zeros (glTF Transform's `sparse` writes all-zero
            // morph targets so), and a Draco-compressed primitive's accessors have none:
            // their values come from the decoded stream.
            let zeros = e == gltf::json::validation::Error::Missing
                && path.starts_with("accessors[")
                && path.ends_with("].bufferView");
            if !appearance_only(&path) && !zeros && !path.starts_with("extensionsRequired") {
                errors.push(format!("{path}: {e}"));
            }
        })
    }))
    .map_err(contained)?;
    if !errors.is_empty() {
        let more = if errors.len() > 8 { format!("; and {} more", errors.len() - 8) } else { String::new() };
        errors.truncate(8);
        return Err(Error::invalid("glTF", format!("invalid glTF: {}{more}", errors.join("; "))));
    }
    for (a, anim) in root.animations.iter().enumerate() {
        for (c, ch) in anim.channels.iter().enumerate() {
            let loc = || format!("animation {a} channel {c}");
            if ch.target.node.value() >= root.nodes.len() {
                let msg = format!(
                    "target node {} does not exist (there are {} nodes)",
                    ch.target.node.value(),
                    root.nodes.len()
                );
                return Err(Error::invalid(loc(), msg));
            }
            if ch.target.path == Checked::Invalid {
                return Err(Error::invalid(loc(), "target path is not translation, rotation, scale or weights"));
            }
        }
    }
    Ok(gltf)
}

/// Checks the GLB header and chunk lengths, and returns the bytes the header's length covers.
fn glb_body(bytes: &[u8]) -> Result<&[u8]> {
    let u32_at = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]) as usize;
    if bytes.len() < 12 {
        return Err(Error::invalid(
            "GLB header",
            format!("file is truncated: {} bytes, the header alone is 12", bytes.len()),
        ));
    }
    let (version, length) = (u32_at(4), u32_at(8));
    if version != 2 {
        return Err(Error::unsupported(
            "GLB header",
            format!("version {version} (glTF 2.0 binary files are version 2)"),
        ));
    }
    if length > bytes.len() {
        return Err(Error::invalid(
            "GLB header",
            format!("file is truncated: the header's length is {length} bytes, but there are {}", bytes.len()),
        ));
    }
    if length < 20 {
        return Err(Error::invalid(
            "GLB header",
            format!("length {length} is too small to hold the header and a JSON chunk header"),
        ));
    }
    let body = &bytes[..length];
    let (mut at, mut i) = (12, 0);
    while at < length {
        if length - at < 8 {
            return Err(Error::invalid(
                format!("GLB chunk {i}"),
                format!("header at byte {at} is cut off (truncated file?)"),
            ));
        }
        let (len, ty) = (u32_at(at), &body[at + 4..at + 8]);
        if i == 0 && ty != b"JSON" {
            return Err(Error::invalid(
                "GLB chunk 0",
                format!("must be the JSON chunk, found type \"{}\"", ty.escape_ascii()),
            ));
        }
        if len > length - at - 8 {
            return Err(Error::invalid(
                format!("GLB chunk {i} (\"{}\")", ty.escape_ascii()),
                format!("at byte {at} has length {len}, but only {} bytes follow (truncated file?)", length - at - 8),
            ));
        }
        at += 8 + len;
        i += 1;
    }
    Ok(body)
}

fn load_buffers(gltf: &gltf::Gltf, base_dir: Option<&Path>) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for b in gltf.document.buffers() {
        let loc = format!("buffer {}", b.index());
        if super::meshopt::is_fallback(&b) {
            // Stands in for meshopt-compressed views: nothing to load.
            out.push(Vec::new());
            continue;
        }
        let data = match b.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| Error::invalid(&loc, "refers to the GLB binary chunk, but the file has none"))?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri
                    .split_once(";base64,")
                    .ok_or_else(|| Error::unsupported(&loc, "data URI that is not base64-encoded"))?;
                base64::engine::general_purpose::STANDARD
                    .decode(payload)
                    .map_err(|e| Error::invalid(&loc, format!("bad base64 data URI: {e}")))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let dir = base_dir.ok_or_else(|| {
                    Error::invalid(
                        &loc,
                        format!("external buffer {uri:?} cannot be resolved without the file's folder"),
                    )
                })?;
                let path = dir.join(percent_decode(uri));
                read_external(&path, b.length()).map_err(|source| Error::Io { path, source })?
            }
        };
        if data.len() < b.length() {
            return Err(Error::invalid(
                loc,
                format!("holds {} bytes but byteLength says {} (truncated file?)", data.len(), b.length()),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Reads at most `len` bytes of a regular file: a URI naming a device or a pipe (/dev/zero,
/// /dev/stdin) must not be read forever, nor a huge file read whole.
fn read_external(path: &Path, len: usize) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let file = std::fs::File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut data = Vec::new();
    file.take(len as u64).read_to_end(&mut data)?;
    Ok(data)
}

fn percent_decode(s: &str) -> String {
    let hex = |c: u8| (c as char).to_digit(16).map(|d| d as u8);
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if let (b'%', Some(&h), Some(&l)) = (b[i], b.get(i + 1), b.get(i + 2))
            && let (Some(h), Some(l)) = (hex(h), hex(l))
        {
            out.push(h * 16 + l);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn finite(loc: &str, what: &str, v: &[f32]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::invalid(loc, format!("{what} has a NaN or infinite value")))
    }
}

fn load_nodes(doc: &gltf::Document, animated: &HashSet<usize>, report: &mut ImportReport) -> Result<Skeleton> {
    let mut nodes: Vec<Node> = doc
        .nodes()
        .map(|n| Node { name: n.name().unwrap_or("").to_string(), parent: None, rest: Trs::IDENTITY, matrix: None })
        .collect();
    for n in doc.nodes() {
        let loc = format!("node {} ({:?})", n.index(), n.name().unwrap_or(""));
        for c in n.children() {
            let child = &mut nodes[c.index()];
            let child_loc = format!("node {} ({:?})", c.index(), child.name);
            if c.index() == n.index() {
                return Err(Error::invalid(child_loc, "is its own child (a cycle in the node hierarchy)"));
            }
            match child.parent {
                Some(p) if p as usize == n.index() => {
                    return Err(Error::invalid(child_loc, format!("is listed twice among the children of node {p}")));
                }
                Some(p) => {
                    return Err(Error::invalid(child_loc, format!("has two parents, nodes {p} and {}", n.index())));
                }
                None => {}
            }
            child.parent = Some(n.index() as u32);
        }
        let node = &mut nodes[n.index()];
        match n.transform() {
            gltf::scene::Transform::Matrix { matrix } => {
                let m = Mat4::from_cols_array_2d(&matrix);
                finite(&loc, "matrix", &m.to_cols_array())?;
                if m.row(3) != Vec4::W {
                    return Err(Error::invalid(&loc, "matrix is not affine (last row must be 0 0 0 1)"));
                }
                let (s, r, t) = m.to_scale_rotation_translation();
                let r = r.normalize();
                // A singular matrix (zero scale) has no rotation to recover: keep the matrix
                // as the transform and an identity rotation in the (unused) rest TRS.
                node.rest = Trs { translation: t, rotation: if r.is_finite() { r } else { Quat::IDENTITY }, scale: s };
                if animated.contains(&n.index()) {
                    if !r.is_finite() {
                        return Err(Error::invalid(
                            &loc,
                            "is animated but its matrix is singular (zero scale), so it has no TRS",
                        ));
                    }
                    report.warnings.push(format!(
                        "{loc}: is animated but given by a matrix (the spec forbids this); its matrix was decomposed into TRS"
                    ));
                } else {
                    node.matrix = Some(m);
                }
            }
            gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
                finite(&loc, "TRS", &[translation.as_slice(), &rotation, &scale].concat())?;
                let q = Quat::from_array(rotation);
                node.rest =
                    Trs { translation: translation.into(), rotation: normalize_quat(q, &loc)?, scale: scale.into() };
            }
        }
    }
    Skeleton::new(nodes)
}

fn normalize_quat(q: Quat, loc: &str) -> Result<Quat> {
    let len = q.length();
    if len.is_nan() || len <= 1e-6 {
        return Err(Error::invalid(loc, "rotation quaternion has zero length"));
    }
    Ok(if len == 1.0 { q } else { q / len })
}

fn load_skin(skin: &gltf::Skin, buffers: &Buffers, report: &mut ImportReport) -> Result<Skin> {
    let loc = format!("skin {} ({:?})", skin.index(), skin.name().unwrap_or(""));
    let joints: Vec<u32> = skin.joints().map(|j| j.index() as u32).collect();
    if joints.is_empty() {
        return Err(Error::invalid(loc, "has no joints"));
    }
    if joints.len() > u16::MAX as usize {
        return Err(Error::unsupported(loc, format!("{} joints (at most 65535)", joints.len())));
    }
    let inverse_bind = match skin.inverse_bind_matrices() {
        Some(acc) => {
            let m = read_floats(&acc, &[Dimensions::Mat4], buffers, &format!("{loc} inverseBindMatrices"))?;
            if m.len() / 16 < joints.len() {
                return Err(Error::invalid(
                    loc,
                    format!("{} inverse bind matrices for {} joints", m.len() / 16, joints.len()),
                ));
            }
            let mats: Vec<Mat4> = m.chunks_exact(16).take(joints.len()).map(Mat4::from_cols_slice).collect();
            if let Some(i) = mats.iter().position(|m| (m.row(3) - Vec4::W).abs().max_element() > 1e-4) {
                return Err(Error::invalid(
                    loc,
                    format!("inverse bind matrix {i} is not affine (last row must be 0 0 0 1)"),
                ));
            }
            mats
        }
        None => {
            report.warnings.push(format!("{loc}: no inverseBindMatrices; using identity matrices as the spec says"));
            vec![Mat4::IDENTITY; joints.len()]
        }
    };
    Ok(Skin { name: skin.name().unwrap_or("").to_string(), joints, inverse_bind })
}

fn load_mesh(mesh: &gltf::Mesh, buffers: &Buffers, report: &mut ImportReport) -> Result<Mesh> {
    let mut primitives = Vec::new();
    for p in mesh.primitives() {
        let loc = format!("mesh {} ({:?}) primitive {}", mesh.index(), mesh.name().unwrap_or(""), p.index());
        if matches!(p.mode(), Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip) {
            report.warnings.push(format!("{loc}: {:?} primitive skipped (only triangles are used)", p.mode()));
            continue;
        }
        let geometry = load_primitive(&p, buffers, &loc, report)?;
        let targets = load_targets(&p, buffers, geometry.positions.len(), &loc)?;
        if let Some(first) = primitives.first().map(|q: &Primitive| q.targets.len())
            && first != targets.len()
        {
            return Err(Error::invalid(
                &loc,
                format!("has {} morph targets, but primitive 0 of the mesh has {first}", targets.len()),
            ));
        }
        primitives.push(Primitive { index: p.index(), geometry, targets });
    }
    let weights = mesh.weights().map(<[f32]>::to_vec).unwrap_or_default();
    let loc = format!("mesh {} ({:?})", mesh.index(), mesh.name().unwrap_or(""));
    finite(&loc, "weights", &weights)?;
    let targets = primitives.first().map_or(0, |p| p.targets.len());
    if !weights.is_empty() && weights.len() != targets {
        return Err(Error::invalid(loc, format!("{} default weights for {targets} morph targets", weights.len())));
    }
    Ok(Mesh { name: mesh.name().unwrap_or("").to_string(), primitives, weights })
}

/// POSITION and NORMAL deltas of every morph target (TANGENT deltas are not used).
fn load_targets(p: &gltf::Primitive, buffers: &Buffers, n: usize, loc: &str) -> Result<Vec<MorphTarget>> {
    let mut out = Vec::new();
    for (k, t) in p.morph_targets().enumerate() {
        let read = |acc: Option<gltf::Accessor>, what: &str| -> Result<Vec<Vec3>> {
            let Some(acc) = acc else { return Ok(Vec::new()) };
            let v = vec3s(read_floats(&acc, &[Dimensions::Vec3], buffers, &format!("{loc} morph target {k} {what}"))?);
            if v.len() != n {
                return Err(Error::invalid(
                    loc,
                    format!("morph target {k} {what} has {} elements but POSITION has {n}", v.len()),
                ));
            }
            Ok(v)
        };
        let mut positions = read(t.positions(), "POSITION")?;
        if positions.is_empty() {
            positions = vec![Vec3::ZERO; n];
        }
        out.push(MorphTarget { positions, normals: read(t.normals(), "NORMAL")? });
    }
    Ok(out)
}

fn vec3s(v: Vec<f32>) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

fn load_primitive(p: &gltf::Primitive, buffers: &Buffers, loc: &str, report: &mut ImportReport) -> Result<SkinnedMesh> {
    use gltf::Semantic;
    let pos = p.get(&Semantic::Positions).ok_or_else(|| Error::invalid(loc, "has no POSITION attribute"))?;
    let positions = vec3s(read_floats(&pos, &[Dimensions::Vec3], buffers, &format!("{loc} POSITION"))?);
    let n = positions.len();
    let normals = match p.get(&Semantic::Normals) {
        Some(acc) => {
            let v = vec3s(read_floats(&acc, &[Dimensions::Vec3], buffers, &format!("{loc} NORMAL"))?);
            if v.len() != n {
                return Err(Error::invalid(loc, format!("NORMAL has {} elements but POSITION has {n}", v.len())));
            }
            v
        }
        None => Vec::new(),
    };
    let indices: Vec<u32> = match p.indices() {
        Some(acc) => read_uints(&acc, &[Dimensions::Scalar], buffers, &format!("{loc} indices"))?,
        None => (0..n as u32).collect(),
    };
    if let Some((i, &v)) = indices.iter().enumerate().find(|(_, v)| **v as usize >= n) {
        return Err(Error::invalid(loc, format!("index {i} is {v}, but there are only {n} vertices")));
    }
    let triangles = assemble_triangles(p.mode(), &indices, loc)?;
    let influences = load_influences(p, buffers, n, loc, report)?;
    let mesh = SkinnedMesh { positions, normals, triangles, influences, ..SkinnedMesh::default() };
    report.degenerate_triangles += mesh.degenerate_triangles();
    Ok(mesh)
}

fn assemble_triangles(mode: Mode, idx: &[u32], loc: &str) -> Result<Vec<[u32; 3]>> {
    Ok(match mode {
        Mode::Triangles => {
            if !idx.len().is_multiple_of(3) {
                return Err(Error::invalid(loc, format!("{} indices is not a multiple of 3", idx.len())));
            }
            idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
        // glTF 2.0 section 3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2); fan is (i+1, i+2, 0).
        Mode::TriangleStrip => {
            (0..idx.len().saturating_sub(2)).map(|i| [idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]]).collect()
        }
        Mode::TriangleFan => (0..idx.len().saturating_sub(2)).map(|i| [idx[i + 1], idx[i + 2], idx[0]]).collect(),
        _ => Vec::new(),
    })
}

fn load_influences(
    p: &gltf::Primitive,
    buffers: &Buffers,
    n: usize,
    loc: &str,
    report: &mut ImportReport,
) -> Result<Option<Influences>> {
    use gltf::Semantic;
    let mut sets = Vec::new();
    for set in 0..2u32 {
        match (p.get(&Semantic::Joints(set)), p.get(&Semantic::Weights(set))) {
            (None, None) => break,
            (Some(j), Some(w)) => {
                let jl = format!("{loc} JOINTS_{set}");
                let wl = format!("{loc} WEIGHTS_{set}");
                let joints = read_uints(&j, &[Dimensions::Vec4], buffers, &jl)?;
                let weights = read_floats(&w, &[Dimensions::Vec4], buffers, &wl)?;
                if joints.len() != 4 * n || weights.len() != 4 * n {
                    return Err(Error::invalid(
                        loc,
                        format!(
                            "JOINTS_{set}/WEIGHTS_{set} have {}/{} elements but POSITION has {n}",
                            joints.len() / 4,
                            weights.len() / 4
                        ),
                    ));
                }
                sets.push((joints, weights));
            }
            _ => return Err(Error::invalid(loc, format!("JOINTS_{set} and WEIGHTS_{set} must come together"))),
        }
    }
    if sets.is_empty() {
        return Ok(None);
    }
    if p.get(&Semantic::Joints(2)).is_some() {
        report.warnings.push(format!("{loc}: JOINTS_2 and beyond ignored (at most 8 influences are used)"));
    }
    let stride = 4 * sets.len();
    let mut inf = Influences { stride, joints: vec![0; n * stride], weights: vec![0.0; n * stride] };
    let mut pairs: Vec<(u32, f32)> = Vec::with_capacity(stride);
    for v in 0..n {
        pairs.clear();
        let first_joint = sets[0].0[4 * v];
        // Finite weights can still overflow their f32 sum (giving NaN weights): scale huge
        // ones down first, exactly (a power of two); weights up to 1e30 are untouched.
        let huge = sets.iter().any(|(_, ws)| ws[4 * v..4 * v + 4].iter().any(|w| *w > 1e30));
        let scale = if huge { 2f32.powi(-64) } else { 1.0 };
        for (s, (js, ws)) in sets.iter().enumerate() {
            for k in 0..4 {
                let (j, w) = (js[4 * v + k], ws[4 * v + k]);
                if w < 0.0 {
                    return Err(Error::invalid(
                        loc,
                        format!("vertex {v}: WEIGHTS_{s} component {k} is negative ({w})"),
                    ));
                }
                let w = w * scale;
                if w == 0.0 {
                    continue;
                }
                if j > u16::MAX as u32 {
                    return Err(Error::invalid(loc, format!("vertex {v}: joint index {j} is too large")));
                }
                match pairs.iter_mut().find(|(pj, _)| *pj == j) {
                    Some(p) => p.1 += w,
                    None => pairs.push((j, w)),
                }
            }
        }
        let sum: f32 = pairs.iter().map(|p| p.1).sum();
        if pairs.is_empty() {
            if first_joint > u16::MAX as u32 {
                return Err(Error::invalid(
                    loc,
                    format!("vertex {v}: all weights are zero and its first joint index {first_joint} is too large"),
                ));
            }
            report.zero_weight_vertices += 1;
            pairs.push((first_joint, 1.0));
        } else if (sum - 1.0).abs() > 1e-3 {
            report.renormalized_vertices += 1;
        }
        if sum != 1.0 && sum > 0.0 {
            pairs.iter_mut().for_each(|p| p.1 /= sum);
        }
        pairs.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        for (k, &(j, w)) in pairs.iter().enumerate() {
            inf.joints[v * stride + k] = j as u16;
            inf.weights[v * stride + k] = w;
        }
    }
    Ok(Some(inf))
}

fn load_instances(
    doc: &gltf::Document,
    skins: &[Skin],
    meshes: &[Mesh],
    report: &mut ImportReport,
) -> Result<Vec<Instance>> {
    let mut out = Vec::new();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let loc = format!("node {} ({:?})", node.index(), node.name().unwrap_or(""));
        let skin = node.skin().map(|s| s.index() as u32);
        let m = &meshes[mesh.index()];
        match skin {
            Some(s) => {
                let count = skins[s as usize].joints.len();
                for p in &m.primitives {
                    // A primitive without weights is an error of the character (glTF requires
                    // them under a skin); a file can still be inspected.
                    let Some(inf) = &p.geometry.influences else { continue };
                    if let Some(v) = (0..inf.vertex_count()).find(|&v| inf.of(v).any(|(j, _)| j as usize >= count)) {
                        let j = inf.of(v).map(|(j, _)| j).max().unwrap_or(0);
                        return Err(Error::invalid(
                            format!("mesh {} primitive {} vertex {v}", mesh.index(), p.index),
                            format!("joint index {j} is out of range: skin {s} used by {loc} has {count} joints"),
                        ));
                    }
                }
            }
            None if m.primitives.iter().any(|p| p.geometry.influences.is_some()) => {
                report.warnings.push(format!(
                    "{loc}: mesh {} has joint weights but the node has no skin; drawn rigid",
                    mesh.index()
                ));
            }
            None => {}
        }
        out.push(Instance { node: node.index() as u32, mesh: mesh.index() as u32, skin });
    }
    Ok(out)
}

/// Nodes' `weights` (overriding their mesh's defaults): one per morph target, finite.
fn load_node_weights(doc: &gltf::Document, meshes: &[Mesh]) -> Result<std::collections::BTreeMap<u32, Vec<f32>>> {
    let mut out = std::collections::BTreeMap::new();
    for n in doc.nodes() {
        let Some(w) = n.weights() else { continue };
        let loc = format!("node {} ({:?})", n.index(), n.name().unwrap_or(""));
        finite(&loc, "weights", w)?;
        let targets = n.mesh().map_or(0, |m| meshes[m.index()].morph_targets());
        if w.len() != targets {
            return Err(Error::invalid(loc, format!("{} weights for {targets} morph targets of its mesh", w.len())));
        }
        out.insert(n.index() as u32, w.to_vec());
    }
    Ok(out)
}

fn load_clip(anim: &gltf::Animation, meshes: &[Mesh], buffers: &Buffers, report: &mut ImportReport) -> Result<Clip> {
    use gltf::animation::Property;
    let name = anim.name().unwrap_or("").to_string();
    let mut clip = Clip { name: name.clone(), start: f32::INFINITY, end: f32::NEG_INFINITY, ..Clip::default() };
    for ch in anim.channels() {
        let loc = format!("animation {} ({name:?}) channel {}", anim.index(), ch.index());
        let sampler = ch.sampler();
        let times = read_floats(&sampler.input(), &[Dimensions::Scalar], buffers, &format!("{loc} input"))?;
        if times.is_empty() {
            report.warnings.push(format!("{loc}: no keyframes; channel ignored"));
            continue;
        }
        if let Some(i) = times.windows(2).position(|w| w[1] < w[0]) {
            return Err(Error::invalid(
                &loc,
                format!("key times decrease at key {}: {} after {}", i + 1, times[i + 1], times[i]),
            ));
        }
        clip.start = clip.start.min(times[0]);
        clip.end = clip.end.max(times[times.len() - 1]);
        let interpolation = match sampler.interpolation() {
            gltf::animation::Interpolation::Linear => Interpolation::Linear,
            gltf::animation::Interpolation::Step => Interpolation::Step,
            gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
        };
        let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        let node = ch.target().node().index() as u32;
        let output = sampler.output();
        let out_loc = format!("{loc} output");
        let check_count = |values: usize| -> Result<()> {
            if values != per_key * times.len() {
                return Err(Error::invalid(
                    &loc,
                    format!(
                        "{} keys need {} output values ({}), found {values}",
                        times.len(),
                        per_key * times.len(),
                        interpolation.name()
                    ),
                ));
            }
            Ok(())
        };
        match ch.target().property() {
            Property::Translation | Property::Scale => {
                let values = vec3s(read_floats(&output, &[Dimensions::Vec3], buffers, &out_loc)?);
                check_count(values.len())?;
                let c = Channel { node, interpolation, times, values };
                if ch.target().property() == Property::Translation {
                    clip.translations.push(c)
                } else {
                    clip.scales.push(c)
                }
            }
            Property::Rotation => {
                let raw = read_floats(&output, &[Dimensions::Vec4], buffers, &out_loc)?;
                let mut values: Vec<Quat> = raw.chunks_exact(4).map(Quat::from_slice).collect();
                check_count(values.len())?;
                for (i, q) in values.iter_mut().enumerate() {
                    let is_tangent = interpolation == Interpolation::CubicSpline && i % 3 != 1;
                    if !is_tangent {
                        *q = normalize_quat(*q, &format!("{out_loc} key {}", i / per_key))?;
                    }
                }
                clip.rotations.push(Channel { node, interpolation, times, values });
            }
            Property::MorphTargetWeights => {
                let target_node = ch.target().node();
                let targets = target_node.mesh().map_or(0, |m| meshes[m.index()].morph_targets());
                if targets == 0 {
                    return Err(Error::invalid(
                        &loc,
                        format!("animates the morph weights of node {node}, which draws no mesh with morph targets"),
                    ));
                }
                let values = read_floats(&output, &[Dimensions::Scalar], buffers, &out_loc)?;
                if values.len() != per_key * times.len() * targets {
                    return Err(Error::invalid(
                        &loc,
                        format!(
                            "{} keys × {targets} morph targets need {} weight values ({}), found {}",
                            times.len(),
                            per_key * times.len() * targets,
                            interpolation.name(),
                            values.len()
                        ),
                    ));
                }
                // Per key: all targets' values (CUBICSPLINE: in-tangents, values, out-tangents).
                for target in 0..targets {
                    let values = (0..per_key * times.len())
                        .map(|i| values[(i / per_key) * per_key * targets + (i % per_key) * targets + target])
                        .collect();
                    let channel = Channel { node, interpolation, times: times.clone(), values };
                    clip.weights.push(WeightChannel { target: target as u32, channel });
                }
            }
        }
    }
    if clip.start > clip.end {
        clip.start = 0.0;
        clip.end = 0.0;
    }
    Ok(clip)
}
