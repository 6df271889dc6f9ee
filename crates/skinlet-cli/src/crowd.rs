//! `skinlet cull --scene crowd`: the paper's crowd scene (fig. 10) on the CPU, with table
//! 1's columns.

use crate::{RefineArgs, bake::bake_asset};
use anyhow::{Context, Result};
use serde_json::{Value, json};
use skinlet::clip::Clip;
use skinlet::meshlet::Builder;
use skinlet_lab::crowd::{CULLING_METHODS, CrowdParams, CrowdStats, WHOLE_MESH_BOUNDS, posed_crowd, run};

/// The report: `meshlets_total` over all instances and frames; the three pipelines'
/// culled shares (backface test only, frustum test only, both: `culled_total_pct`); what
/// the backface test alone saves (`culled_backface_triangles_pct`,
/// `culled_backface_skinning_pct`) against the per-triangle limit
/// (`backfacing_triangles_pct`); meshlet vertex references per instance-frame without
/// culling and skinned after it (`vertex_refs_per_instance_frame`,
/// `vertex_refs_skinned_per_instance_frame`: absolute, to compare builders);
/// `false_culls` is null unless checked.
pub fn to_json(s: &CrowdStats, checked: bool) -> Value {
    let loose = s.looseness();
    let [refs, skinned] = s.vertex_refs_per_instance_frame();
    json!({
        "instances": s.instances, "frames": s.frames, "meshlets_total": s.meshlets,
        "culled_backface_pct": s.backface_only_pct(), "culled_frustum_pct": s.frustum_only_pct(),
        "culled_total_pct": s.both_pct(), "triangles_saved_pct": s.triangles_saved_pct(),
        "culled_backface_triangles_pct": s.backface_only_triangles_pct(),
        "culled_backface_skinning_pct": s.backface_only_skinning_pct(),
        "backfacing_triangles_pct": s.backfacing_triangles_pct(),
        "skinning_saved_pct": s.skinning_saved_pct(), "mesh_aabb_culled_pct": s.whole_mesh_pct(),
        "vertex_refs_per_instance_frame": refs, "vertex_refs_skinned_per_instance_frame": skinned,
        "ns_per_meshlet": s.ns_per_meshlet(),
        "whole_mesh_looseness": WHOLE_MESH_BOUNDS.iter().zip(loose).map(|(n, l)| json!({"bound": n, "diagonal_ratio": l})).collect::<Vec<_>>(),
        "checked_triangles": s.checked_triangles,
        "false_culls": if checked { json!(s.false_culls) } else { Value::Null },
        "envelope_frames": s.envelope_frames, "any_pose_frames": s.any_pose_frames,
        "unculled_frames": s.unculled_frames, "guard_fallback_pct": s.guard_fallback_pct(),
        "bounds_alone": CULLING_METHODS.iter().zip(&s.methods).map(|(n, m)| json!({
            "bound": n, "instance_frames": m.meshlets / (s.meshlets / (s.instances * s.frames).max(1)).max(1),
            "culled_pct": m.culled_pct(), "ns_per_meshlet": m.ns_per_meshlet()})).collect::<Vec<_>>(),
        "guard_ns_per_instance": s.guard_time.as_secs_f64() * 1e9 / (s.instances * s.frames).max(1) as f64,
        "joint_matrices_ns_per_instance": s.matrices_time.as_secs_f64() * 1e9 / (s.instances * s.frames).max(1) as f64,
    })
}

pub fn print(s: &CrowdStats, verify: bool) {
    println!("  {} instances x {} frames, {} meshlets drawn without culling", s.instances, s.frames, s.meshlets);
    println!(
        "  meshlets culled: backface only {:.1}%, frustum only {:.1}%, both {:.1}%  (paper's table 1 columns)",
        s.backface_only_pct(),
        s.frustum_only_pct(),
        s.both_pct()
    );
    println!(
        "  backface test alone: {:.1}% of triangles and {:.1}% of vertex skinning in culled meshlets \
         ({:.1}% of triangles face away one by one)",
        s.backface_only_triangles_pct(),
        s.backface_only_skinning_pct(),
        s.backfacing_triangles_pct()
    );
    println!(
        "  with both + per-triangle culling: {:.1}% of triangles and {:.1}% of vertex skinning saved",
        s.triangles_saved_pct(),
        s.skinning_saved_pct()
    );
    let [refs, skinned] = s.vertex_refs_per_instance_frame();
    println!("  meshlet vertex references skinned per instance-frame: {skinned:.0} of {refs:.0}");
    println!(
        "  whole-mesh culling by per-joint boxes alone: {:.1}% of meshlets; meshlet culling: {:.2} ns per meshlet",
        s.whole_mesh_pct(),
        s.ns_per_meshlet()
    );
    let loose: Vec<String> = WHOLE_MESH_BOUNDS.iter().zip(s.looseness()).map(|(n, l)| format!("{n} {l:.2}")).collect();
    println!("  whole-mesh bound diagonal / exact box diagonal: {}", loose.join(", "));
    if s.envelope_frames + s.any_pose_frames + s.unculled_frames > 0 {
        println!(
            "  guard: {} instance-frames inside the pose envelope, {} outside (any-pose boxes), {} not culled \
             (morph weights outside): {:.1}% fell back",
            s.envelope_frames,
            s.any_pose_frames,
            s.unculled_frames,
            s.guard_fallback_pct()
        );
    }
    let frames = (s.instances * s.frames).max(1) as f64;
    for (name, m) in CULLING_METHODS.iter().zip(&s.methods) {
        if let (Some(pct), Some(ns)) = (m.culled_pct(), m.ns_per_meshlet()) {
            println!("  {name} alone, where they hold: {pct:.1}% of meshlets culled, {ns:.2} ns per meshlet");
        }
    }
    println!(
        "  per instance: pose guard {:.0} ns, joint matrices from the pose {:.0} ns",
        s.guard_time.as_secs_f64() * 1e9 / frames,
        s.matrices_time.as_secs_f64() * 1e9 / frames
    );
    if verify {
        println!(
            "  brute force: {} culled triangles checked, {} visible after all",
            s.checked_triangles, s.false_culls
        );
    }
}

