//! Where the tests find the shared real assets: `$SKINLET_ASSETS`, else `../shared/assets`
//! beside the workspace. Missing assets skip the real-asset checks with a note, unless
//! `SKINLET_REQUIRE_ASSETS=1` (CI sets it), where they fail. Likewise the npm tools
//! (`SKINLET_REQUIRE_TOOLS=1`) and, in the GPU tests, the device (`SKINLET_REQUIRE_GPU=1`):
//! one rule for all three, [`required`]. Shared by the skinlet, skinlet-cli and skinlet-gpu
//! tests.

#![allow(dead_code)] // each test binary uses some of these

use std::path::PathBuf;

/// True when `var` is `1`: a missing prerequisite then fails the test instead of skipping it.
pub fn required(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| v == "1")
}

pub fn assets_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    if dir.join("skinned").is_dir() {
        return Some(dir);
    }
    assert!(!required("SKINLET_REQUIRE_ASSETS"), "no assets at {} but SKINLET_REQUIRE_ASSETS=1", dir.display());
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
        !required("SKINLET_REQUIRE_TOOLS"),
        "{package} is missing from {} but SKINLET_REQUIRE_TOOLS=1 (npm install --prefix tools)",
        dir.display()
    );
    eprintln!("note: {package} is missing from {} (npm install --prefix tools); skipping", dir.display());
    None
}

/// SplitMix64: a small, seeded, reproducible generator.
pub struct SplitMix(pub u64);

impl SplitMix {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Below `n` (not 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// In [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// The meshlets whose vertices lie in `vertices` (one part's).
pub fn part_meshlets(m: &skinlet::meshlet::Meshlets, vertices: &std::ops::Range<u32>) -> skinlet::meshlet::Meshlets {
    let mut out = skinlet::meshlet::Meshlets::default();
    for k in m.meshlets.iter().filter(|k| vertices.contains(&m.vertices_of(k)[0])) {
        out.push(m.vertices_of(k), m.triangles_of(k));
    }
    out
}

/// The boundary (mod 2) of the triangles: the undirected edges used by an odd number of them.
pub fn boundary(triangles: impl IntoIterator<Item = [u32; 3]>) -> std::collections::BTreeSet<(u32, u32)> {
    let mut count = std::collections::BTreeMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    count.into_iter().filter(|&(_, n)| n % 2 == 1).map(|(e, _)| e).collect()
}
