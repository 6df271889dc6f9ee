//! Every file real tools write (issue 36): a corpus made here from the shared characters by
//! the pinned tools (`tools/package.json`: gltfpack 1.3.0, @gltf-transform/cli 4.5.1) and by
//! JSON edits that add what exporters and texture pipelines write but changes no geometry
//! (texture and image extensions, missing or unreadable images, material extensions and
//! variants, lights, cameras, extras). Every file must import, bake whole (the bake's
//! triangles plus the degenerate ones it drops equal the triangles three.js draws) and pose
//! like three.js (`tools/oracle.mjs`, three 0.187.0, which decodes meshopt and Draco itself)
//! at 13%, 50% and 87% of clip 0: every vertex of every part within [`TOLERANCE`] of the
//! posed character's size.
//!
//! The test prints the table of `docs/CHARACTERS.md` and fails on any file that does not
//! pass. Without the tools or the assets it skips with a note, unless
//! `SKINLET_REQUIRE_TOOLS=1` / `SKINLET_REQUIRE_ASSETS=1` (CI sets both).
//!
//! Which characters: the gltfpack options on CesiumMan (textured, a `matrix` root turning
//! Z-up into Y-up) and Fox (non-indexed, 3 clips), two of them on Xbot (two meshes, 67
//! joints, centimetre skeleton); MorphStressTest for what touches morph targets (quantized
//! deltas, `sparse`, Draco with morph targets); Fox also for `weld`, `reorder` and
//! `resample`; mannequiny (3 primitives and untextured materials) for `dedup` and `palette`
//! (`--min 2`, so that its 3 materials merge into one palette texture); CesiumMan for the
//! rest and for the edits. BrainStem is left out for time (its bake alone takes most of a
//! minute). Each file is baked with clip 0, the clip posed against three.js: the bounds of
//! every clip would take minutes and read nothing more of the file. About 2 minutes in all
//! on 2 cores. `SKINLET_CORPUS_ONLY=text` runs only the files whose name holds `text`.

mod common;

use common::assets_dir;
use glam::Vec3;
use serde_json::{Value, json};
use skinlet::Asset;
use skinlet::bake::{bake, prepare_character};
use skinlet::bounds::refine::Refinement;
use skinlet::clip::Clip;
use skinlet::meshlet::{Builder, MeshletLimits};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Largest distance allowed between a vertex posed by skinlet and by three.js, relative to
/// the diagonal of the posed character's box: the same as `tests/oracle.rs`. It can stay
/// this tight for quantized and compressed files because both read the same file: three
/// dequantizes the same integers and decodes the same meshopt and Draco streams; what is
/// left is f32 rounding (skinlet) against f64 (three's matrices).
const TOLERANCE: f32 = 1e-5;

