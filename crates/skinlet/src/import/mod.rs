//! Loading assets from files: glTF 2.0 for skinned characters, OBJ for static meshes.

mod accessor;
mod draco;
mod gltf;
mod meshopt;
mod obj;

pub use self::gltf::load_gltf_slice;
pub use obj::load_obj_str;

use crate::model::Asset;
use crate::{Error, Result};
use std::path::Path;

/// Loads a .glb, .gltf or .obj file (chosen by content, then by extension).
pub fn load(path: &Path) -> Result<Asset> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    load_bytes(&bytes, path)
}

/// Loads from bytes already read; `path` names the file in errors and resolves external buffers.
pub fn load_bytes(bytes: &[u8], path: &Path) -> Result<Asset> {
    let name = path.display().to_string();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let first = bytes.iter().find(|b| !b.is_ascii_whitespace());
    if bytes.starts_with(b"glTF") || first == Some(&b'{') || ext == "glb" || ext == "gltf" {
        // glTF locations ("mesh 0 primitive 1") do not name the file: prefix it.
        load_gltf_slice(bytes, path.parent()).map_err(|e| match e {
            Error::Invalid { location, message } => Error::Invalid { location: format!("{name}: {location}"), message },
            Error::Unsupported { location, message } => {
                Error::Unsupported { location: format!("{name}: {location}"), message }
            }
            e => e,
        })
    } else if ext == "obj" {
        let text = std::str::from_utf8(bytes).map_err(|e| Error::invalid(&name, format!("not UTF-8 text: {e}")))?;
        load_obj_str(text, &name)
    } else {
        Err(Error::unsupported(&name, "unknown file type (expected .glb, .gltf or .obj)"))
    }
}
