//! Any bytes, read as a .glb/.gltf (chosen by content) and as an .obj: the importer must
//! return Ok or an Err that says something, and never panic, hang or allocate absurdly
//! (libFuzzer's -timeout and -rss_limit_mb catch the last two).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    for name in ["fuzz.glb", "fuzz.obj"] {
        if let Err(e) = skinlet::import::load_bytes(data, Path::new(name)) {
            assert!(!e.to_string().trim().is_empty(), "empty error message");
        }
    }
});