/// One step making a corpus file from the previous one.
#[derive(Clone, Copy)]
enum Step {
    /// gltfpack with these options.
    Pack(&'static [&'static str]),
    /// A glTF Transform command with these options.
    Transform(&'static str, &'static [&'static str]),
    /// An edit of the GLB's JSON, described.
    Edit(&'static str, fn(&mut Value)),
}

struct Recipe {
    /// The file's name in the table (without `.glb`).
    name: &'static str,
    /// The shared asset it starts from, relative to the assets folder.
    source: &'static str,
    steps: &'static [Step],
    /// Strings the made file's JSON must hold: the tool did what the row says.
    expect: &'static [&'static str],
}

const CESIUM: &str = "skinned/CesiumMan.glb";
const XBOT: &str = "skinned/Xbot.glb";
const FOX: &str = "skinned/Fox.glb";
const MANNEQUINY: &str = "skinned/mannequiny.glb";
const MORPH: &str = "morph/MorphStressTest.gltf";

const MESHOPT: &str = "EXT_meshopt_compression";
const QUANTIZED: &str = "KHR_mesh_quantization";
const DRACO: &str = "KHR_draco_mesh_compression";

fn recipes() -> Vec<Recipe> {
    use Step::*;
    let r = |name, source, steps, expect| Recipe { name, source, steps, expect };
    let mut out = Vec::new();
    // gltfpack: compression, quantization bit counts, what it keeps, simplification.
    for (prefix, source) in [("cesium", CESIUM), ("fox", FOX)] {
        let name = |s: &str| -> &'static str { format!("{prefix}-{s}").leak() };
        out.extend([
            r(name("pack-c"), source, &[Pack(&["-c"])], &[MESHOPT, QUANTIZED]),
            r(name("pack-cc"), source, &[Pack(&["-cc"])], &[MESHOPT, QUANTIZED]),
            r(name("pack-cc-khr"), source, &[Pack(&["-cc", "-ce", "khr"])], &["KHR_meshopt_compression", QUANTIZED]),
            r(name("pack-kn"), source, &[Pack(&["-kn"])], &[QUANTIZED]),
            r(name("pack-km"), source, &[Pack(&["-km"])], &[QUANTIZED]),
            r(
                name("pack-ke"),
                source,
                &[Edit("extras objects everywhere", object_extras), Pack(&["-ke"])],
                &["\"extras\""],
            ),
            r(name("pack-v10"), source, &[Pack(&["-vp", "10", "-vn", "4", "-vt", "8"])], &[QUANTIZED]),
            r(name("pack-v16"), source, &[Pack(&["-vp", "16", "-vn", "16", "-vt", "16"])], &[QUANTIZED]),
            r(name("pack-vpn"), source, &[Pack(&["-vpn", "-vp", "12"])], &[QUANTIZED]),
            r(name("pack-vpf"), source, &[Pack(&["-vpf"])], &[QUANTIZED]),
            r(name("pack-si"), source, &[Pack(&["-si", "0.5"])], &[QUANTIZED]),
        ]);
    }
    out.extend([
        r("xbot-pack-cc", XBOT, &[Pack(&["-cc"])], &[MESHOPT, QUANTIZED]),
        r("xbot-pack-v10-si", XBOT, &[Pack(&["-vp", "10", "-si", "0.5"])], &[QUANTIZED]),
        r("morph-pack-cc", MORPH, &[Pack(&["-cc"])], &[MESHOPT, "\"targets\""]),
        r("morph-pack-v10", MORPH, &[Pack(&["-vp", "10", "-vn", "4"])], &[QUANTIZED, "\"targets\""]),
        // glTF Transform, one command at a time.
        r("cesium-draco", CESIUM, &[Transform("draco", &[])], &[DRACO]),
        r("morph-draco", MORPH, &[Transform("draco", &[])], &[DRACO, "\"targets\""]),
        r("cesium-meshopt", CESIUM, &[Transform("meshopt", &[])], &[MESHOPT]),
        r("morph-meshopt", MORPH, &[Transform("meshopt", &[])], &[MESHOPT, "\"targets\""]),
        r("cesium-quantize", CESIUM, &[Transform("quantize", &[])], &[QUANTIZED]),
        r("morph-quantize", MORPH, &[Transform("quantize", &[])], &[QUANTIZED, "\"targets\""]),
        r("fox-weld", FOX, &[Transform("weld", &[])], &["\"indices\""]),
        r("cesium-weld", CESIUM, &[Transform("weld", &[])], &[]),
        r("mannequiny-dedup", MANNEQUINY, &[Transform("dedup", &[])], &[]),
        r("cesium-dedup", CESIUM, &[Transform("dedup", &[])], &[]),
        r("cesium-instance", CESIUM, &[Transform("instance", &[])], &[]),
        r("morph-sparse", MORPH, &[Transform("sparse", &[])], &["\"sparse\""]),
        r("cesium-resample", CESIUM, &[Transform("resample", &[])], &[]),
        r("fox-resample", FOX, &[Transform("resample", &[])], &[]),
        r("cesium-flatten", CESIUM, &[Transform("flatten", &[])], &[]),
        r("morph-flatten", MORPH, &[Transform("flatten", &[])], &[]),
        r("cesium-join", CESIUM, &[Transform("join", &[])], &[]),
        r("morph-join", MORPH, &[Transform("join", &[])], &[]),
        r("cesium-prune", CESIUM, &[Transform("prune", &[])], &[]),
        r("cesium-reorder", CESIUM, &[Transform("reorder", &[])], &[]),
        r("fox-reorder", FOX, &[Transform("reorder", &[])], &[]),
        r(
            "mannequiny-palette",
            MANNEQUINY,
            &[Transform("palette", &["--min", "2"])],
            &["PaletteMaterial", "\"TEXCOORD_2\""],
        ),
        // Chains: Draco over sparse morph targets; meshopt over quantized, resampled clips.
        r("morph-sparse-draco", MORPH, &[Transform("sparse", &[]), Transform("draco", &[])], &[DRACO, "\"sparse\""]),
        r(
            "cesium-resample-quantize-meshopt",
            CESIUM,
            &[Transform("resample", &[]), Transform("quantize", &[]), Transform("meshopt", &[])],
            &[MESHOPT, QUANTIZED],
        ),
        // Edits: what changes no geometry.
        r(
            "cesium-pack-cc-basisu",
            CESIUM,
            &[Pack(&["-cc"]), Edit("textures only in KHR_texture_basisu (KTX2)", basisu)],
            &["KHR_texture_basisu"],
        ),
        r("cesium-webp", CESIUM, &[Edit("textures only in EXT_texture_webp", webp)], &["EXT_texture_webp"]),
        r("cesium-avif", CESIUM, &[Edit("textures only in EXT_texture_avif", avif)], &["EXT_texture_avif"]),
        r("cesium-missing-image", CESIUM, &[Edit("image file missing", missing_image)], &[MISSING_IMAGE]),
        r("cesium-unreadable-image", CESIUM, &[Edit("image that is not a PNG", unreadable_image)], &[UNREADABLE_IMAGE]),
        r(
            "cesium-material-ext",
            CESIUM,
            &[Edit("material extensions (clearcoat, sheen, emissive strength, IOR, unlit)", material_extensions)],
            &["KHR_materials_clearcoat"],
        ),
        r("cesium-variants", CESIUM, &[Edit("KHR_materials_variants", material_variants)], &["KHR_materials_variants"]),
        r(
            "cesium-lights",
            CESIUM,
            &[Edit("KHR_lights_punctual (a light on a joint)", lights)],
            &["KHR_lights_punctual"],
        ),
        r("cesium-cameras", CESIUM, &[Edit("cameras (one on a joint)", cameras)], &["\"cameras\""]),
        r("cesium-extras", CESIUM, &[Edit("extras of every JSON type everywhere", any_extras)], &["\"extras\""]),
    ]);
    out
}

// ---------------------------------------------------------------------------------------
// JSON edits.

const MISSING_IMAGE: &str = "corpus-no-such-texture.png";
const UNREADABLE_IMAGE: &str = "corpus-unreadable.png";

fn push(list: &mut Value, v: Value) -> usize {
    if !list.is_array() {
        *list = json!([]);
    }
    let a = list.as_array_mut().unwrap();
    a.push(v);
    a.len() - 1
}

/// Lists `ext` in `extensionsUsed` and, if `required`, in `extensionsRequired`.
fn uses(j: &mut Value, ext: &str, required: bool) {
    let keys: &[&str] = if required { &["extensionsUsed", "extensionsRequired"] } else { &["extensionsUsed"] };
    for key in keys {
        if !j[*key].as_array().is_some_and(|a| a.iter().any(|e| e == ext)) {
            push(&mut j[*key], json!(ext));
        }
    }
}

/// Every texture's image only in extension `ext` (no `source`), as texture pipelines write
/// them; the new images hold the old bytes under `mime` (so they do not decode as such).
fn texture_ext(j: &mut Value, ext: &str, mime: &str) {
    let textures = j["textures"].as_array().expect("a file with textures").len();
    assert!(textures > 0);
    for t in 0..textures {
        let old = j["textures"][t]["source"].take();
        let old = old.as_u64().expect("a texture with a source") as usize;
        let mut image = j["images"][old].clone();
        image["mimeType"] = json!(mime);
        let source = push(&mut j["images"], image);
        let texture = j["textures"][t].as_object_mut().unwrap();
        texture.remove("source");
        texture.insert("extensions".into(), json!({ ext: { "source": source } }));
    }
    uses(j, ext, true);
}

fn basisu(j: &mut Value) {
    texture_ext(j, "KHR_texture_basisu", "image/ktx2");
}

fn webp(j: &mut Value) {
    texture_ext(j, "EXT_texture_webp", "image/webp");
}

fn avif(j: &mut Value) {
    texture_ext(j, "EXT_texture_avif", "image/avif");
}

fn missing_image(j: &mut Value) {
    let images = j["images"].as_array_mut().expect("a file with images");
    images[0] = json!({ "uri": MISSING_IMAGE });
}

fn unreadable_image(j: &mut Value) {
    let images = j["images"].as_array_mut().expect("a file with images");
    images[0] = json!({ "uri": UNREADABLE_IMAGE, "mimeType": "image/png" });
}

fn material_extensions(j: &mut Value) {
    let m = &mut j["materials"][0];
    m["extensions"] = json!({
        "KHR_materials_clearcoat": { "clearcoatFactor": 1.0, "clearcoatTexture": { "index": 0 } },
        "KHR_materials_sheen": { "sheenColorFactor": [1.0, 0.5, 0.2], "sheenRoughnessFactor": 0.4 },
        "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 },
        "KHR_materials_ior": { "ior": 1.7 },
        "KHR_materials_unlit": {},
    });
    for ext in
        ["KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_emissive_strength", "KHR_materials_ior"]
    {
        uses(j, ext, true);
    }
    uses(j, "KHR_materials_unlit", false);
}

fn material_variants(j: &mut Value) {
    let mut gold = j["materials"][0].clone();
    gold["name"] = json!("gold");
    gold["pbrMetallicRoughness"] = json!({ "baseColorFactor": [1.0, 0.8, 0.2, 1.0], "metallicFactor": 1.0 });
    let gold = push(&mut j["materials"], gold);
    j["extensions"]["KHR_materials_variants"] = json!({ "variants": [{ "name": "plain" }, { "name": "gold" }] });
    for mesh in j["meshes"].as_array_mut().unwrap() {
        for p in mesh["primitives"].as_array_mut().unwrap() {
            let plain = p["material"].clone();
            p["extensions"]["KHR_materials_variants"] =
                json!({ "mappings": [{ "material": plain, "variants": [0] }, { "material": gold, "variants": [1] }] });
        }
    }
    uses(j, "KHR_materials_variants", true);
}

/// The first joint of the first skin, to hang lights and cameras on.
fn a_joint(j: &Value) -> usize {
    j["skins"][0]["joints"][0].as_u64().unwrap() as usize
}

/// Makes `node` a child of `parent`.
fn adopt(j: &mut Value, parent: usize, node: usize) {
    push(&mut j["nodes"][parent]["children"], json!(node));
}

/// Adds `node` to the default scene's roots.
fn add_root(j: &mut Value, node: usize) {
    let scene = j["scene"].as_u64().unwrap_or(0) as usize;
    push(&mut j["scenes"][scene]["nodes"], json!(node));
}

fn lights(j: &mut Value) {
    j["extensions"]["KHR_lights_punctual"] = json!({ "lights": [
        { "type": "point", "color": [1.0, 0.9, 0.8], "intensity": 20.0, "range": 10.0 },
        { "type": "spot", "intensity": 50.0, "spot": { "innerConeAngle": 0.2, "outerConeAngle": 0.6 } },
        { "type": "directional", "intensity": 3.0 },
    ]});
    let joint = a_joint(j);
    let on_joint = push(
        &mut j["nodes"],
        json!({ "name": "head lamp", "translation": [0.0, 0.1, 0.0], "extensions": { "KHR_lights_punctual": { "light": 0 } } }),
    );
    adopt(j, joint, on_joint);
    let spot =
        push(&mut j["nodes"], json!({ "name": "spot", "extensions": { "KHR_lights_punctual": { "light": 1 } } }));
    add_root(j, spot);
    let sun = push(
        &mut j["nodes"],
        json!({ "name": "sun", "rotation": [-0.38, 0.0, 0.0, 0.92], "extensions": { "KHR_lights_punctual": { "light": 2 } } }),
    );
    add_root(j, sun);
    uses(j, "KHR_lights_punctual", false);
}

fn cameras(j: &mut Value) {
    push(
        &mut j["cameras"],
        json!({ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.01, "zfar": 100.0 } }),
    );
    push(
        &mut j["cameras"],
        json!({ "type": "orthographic", "orthographic": { "xmag": 2.0, "ymag": 2.0, "znear": 0.01, "zfar": 50.0 } }),
    );
    let joint = a_joint(j);
    let eye = push(&mut j["nodes"], json!({ "name": "eye camera", "camera": 0, "translation": [0.0, 0.1, 0.2] }));
    adopt(j, joint, eye);
    let overview = push(&mut j["nodes"], json!({ "name": "overview", "camera": 1, "translation": [0.0, 1.0, 5.0] }));
    add_root(j, overview);
}

