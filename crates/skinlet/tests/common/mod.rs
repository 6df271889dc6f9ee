//! Where the tests find the shared real assets: `$SKINLET_ASSETS`, else `../shared/assets`
//! beside the workspace. Missing assets skip the real-asset checks with a note, unless
//! `SKINLET_REQUIRE_ASSETS` is set (CI sets it), where they fail. Likewise the npm tools.

#![allow(dead_code)] // each test binary uses some of these

use std::path::PathBuf;

pub fn assets_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    if dir.join("skinned").is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("SKINLET_REQUIRE_ASSETS").is_none(),
        "no assets at {} but SKINLET_REQUIRE_ASSETS is set",
        dir.display()
    );
    eprintln!("note: no assets at {} (set SKINLET_ASSETS); skipping", dir.display());
    None
}

/// Where the tests find the npm tools (`tools/`, after `npm install --prefix tools`): the
/// folder when its `node_modules` holds `package`, else `None` with a note, unless
/// `SKINLET_REQUIRE_TOOLS` is set (CI sets it), where it fails.
pub fn tools_dir(package: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tools"));
    if dir.join("node_modules").join(package).is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("SKINLET_REQUIRE_TOOLS").is_none(),
        "{package} is missing from {} but SKINLET_REQUIRE_TOOLS is set (npm install --prefix tools)",
        dir.display()
    );
    eprintln!("note: {package} is missing from {} (npm install --prefix tools); skipping", dir.display());
    None
}
