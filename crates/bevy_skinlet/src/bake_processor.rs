//! Baking glTF characters when Bevy processes assets (the `bake` feature: it links the
//! baker, for the machine that processes assets; a game ships without it).
//!
//! A bake recipe, `NAME.skinlet.ron` beside the glTF file, says what to bake:
//!
//! ```ron
//! (gltf: "Fox.glb", builder: "skin-aware", envelope_margin_degrees: Some(10.0))
//! ```
//!
//! Loading the recipe (with [`SkinletBakePlugin`]) bakes the glTF file and gives the same
//! [`Bake`] asset a `.skinlet` file gives. With Bevy's asset processing on
//! (`AssetMode::Processed`), the processor registered for `.skinlet.ron` stores the bake in
//! the processed folder, and Bevy rebakes it when the recipe or the glTF file changes (the
//! glTF file is a dependency of the load): bakes are cached and rebuilt Bevy's own way.
//! `skinlet bake` does the same for other build systems.
//!
//! The bake: the whole character of the file's default scene, every clip, meshlets from the
//! recipe's builder (`skin-aware` by default), bounds over the clips without refinement (so
//! the same input always gives the same bytes), and a pose envelope around the clips widened
//! by the margin (10° by default; `None`: no envelope). A `.gltf` file must embed its
//! buffers.

use crate::bake_asset::{Bake, BakeLoader, BakeSettings};
use bevy::asset::io::{Reader, Writer};
use bevy::asset::processor::LoadTransformAndSave;
use bevy::asset::saver::{AssetSaver, SavedAsset};
use bevy::asset::transformer::IdentityAssetTransformer;
use bevy::asset::{AssetLoader, AssetPath, AsyncWriteExt, LoadContext};
use bevy::prelude::*;
use serde::{Deserialize, Serialize};
use skinlet::meshlet::{Builder, MeshletLimits};
use std::path::Path;

/// What a `.skinlet.ron` recipe asks for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeRecipe {
    /// The glTF file (`.glb`, or `.gltf` with embedded buffers), relative to the recipe.
    pub gltf: String,
    /// The meshlet builder, by `skinlet bake --builder`'s names.
    #[serde(default = "default_builder")]
    pub builder: String,
    /// The pose envelope's margin around the clips, in degrees (0 to 180); `None`: no
    /// envelope.
    #[serde(default = "default_margin")]
    pub envelope_margin_degrees: Option<f64>,
}

fn default_builder() -> String {
    Builder::SkinAware.name().to_string()
}

fn default_margin() -> Option<f64> {
    Some(10.0)
}

impl BakeRecipe {
    /// A recipe with the defaults for `gltf`.
    pub fn new(gltf: impl Into<String>) -> BakeRecipe {
        BakeRecipe { gltf: gltf.into(), builder: default_builder(), envelope_margin_degrees: default_margin() }
    }
}

/// Why a recipe could not be baked.
#[derive(Debug, thiserror::Error)]
pub enum BakeRecipeError {
    #[error("could not read the recipe: {0}")]
    Io(#[from] std::io::Error),
    #[error("{path}: not a bake recipe: {error}")]
    Recipe { path: String, error: String },
    #[error("{path}: could not read {gltf}: {error}")]
    Gltf { path: String, gltf: String, error: String },
    #[error("{path}: baking {gltf}: {error}")]
    Bake { path: String, gltf: String, error: String },
}

/// Bakes a glTF file's bytes as a recipe asks (`name` names the file in errors). The bytes
/// of a `.skinlet` file.
pub fn bake_gltf(bytes: &[u8], name: &Path, recipe: &BakeRecipe) -> Result<Vec<u8>, String> {
    let builder = Builder::from_name(&recipe.builder).ok_or_else(|| {
        let names: Vec<&str> = Builder::ALL.iter().map(|b| b.name()).collect();
        format!("unknown builder {:?} (one of {})", recipe.builder, names.join(", "))
    })?;
    if let Some(m) = recipe.envelope_margin_degrees
        && !(0.0..=180.0).contains(&m)
    {
        return Err(format!("envelope margin {m}° is outside 0 to 180"));
    }
    // No base folder: external buffers are refused with an error naming them.
    let asset = skinlet::import::load_gltf_slice(bytes, None).map_err(|e| format!("{}: {e}", name.display()))?;
    let character = asset.character().map_err(|e| e.to_string())?;
    let clips: Vec<&skinlet::clip::Clip> = asset.clips.iter().collect();
    let how = skinlet::bounds::refine::Refinement::NONE;
    let (mut baked, _) =
        skinlet::bake::bake(&asset, &character, &clips, builder, MeshletLimits::NVIDIA, &how, &mut |_| {})
            .map_err(|e| e.to_string())?;
    if let (Some(margin), false) = (recipe.envelope_margin_degrees, clips.is_empty()) {
        let envelope = skinlet::bounds::envelope::Envelope::from_clips(
            &asset.skeleton,
            &baked.palette(),
            &baked.mesh,
            &clips,
            margin.to_radians(),
        )
        .map_err(|e| e.to_string())?;
        skinlet::bake::add_envelope(&mut baked, &asset, envelope).map_err(|e| e.to_string())?;
    }
    Ok(skinlet::bake::to_bytes(&baked))
}

/// Loads `.skinlet.ron` recipes as [`Bake`]s: reads the glTF file (a dependency of the
/// load, so processing reruns when it changes) and bakes it.
#[derive(Default, TypePath)]
pub struct BakeRecipeLoader;

impl AssetLoader for BakeRecipeLoader {
    type Asset = Bake;
    type Settings = ();
    type Error = BakeRecipeError;

