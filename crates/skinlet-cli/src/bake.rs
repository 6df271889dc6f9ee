//! `skinlet bake`: the baker's front end (progress bar, summary table or JSON).

use crate::{RefineArgs, select_clips, stop_name};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use skinlet::bake::{BakeStats, Baked, bake};
use skinlet::bounds::refine::Progress;
use skinlet::bounds::sphere_cone::Class;
use skinlet::clip::Clip;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::{Asset, Character};
use std::path::Path;

/// Share of meshlets in each class, in percent: (both, frustum only, none).
pub fn class_shares(b: &Baked) -> (f64, f64, f64) {
    shares(&b.classes)
}

fn shares(classes: &[Class]) -> (f64, f64, f64) {
    let pct = |c: Class| 100.0 * classes.iter().filter(|&&x| x == c).count() as f64 / classes.len().max(1) as f64;
    (pct(Class::Both), pct(Class::FrustumOnly), pct(Class::None))
}

/// The pose envelope `--envelope SPEC` asks for: `clips[:MARGIN_DEG]` (around the baked clips,
/// widened by the margin) or a joint-limits JSON file applied over the clips' envelope.
pub fn envelope_of(spec: &str, asset: &Asset, baked: &Baked) -> Result<skinlet::bounds::envelope::Envelope> {
    use skinlet::bounds::envelope::Envelope;
    let clips = clips_of(baked, asset, "the source")?;
    let from_clips = |margin_deg: f64| {
        Envelope::from_clips(&asset.skeleton, &baked.palette(), &baked.mesh, &clips, margin_deg.to_radians())
    };
    if let Some(rest) = spec.strip_prefix("clips") {
        let margin = match rest.strip_prefix(':') {
            Some(m) => m
                .parse::<f64>()
                .ok()
                .filter(|m| (0.0..=180.0).contains(m))
                .with_context(|| format!("--envelope {spec}: the margin must be degrees from 0 to 180"))?,
            None if rest.is_empty() => 0.0,
            None => anyhow::bail!("--envelope {spec}: expected clips, clips:MARGIN_DEG or a .json file"),
        };
        return Ok(from_clips(margin)?);
    }
    let text = std::fs::read_to_string(spec)
        .with_context(|| format!("--envelope {spec}: cannot read the joint-limits file"))?;
    from_clips(0.0)?.with_limits(&asset.skeleton, &text).with_context(|| format!("--envelope {spec}"))
}

/// The clips `baked`'s bounds hold for, found by name in `asset` (loaded from `file`).
pub fn clips_of<'a>(baked: &Baked, asset: &'a Asset, file: &str) -> Result<Vec<&'a Clip>> {
    baked
        .settings
        .clips
        .iter()
        .map(|n| asset.clips.iter().find(|c| &c.name == n).with_context(|| format!("{file} has no clip {n:?}")))
        .collect()
}

/// Errors unless the bake at `path` was made from `character` (loaded from `file`): same
/// welded vertices, drivers (nodes and inverse bind matrices) and parts.
pub fn check_source(baked: &Baked, character: &Character, file: &str, path: &Path) -> Result<()> {
    let prepared = skinlet::bake::prepare_character(character)?;
    let same_parts = baked.parts.len() == character.parts.len()
        && baked
            .parts
            .iter()
            .zip(&character.parts)
            .all(|(b, c)| (b.node, b.mesh, b.primitive) == (c.node, c.mesh, c.primitive));
    anyhow::ensure!(
        prepared.mesh == baked.mesh
            && character.palette.joints == baked.joint_nodes
            && character.palette.inverse_bind == baked.inverse_bind
            && same_parts,
        "{} was not baked from {file} (its vertices, drivers or parts differ)",
        path.display()
    );
    Ok(())
}