/// `extras` objects on the root, the asset and every object that can have them: what
/// exporters write, and all that gltfpack 1.3's `-ke` copies correctly (it writes a string
/// extra without its quotes, which is not JSON).
fn object_extras(j: &mut Value) {
    add_extras(j, 1);
}

/// `extras` of every JSON type (glTF allows any; it recommends objects).
fn any_extras(j: &mut Value) {
    add_extras(j, 6);
}

/// `extras` on the root, the asset and every object that can have them, cycling through the
/// first `kinds` of: object, array, string, number, boolean, null.
fn add_extras(j: &mut Value, kinds: usize) {
    let mut k = 0;
    let mut next = || {
        k += 1;
        match k % kinds {
            0 => json!({ "exporter": "corpus", "id": k, "tags": ["a", "b"] }),
            1 => json!(["extra", k]),
            2 => json!("a string extra"),
            3 => json!(k as f64 * 0.5),
            4 => json!(true),
            _ => Value::Null,
        }
    };
    j["extras"] = next();
    j["asset"]["extras"] = next();
    let lists = [
        "accessors",
        "animations",
        "buffers",
        "bufferViews",
        "cameras",
        "images",
        "materials",
        "meshes",
        "nodes",
        "samplers",
        "scenes",
        "skins",
        "textures",
    ];
    for list in lists {
        // (`get_mut`: indexing would add the missing lists as nulls)
        for item in j.get_mut(list).and_then(Value::as_array_mut).into_iter().flatten() {
            item["extras"] = next();
        }
    }
    for mesh in j["meshes"].as_array_mut().unwrap() {
        for p in mesh["primitives"].as_array_mut().unwrap() {
            p["extras"] = next();
        }
    }
    for anim in j.get_mut("animations").and_then(Value::as_array_mut).into_iter().flatten() {
        for key in ["channels", "samplers"] {
            for item in anim[key].as_array_mut().unwrap() {
                item["extras"] = next();
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// GLB files.

fn glb_json(bytes: &[u8]) -> (Value, &[u8]) {
    assert_eq!(&bytes[..4], b"glTF");
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    (serde_json::from_slice(&bytes[20..20 + n]).unwrap(), &bytes[20 + n..])
}

/// A GLB of `json` and the chunks after the JSON one (`rest`, unchanged).
fn glb(json: &Value, rest: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(json).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 20 + text.len() + rest.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(rest);
    out
}

fn run(tool: &Path, args: &[&str]) -> Result<(), String> {
    let out = Command::new(tool).args(args).output().map_err(|e| format!("{}: {e}", tool.display()))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("{} {args:?}: {}", tool.display(), String::from_utf8_lossy(&out.stderr)))
    }
}

struct Tools {
    gltfpack: PathBuf,
    transform: PathBuf,
    /// The folder of `oracle.mjs`.
    dir: PathBuf,
}

/// Makes `recipe`'s file in `tmp` (each step writing a `.glb`); returns its path.
fn make(recipe: &Recipe, assets: &Path, tools: &Tools, tmp: &Path) -> Result<PathBuf, String> {
    let mut input = assets.join(recipe.source);
    for (i, step) in recipe.steps.iter().enumerate() {
        let last = i + 1 == recipe.steps.len();
        let out = tmp.join(if last { format!("{}.glb", recipe.name) } else { format!("{}.{i}.glb", recipe.name) });
        let (i_str, o_str) = (input.to_str().unwrap(), out.to_str().unwrap());
        match step {
            Step::Pack(options) => {
                let mut args = vec!["-i", i_str, "-o", o_str];
                args.extend_from_slice(options);
                run(&tools.gltfpack, &args)?;
            }
            Step::Transform(command, options) => {
                let mut args = vec![*command, i_str, o_str];
                args.extend_from_slice(options);
                run(&tools.transform, &args)?;
            }
            Step::Edit(_, edit) => {
                let bytes = std::fs::read(&input).unwrap();
                let (mut json, rest) = glb_json(&bytes);
                edit(&mut json);
                std::fs::write(&out, glb(&json, rest)).unwrap();
            }
        }
        input = out;
    }
    let text = serde_json::to_string(&glb_json(&std::fs::read(&input).unwrap()).0).unwrap();
    for e in recipe.expect {
        if !text.contains(e) {
            return Err(format!("the made file does not hold {e:?}: the tool did not do what the row says"));
        }
    }
    Ok(input)
}

fn describe(steps: &[Step]) -> String {
    let one = |s: &Step| match s {
        Step::Pack(o) => format!("gltfpack {}", o.join(" ")),
        Step::Transform(c, o) => format!("gltf-transform {c}{}", o.iter().map(|o| format!(" {o}")).collect::<String>()),
        Step::Edit(what, _) => format!("edit: {what}"),
    };
    steps.iter().map(one).collect::<Vec<_>>().join(", then ")
}

// ---------------------------------------------------------------------------------------
// Checking one file.

struct Outcome {
    /// Triangles in the bake, and degenerate ones it drops (a vertex repeated: they draw nothing).
    baked: usize,
    degenerate: usize,
    /// Triangles three.js draws.
    three: usize,
    /// Largest vertex distance from three.js, relative to the posed character's size.
    worst: f32,
}

/// Imports, bakes and poses `path` against three.js; `Err` says what failed.
fn check(path: &Path, tools: &Tools) -> Result<Outcome, String> {
    let started = std::time::Instant::now();
    let asset = skinlet::import::load(path).map_err(|e| format!("import: {e}"))?;
    let character = asset.character().map_err(|e| format!("character: {e}"))?;
    // Clip 0, the one posed against three.js (see the top of the file).
    let clips: Vec<&Clip> = asset.clips.iter().take(1).collect();
    let limits = MeshletLimits::NVIDIA;
    let (baked, _) = bake(&asset, &character, &clips, Builder::SkinAware, limits, &Refinement::NONE, &mut |_| {})
        .map_err(|e| format!("bake: {e}"))?;
    let degenerate = prepare_character(&character).map_err(|e| format!("prepare: {e}"))?.dropped_triangles;
    let baked_at = std::time::Instant::now();
    let (three, worst) = against_three(&asset, path, tools)?;
    eprintln!(
        "  {}: import and bake {:.1} s, three.js {:.1} s",
        path.display(),
        (baked_at - started).as_secs_f32(),
        baked_at.elapsed().as_secs_f32()
    );
    Ok(Outcome { baked: baked.mesh.triangles.len(), degenerate, three, worst })
}

/// three's triangles, and the largest distance between its posed vertices and skinlet's
/// (relative to the size) at three times of clip 0.
fn against_three(asset: &Asset, glb: &Path, tools: &Tools) -> Result<(usize, f32), String> {
    let character = asset.character().map_err(|e| e.to_string())?;
    let clip = asset.clips.first();
    let times: Vec<f32> = match clip {
        Some(c) => [0.13, 0.5, 0.87].iter().map(|f| c.start + f * c.duration()).collect(),
        None => vec![0.0],
    };
    let out = Command::new("node")
        .arg(tools.dir.join("oracle.mjs"))
        .arg(glb)
        .arg("0")
        .args(times.iter().map(|t| t.to_string()))
        .output()
        .map_err(|e| format!("node: {e}"))?;
    if !out.status.success() {
        return Err(format!("three.js: {}", String::from_utf8_lossy(&out.stderr)));
    }
    let three: Value = serde_json::from_slice(&out.stdout).map_err(|e| format!("three.js output: {e}"))?;
    let (mut triangles, mut worst) = (None, 0f32);
    for (sample, &t) in three["samples"].as_array().unwrap().iter().zip(&times) {
        let (posed, _) = character.posed(&asset.skeleton, clip, t).map_err(|e| e.to_string())?;
        let (lo, hi) = posed.iter().fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
        let size = (hi - lo).length();
        let parts = sample["parts"].as_array().unwrap();
        if parts.len() != character.parts.len() {
            return Err(format!(
                "three.js draws {} primitives, skinlet has {} parts",
                parts.len(),
                character.parts.len()
            ));
        }
        let drawn: u64 = parts.iter().map(|p| p["triangles"].as_u64().unwrap()).sum();
        triangles = Some(drawn as usize);
        for p in parts {
            let key = ["node", "mesh", "primitive"].map(|k| p[k].as_u64().unwrap_or(u64::MAX) as u32);
            let part = (character.parts.iter())
                .find(|q| [q.node, q.mesh, q.primitive] == key)
                .ok_or_else(|| format!("three.js draws {key:?}, skinlet has no such part"))?;
            let theirs = p["positions"].as_array().unwrap();
            let ours = &posed[part.vertices.start as usize..part.vertices.end as usize];
            if theirs.len() != 3 * ours.len() {
                return Err(format!("{key:?}: three.js has {} vertices, skinlet {}", theirs.len() / 3, ours.len()));
            }
            for (v, ours) in ours.iter().enumerate() {
                let theirs = Vec3::from_array(std::array::from_fn(|k| theirs[3 * v + k].as_f64().unwrap() as f32));
                let d = theirs.distance(*ours) / size;
                if !d.is_finite() {
                    return Err(format!("{key:?} vertex {v}: skinlet says {ours}, three.js {theirs}"));
                }
                worst = worst.max(d);
            }
        }
    }
    Ok((triangles.unwrap_or(0), worst))
}

fn thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[test]
fn every_file_real_tools_write_bakes_and_poses_like_three_js() {
    let Some(assets) = assets_dir() else { return };
    let (Some(_), Some(_), Some(dir)) =
        (common::tools_dir("gltfpack"), common::tools_dir("@gltf-transform/cli"), common::tools_dir("three"))
    else {
        return;
    };
    let bin = dir.join("node_modules/.bin");
    let tools = Tools { gltfpack: bin.join("gltfpack"), transform: bin.join("gltf-transform"), dir };
    let tmp = std::env::temp_dir().join(format!("skinlet-corpus-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    // The unreadable image the edits point at (the missing one is never written).
    std::fs::write(tmp.join(UNREADABLE_IMAGE), b"this is not a PNG file").unwrap();
    let started = std::time::Instant::now();
    let recipes = recipes();
    let mut rows = Vec::new();
    let mut failed = Vec::new();
    // SKINLET_CORPUS_ONLY=text: only the files whose name holds it (while working on one).
    let only = std::env::var("SKINLET_CORPUS_ONLY").unwrap_or_default();
    for recipe in recipes.iter().filter(|r| r.name.contains(only.as_str())) {
        let file = format!("{}.glb", recipe.name);
        let made_at = std::time::Instant::now();
        let made = make(recipe, &assets, &tools, &tmp);
        eprintln!("  {file}: made in {:.1} s", made_at.elapsed().as_secs_f32());
        let result = made.and_then(|path| check(&path, &tools));
        let how = describe(recipe.steps);
        let source = Path::new(recipe.source).file_name().unwrap().to_string_lossy().into_owned();
        let row = match &result {
            Ok(o) => {
                let whole = o.baked + o.degenerate == o.three;
                let tris = if o.degenerate > 0 {
                    format!("{} (+{} degenerate) / {}", thousands(o.baked), o.degenerate, thousands(o.three))
                } else {
                    format!("{} / {}", thousands(o.baked), thousands(o.three))
                };
                if !whole {
                    failed.push(format!("{file}: the bake holds {tris} triangles (skinlet / three.js)"));
                }
                if o.worst > TOLERANCE || o.worst.is_nan() {
                    failed.push(format!("{file}: a vertex is {:.2e} of the size from three.js", o.worst));
                }
                let verdict = if whole && o.worst <= TOLERANCE { "ok" } else { "**FAILS**" };
                format!("| {file} | {source}: {how} | {tris} | {:.1e} | {verdict} |", o.worst)
            }
            Err(e) => {
                failed.push(format!("{file}: {e}"));
                let first = e.lines().next().unwrap_or("").replace('|', "\\|");
                format!("| {file} | {source}: {how} | – | – | **FAILS**: {first} |")
            }
        };
        eprintln!("{row}");
        rows.push(row);
    }
    println!("| file | made from: tool and options | triangles skinlet / three.js | worst pose error | result |");
    println!("|---|---|---:|---:|---|");
    for row in &rows {
        println!("{row}");
    }
    assert!(!rows.is_empty(), "no file made (SKINLET_CORPUS_ONLY={only:?})");
    println!(
        "\n{} files, {} pass; tolerance {TOLERANCE:.0e} of the size; {:.0} s",
        rows.len(),
        rows.iter().filter(|r| r.ends_with("| ok |")).count(),
        started.elapsed().as_secs_f32()
    );
    assert!(failed.is_empty(), "{} of {} files fail:\n{}", failed.len(), rows.len(), failed.join("\n"));
    let _ = std::fs::remove_dir_all(&tmp);
}

/// A required extension skinlet does not know could change the geometry: the import is an
/// error naming it, also when the file is otherwise one the corpus accepts.
#[test]
fn unknown_required_extensions_are_named() {
    let Some(assets) = assets_dir() else { return };
    let bytes = std::fs::read(assets.join(CESIUM)).unwrap();
    let (json, rest) = glb_json(&bytes);
    for ext in ["EXT_mesh_gpu_instancing", "KHR_animation_pointer", "VENDOR_displacement"] {
        let mut j = json.clone();
        basisu(&mut j);
        uses(&mut j, ext, true);
        let e = skinlet::import::load_bytes(&glb(&j, rest), Path::new("unknown.glb")).unwrap_err().to_string();
        assert!(e.contains("extensionsRequired") && e.contains(ext), "{e}");
        // Used but not required: the file must be usable without it, so skinlet reads it.
        let mut j = json.clone();
        uses(&mut j, ext, false);
        skinlet::import::load_bytes(&glb(&j, rest), Path::new("optional.glb")).unwrap();
    }
}
