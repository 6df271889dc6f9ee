//! `skinlet crowd`: the paper's crowd scene (fig. 10) on the CPU, with table 1's columns.

use crate::{RefineArgs, bake::bake_asset};
use anyhow::Result;
use serde_json::{Value, json};
use skinlet::clip::Clip;
use skinlet::cull::crowd::{CrowdParams, CrowdStats, WHOLE_MESH_BOUNDS, crowd, run};
use skinlet::meshlet::Builder;

pub fn to_json(s: &CrowdStats) -> Value {
    let loose = s.looseness();
    json!({
        "instances": s.instances, "frames": s.frames, "meshlets": s.meshlets,
        "culled_backface_only_pct": s.backface_only_pct(), "culled_frustum_only_pct": s.frustum_only_pct(),
        "culled_both_pct": s.both_pct(), "triangles_saved_pct": s.triangles_saved_pct(),
        "skinning_saved_pct": s.skinning_saved_pct(), "whole_mesh_culled_pct": s.whole_mesh_pct(),
        "ns_per_meshlet": s.ns_per_meshlet(),
        "whole_mesh_looseness": WHOLE_MESH_BOUNDS.iter().zip(loose).map(|(n, l)| json!({"bound": n, "volume_ratio": l})).collect::<Vec<_>>(),
        "checked_triangles": s.checked_triangles, "false_culls": s.false_culls,
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
        "  with both + per-triangle culling: {:.1}% of triangles and {:.1}% of vertex skinning saved",
        s.triangles_saved_pct(),
        s.skinning_saved_pct()
    );
    println!(
        "  whole-mesh culling by per-joint boxes alone: {:.1}% of meshlets; meshlet culling: {:.2} ns per meshlet",
        s.whole_mesh_pct(),
        s.ns_per_meshlet()
    );
    let loose: Vec<String> = WHOLE_MESH_BOUNDS.iter().zip(s.looseness()).map(|(n, l)| format!("{n} {l:.2}")).collect();
    println!("  whole-mesh bound volume / exact box: {}", loose.join(", "));
    if verify {
        println!(
            "  brute force: {} culled triangles checked, {} visible after all",
            s.checked_triangles, s.false_culls
        );
    }
}

#[allow(clippy::too_many_arguments)]
pub fn command(
    file: &str,
    instances: usize,
    frames: usize,
    seed: u64,
    orthographic: bool,
    verify: bool,
    args: RefineArgs,
    json: bool,
) -> Result<()> {
    anyhow::ensure!(instances >= 1 && frames >= 1, "--instances and --frames must be at least 1");
    let (asset, skin) = crate::load_skinned(file)?;
    let (baked, _) = bake_asset(&asset, skin, None, Builder::SkinAware, args, json)?;
    let params = CrowdParams { instances, frames, seed, orthographic, ..CrowdParams::default() };
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let scene = crowd(&baked.mesh.positions, clips.len(), &params);
    let s = run(&baked, &asset.skeleton, &asset.skins[skin as usize], &clips, &scene, &params, verify)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&to_json(&s))?);
    } else {
        println!("{file}: crowd scene ({} camera)", if orthographic { "orthographic" } else { "perspective" });
        print(&s, verify);
    }
    if s.false_culls > 0 {
        std::process::exit(1);
    }
    Ok(())
}