/// The asset, its character and the character's bake for `file`: a bake (with `gltf`, the
/// file it was baked from) or a glTF file, baked first.
pub fn load(
    file: &str,
    gltf: Option<&str>,
    builder: Option<Builder>,
    args: RefineArgs,
    json: bool,
) -> Result<(skinlet::Asset, skinlet::Character, skinlet::bake::Baked)> {
    let is_bake = std::fs::File::open(file)
        .and_then(|mut f| {
            let mut magic = [0u8; 8];
            std::io::Read::read_exact(&mut f, &mut magic).map(|_| &magic == b"SKINLET\0")
        })
        .unwrap_or(false);
    if is_bake {
        let gltf =
            gltf.with_context(|| format!("{file} is a bake: name the glTF file it was baked from with --gltf"))?;
        let (asset, character) = crate::load_character(gltf)?;
        let baked = skinlet::bake::read(std::path::Path::new(file))?;
        crate::bake::check_source(&baked, &character, gltf, std::path::Path::new(file))?;
        if let Some(b) = builder.filter(|&b| b != baked.settings.builder) {
            anyhow::bail!(
                "{file} was baked with the {} builder, not {}: rebake it, or cull the glTF file with --builder",
                baked.settings.builder.name(),
                b.name()
            );
        }
        Ok((asset, character, baked))
    } else {
        anyhow::ensure!(gltf.is_none(), "--gltf goes with a bake file; {file} is not one");
        let (asset, character) = crate::load_character(file)?;
        let (baked, _) = bake_asset(&asset, &character, None, builder.unwrap_or(Builder::SkinAware), args, json)?;
        Ok((asset, character, baked))
    }
}

/// Runs the crowd for `file`: a bake (with `gltf`, the file it was baked from) or a glTF
/// file, baked first (with `builder`, skin-aware by default).
#[allow(clippy::too_many_arguments)]
pub fn command(
    file: &str,
    gltf: Option<&str>,
    builder: Option<&str>,
    params: &CrowdParams,
    check: bool,
    additive_deg: f32,
    args: RefineArgs,
    json: bool,
) -> Result<()> {
    anyhow::ensure!(params.instances >= 1 && params.frames >= 1, "--instances and --frames must be at least 1");
    anyhow::ensure!((0.0..=180.0).contains(&additive_deg), "--additive-deg must be from 0 to 180");
    let builder = builder.map(|b| Builder::from_name(b).context("unknown meshlet builder")).transpose()?;
    let (asset, _, mut baked) = load(file, gltf, builder, args, json)?;
    if params.animation != skinlet_lab::crowd::Animation::Clips && baked.envelope.is_none() {
        anyhow::ensure!(
            gltf.is_none(),
            "--animation {} needs a pose envelope: bake {file} with --envelope",
            params.animation.name()
        );
        let env = crate::bake::envelope_of(&format!("clips:{additive_deg}"), &asset, &baked)?;
        skinlet::bake::add_envelope(&mut baked, &asset, env)?;
    }
    let clips: Vec<&Clip> = crate::bake::clips_of(&baked, &asset, gltf.unwrap_or(file))?;
    let palette = baked.palette();
    let scene = posed_crowd(&asset.skeleton, &palette, &baked.mesh, &clips, params)?;
    let s = run(&baked, &asset.skeleton, &palette, &clips, &scene, params, check)?;
    let meshlets = baked.meshlets.len();
    let both = baked.classes.iter().filter(|&&c| c == skinlet::bounds::sphere_cone::Class::Both).count();
    let both_pct = 100.0 * both as f64 / meshlets.max(1) as f64;
    if json {
        let mut report = to_json(&s, check);
        report["builder"] = json!(baked.settings.builder.name());
        report["meshlets"] = json!(meshlets);
        report["class_both_pct"] = json!(both_pct);
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let camera = if params.orthographic { "orthographic" } else { "perspective" };
        println!("{file}: crowd scene ({camera} camera, {} animation)", params.animation.name());
        println!(
            "  {meshlets} meshlets ({} builder), {both_pct:.0}% of them frustum- and backface-cullable",
            baked.settings.builder.name()
        );
        print(&s, check);
    }
    if s.false_culls > 0 {
        std::process::exit(1);
    }
    Ok(())
}
