//! `skinlet bench`: speed measured against a baseline in the same run.

use anyhow::{Context, Result};
use serde_json::{Value, json};
use skinlet::clip::Clip;
use skinlet::cull::joint_aabb::Box3;
use skinlet_lab::bevy_baseline::Workload;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Subcommand)]
pub enum What {
    /// Whole-mesh box updates from per-joint boxes: ours against the Bevy pull request's.
    ///
    /// Poses INSTANCES copies of the character (crowd scene, random clip times), then times,
    /// on one thread, the PR's update (mesh-space boxes, each joint's transform fetched
    /// through its ECS entity, times its inverse bind pose, Arvo into world space, then into
    /// entity space) and ours (joint-space boxes, one palette of entity-space joint matrices,
    /// two boxes per AVX register where the CPU has AVX2 and FMA), alternating them, and
    /// prints the median joints per microsecond of each and their ratio. The default is the
    /// PR's workload: 1,000 foxes (Fox.glb, 22 skinned joints), and 100,000.
    JointAabb {
        /// .glb or .gltf file, or @demo[:TRIANGLES] (default: Fox.glb from the shared assets,
        /// $SKINLET_ASSETS or ../shared/assets).
        file: Option<String>,
        /// Instance counts, comma-separated.
        #[arg(long, default_value = "1000,100000")]
        instances: String,
        /// Seconds spent timing each method per instance count (at least 10 rounds).
        #[arg(long, default_value_t = 1.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
    /// Import time of glTF files against each other, e.g. a compressed file (gltfpack -cc)
    /// against its original: each file read into memory once, then parsed, decoded and
    /// turned into the whole character, alternating the files, median of each.
    Import {
        /// Two or more .glb/.gltf files; ratios are against the first.
        #[arg(num_args = 2.., required = true)]
        files: Vec<PathBuf>,
        /// Seconds spent timing each file (at least 10 rounds).
        #[arg(long, default_value_t = 2.0)]
        seconds: f64,
        #[arg(long)]
        json: bool,
    },
}

pub fn command(what: &What) -> Result<()> {
    match what {
        What::JointAabb { file, instances, seconds, json } => joint_aabb(file.as_deref(), instances, *seconds, *json),
        What::Import { files, seconds, json } => import(files, *seconds, *json),
    }
}

fn import(files: &[PathBuf], seconds: f64, json: bool) -> Result<()> {
    anyhow::ensure!(seconds > 0.0 && seconds.is_finite(), "--seconds must be positive");
    let bytes: Vec<Vec<u8>> = (files.iter())
        .map(|f| std::fs::read(f).with_context(|| format!("cannot read {}", f.display())))
        .collect::<Result<_>>()?;
    let mut triangles = vec![0usize; files.len()];
    let failed = std::cell::RefCell::new(None);
    let mut calls: Vec<Box<dyn FnMut()>> = Vec::new();
    for ((path, b), tris) in files.iter().zip(&bytes).zip(triangles.iter_mut()) {
        // Checked once here, so the timed calls cannot fail.
        let character = crate::character_of(&skinlet::import::load_bytes(b, path)?)?;
        *tris = character.triangle_count();
        let failed = &failed;
        calls.push(Box::new(move || {
            if let Err(e) = skinlet::import::load_bytes(b, path).and_then(|a| crate::character_of(&a)) {
                failed.borrow_mut().get_or_insert(e.to_string());
            }
        }));
    }
    let mut refs: Vec<&mut dyn FnMut()> = calls.iter_mut().map(|c| &mut **c as &mut dyn FnMut()).collect();
    let t = time_alternating(&mut refs, seconds);
    drop(calls);
    if let Some(e) = failed.into_inner() {
        anyhow::bail!("an import failed while timing: {e}");
    }
    let rows: Vec<Value> = (files.iter().zip(&bytes).zip(&t).zip(&triangles))
        .map(|(((f, b), s), tris)| {
            json!({"file": f.display().to_string(), "bytes": b.len(), "triangles": tris, "import_ms": s * 1e3, "ratio": s / t[0]})
        })
        .collect();
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!("{:>10} {:>10} {:>10} {:>8}  file", "bytes", "triangles", "import ms", "ratio");
    for r in &rows {
        println!(
            "{:>10} {:>10} {:>10.3} {:>8.2}  {}",
            r["bytes"].as_u64().unwrap_or(0),
            r["triangles"].as_u64().unwrap_or(0),
            r["import_ms"].as_f64().unwrap_or(0.0),
            r["ratio"].as_f64().unwrap_or(0.0),
            r["file"].as_str().unwrap_or("")
        );
    }
    Ok(())
}

fn default_fox() -> Result<String> {
    let dir = std::env::var_os("SKINLET_ASSETS").map_or_else(|| PathBuf::from("../shared/assets"), PathBuf::from);
    let path = dir.join("skinned").join("Fox.glb");
    anyhow::ensure!(
        path.exists(),
        "no FILE given and {} does not exist (set SKINLET_ASSETS, or pass a .glb file or @demo)",
        path.display()
    );
    Ok(path.to_string_lossy().into_owned())
}

/// Median seconds per call of each of `methods`, called in turn until each has run for
/// `seconds` and at least 10 times.
fn time_alternating(methods: &mut [&mut dyn FnMut()], seconds: f64) -> Vec<f64> {
    let mut samples: Vec<Vec<f64>> = vec![Vec::new(); methods.len()];
    let mut spent = vec![Duration::ZERO; methods.len()];
    while spent.iter().any(|s| s.as_secs_f64() < seconds) || samples[0].len() < 10 {
        for (i, m) in methods.iter_mut().enumerate() {
            let t = Instant::now();
            m();
            let d = t.elapsed();
            spent[i] += d;
            samples[i].push(d.as_secs_f64());
        }
    }
    // At least 10 samples each: every median exists.
    samples.into_iter().map(|s| median(s).unwrap_or(f64::NAN)).collect()
}

/// The middle sample (the upper one of an even count); `None` without samples.
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

fn joint_aabb(file: Option<&str>, instances: &str, seconds: f64, json: bool) -> Result<()> {
    let file = match file {
        Some(f) => f.to_string(),
        None => default_fox()?,
    };
    let counts = instances
        .split(',')
        .map(|s| s.trim().parse::<usize>().ok().filter(|&n| n >= 1))
        .collect::<Option<Vec<_>>>()
        .with_context(|| format!("--instances {instances:?}: expected positive counts, comma-separated"))?;
    anyhow::ensure!(seconds > 0.0 && seconds.is_finite(), "--seconds must be positive");
    let asset = crate::load(&file)?;
    let mut rows = Vec::new();
    for n in counts {
        let w = Workload::new(&asset, n, 1)?;
        let (skin, mesh) = (&w.character.palette, &w.character.mesh);
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let folded = skinlet::cull::joint_aabb::fold_leaves(&w.boxes, &asset.skeleton, skin, mesh, &clips, 2)?;
        let (mut bevy_out, mut ours_out, mut folded_out) =
            (Vec::with_capacity(n), vec![Box3::EMPTY; n], vec![Box3::EMPTY; n]);
        let mut bevy = || w.bevy.update(false, &mut bevy_out);
        let mut ours = || w.boxes.update_all(&w.palette, w.stride, &mut ours_out).expect("palette sized by Workload");
        let mut fold = || folded.update_all(&w.palette, w.stride, &mut folded_out).expect("palette sized by Workload");
        let t = time_alternating(&mut [&mut bevy, &mut ours, &mut fold], seconds);
        let joints = (w.bevy.boxes() * n) as f64;
        let per_us = |s: f64| joints / (s * 1e6);
        rows.push(json!({
            "file": file, "instances": n, "joint_boxes": w.bevy.boxes(), "folded_boxes": folded.joints.len(),
            "bevy_joints_per_us": per_us(t[0]), "ours_joints_per_us": per_us(t[1]), "ratio": t[0] / t[1],
            "folded_joints_per_us": per_us(t[2]), "folded_ratio": t[0] / t[2],
        }));
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&Value::Array(rows))?);
        return Ok(());
    }
    println!("{file}: joint-box updates, one thread (joints per microsecond, median)");
    println!(
        "{:>10} {:>7} {:>10} {:>10} {:>7} {:>14} {:>7}",
        "instances", "boxes", "bevy", "ours", "ratio", "ours folded", "ratio"
    );
    for r in &rows {
        println!(
            "{:>10} {:>7} {:>10.1} {:>10.1} {:>6.2}x {:>14.1} {:>6.2}x",
            r["instances"].as_u64().unwrap_or(0),
            r["joint_boxes"].as_u64().unwrap_or(0),
            r["bevy_joints_per_us"].as_f64().unwrap_or(0.0),
            r["ours_joints_per_us"].as_f64().unwrap_or(0.0),
            r["ratio"].as_f64().unwrap_or(0.0),
            r["folded_joints_per_us"].as_f64().unwrap_or(0.0),
            r["folded_ratio"].as_f64().unwrap_or(0.0),
        );
    }
    println!("(folded: leaf joints folded twice into ancestors, conservative for the file's clips only)");
    Ok(())
}