    async fn load(&self, reader: &mut dyn Reader, _: &(), context: &mut LoadContext<'_>) -> Result<Bake, Self::Error> {
        let path = context.path().to_string();
        let mut text = Vec::new();
        reader.read_to_end(&mut text).await?;
        let recipe: BakeRecipe = ron::de::from_bytes(&text)
            .map_err(|e| BakeRecipeError::Recipe { path: path.clone(), error: e.to_string() })?;
        let gltf_path: AssetPath = context
            .path()
            .resolve_embed_str(&recipe.gltf)
            .map_err(|e| BakeRecipeError::Recipe { path: path.clone(), error: e.to_string() })?;
        let gltf_err = |error: String| BakeRecipeError::Gltf { path: path.clone(), gltf: recipe.gltf.clone(), error };
        let bytes = context.read_asset_bytes(gltf_path.clone()).await.map_err(|e| gltf_err(e.to_string()))?;
        let bake_err = |error: String| BakeRecipeError::Bake { path: path.clone(), gltf: recipe.gltf.clone(), error };
        let baked = bake_gltf(&bytes, Path::new(&recipe.gltf), &recipe).map_err(bake_err)?;
        Bake::from_bytes(&baked).map_err(|e| bake_err(e.to_string()))
    }

    fn extensions(&self) -> &[&str] {
        &["skinlet.ron"]
    }
}

/// Writes a [`Bake`] as its `.skinlet` bytes (read back by [`BakeLoader`]).
#[derive(Default, TypePath)]
pub struct BakeSaver;

impl AssetSaver for BakeSaver {
    type Asset = Bake;
    type Settings = ();
    type OutputLoader = BakeLoader;
    type Error = std::io::Error;

    async fn save(
        &self,
        writer: &mut Writer,
        asset: SavedAsset<'_, '_, Bake>,
        _: &(),
        _: AssetPath<'_>,
    ) -> Result<BakeSettings, std::io::Error> {
        writer.write_all(asset.bytes()).await?;
        Ok(BakeSettings::default())
    }
}

/// The processor Bevy runs on `.skinlet.ron` recipes: bake, then store the bake's bytes.
pub type BakeProcessor = LoadTransformAndSave<BakeRecipeLoader, IdentityAssetTransformer<Bake>, BakeSaver>;

/// Registers the recipe loader and, where Bevy processes assets, the bake processor as the
/// default for `.skinlet.ron`. Add it beside [`crate::SkinletPlugin`] on the machine that
/// processes assets.
#[derive(Default)]
pub struct SkinletBakePlugin;

impl Plugin for SkinletBakePlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<Bake>().register_asset_loader(BakeRecipeLoader);
        if app.world().get_resource::<bevy::asset::processor::AssetProcessor>().is_some() {
            app.register_asset_processor::<BakeProcessor>(BakeProcessor::new(
                IdentityAssetTransformer::new(),
                BakeSaver,
            ))
            .set_default_asset_processor::<BakeProcessor>("skinlet.ron");
        }
    }
}
