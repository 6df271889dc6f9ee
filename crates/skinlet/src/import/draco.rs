//! Primitives compressed with `KHR_draco_mesh_compression`, decoded with the `draco-core`
//! crate (a pure-Rust port of Google's Draco decoder, bitstream-compatible with it). A
//! compressed primitive names the accessors of its attributes and indices; their values come
//! from the decoded Draco mesh instead of a buffer view, and the accessor reader hands them
//! out like any other accessor's (glTF's rules on types, counts and normalization apply as
//! usual). Morph targets stay outside the stream, in plain accessors read as usual, one
//! element per decoded point in the stream's order (the encoder must keep the two in step:
//! glTF Transform encodes a primitive with morph targets sequentially, without merging
//! points; three.js reads them the same way); a target whose count differs from the
//! decoded points is an error. Sizes are bounded before decoding (the decoded attributes at
//! most 4096× the compressed bytes, or 64 MiB), and a failed decode is an error naming the
//! mesh and primitive; panics in the third-party decoder are contained.

use crate::{Error, Result};
use draco_core::{DecodeLimits, DecoderBuffer, FaceIndex, Mesh, MeshDecoder};
use serde_json::Value;
use std::collections::HashMap;

pub(crate) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// Decoded accessor values (components of every element, in order) of every Draco-compressed
/// primitive of `doc`, by accessor index; `buffers` holds the loaded buffers by index.
pub(crate) fn decode_primitives(doc: &gltf::Document, buffers: &[Vec<u8>]) -> Result<HashMap<usize, Vec<f64>>> {
    let mut out = HashMap::new();
    for mesh in doc.meshes() {
        for p in mesh.primitives() {
            let Some(ext) = p.extensions().and_then(|e| e.get(EXTENSION)) else { continue };
            let loc = format!("mesh {} primitive {} ({EXTENSION})", mesh.index(), p.index());
            if p.mode() != gltf::mesh::Mode::Triangles {
                return Err(Error::unsupported(&loc, format!("a compressed primitive of mode {:?}", p.mode())));
            }
            let decoded = decode(ext, doc, buffers, &loc)?;
            let indices = p.indices().ok_or_else(|| Error::invalid(&loc, "a compressed primitive needs indices"))?;
            if indices.count() != 3 * decoded.num_faces() {
                return Err(Error::invalid(
                    &loc,
                    format!(
                        "the stream holds {} triangles, accessor {} wants {} indices",
                        decoded.num_faces(),
                        indices.index(),
                        indices.count()
                    ),
                ));
            }
            let faces: Vec<f64> =
                (0..decoded.num_faces()).flat_map(|f| decoded.face(FaceIndex(f as u32)).map(|v| v.0 as f64)).collect();
            out.insert(indices.index(), faces);
            let ids = ext.get("attributes").and_then(Value::as_object);
            let ids = ids.ok_or_else(|| Error::invalid(&loc, "attributes is missing or not an object"))?;
            for (semantic, accessor) in p.attributes() {
                let name = semantic.to_string();
                let Some(id) = ids.get(&name) else { continue };
                let id = id.as_u64().and_then(|i| u32::try_from(i).ok());
                let id = id.ok_or_else(|| Error::invalid(&loc, format!("attribute id of {name} is not a number")))?;
                let attribute = decoded.attribute_by_unique_id(id).ok_or_else(|| {
                    Error::invalid(&loc, format!("{name} names Draco attribute {id}, which the stream does not hold"))
                })?;
                let n = accessor.dimensions().multiplicity();
                if attribute.num_components() as usize != n || decoded.num_points() != accessor.count() {
                    return Err(Error::invalid(
                        &loc,
                        format!(
                            "{name}: the stream holds {} points of {} components, accessor {} wants {} of {n}",
                            decoded.num_points(),
                            attribute.num_components(),
                            accessor.index(),
                            accessor.count()
                        ),
                    ));
                }
                let values = attribute.read_f32s(decoded.num_points(), n).into_iter().map(f64::from);
                out.insert(accessor.index(), values.map(|x| normalized(&accessor, x)).collect());
            }
        }
    }
    Ok(out)
}

/// glTF's mapping of a normalized integer to [0, 1] or [-1, 1]; other values unchanged.
fn normalized(acc: &gltf::Accessor, x: f64) -> f64 {
    use gltf::accessor::DataType;
    if !acc.normalized() {
        return x;
    }
    match acc.data_type() {
        DataType::U8 => x / 255.0,
        DataType::U16 => x / 65535.0,
        DataType::I8 => (x / 127.0).max(-1.0),
        DataType::I16 => (x / 32767.0).max(-1.0),
        _ => x,
    }
}

fn decode(ext: &Value, doc: &gltf::Document, buffers: &[Vec<u8>], loc: &str) -> Result<Mesh> {
    let view = ext.get("bufferView").and_then(Value::as_u64).and_then(|v| doc.views().nth(v as usize));
    let view = view.ok_or_else(|| Error::invalid(loc, "bufferView is missing or does not exist"))?;
    let buffer = buffers.get(view.buffer().index());
    let bytes = view.offset().checked_add(view.length()).and_then(|end| buffer?.get(view.offset()..end));
    let bytes =
        bytes.ok_or_else(|| Error::invalid(loc, format!("buffer view {} runs past its buffer", view.index())))?;
    let limits = DecodeLimits::default()
        .with_max_points(1 << 26)
        .with_max_faces(1 << 27)
        .with_max_decoded_bytes((bytes.len() as u64).saturating_mul(4096).max(64 << 20));
    let mut mesh = Mesh::new();
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        MeshDecoder::new().decode(&mut DecoderBuffer::new(bytes).with_limits(limits), &mut mesh)
    }));
    match decoded {
        Ok(Ok(())) => Ok(mesh),
        Ok(Err(e)) => Err(Error::invalid(loc, format!("the Draco stream does not decode: {e}"))),
        Err(_) => Err(Error::invalid(loc, "the Draco stream does not decode (the decoder failed)")),
    }
}