/// Bakes the whole `character` of `asset` with a progress bar on stderr (hidden when stderr
/// is not a terminal or `quiet`).
pub fn bake_asset(
    asset: &Asset,
    character: &Character,
    clips: Option<&str>,
    builder: Builder,
    args: RefineArgs,
    quiet: bool,
) -> Result<(Baked, BakeStats)> {
    let how = args.refinement()?;
    let clips = select_clips(asset, clips)?;
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    match how.budget {
        Some(budget) => {
            bar.set_length(budget.as_millis() as u64);
            bar.set_style(ProgressStyle::with_template("{msg} [{bar:30}] {elapsed}/budget").expect("valid template"));
        }
        None => bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template")),
    }
    bar.set_message("bounds over key intervals");
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let mut progress = |p: Progress| {
        bar.set_position(p.elapsed.as_millis() as u64);
        bar.set_message(format!("refining: round {}, {} meshlets still improving", p.rounds, p.active));
    };
    let out = bake(asset, character, &clips, builder, MeshletLimits::NVIDIA, &how, &mut progress)?;
    bar.finish_and_clear();
    Ok(out)
}

/// The optional sections `skinlet bake` adds.
pub struct Extras<'a> {
    pub overdraw: bool,
    pub contours: Option<&'a str>,
    pub envelope: Option<&'a str>,
    pub lod: bool,
}

