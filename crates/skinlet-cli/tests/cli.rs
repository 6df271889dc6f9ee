//! End-to-end tests of the `skinlet` binary. `inspect --json` is checked against the facts
//! that ../shared/assets/SOURCES.md records for every skinned asset (measured there by an
//! independent script), and `pose --json` against the library's reference skinning.

#[path = "../../skinlet/tests/common/mod.rs"]
mod common;
use common::assets_dir;

use serde_json::Value;
use std::process::Command;

fn skinlet(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_skinlet")).args(args).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn json_of(args: &[&str]) -> Value {
    let (code, out, err) = skinlet(args);
    assert_eq!(code, 0, "skinlet {args:?} failed: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("skinlet {args:?}: bad JSON ({e}): {out}"))
}

fn num(s: &str) -> f64 {
    s.trim().replace(',', "").parse().unwrap_or_else(|_| panic!("not a number: {s:?}"))
}

/// Facts of one file as SOURCES.md states them.
#[derive(Debug, Default)]
struct Facts {
    triangles: f64,
    joints: f64,
    clip_count: f64,
    vertices: f64,
    histogram: Vec<(usize, f64)>,
    /// name, start, duration, channels T/R/S/W, max keys
    clips: Vec<(String, f64, f64, [f64; 4], f64)>,
}

fn parse_sources(text: &str, file: &str) -> Facts {
    let mut f = Facts::default();
    let row = text.lines().find(|l| l.starts_with(&format!("| skinned/{file} |"))).expect("summary row");
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let first_word = |c: &str| num(c.split_whitespace().next().unwrap_or(""));
    (f.triangles, f.joints, f.clip_count) = (num(cells[2]), num(cells[3]), first_word(cells[4]));
    let section = text.split(&format!("### skinned/{file}\n")).nth(1).expect("section").split("\n### ").next().unwrap();
    for line in section.lines() {
        if let Some(g) = line.strip_prefix("- Geometry:") {
            let stored = g.split(';').nth(1).unwrap();
            f.vertices = num(stored.split("vertices").next().unwrap());
        }
        if let Some(h) = line.split('→').nth(1) {
            for part in h.split(';').next().unwrap().split(',') {
                let (k, n) = part.trim().split_once(':').unwrap();
                f.histogram.push((k.parse().unwrap(), num(n)));
            }
        }
        let c: Vec<&str> = line.split('|').map(str::trim).collect();
        if c.len() == 8 && c[0].is_empty() && c[2].contains('–') {
            let start = num(c[2].split('–').next().unwrap());
            let trsw: Vec<f64> = c[4].split('(').nth(1).unwrap().trim_end_matches(')').split('/').map(num).collect();
            let name = if c[1] == "(unnamed)" { String::new() } else { c[1].to_string() };
            f.clips.push((name, start, num(c[3]), [trsw[0], trsw[1], trsw[2], trsw[3]], num(c[6])));
        }
    }
    f
}

#[test]
fn inspect_json_matches_sources_md() {
    let Some(dir) = assets_dir() else { return };
    let sources = std::fs::read_to_string(dir.join("SOURCES.md")).unwrap();
    let mut files: Vec<String> = std::fs::read_dir(dir.join("skinned"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert!(files.len() >= 8);
    for file in files {
        let facts = parse_sources(&sources, &file);
        let path = dir.join("skinned").join(&file);
        let j = json_of(&["inspect", path.to_str().unwrap(), "--json"]);
        let ctx = |what: &str| format!("{file}: {what}");
        assert_eq!(j["triangles"].as_f64().unwrap(), facts.triangles, "{}", ctx("triangles"));
        assert_eq!(j["vertices"].as_f64().unwrap(), facts.vertices, "{}", ctx("vertices"));
        assert_eq!(j["joints"].as_f64().unwrap(), facts.joints, "{}", ctx("joints"));
        let clips = j["clips"].as_array().unwrap();
        assert_eq!(clips.len() as f64, facts.clip_count, "{}", ctx("clip count"));
        assert_eq!(clips.len(), facts.clips.len(), "{}", ctx("clip table rows"));
        for (c, (name, start, duration, trsw, max_keys)) in clips.iter().zip(&facts.clips) {
            assert_eq!(c["name"].as_str().unwrap(), name, "{}", ctx("clip name"));
            assert!((c["start"].as_f64().unwrap() - start).abs() < 1e-4, "{}", ctx("clip start"));
            assert!((c["duration"].as_f64().unwrap() - duration).abs() < 1e-4, "{}", ctx("clip duration"));
            let ch = &c["channels"];
            let got = ["translation", "rotation", "scale", "weights"].map(|k| ch[k].as_f64().unwrap());
            assert_eq!(&got, trsw, "{}", ctx("channels"));
            assert_eq!(c["max_channel_keys"].as_f64().unwrap(), *max_keys, "{}", ctx("max keys"));
            assert!(c["keys"].as_u64().unwrap() as f64 >= *max_keys, "{}", ctx("keys"));
            assert_eq!(c["interpolation"], serde_json::json!(["LINEAR"]), "{}", ctx("interpolation"));
        }
        let hist = j["influence_histogram"].as_array().unwrap();
        for (k, n) in &facts.histogram {
            assert_eq!(hist[k - 1].as_f64().unwrap(), *n, "{}", ctx(&format!("vertices with {k} influences")));
        }
        let total: f64 = facts.histogram.iter().map(|h| h.1).sum();
        assert_eq!(hist.iter().map(|h| h.as_f64().unwrap()).sum::<f64>(), total, "{}", ctx("histogram total"));
    }
}

#[test]
fn inspect_reads_static_obj() {
    let Some(dir) = assets_dir() else { return };
    let j = json_of(&["inspect", dir.join("static/spot.obj").to_str().unwrap(), "--json"]);
    assert_eq!(j["triangles"], 5856);
    assert_eq!(j["vertices"], 2930);
    assert_eq!(j["joints"], 0);
}

#[test]
fn pose_json_matches_library_skinning() {
    let Some(dir) = assets_dir() else { return };
    let path = dir.join("skinned/CesiumMan.glb");
    let j = json_of(&["pose", path.to_str().unwrap(), "--time", "1.0", "--json"]);
    let asset = skinlet::import::load(&path).unwrap();
    let prims = j["primitives"].as_array().unwrap();
    assert_eq!(prims.len(), 1);
    let p = &prims[0];
    let inst = asset.instances[0];
    assert_eq!(
        (p["node"].as_u64().unwrap(), p["mesh"].as_u64().unwrap(), p["primitive"].as_u64().unwrap()),
        (inst.node as u64, 0, 0)
    );
    let g = &asset.meshes[0].primitives[0].geometry;
    let mut mats = Vec::new();
    skinlet::pose::Poser::default().skinning_matrices(
        &asset.skeleton,
        &asset.skins[0],
        asset.clips.first(),
        1.0,
        &mut mats,
    );
    let mut out = vec![glam::Vec3::ZERO; g.positions.len()];
    skinlet::skinning::skin(g.influences.as_ref().unwrap(), &g.positions, &[], &mats, &mut out, &mut []).unwrap();
    let pos = p["positions"].as_array().unwrap();
    assert_eq!(pos.len(), 3273);
    assert_eq!(p["normals"].as_array().unwrap().len(), 3273);
    for (a, b) in pos.iter().zip(&out) {
        let a: Vec<f32> = a.as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect();
        assert_eq!(a, b.to_array().to_vec(), "JSON must round-trip f32 exactly");
    }
    // Fox has no normals: they are null, not invented.
    let fox =
        json_of(&["pose", dir.join("skinned/Fox.glb").to_str().unwrap(), "--clip", "Run", "--time", "0.3", "--json"]);
    assert!(fox["primitives"][0]["normals"].is_null());
    assert_eq!(fox["primitives"][0]["positions"].as_array().unwrap().len(), 1728);
}

#[test]
fn errors_are_messages_not_panics() {
    let (code, _, err) = skinlet(&["inspect", "/nonexistent/file.glb"]);
    assert_eq!(code, 2);
    assert!(err.contains("cannot read /nonexistent/file.glb"), "{err}");
    let Some(dir) = assets_dir() else { return };
    let (code, _, err) =
        skinlet(&["pose", dir.join("skinned/Fox.glb").to_str().unwrap(), "--clip", "Fly", "--time", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("no clip \"Fly\"") && err.contains("\"Survey\""), "{err}");
}

#[test]
fn demo_runs_and_describes_the_character() {
    let j = json_of(&["demo", "--triangles", "3000", "--json"]);
    assert!(j["joints"].as_u64().unwrap() >= 30);
    let tris = j["triangles"].as_f64().unwrap();
    assert!((tris - 3000.0).abs() <= 300.0, "{tris}");
    let modes: Vec<String> = j["clips"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|c| c["interpolation"].as_array().unwrap().iter().map(|m| m.as_str().unwrap().to_string()))
        .collect();
    for m in ["STEP", "LINEAR", "CUBICSPLINE"] {
        assert!(modes.iter().any(|x| x == m), "demo lacks a {m} clip");
    }
    for crowd in ["crowd", "ik_crowd"] {
        assert_eq!(j[crowd]["false_culls"], 0, "{crowd}: {}", j[crowd]);
        assert!(j[crowd]["checked_triangles"].as_u64().unwrap() > 0, "{crowd}: {}", j[crowd]);
    }
    assert!(j["ik_crowd"]["guard_fallback_pct"].as_f64().unwrap() > 0.0, "{}", j["ik_crowd"]);
    let (code, out, _) = skinlet(&["demo", "--triangles", "2000"]);
    assert_eq!(code, 0);
    assert!(out.contains("joints") && out.contains("walk"), "{out}");
    let j = json_of(&["inspect", "@demo:2000", "--json"]);
    assert!(j["joints"].as_u64().unwrap() >= 30);
}

#[test]
fn meshlets_json_has_one_row_per_builder() {
    let rows = json_of(&["meshlets", "@demo:3000", "--json"]);
    let rows = rows.as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["builder"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["scan", "common-influences", "meshopt", "skin-aware", "cone-split", "meshopt-flex", "meshopt-spatial"]
    );
    for r in rows {
        for field in [
            "meshlets",
            "avg_vertices",
            "avg_triangles",
            "vertex_refs_ratio",
            "single_joint_set_pct",
            "dominant_joint_pct",
            "bytes",
            "build_ms",
        ] {
            assert!(r[field].as_f64().is_some_and(|x| x >= 0.0), "{field} missing in {r}");
        }
        let avg_t = r["avg_triangles"].as_f64().unwrap();
        let total = r["meshlets"].as_f64().unwrap() * avg_t;
        assert!((total - 3000.0).abs() < 300.0, "meshlets hold {total} triangles");
        assert!(r["avg_vertices"].as_f64().unwrap() <= 64.0 && avg_t <= 124.0);
    }
    let one = json_of(&[
        "meshlets",
        "@demo:3000",
        "--builder",
        "skin-aware",
        "--max-vertices",
        "128",
        "--max-triangles",
        "126",
        "--json",
    ]);
    assert_eq!(one.as_array().unwrap().len(), 1);
    let (code, _, err) = skinlet(&["meshlets", "@demo:3000", "--max-vertices", "1000"]);
    assert_eq!(code, 2);
    assert!(err.contains("3..=256"), "{err}");
}

#[test]
fn verify_and_bounds_report_in_json() {
    let Some(dir) = assets_dir() else { return };
    let file = dir.join("skinned/RiggedSimple.glb");
    let v = json_of(&["verify", file.to_str().unwrap(), "--samples", "100", "--json"]);
    assert_eq!(v["violations"], 0, "{v}");
    assert!(v["vertex_checks"].as_u64().unwrap() > 100 * 96 && v["normal_checks"].as_u64().unwrap() > 0);
    assert!(v["mean_radius_ratio"].as_f64().unwrap() >= 1.0 - 1e-5);
    let b = json_of(&["bounds", file.to_str().unwrap(), "--builder", "skin-aware", "--json"]);
    let row = &b[0];
    let total: f64 = ["both_pct", "frustum_only_pct", "none_pct"].iter().map(|k| row[k].as_f64().unwrap()).sum();
    assert!((total - 100.0).abs() < 1e-9, "{row}");
    assert!(row["precompute_s"].as_f64().unwrap() >= 0.0);
    let views = &row["backface_views"];
    for field in ["meshlets_culled_pct", "triangles_culled_pct", "skinning_saved_pct", "backfacing_triangles_pct"] {
        assert!(views[field].as_f64().is_some_and(|x| (0.0..=100.0).contains(&x)), "{field} missing in {views}");
    }
    assert_eq!(views["views"], 64, "{views}");
    assert!(views["vertex_refs_skinned_per_view"].as_f64().is_some_and(|x| x > 0.0), "{views}");
    let (code, _, err) = skinlet(&["verify", file.to_str().unwrap(), "--clips", "nope"]);
    assert_eq!(code, 2);
    assert!(err.contains("no clip \"nope\""), "{err}");
}

#[test]
fn bake_is_deterministic_verifiable_and_its_errors_are_clear() {
    let dir = std::env::temp_dir().join(format!("skinlet-bake-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (a, b) = (dir.join("a.skinlet"), dir.join("b.skinlet"));
    let bake = |out: &std::path::Path| {
        json_of(&["bake", "@demo:2000", "-o", out.to_str().unwrap(), "--rounds", "20", "--budget", "0", "--json"])
    };
    let summary = bake(&a);
    bake(&b);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "same input and options, different bytes");
    for field in ["meshlets", "both_pct", "frustum_only_pct", "none_pct", "precompute_s"] {
        assert!(summary[field].as_f64().is_some_and(|x| x >= 0.0), "{field} missing in {summary}");
    }
    let total: f64 = ["both_pct", "frustum_only_pct", "none_pct"].iter().map(|k| summary[k].as_f64().unwrap()).sum();
    assert!((total - 100.0).abs() < 1e-9, "{summary}");
    assert_eq!((summary["rounds"].as_u64(), summary["stop"].as_str()), (Some(20), Some("rounds")));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2, "a temporary file was left behind");

    let v = json_of(&["verify", "@demo:2000", "--baked", a.to_str().unwrap(), "--samples", "50", "--json"]);
    assert_eq!(v["violations"], 0, "{v}");
    assert!(v["vertex_checks"].as_u64().unwrap() > 0 && v["normal_checks"].as_u64().unwrap() > 0);

    // Baked from another character: refused, not silently verified.
    let (code, _, err) = skinlet(&["verify", "@demo:3000", "--baked", a.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("was not baked from @demo:3000"), "{err}");
    // A damaged file names the problem.
    let mut bytes = std::fs::read(&a).unwrap();
    bytes.truncate(bytes.len() - 10);
    std::fs::write(&b, &bytes).unwrap();
    let (code, _, err) = skinlet(&["verify", "@demo:2000", "--baked", b.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("b.skinlet") && err.contains("lies outside the file"), "{err}");
    std::fs::write(&b, b"not a bake").unwrap();
    let (code, _, err) = skinlet(&["verify", "@demo:2000", "--baked", b.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("wrong magic"), "{err}");
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", dir.join("no/such/dir/x").to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("cannot write"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cull_reports_table_one_columns_and_never_culls_visible_triangles() {
    let j =
        json_of(&["cull", "@demo:2000", "--layout", "crowd", "--instances", "8", "--frames", "3", "--check", "--json"]);
    for field in [
        "culled_backface_pct",
        "culled_frustum_pct",
        "culled_total_pct",
        "triangles_saved_pct",
        "skinning_saved_pct",
        "mesh_aabb_culled_pct",
        "ns_per_meshlet",
        "culled_backface_triangles_pct",
        "culled_backface_skinning_pct",
        "backfacing_triangles_pct",
        "class_both_pct",
    ] {
        assert!(j[field].as_f64().is_some_and(|x| x >= 0.0), "{field} missing in {j}");
    }
    assert_eq!(j["false_culls"], 0, "{j}");
    assert!(j["checked_triangles"].as_u64().unwrap() > 0);
    let (refs, skinned) = (
        j["vertex_refs_per_instance_frame"].as_f64().unwrap(),
        j["vertex_refs_skinned_per_instance_frame"].as_f64().unwrap(),
    );
    assert!(0.0 < skinned && skinned < refs, "{j}");
    assert_eq!(
        (j["builder"].as_str(), j["meshlets"].as_u64().unwrap() * 8 * 3),
        (Some("skin-aware"), j["meshlets_total"].as_u64().unwrap())
    );
    let split =
        json_of(&["cull", "@demo:2000", "--builder", "cone-split", "--instances", "8", "--frames", "3", "--json"]);
    assert_eq!(split["builder"], "cone-split", "{split}");
    let total = j["culled_total_pct"].as_f64().unwrap();
    assert!(total >= j["culled_frustum_pct"].as_f64().unwrap() && total <= 100.0, "{j}");
    let (code, _, err) = skinlet(&["cull", "@demo:2000", "--instances", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("--instances"), "{err}");

    // From a bake file: the same scene and bounds give the same table.
    let dir = std::env::temp_dir().join(format!("skinlet-cull-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bake = dir.join("demo.skinlet");
    let bake = bake.to_str().unwrap();
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", bake]);
    assert_eq!(code, 0, "{err}");
    let b = json_of(&["cull", bake, "--gltf", "@demo:2000", "--instances", "8", "--frames", "3", "--check", "--json"]);
    for field in ["meshlets_total", "culled_backface_pct", "culled_frustum_pct", "culled_total_pct", "false_culls"] {
        assert_eq!(b[field], j[field], "{field}: bake {b} vs glTF {j}");
    }
    let (code, _, err) = skinlet(&["cull", bake]);
    assert_eq!(code, 2);
    assert!(err.contains("--gltf"), "{err}");
    let (code, _, err) = skinlet(&["cull", bake, "--gltf", "@demo:2000", "--builder", "cone-split"]);
    assert_eq!(code, 2);
    assert!(err.contains("baked with the skin-aware builder, not cone-split"), "{err}");
    let (code, _, err) = skinlet(&["cull", bake, "--gltf", "@demo:3000"]);
    assert_eq!(code, 2);
    assert!(err.contains("was not baked from"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn lod_bakes_and_verifies() {
    let dir = std::env::temp_dir().join(format!("skinlet-lod-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (plain, with) = (dir.join("plain.skinlet"), dir.join("lod.skinlet"));
    let (plain, with) = (plain.to_str().unwrap(), with.to_str().unwrap());
    // Both with a pose envelope: the hierarchy gets errors and bounds within it too (`LODE`).
    let envelope = ["--envelope", "clips:10"];
    let a = json_of(&[&["bake", "@demo:2000", "-o", plain, "--rounds", "0", "--json"][..], &envelope].concat());
    let b = json_of(&[&["bake", "@demo:2000", "-o", with, "--rounds", "0", "--lod", "--json"][..], &envelope].concat());
    assert!(a["lod_groups"].is_null() && b["lod_groups"].as_u64().unwrap() > 0, "{b}");
    assert!(b["lod_clusters"].as_u64().unwrap() > 0 && b["lod_levels"].as_u64().unwrap() >= 2, "{b}");
    let ratio = b["bytes"].as_f64().unwrap() / a["bytes"].as_f64().unwrap();
    assert!(ratio > 1.0 && ratio < 2.0, "the hierarchy makes the bake {ratio}× larger");
    let v = json_of(&["verify", "@demo:2000", "--baked", with, "--samples", "4", "--json"]);
    let l = &v["lod"];
    assert_eq!((l["cluster_violations"].as_u64(), l["error_violations"].as_u64()), (Some(0), Some(0)), "{v}");
    assert!(l["cluster_vertex_checks"].as_u64().unwrap() > 0 && l["error_points"].as_u64().unwrap() > 0, "{v}");
    let e = &l["envelope"];
    assert_eq!((e["cluster_violations"].as_u64(), e["error_violations"].as_u64()), (Some(0), Some(0)), "{v}");
    assert!(e["cluster_vertex_checks"].as_u64().unwrap() > 0 && e["error_points"].as_u64().unwrap() > 0, "{v}");
    // On a crowd: fewer triangles the larger the threshold, never more than full detail,
    // before culling and after (frustum and backface culling on the CPU).
    let crowd = ["--gltf", "@demo:2000", "--crowd", "dense", "--instances", "48", "--frames", "1", "--width", "480"];
    let j = json_of(&[&["lod", with][..], &crowd, &["--pixels", "4,16", "--culled", "--json"]].concat());
    let t = &j["thresholds"];
    let count = |v: &Value, key: &str| v[key].as_u64().unwrap_or_else(|| panic!("no {key} in {v}"));
    let full = count(&t[0], "triangles_full_detail");
    let (fine, coarse) = (count(&t[0], "triangles_lod"), count(&t[1], "triangles_lod"));
    assert_eq!(full, 48 * b["baked_triangles"].as_u64().unwrap(), "{j}");
    assert!(coarse < fine && fine <= full, "{j}");
    let (culled_full, culled_fine) =
        (count(&t[0]["culled"], "triangles_full_detail"), count(&t[0]["culled"], "triangles_lod"));
    let culled_coarse = count(&t[1]["culled"], "triangles_lod");
    assert!(
        culled_full < full && culled_fine < fine && culled_coarse <= culled_fine && culled_fine <= culled_full,
        "{j}"
    );
    // The cuts selected and culled on the GPU (only the two rows asked for): fewer triangles
    // than full detail, both culled, as many as the CPU counts with the same tests for the same
    // still crowd (both conservative, they may differ near the margins), silhouettes within
    // the pixels (and half a pixel's diagonal for rasterization).
    let args = ["--pipelines", "VS", "--lod", "--lod-pixels", "4", "--cullings", "both,both+lod", "--still"];
    let g = json_of(&[&["gpu-bench", with][..], &crowd, &args, &["--repeats", "1", "--json"]].concat());
    let l = &g["lod"];
    let (drawn, full) = (count(l, "triangles_drawn"), count(l, "triangles_full_detail"));
    assert!(drawn < full && l["vertex_refs_drawn"].as_u64() < l["vertex_refs_full_detail"].as_u64(), "{l}");
    for (gpu, cpu) in [(drawn, culled_fine), (full, culled_full)] {
        assert!(gpu.abs_diff(cpu) as f64 <= 0.01 * cpu as f64, "GPU {gpu} and CPU {cpu} triangles: {l} {j}");
    }
    assert!(l["max_silhouette_px"].as_f64().unwrap() <= 4.0 + std::f64::consts::FRAC_1_SQRT_2, "{l}");
    let rows = g["rows"].as_array().unwrap();
    assert_eq!(rows.iter().map(|r| r["culling"].as_str().unwrap()).collect::<Vec<_>>(), ["both", "both+lod"], "{g}");
    assert!(rows[1]["image_equal_to_unculled"].is_null() && rows[1]["triangles_per_frame"].as_u64() == Some(drawn));
    // Crossfades: the instances the guard admits draw the cuts of the errors within the
    // envelope, culled with its bounds there.
    let blend = [&args[..], &["--animation", "blend", "--repeats", "1", "--json"]].concat();
    let g = json_of(&[&["gpu-bench", with][..], &crowd, &blend].concat());
    let l = &g["lod"];
    assert_eq!(g["animation"], "blend", "{g}");
    assert!(count(l, "triangles_drawn") < count(l, "triangles_full_detail"), "{l}");
    assert!(l["max_silhouette_px"].as_f64().unwrap() <= 4.0 + std::f64::consts::FRAC_1_SQRT_2, "{l}");
    // No row left: a clear error.
    let (code, _, err) =
        skinlet(&[&["gpu-bench", with][..], &crowd, &["--pipelines", "CS", "--cullings", "both+lod"]].concat());
    assert!(code != 0 && err.contains("no row to draw"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn envelopes_bake_and_game_poses_cull_with_the_guard() {
    let dir = std::env::temp_dir().join(format!("skinlet-envelope-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (plain, with) = (dir.join("plain.skinlet"), dir.join("envelope.skinlet"));
    let (plain, with) = (plain.to_str().unwrap(), with.to_str().unwrap());
    let j = json_of(&["bake", "@demo:2000", "-o", with, "--envelope", "clips:10", "--json"]);
    assert!(j["envelope_nodes"].as_u64().unwrap() > 0 && j["any_pose_boxes"].as_u64().unwrap() > 0, "{j}");
    let shares: f64 = ["envelope_both_pct", "envelope_frustum_only_pct", "envelope_none_pct"]
        .iter()
        .map(|k| j[k].as_f64().unwrap())
        .sum();
    assert!((shares - 100.0).abs() < 1e-6, "{j}");
    // verify checks the envelope bounds at poses inside the envelope too.
    let v = json_of(&["verify", "@demo:2000", "--baked", with, "--samples", "20", "--json"]);
    assert_eq!(v["envelope"]["violations"], 0, "{v}");
    assert!(v["envelope"]["vertex_checks"].as_u64().unwrap() > 0, "{v}");
    // IK poses: the guard sends some instance-frames to the any-pose boxes; nothing visible
    // is culled. The same from the bake file.
    let args = ["--animation", "ik", "--instances", "8", "--frames", "3", "--check", "--json"];
    let a = json_of(&[&["cull", "@demo:2000"][..], &args].concat());
    let b = json_of(&[&["cull", with, "--gltf", "@demo:2000"][..], &args].concat());
    for r in [&a, &b] {
        assert_eq!(r["false_culls"], 0, "{r}");
        let fallback = r["guard_fallback_pct"].as_f64().unwrap();
        assert!(fallback > 0.0 && fallback < 100.0, "{r}");
        assert_eq!(r["envelope_frames"].as_u64().unwrap() + r["any_pose_frames"].as_u64().unwrap(), 24, "{r}");
    }
    // A bake without an envelope cannot cull game poses; bad specs and limits say why.
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", plain]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = skinlet(&["cull", plain, "--gltf", "@demo:2000", "--animation", "blend"]);
    assert_ne!(code, 0);
    assert!(err.contains("--envelope"), "{err}");
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", plain, "--envelope", "clips:abc"]);
    assert_ne!(code, 0);
    assert!(err.contains("margin"), "{err}");
    let limits = dir.join("limits.json");
    std::fs::write(&limits, r#"{"joints": {"head": {"angle_deg": 30}}}"#).unwrap();
    let j = json_of(&["bake", "@demo:2000", "-o", plain, "--envelope", limits.to_str().unwrap(), "--json"]);
    assert!(j["envelope_nodes"].as_u64().unwrap() > 0, "{j}");
    std::fs::write(&limits, r#"{"joints": {"no such joint": {"angle_deg": 30}}}"#).unwrap();
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", plain, "--envelope", limits.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("no such joint"), "{err}");
    std::fs::write(&limits, r#"{"joints": {"head": {"angle_deg": 300}}}"#).unwrap();
    let (code, _, err) = skinlet(&["bake", "@demo:2000", "-o", plain, "--envelope", limits.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("angle_deg"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_joint_aabb_measures_both_updates() {
    let rows = json_of(&["bench", "joint-aabb", "@demo:2000", "--instances", "20,50", "--seconds", "0.05", "--json"]);
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for r in rows {
        for field in ["ours_joints_per_us", "bevy_joints_per_us", "ratio", "folded_ratio"] {
            assert!(r[field].as_f64().is_some_and(|x| x > 0.0 && x.is_finite()), "{field} in {r}");
        }
        let ratio = r["bevy_joints_per_us"].as_f64().unwrap() / r["ours_joints_per_us"].as_f64().unwrap();
        assert!((ratio * r["ratio"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{r}");
    }
    let (code, _, err) = skinlet(&["bench", "joint-aabb", "@demo:2000", "--instances", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("--instances"), "{err}");
}

#[test]
fn overdraw_prints_one_row_per_method() {
    let small = ["overdraw", "@demo:1000", "--max-keyframes", "2", "--views", "20", "--k", "2"];
    for (options, patches) in [
        (&["--order", "occlusion"][..], "compact 32"),
        (&["--order", "distance", "--lambda", "0.85"][..], "linear λ=0.85"),
        (&["--patch-size", "48"][..], "compact 48"),
    ] {
        let rows = json_of(&[&small[..], options, &["--json"]].concat());
        let rows = rows.as_array().unwrap();
        let methods: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
        assert_eq!(methods, ["original", "tipsify-per-frame", "single", "joint"]);
        for r in rows {
            for field in ["buffers", "acmr", "ovr", "preprocess_s"] {
                assert!(r[field].as_f64().is_some_and(|x| x >= 0.0), "{field} missing in {r}");
            }
            assert_eq!(r["patches"], patches, "{r}");
            assert_eq!(r["lambda"].as_f64(), patches.starts_with("linear").then_some(0.85f32 as f64), "{r}");
            assert!(r["ovr"].as_f64().unwrap() >= 1.0 && r["acmr"].as_f64().unwrap() <= 3.0, "{r}");
            // The share of the way to no overdraw, from the original row's OVR.
            let original = rows[0]["ovr"].as_f64().unwrap();
            let share = r["share_to_no_overdraw"].as_f64().unwrap();
            assert!((share - (original - r["ovr"].as_f64().unwrap()) / (original - 1.0)).abs() < 1e-9, "{r}");
        }
    }
    for (bad, mentions) in [
        (&["--order", "random"][..], "--order"),
        (&["--patch-size", "2"][..], "--patch-size"),
        (&["--lambda", "0"][..], "--lambda"),
        (&["--lambda", "1", "--patch-size", "16"][..], "--patch-size"),
    ] {
        let (code, _, err) = skinlet(&[&["overdraw", "@demo:1000"][..], bad].concat());
        assert_ne!(code, 0, "{bad:?}");
        assert!(err.contains(mentions), "{bad:?}: {err}");
    }
}

#[test]
fn bake_can_store_overdraw_orders() {
    let out = std::env::temp_dir().join(format!("skinlet-overdraw-{}.skinlet", std::process::id()));
    let j = json_of(&["bake", "@demo:1500", "-o", out.to_str().unwrap(), "--overdraw", "--json"]);
    assert_eq!(j["overdraw_buffers"], 5, "{j}");
    let v = json_of(&["verify", "@demo:1500", "--baked", out.to_str().unwrap(), "--samples", "20", "--json"]);
    assert_eq!(v["violations"], 0);
    std::fs::remove_file(&out).unwrap();
}

#[test]
fn contours_compare_methods_exactly_draw_svg_and_bake() {
    // Static: the demo's bind pose; every method, JSON rows with the issue's fields.
    let svg = std::env::temp_dir().join(format!("skinlet-contours-{}.svg", std::process::id()));
    let rows =
        json_of(&["contours", "@demo:1500", "--static", "--repeats", "1", "--svg", svg.to_str().unwrap(), "--json"]);
    let names: Vec<&str> = rows.as_array().unwrap().iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(names, ["brute", "patches", "patches-mean", "snch", "meshlets"]);
    for r in rows.as_array().unwrap() {
        assert_eq!(r["mismatched_views"], 0, "{r}");
        for field in ["patches", "tested_edges_pct", "speedup_vs_brute", "build_s"] {
            assert!(r[field].as_f64().is_some_and(|x| x >= 0.0), "{field} missing in {r}");
        }
    }
    let drawing = std::fs::read_to_string(&svg).unwrap();
    assert!(drawing.starts_with("<svg") && drawing.matches("<line").count() > 20, "{drawing}");
    std::fs::remove_file(&svg).unwrap();
    // Skinned: over frames of the clips.
    let rows = json_of(&["contours", "@demo:1500", "--frames", "2", "--rounds", "1", "--repeats", "1", "--json"]);
    let names: Vec<&str> = rows.as_array().unwrap().iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(names, ["brute", "rigid", "animated"]);
    assert!(rows.as_array().unwrap().iter().all(|r| r["mismatched_views"] == 0), "{rows}");
    let (code, _, err) = skinlet(&["contours", "@demo:1500", "--method", "nope"]);
    assert!(code != 0 && err.contains("--method"), "{err}");
    // Generated scans, simplified: the contour share is the floor of every method.
    let (code, text, err) = skinlet(&["contours", "@sphere:4000", "--simplify", "0.5", "--repeats", "1"]);
    assert_eq!(code, 0, "{err}");
    let triangles: f64 = text.split(": ").nth(1).and_then(|t| t.split(' ').next()).map(num).unwrap_or(0.0);
    assert!((1800.0..=2050.0).contains(&triangles) && text.contains("dihedral angles: median"), "{text}");
    let rows = json_of(&["contours", "@cup:3000:0.05", "--method", "patches", "--repeats", "1", "--json"]);
    for r in rows.as_array().unwrap() {
        let (tested, floor) = (r["tested_edges_pct"].as_f64().unwrap(), r["contour_edges_pct"].as_f64().unwrap());
        assert!(floor > 0.0 && tested >= floor && r["mismatched_views"] == 0, "{r}");
    }
    for (args, says) in [
        (&["contours", "@sphere:many"][..], "bad triangle count"),
        (&["contours", "@sphere:100:0.1:3"], "too many fields"),
        (&["contours", "@cube"], "unknown built-in"),
        (&["inspect", "@demo:1500:0.1"], "no noise"),
        (&["contours", "@sphere:1000", "--simplify", "2"], "--simplify"),
        (&["contours", "@demo:1500", "--simplify", "0.5"], "--static"),
    ] {
        let (code, _, err) = skinlet(args);
        assert!(code == 2 && err.contains(says), "{args:?}: {err}");
    }
    // The bake stores patches.
    let out = std::env::temp_dir().join(format!("skinlet-contours-{}.skinlet", std::process::id()));
    let j = json_of(&[
        "bake",
        "@demo:1500",
        "-o",
        out.to_str().unwrap(),
        "--contours",
        "visible",
        "--rounds",
        "2",
        "--json",
    ]);
    assert!(j["contour_patches"].as_u64().is_some_and(|n| n > 10), "{j}");
    std::fs::remove_file(&out).unwrap();
}

#[test]
fn render_writes_a_png_of_the_posed_character() {
    let dir = std::env::temp_dir().join(format!("skinlet-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("demo.png");
    let (code, stdout, err) =
        skinlet(&["render", "@demo:2000", "--time", "0.3", "--size", "64", "-o", out.to_str().unwrap(), "--json"]);
    if code != 0 && err.contains("no GPU adapter") && !common::required("SKINLET_REQUIRE_GPU") {
        eprintln!("skipping: {err}");
        return;
    }
    assert_eq!(code, 0, "{err}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["size"], 64);
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // The colored views need mesh shaders (lavapipe from bookworm-backports has them; CI
    // requires them).
    let needs_mesh = common::required("SKINLET_REQUIRE_GPU");
    for view in ["meshlets", "culled", "classes", "contours", "overdraw"] {
        let (code, stdout, err) =
            skinlet(&["render", "@demo:2000", "--view", view, "--size", "64", "-o", out.to_str().unwrap(), "--json"]);
        if code != 0 && err.contains("no mesh shaders") && !needs_mesh {
            eprintln!("skipping --view {view}: {err}");
            continue;
        }
        assert_eq!(code, 0, "{view}: {err}");
        let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let s = &j["summary"];
        if view == "overdraw" {
            let ratios = ["ovr_prepared_order", "ovr_skinlet_order"].map(|k| s[k].as_f64().unwrap());
            assert!(ratios.iter().all(|&r| r >= 1.0), "{j}");
            continue;
        }
        if view == "contours" {
            let (found, tested, edges) =
                ["contour_edges", "tested_edges", "edges"].map(|k| s[k].as_u64().unwrap()).into();
            assert!(0 < found && found <= tested && tested < edges, "{j}");
            continue;
        }
        assert!(s["meshlets"].as_u64().unwrap() > 0, "{j}");
        if view == "classes" {
            let parts: u64 = ["both", "frustum_only", "none"].iter().map(|k| s[k].as_u64().unwrap()).sum();
            assert_eq!(parts, s["meshlets"].as_u64().unwrap(), "{j}");
        }
        if view == "culled" {
            let parts: u64 = ["kept", "frustum_culled", "backface_culled"].iter().map(|k| s[k].as_u64().unwrap()).sum();
            assert_eq!(parts, s["meshlets"].as_u64().unwrap(), "{j}");
        }
    }
    // gpu-bench: every pipeline and culling row, GPU-timed where timestamps exist; the
    // GPU-driven rows issue one draw call (two per round with occlusion culling), every row's
    // image is the unculled one, and no row draws fewer meshlets than have a visible fragment.
    let gpu_bench = |repeats: &str, extra: &[&str]| {
        let mut args = vec!["gpu-bench", "@demo:2000", "--frames", "1", "--repeats", repeats];
        args.extend(["--width", "160", "--budget", "0", "--rounds", "0", "--json"]);
        args.extend(extra);
        skinlet(&args)
    };
    let (code, stdout, err) = gpu_bench("2", &["--instances", "6"]);
    assert_eq!(code, 0, "{err}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let rows = j["rows"].as_array().unwrap();
    assert!(rows.len() == 20 || (rows.len() == 10 && !needs_mesh), "{j}");
    for r in rows {
        let wall = &r["wall_ms"];
        assert!(wall["min"].as_f64().unwrap() > 0.0, "{r}");
        assert!(wall["min"].as_f64() <= wall["median"].as_f64() && wall["median"].as_f64() <= wall["max"].as_f64());
        assert_eq!(r["gpu_ms"].is_object(), j["timestamps"] == true, "{r}");
        let culled = r["culled_pct"].as_f64();
        assert_eq!(culled.is_some(), r["culling"] != "none", "{r}");
        assert_eq!(r["vs_none_pct"].is_object(), r["culling"] != "none" && j["timestamps"] == true, "{r}");
        assert_eq!(r["image_equal_to_unculled"], true, "{r}");
        let drawn = r["meshlets_drawn"].as_f64().unwrap();
        assert!(drawn >= j["meshlets_visible_oracle"].as_f64().unwrap(), "{r}");
        assert!(drawn <= j["meshlets_per_frame"].as_f64().unwrap(), "{r}");
        if r["pipeline"].as_str().unwrap().starts_with("VS") {
            // Occlusion culling: the first phase's draw and one per round of the second.
            let occluded = r["culling"] == "both+occlusion" || r["culling"] == "both+occl+tri";
            let calls = if occluded { 2 * j["occlusion_rounds"].as_u64().unwrap() } else { 1 };
            assert_eq!(r["draws_issued"], calls, "{r}");
        }
        let triangle_pass = r["culling"] == "both+triangles" || r["culling"] == "both+occl+tri";
        assert_eq!(r["triangle_pass_vertices_per_frame"].is_u64(), triangle_pass, "{r}");
    }
    let row = |j: &serde_json::Value, culling: &str| {
        let rows = j["rows"].as_array().unwrap();
        rows.iter().find(|r| r["pipeline"] == "VS" && r["culling"] == culling).unwrap().clone()
    };
    assert!(row(&j, "both+occlusion")["meshlets_drawn"].as_f64() <= row(&j, "both")["meshlets_drawn"].as_f64());
    // The triangle pass keeps some of the same survivors' triangles.
    let (both, triangles) = (row(&j, "both"), row(&j, "both+triangles"));
    assert!(triangles["meshlets_drawn"].as_f64() <= both["meshlets_drawn"].as_f64(), "{j}");
    assert!(triangles["triangles_per_frame"].as_u64() < both["triangles_per_frame"].as_u64(), "{j}");
    // Boxes of the very pose tested against the unculled depth: the pyramid's texels reach
    // at least the pixels, and occlusion culling's boxes (which hold every such box) are tested
    // against depth that at most part of the crowd wrote.
    // A meshlet with an unhidden triangle has an unhidden box.
    let (exact, pyramid) = (&j["meshlets_unhidden_pose_box"], &j["meshlets_unhidden_pose_box_pyramid"]);
    assert!(j["meshlets_unhidden_pose_triangles"].as_f64() <= exact.as_f64(), "{j}");
    assert!(exact.as_f64().unwrap() <= pyramid.as_f64().unwrap(), "{j}");
    assert!(pyramid.as_f64() <= row(&j, "both+occlusion")["meshlets_drawn"].as_f64(), "{j}");
    // The dense crowd, VS only: draw calls do not grow with the instances, occlusion culls.
    let dense = |n: &str| {
        let (code, stdout, err) = gpu_bench("1", &["--crowd", "dense", "--pipelines", "VS", "--instances", n]);
        assert_eq!(code, 0, "{err}");
        serde_json::from_str::<serde_json::Value>(&stdout).unwrap()
    };
    let (small, large) = (dense("6"), dense("48"));
    assert_eq!(large["rows"].as_array().unwrap().len(), 7, "{large}");
    for culling in ["none", "both", "both+occlusion", "both+occl+tri"] {
        assert_eq!(row(&small, culling)["draws_issued"], row(&large, culling)["draws_issued"]);
    }
    let (both, occluded) = (row(&large, "both"), row(&large, "both+occlusion"));
    assert!(occluded["meshlets_drawn"].as_f64() < both["meshlets_drawn"].as_f64(), "{large}");
    // Game poses on the GPU: the same rows, some instance-frames refused by the guard.
    let (code, stdout, err) = gpu_bench("1", &["--instances", "6", "--animation", "ik"]);
    assert_eq!(code, 0, "{err}");
    let k: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(k["rows"].as_array().unwrap().len(), rows.len(), "{k}");
    assert!(k["guard_fallback_pct"].as_f64().unwrap() > 0.0, "{k}");
    let (code, _, err) = skinlet(&["render", "@demo:2000", "--size", "4", "-o", out.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("--size"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pose_and_bake_cover_the_whole_demo_character() {
    // `pose --json`: one entry per drawing node and primitive, in scene space: rigid parts at
    // their node's global transform (computed here from the library's node globals).
    let j = json_of(&["pose", "@demo:2000", "--clip", "wave", "--time", "0.7", "--json"]);
    let asset =
        skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 2000, ..Default::default() });
    let prims = j["primitives"].as_array().unwrap();
    assert_eq!(prims.len(), asset.instances.len());
    let clip = asset.clips.iter().find(|c| c.name == "wave");
    let globals = skinlet::pose::Poser::default().globals(&asset.skeleton, clip, 0.7).to_vec();
    for (p, inst) in prims.iter().zip(&asset.instances) {
        assert_eq!(p["node"].as_u64().unwrap(), inst.node as u64);
        let g = &asset.meshes[inst.mesh as usize].primitives[0].geometry;
        let pos = p["positions"].as_array().unwrap();
        assert_eq!(pos.len(), g.positions.len());
        if inst.skin.is_none() {
            for (a, b) in pos.iter().zip(&g.positions) {
                let want = globals[inst.node as usize].transform_point3(b.as_dvec3());
                let got = glam::DVec3::from_slice(
                    &a.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect::<Vec<_>>(),
                );
                assert!(got.distance(want) < 1e-5, "node {}: {got} vs {want}", inst.node);
            }
        }
    }
    // `bake --json`: every part's triangles, a mesh counted once per node that draws it.
    let out = std::env::temp_dir().join(format!("skinlet-whole-{}.skinlet", std::process::id()));
    let b = json_of(&["bake", "@demo:2000", "-o", out.to_str().unwrap(), "--budget", "0", "--json"]);
    let _ = std::fs::remove_file(&out);
    let drawn: usize =
        asset.instances.iter().map(|i| asset.meshes[i.mesh as usize].primitives[0].geometry.triangles.len()).sum();
    assert_eq!(b["triangles"].as_u64().unwrap() as usize, drawn);
    assert_eq!(b["parts"].as_u64().unwrap() as usize, asset.instances.len());
    assert_eq!(b["skinned_parts"], 2);
}

#[test]
fn bench_import_times_files_against_the_first() {
    let Some(dir) = assets_dir() else { return };
    let (a, b) = (dir.join("skinned/Fox.glb"), dir.join("skinned/RiggedSimple.glb"));
    let rows = json_of(&["bench", "import", a.to_str().unwrap(), b.to_str().unwrap(), "--seconds", "0.05", "--json"]);
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["ratio"], 1.0);
    assert_eq!(rows[0]["triangles"], 576);
    assert!(rows[1]["import_ms"].as_f64().unwrap() > 0.0);
}

#[test]
fn scene_option_selects_the_gltf_scene() {
    let j = json_of(&["inspect", "@demo:1000", "--json"]);
    assert_eq!(j["parts"].as_array().unwrap().len(), 6);
    let (code, _, err) = skinlet(&["bake", "@demo:1000", "-o", "/nonexistent/x.skinlet", "--scene", "1"]);
    assert_eq!(code, 2);
    assert!(err.contains("scene 1 does not exist"), "{err}");
}

#[test]
fn node_and_part_filters_keep_those_parts() {
    let all = json_of(&["inspect", "@demo:1000", "--json"]);
    let parts = all["parts"].as_array().unwrap();
    let propeller = parts[3]["node"].to_string();
    let j = json_of(&["inspect", "@demo:1000", "--node", &propeller, "--json"]);
    assert_eq!(j["parts"].as_array().unwrap().len(), 1);
    assert_eq!(j["parts"][0]["node"].to_string(), propeller);
    let j = json_of(&["inspect", "@demo:1000", "--part", "0", "--part", "4", "--json"]);
    let kept: Vec<&Value> = j["parts"].as_array().unwrap().iter().map(|p| &p["node"]).collect();
    assert_eq!(kept, [&parts[0]["node"], &parts[4]["node"]]);
    // A bake of the propeller alone holds its triangles only.
    let out = std::env::temp_dir().join(format!("skinlet-filter-{}.skinlet", std::process::id()));
    let b =
        json_of(&["bake", "@demo:1000", "--node", &propeller, "-o", out.to_str().unwrap(), "--budget", "0", "--json"]);
    let _ = std::fs::remove_file(&out);
    assert_eq!((b["parts"].as_u64(), &b["triangles"]), (Some(1), &parts[3]["triangles"]));
    // Filters that name nothing are errors that say so.
    let (code, _, err) = skinlet(&["pose", "@demo:1000", "--time", "0", "--node", "9999"]);
    assert!(code == 2 && err.contains("node 9999 draws no part of the character"), "{err}");
    let (code, _, err) = skinlet(&["pose", "@demo:1000", "--time", "0", "--part", "6"]);
    assert!(code == 2 && err.contains("the character has 6 parts"), "{err}");
    let j = json_of(&["inspect", "@demo:1000", "--part", "6", "--json"]);
    assert!(j["character_error"].as_str().is_some_and(|e| e.contains("the character has 6 parts")), "{j}");
}

#[test]
fn render_draws_morph_targets_in_every_pipeline() {
    let Some(dir) = assets_dir() else { return };
    let file = dir.join("morph/MorphStressTest.gltf");
    let out = std::env::temp_dir().join(format!("skinlet-render-morph-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let mut images = Vec::new();
    for (skinning, time) in [("vertex", "0.0"), ("vertex", "0.9"), ("compute", "0.9"), ("mesh", "0.9")] {
        let png = out.join(format!("{skinning}-{time}.png"));
        let args = ["render", file.to_str().unwrap(), "--clip", "TheWave", "--time", time, "--skinning", skinning];
        let (code, _, err) = skinlet(&[&args[..], &["--size", "64", "-o", png.to_str().unwrap()]].concat());
        if code != 0 && err.contains("no GPU adapter") && !common::required("SKINLET_REQUIRE_GPU") {
            eprintln!("skipping: {err}");
            return;
        }
        assert_eq!(code, 0, "{err}");
        images.push(std::fs::read(&png).unwrap());
    }
    // The morphs move the shape between the two times; every pipeline draws the same image.
    assert_ne!(images[0], images[1]);
    assert_eq!(images[1], images[2]);
    assert_eq!(images[1], images[3]);
    // The views that bake draw it too: the bounds hold over the morphs.
    let png = out.join("culled.png");
    let args = ["render", file.to_str().unwrap(), "--clip", "TheWave", "--view", "culled", "--size", "64", "-o"];
    let (code, _, err) = skinlet(&[&args[..], &[png.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    let _ = std::fs::remove_dir_all(&out);
}
