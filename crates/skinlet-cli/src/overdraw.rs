//! `skinlet overdraw`: Han & Sander's table 2 for one character.

use crate::{prepared_character, select_clips};
use anyhow::Result;
use serde_json::json;
use skinlet::overdraw::cluster::{ClusterParams, Patches, cluster, lookup};
use skinlet::overdraw::evaluate::{EvalParams, evaluate, keyframes};
use skinlet::overdraw::measure::Raster;
use std::path::Path;

/// Renders keyframe 0 of the first clip from the front (+z, at 3× the bounding radius) with
/// the original order and with the clustered buffer the lookup picks, side by side, as an
/// overdraw heat map; returns both overdraw ratios.
fn heatmap(
    path: &Path,
    keyframes: &[Vec<glam::Vec3>],
    original: &[[u32; 3]],
    params: &ClusterParams,
) -> Result<(f64, f64)> {
    let c = cluster(keyframes, original, params);
    let lookup = lookup(&c, 37, 72);
    let eye = c.framing.eye(glam::Vec3::new(0.0, 0.25, 1.0).normalize(), 3.0);
    let ours = &c.buffers[lookup.get(0, (eye - c.framing.center).normalize()) as usize];
    let size = 256;
    let mut raster = Raster::new(size, size);
    let vp = c.framing.view_proj(eye);
    let mut image = vec![0u8; (2 * size * size * 3) as usize];
    let mut ratios = [0.0; 2];
    for (half, order) in [original, &ours[..]].iter().enumerate() {
        ratios[half] = raster.render(&keyframes[0], order, &vp).ratio();
        for (row, pixels) in raster.heatmap().chunks((size * 3) as usize).enumerate() {
            let at = (row * 2 * size as usize + half * size as usize) * 3;
            image[at..at + pixels.len()].copy_from_slice(pixels);
        }
    }
    crate::write_png(path, 2 * size, size, png::ColorType::Rgb, &image)?;
    Ok((ratios[0], ratios[1]))
}

/// The patch rule of `--lambda` (linear patches) or else `--patch-size` (compact patches).
pub fn patch_rule(lambda: Option<f32>, patch_size: u32) -> Result<Patches> {
    match lambda {
        Some(lambda) if lambda.is_finite() && lambda > 0.0 => Ok(Patches::Linear { lambda }),
        Some(lambda) => anyhow::bail!("--lambda must be a number > 0 (got {lambda})"),
        None if (4..=256).contains(&patch_size) => Ok(Patches::Compact { size: patch_size }),
        None => anyhow::bail!("--patch-size must be between 4 and 256 (got {patch_size})"),
    }
}

/// The table for `file`; `params` gives k, the seed, the patch rule and the patch order.
pub fn command(
    file: &str,
    clips: Option<&str>,
    max_keyframes: usize,
    views: usize,
    params: &ClusterParams,
    heatmap_path: Option<&Path>,
    json: bool,
) -> Result<()> {
    anyhow::ensure!((1..=255).contains(&params.k), "--k must be between 1 and 255");
    anyhow::ensure!(max_keyframes >= 1 && views >= 1, "--max-keyframes and --views must be at least 1");
    let (asset, character, prepared) = prepared_character(file)?;
    let clips = select_clips(&asset, clips)?;
    anyhow::ensure!(!clips.is_empty(), "{file} has no animation clips");
    let frames = clips
        .iter()
        .map(|c| Ok(keyframes(&asset.skeleton, &character.palette, &prepared.mesh, c, max_keyframes)?.1))
        .collect::<Result<Vec<Vec<Vec<glam::Vec3>>>>>()?;
    if let Some(path) = heatmap_path {
        let (before, after) = heatmap(path, &frames[0], &prepared.mesh.triangles, params)?;
        if !json {
            println!(
                "{}: overdraw heat map of clip {:?}, keyframe 0, front view: original {before:.3} (left), clustered {after:.3} (right)",
                path.display(),
                clips[0].name
            );
        }
    }
    let rows =
        evaluate(&frames, &prepared.mesh.triangles, &EvalParams { cluster: *params, views, ..EvalParams::default() });
    // The share of the way from the original order's overdraw to none (None: no overdraw).
    let original = rows.first().map_or(1.0, |r| r.ovr);
    let share = |ovr: f64| (original > 1.0).then(|| (original - ovr) / (original - 1.0));
    if json {
        let out: Vec<_> = rows
            .iter()
            .map(|r| json!({"method": r.method, "patches": r.patches.to_string(), "lambda": match r.patches { Patches::Linear { lambda } => Some(lambda), Patches::Compact { .. } => None }, "buffers": r.buffers, "acmr": r.acmr, "ovr": r.ovr, "share_to_no_overdraw": share(r.ovr), "preprocess_s": r.preprocess_s}))
            .collect();
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let keys: usize = frames.iter().map(|f| f.len()).sum();
    println!(
        "{file}: {} triangles, {} clips, {keys} keyframes, {views} random views per clip at 3x the bounding radius",
        prepared.mesh.triangles.len(),
        clips.len()
    );
    println!("  patches: {}", params.patches);
    println!("  {:<18} {:>8} {:>7} {:>7} {:>7} {:>13}", "method", "buffers", "ACMR", "OVR", "share", "preprocess s");
    for r in &rows {
        let share = share(r.ovr).map_or("-".to_string(), |x| format!("{:.0}%", 100.0 * x));
        println!(
            "  {:<18} {:>8} {:>7.3} {:>7.3} {share:>7} {:>13.2}",
            r.method, r.buffers, r.acmr, r.ovr, r.preprocess_s
        );
    }
    println!(
        "  (ACMR: FIFO cache of 16; OVR: shaded fragments per visible pixel, 1 = no overdraw; share: of the way from the original OVR to 1; single: per clip)"
    );
    Ok(())
}
