//! Where the tests find the shared real assets: `$SKINLET_ASSETS`, else `../shared/assets`
//! beside the workspace. Missing assets skip the real-asset checks with a note, unless
//! `SKINLET_REQUIRE_ASSETS` is set (CI sets it), where they fail.

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
