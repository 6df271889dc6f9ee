//! Buffer views compressed with `EXT_meshopt_compression` or `KHR_meshopt_compression`
//! (what gltfpack writes), decoded with meshoptimizer's own decoders (the `meshopt` crate
//! builds them): vertex attributes (`ATTRIBUTES`, with the `OCTAHEDRAL`, `QUATERNION` and
//! `EXPONENTIAL` filters), triangle indices (`TRIANGLES`) and index sequences (`INDICES`).
//! The decoders are safe on untrusted input (they may decode garbage, never read or write
//! out of bounds); every size is checked before they run, and a failed decode is an error
//! naming the buffer view. The accessors then read the decoded bytes like any other view.

use crate::{Error, Result};
use serde_json::Value;
use std::collections::HashMap;

/// The two extension names, the ratified one last.
pub(crate) const EXTENSIONS: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// A decoded view may be at most this many times larger than its compressed bytes, or
/// [`MAX_SMALL`] bytes: meshoptimizer's codecs shrink real data 2-10x and constant data
/// about 1000x (measured: 159 bytes for 136 KB of BrainStem's joints), so a small file
/// cannot make the importer allocate gigabytes.
const MAX_RATIO: usize = 4096;
const MAX_SMALL: usize = 64 << 20;

/// The extension object of a buffer or buffer view, if it has one.
pub(crate) fn extension(ext: Option<&serde_json::Map<String, Value>>) -> Option<&Value> {
    let ext = ext?;
    EXTENSIONS.iter().find_map(|name| ext.get(*name))
}

/// True for a buffer that only stands in for compressed data (`fallback: true`): it has no
/// bytes of its own to load.
pub(crate) fn is_fallback(buffer: &gltf::Buffer) -> bool {
    extension(buffer.extensions()).and_then(|e| e.get("fallback")).and_then(Value::as_bool) == Some(true)
}

/// Decodes every compressed view of `doc`; `buffers` holds the loaded buffers by index.
pub(crate) fn decode_views(doc: &gltf::Document, buffers: &[Vec<u8>]) -> Result<HashMap<usize, Vec<u8>>> {
    let mut out = HashMap::new();
    for view in doc.views() {
        if let Some(ext) = extension(view.extensions()) {
            let loc = format!("buffer view {} (meshopt compression)", view.index());
            out.insert(view.index(), decode(ext, view.length(), buffers, &loc)?);
        }
    }
    Ok(out)
}

fn decode(ext: &Value, view_length: usize, buffers: &[Vec<u8>], loc: &str) -> Result<Vec<u8>> {
    let field = |name: &str| ext.get(name).and_then(Value::as_u64).map(|x| x as usize);
    let need =
        |name: &str| field(name).ok_or_else(|| Error::invalid(loc, format!("{name} is missing or not a number")));
    let (buffer, length, stride, count) = (need("buffer")?, need("byteLength")?, need("byteStride")?, need("count")?);
    let offset = field("byteOffset").unwrap_or(0);
    let mode = ext.get("mode").and_then(Value::as_str).unwrap_or("");
    let filter = ext.get("filter").and_then(Value::as_str).unwrap_or("NONE");
    let source = buffers.get(buffer).ok_or_else(|| Error::invalid(loc, format!("buffer {buffer} does not exist")))?;
    let bytes = offset.checked_add(length).and_then(|end| source.get(offset..end)).ok_or_else(|| {
        Error::invalid(
            loc,
            format!("{length} bytes at offset {offset} run past the end of buffer {buffer} ({} bytes)", source.len()),
        )
    })?;
    count.checked_mul(stride).filter(|&s| s <= view_length).ok_or_else(|| {
        Error::invalid(loc, format!("{count} elements of {stride} bytes do not fit in the view's {view_length} bytes"))
    })?;
    if view_length > length.saturating_mul(MAX_RATIO).max(MAX_SMALL) {
        return Err(Error::unsupported(
            loc,
            format!("{view_length} bytes decoded from {length} is past the limit of {MAX_RATIO}x (corrupt file?)"),
        ));
    }
    let mut data = vec![0u8; view_length];
    let dest = data.as_mut_ptr().cast();
    let ok = match mode {
        "ATTRIBUTES" => {
            if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
                return Err(Error::invalid(loc, format!("ATTRIBUTES byteStride {stride} (a multiple of 4 up to 256)")));
            }
            // SAFETY: `data` holds at least count × stride bytes (checked above); the decoder
            // reads at most `bytes.len()` bytes of `bytes`.
            unsafe { meshopt::ffi::meshopt_decodeVertexBuffer(dest, count, stride, bytes.as_ptr(), bytes.len()) == 0 }
        }
        "TRIANGLES" | "INDICES" => {
            if stride != 2 && stride != 4 {
                return Err(Error::invalid(loc, format!("{mode} byteStride {stride} (2 or 4)")));
            }
            if mode == "TRIANGLES" && !count.is_multiple_of(3) {
                return Err(Error::invalid(loc, format!("TRIANGLES count {count} is not a multiple of 3")));
            }
            // SAFETY: as above, with indices of `stride` bytes.
            unsafe {
                if mode == "TRIANGLES" {
                    meshopt::ffi::meshopt_decodeIndexBuffer(dest, count, stride, bytes.as_ptr(), bytes.len()) == 0
                } else {
                    meshopt::ffi::meshopt_decodeIndexSequence(dest, count, stride, bytes.as_ptr(), bytes.len()) == 0
                }
            }
        }
        other => return Err(Error::unsupported(loc, format!("mode {other:?} (ATTRIBUTES, TRIANGLES or INDICES)"))),
    };
    if !ok {
        return Err(Error::invalid(loc, format!("the {mode} data does not decode (corrupt or truncated)")));
    }
    let valid = match filter {
        "NONE" => true,
        "OCTAHEDRAL" => mode == "ATTRIBUTES" && (stride == 4 || stride == 8),
        "QUATERNION" => mode == "ATTRIBUTES" && stride == 8,
        "EXPONENTIAL" => mode == "ATTRIBUTES",
        other => return Err(Error::unsupported(loc, format!("filter {other:?}"))),
    };
    if !valid {
        return Err(Error::invalid(loc, format!("filter {filter} does not apply to {mode} with byteStride {stride}")));
    }
    // SAFETY: the filters rewrite `count` elements of `stride` bytes in place; `data` holds
    // that many (checked above) and the strides are the ones each filter requires.
    unsafe {
        match filter {
            "OCTAHEDRAL" => meshopt::ffi::meshopt_decodeFilterOct(dest, count, stride),
            "QUATERNION" => meshopt::ffi::meshopt_decodeFilterQuat(dest, count, stride),
            "EXPONENTIAL" => meshopt::ffi::meshopt_decodeFilterExp(dest, count, stride),
            _ => {}
        }
    }
    Ok(data)
}
