//! `.skinlet` bake files as Bevy assets: the bytes checked by `skinlet_runtime`'s
//! `BakeView` at load (a bad file is a load error that names the section and byte), kept
//! aligned for zero-copy views (and GPU uploads), with what the per-frame bounds need read
//! out once: the per-part boxes, the drivers' nodes and names, the morph weights' nodes, the
//! baked clips' names and the pose guard.

use bevy::asset::io::Reader;
use bevy::asset::{Asset, AssetLoader, LoadContext};
use bevy::reflect::TypePath;
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::part_bounds::PartBounds;
use skinlet_runtime::pose_guard::PoseGuard;

/// How a `.skinlet` file is loaded (`AssetServer::load_with_settings`, or its `.meta` file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BakeSettings {
    /// Drop each part's clip and envelope bounds where they are no tighter than its any-pose
    /// boxes at the bind pose (`PartBounds::pruned`): those parts then move the any-pose boxes
    /// alone, and an instance whose parts all do skips working out its pose. On by default;
    /// off, every stored bound is used where it holds (both are conservative).
    pub prune: bool,
}

impl Default for BakeSettings {
    fn default() -> Self {
        BakeSettings { prune: true }
    }
}

/// A bake file, checked, with what the bounds systems read every frame.
#[derive(Asset, TypePath, Debug)]
pub struct Bake {
    /// The file's bytes, 4-byte aligned as `BakeView` needs (`bytemuck::cast_slice`).
    words: Vec<u32>,
    len: usize,
    pub(crate) parts: PartBounds,
    /// Per driver: its glTF node and the node's name.
    pub(crate) drivers: Vec<(u32, String)>,
    /// Per morph weight (`MRPH`'s order): the node whose mesh it morphs, the target, the
    /// default weight.
    pub(crate) morph_weights: Vec<(u32, u32, f32)>,
    /// The clips the clip bounds hold for.
    pub(crate) clips: Vec<String>,
    /// The pose guard of the envelope, when the bake has one.
    pub(crate) guard: Option<PoseGuard>,
    /// One more than the largest node index the bake names (drivers, parts, envelope nodes).
    pub(crate) nodes: usize,
}

/// Why a bake file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum BakeLoadError {
    #[error("could not read the bake: {0}")]
    Io(#[from] std::io::Error),
    #[error("{path}: {error}")]
    Bake { path: String, error: skinlet_runtime::Error },
}

impl Bake {
    /// A bake from the bytes of a `.skinlet` file, with the default [`BakeSettings`]. Errors
    /// on anything `BakeView` refuses.
    pub fn from_bytes(bytes: &[u8]) -> Result<Bake, skinlet_runtime::Error> {
        Bake::with_settings(bytes, &BakeSettings::default())
    }

    /// A bake from the bytes of a `.skinlet` file, loaded as `settings` say.
    pub fn with_settings(bytes: &[u8], settings: &BakeSettings) -> Result<Bake, skinlet_runtime::Error> {
        let mut words = vec![0u32; bytes.len().div_ceil(4)];
        bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
        let view = BakeView::new(&bytemuck::cast_slice(&words)[..bytes.len()])?;
        let nodes = view.joint_nodes();
        let names = view.joint_names();
        let drivers: Vec<(u32, String)> = nodes.iter().zip(names).map(|(&n, s)| (n, s.to_string())).collect();
        let morphs = view.morphs();
        let morph_weights: Vec<(u32, u32, f32)> =
            morphs.map_or(&[][..], |m| m.weights).iter().map(|w| (w.node, w.target, w.default)).collect();
        let envelope = view.envelope();
        let guard = envelope.map(|e| e.guard()).transpose()?;
        let parts = PartBounds::new(&view)?;
        let parts = if settings.prune { parts.pruned() } else { parts };
        let clips = view.info().clips.iter().map(|c| c.to_string()).collect();
        let node_count = (drivers.iter().map(|d| d.0))
            .chain(parts.parts().iter().map(|p| p.node))
            .chain(morph_weights.iter().map(|w| w.0))
            .chain(envelope.iter().flat_map(|e| e.nodes.iter().map(|r| r.node)))
            .map(|n| n as usize + 1)
            .max()
            .unwrap_or(0);
        Ok(Bake { len: bytes.len(), words, parts, drivers, morph_weights, clips, guard, nodes: node_count })
    }

    /// The file's bytes (4-byte aligned: `BakeView::new` takes them as they are).
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.words)[..self.len]
    }

    /// The file's bytes as 4-byte aligned words (the last one zero-padded; `bytes` is the
    /// first `bytes().len()` of them).
    pub(crate) fn words(&self) -> &[u32] {
        &self.words
    }

    /// A view of the bake (checked at load, so this only fails if the bytes were changed).
    pub fn view(&self) -> Result<BakeView<'_>, skinlet_runtime::Error> {
        BakeView::new(self.bytes())
    }

    /// The per-part boxes (`skinlet_runtime::part_bounds`).
    pub fn part_bounds(&self) -> &PartBounds {
        &self.parts
    }

    /// The names of the clips the clip bounds hold for.
    pub fn clips(&self) -> &[String] {
        &self.clips
    }

    /// Whether the bake has a pose envelope (bounds for blends, layers and IK it admits).
    pub fn has_envelope(&self) -> bool {
        self.guard.is_some()
    }
}

/// Loads `.skinlet` files as [`Bake`]s.
#[derive(Default, TypePath)]
pub struct BakeLoader;

impl AssetLoader for BakeLoader {
    type Asset = Bake;
    type Settings = BakeSettings;
    type Error = BakeLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        settings: &BakeSettings,
        context: &mut LoadContext<'_>,
    ) -> Result<Bake, BakeLoadError> {
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).await?;
        Bake::with_settings(&bytes, settings)
            .map_err(|error| BakeLoadError::Bake { path: context.path().to_string(), error })
    }

    fn extensions(&self) -> &[&str] {
        &["skinlet"]
    }
}