pub fn run(
    file: &str,
    out: &Path,
    builder: &str,
    clips: Option<&str>,
    args: RefineArgs,
    extras: Extras,
    json: bool,
) -> Result<()> {
    let Extras { overdraw, contours, envelope, lod } = extras;
    let builder = Builder::from_name(builder).context("unknown builder")?;
    let (asset, character) = crate::load_character(file)?;
    let (mut baked, stats) = bake_asset(&asset, &character, clips, builder, args, json)?;
    let overdraw_s = if overdraw {
        let started = std::time::Instant::now();
        skinlet::bake::add_overdraw(&mut baked, &asset, &skinlet::overdraw::cluster::ClusterParams::default(), 16)?;
        Some(started.elapsed().as_secs_f64())
    } else {
        None
    };
    let contours_s = if let Some(which) = contours {
        let started = std::time::Instant::now();
        let r = args.refinement()?;
        let how = skinlet::contour::skinned::refinement(r.budget, r.max_rounds);
        let params =
            skinlet::contour::skinned::SkinnedParams::new(skinlet::contour::skinned::SkinnedMethod::Animated, how);
        skinlet::bake::add_contours(&mut baked, &asset, &params, which == "visible")?;
        Some(started.elapsed().as_secs_f64())
    } else {
        None
    };
    let envelope_s = if let Some(spec) = envelope {
        let started = std::time::Instant::now();
        let env = envelope_of(spec, &asset, &baked)?;
        skinlet::bake::add_envelope(&mut baked, &asset, env)?;
        Some(started.elapsed().as_secs_f64())
    } else {
        None
    };
    let lod_s = if lod {
        let started = std::time::Instant::now();
        skinlet::bake::add_lod(&mut baked, &asset, &skinlet::meshlet::lod::LodParams::default())?;
        Some(started.elapsed().as_secs_f64())
    } else {
        None
    };
    skinlet::bake::write(out, &baked)?;
    let bytes = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    let envelope_shares = baked.envelope.as_ref().map(|e| shares(&e.classes));
    let (both, frustum, none) = class_shares(&baked);
    let s = &baked.settings;
    let precompute_s = stats.precompute.as_secs_f64();
    if json {
        let summary = json!({
            "output": out.display().to_string(), "bytes": bytes, "builder": builder.name(),
            "meshlets": baked.meshlets.len(), "vertices": baked.mesh.positions.len(),
            "triangles": character.triangle_count(), "baked_triangles": baked.mesh.triangles.len(),
            "parts": baked.parts.len(), "skinned_parts": baked.parts.iter().filter(|p| p.kind != skinlet::PartKind::Rigid).count(),
            "drivers": baked.joint_nodes.len(),
            "clips": s.clips, "sr": s.s_r, "alpha_deg": s.alpha_t.to_degrees(),
            "both_pct": both, "frustum_only_pct": frustum, "none_pct": none,
            "precompute_s": precompute_s, "rounds": s.rounds, "stop": stop_name(s.stop),
            "vertex_influence_intervals": stats.work,
            "overdraw_buffers": baked.overdraw.as_ref().map(|o| o.buffers.len()), "overdraw_s": overdraw_s,
            "contour_patches": baked.contours.as_ref().map(|c| c.patches.patches.len()), "contours_s": contours_s,
            "envelope_nodes": baked.envelope.as_ref().map(|e| e.envelope.nodes.len()), "envelope_s": envelope_s,
            "envelope_both_pct": envelope_shares.map(|s| s.0), "envelope_frustum_only_pct": envelope_shares.map(|s| s.1),
            "envelope_none_pct": envelope_shares.map(|s| s.2),
            "any_pose_boxes": baked.envelope.as_ref().map(|e| e.any_pose.joints.len()),
            "lod_groups": baked.lod.as_ref().map(|l| l.groups.len()),
            "lod_clusters": baked.lod.as_ref().map(|l| l.clusters.len()),
            "lod_levels": baked.lod.as_ref().map(|l| l.groups.iter().map(|g| g.0).max().unwrap_or(0)),
            "lod_s": lod_s,
        });
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    println!("{} -> {} ({bytes} bytes)", file, out.display());
    let skinned = baked.parts.iter().filter(|p| p.kind != skinlet::PartKind::Rigid).count();
    println!(
        "  {} parts ({skinned} skinned, {} rigid) over {} drivers; {} triangles drawn",
        baked.parts.len(),
        baked.parts.len() - skinned,
        baked.joint_nodes.len(),
        character.triangle_count()
    );
    println!(
        "  {} {} meshlets over {} vertices, {} triangles; bounds over {} clips",
        baked.meshlets.len(),
        builder.name(),
        baked.mesh.positions.len(),
        baked.mesh.triangles.len(),
        s.clips.len()
    );
    let dropped = character.triangle_count() - baked.mesh.triangles.len();
    if dropped > 0 {
        println!("  {dropped} triangles repeat a vertex after welding and draw nothing: not stored");
    }
    println!(
        "  classes at s_r {} and {:.0}°: {both:.1}% both, {frustum:.1}% frustum only, {none:.1}% none",
        s.s_r,
        s.alpha_t.to_degrees()
    );
    println!(
        "  precomputation {precompute_s:.2} s: {} refinement rounds ({}), {:.2e} vertex-influence-intervals",
        s.rounds,
        stop_name(s.stop),
        stats.work as f64
    );
    if let (Some(c), Some(secs)) = (&baked.contours, contours_s) {
        let p = &c.patches;
        println!(
            "  {} contour patches ({} rigid + {} animated quads of {}; the rest tested every frame) ({secs:.1} s)",
            p.patches.len(),
            p.rigid_quads,
            p.animated_quads,
            p.patches.order.len()
        );
    }
    if let (Some(l), Some(secs)) = (&baked.lod, lod_s) {
        let levels = l.groups.iter().map(|g| g.0).max().unwrap_or(0);
        let triangles: usize = l.meshlets.meshlets.iter().map(|m| m.triangle_count as usize).sum();
        println!(
            "  cluster LOD: {} groups over {levels} levels, {} clusters above the meshlets ({triangles} triangles) ({secs:.1} s)",
            l.groups.len(),
            l.clusters.len()
        );
    }
    if let (Some(o), Some(secs)) = (&baked.overdraw, overdraw_s) {
        println!(
            "  {} overdraw-reducing index buffers over {} keyframes, lookup {} x {} per keyframe ({secs:.1} s)",
            o.buffers.len(),
            o.keyframes.len(),
            o.lookup.polar,
            o.lookup.azimuth
        );
    }
    if let (Some(e), Some(secs), Some((both, frustum, none))) = (&baked.envelope, envelope_s, envelope_shares) {
        let widest = e.envelope.nodes.iter().map(|r| r.angle).fold(0.0f32, f32::max).to_degrees();
        println!(
            "  pose envelope over {} nodes (widest cap {widest:.0}°): {both:.1}% both, {frustum:.1}% frustum only, \
             {none:.1}% none; {:.1} any-pose boxes per meshlet ({secs:.1} s)",
            e.envelope.nodes.len(),
            e.any_pose.joints.len() as f64 / baked.meshlets.len().max(1) as f64
        );
    }
    if s.stop == skinlet::bounds::refine::Stop::Budget {
        println!("  the budget ran out: pass --rounds {} to reproduce these bytes on any machine", s.rounds);
    }
    Ok(())
}
