//! `skinlet contours`: Tsiapkolis & Bénard's evaluation (42 directions × 6 distances) for
//! one mesh, and an SVG of the contours from one view.

use anyhow::{Context, Result};
use serde_json::json;
use skinlet::contour::patches::PatchParams;
use skinlet::contour::{Edges, Projection, brute_force};
use skinlet::cull::Camera;
use skinlet_lab::contour_eval::{Method, MethodResult, evaluate, frame, views};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The options of `skinlet contours` (the file is `Command::Contours::file`).
#[derive(clap::Args)]
pub struct Args {
    /// Static meshes: brute, patches, patches-mean, snch, meshlets or all; skinned:
    /// brute, rigid (the paper: patches on rigid parts), animated (ours: every patch with
    /// bounds over the clips) or all. Brute always runs: it is the reference and baseline.
    #[arg(long, default_value = "all")]
    pub method: String,
    /// Drop concave edges, whose contours are always hidden (as the paper does; on
    /// skinned meshes only rigid ones, whose concavity cannot change).
    #[arg(long)]
    pub visible_only: bool,
    /// Skinned files: clip names or indices, comma-separated (default: all clips).
    #[arg(long, alias = "clip")]
    pub clips: Option<String>,
    /// Skinned files: sampled frames per clip.
    #[arg(long, default_value_t = 8)]
    pub frames: usize,
    /// Treat a skinned file as static (its bind pose) and compare the static methods.
    #[arg(long = "static")]
    pub as_static: bool,
    /// Static meshes: simplify to this share of the triangles first (meshoptimizer's
    /// simplifier), e.g. 0.25 for another decimation of a scan.
    #[arg(long, value_name = "RATIO")]
    pub simplify: Option<f32>,
    /// Skinned files: seconds to spend tightening the animated bounds (halving the time
    /// pieces where they are loosest); 0: no limit (then --rounds decides).
    #[arg(long, default_value_t = 60.0)]
    pub budget: f64,
    /// Skinned files: most refinement rounds (default: until converged or the budget is
    /// spent; 0: key intervals only).
    #[arg(long)]
    pub rounds: Option<usize>,
    /// Skinned files: time windows per clip, each with its own bounds, chosen at run time
    /// by the playing clip and time (1: one bound over all clips).
    #[arg(long, default_value_t = skinlet::contour::skinned::DEFAULT_WINDOWS)]
    pub windows: usize,
    /// Timing rounds, methods interleaved (the fastest round of each counts).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Cost of a patch test in edge tests (t_P / t_e) for the decomposition.
    #[arg(long)]
    pub cost_ratio: Option<f64>,
    /// Measure t_e and t_P on this machine first (section 4.2) and use their ratio.
    #[arg(long)]
    pub calibrate: bool,
    /// Viewing distance the decomposition optimizes for, in model sizes (d_cam).
    #[arg(long, default_value_t = 10.0)]
    pub d_cam: f64,
    /// Largest group of edges fused together (c_max): larger is slower to build and
    /// slightly better.
    #[arg(long, default_value_t = 4096)]
    pub group: usize,
    /// GPU limits per patch (e.g. --max-edges 126 --max-vertices 64 for mesh shaders).
    #[arg(long)]
    pub max_edges: Option<usize>,
    #[arg(long)]
    pub max_vertices: Option<usize>,
    /// Also draw the contours from a front view into this SVG file.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

impl Args {
    /// The decomposition parameters the options ask for, checked.
    fn patch_params(&self) -> Result<PatchParams> {
        anyhow::ensure!(self.d_cam.is_finite() && self.d_cam > 0.0, "--d-cam must be > 0");
        anyhow::ensure!(self.group >= 1, "--group must be at least 1");
        anyhow::ensure!(
            self.max_edges != Some(0) && self.max_vertices.is_none_or(|v| v >= 2),
            "--max-edges must be >= 1 and --max-vertices >= 2"
        );
        anyhow::ensure!(self.repeats >= 1 && self.frames >= 1, "--repeats and --frames must be at least 1");
        anyhow::ensure!((1..=256).contains(&self.windows), "--windows must be between 1 and 256");
        let mut params = PatchParams {
            d_cam: self.d_cam,
            group: self.group,
            max_edges: self.max_edges,
            max_vertices: self.max_vertices,
            ..PatchParams::default()
        };
        if let Some(r) = self.cost_ratio {
            anyhow::ensure!(r.is_finite() && r > 0.0, "--cost-ratio must be > 0");
            params.cost_ratio = r;
        }
        Ok(params)
    }
}

pub fn command(file: &str, o: &Args) -> Result<()> {
    let params = o.patch_params()?;
    let (asset, character) = crate::load_character(file)?;
    let skinned_parts = character.parts.iter().any(|p| matches!(p.kind, skinlet::PartKind::Skinned { .. }));
    if skinned_parts && !o.as_static && !asset.clips.is_empty() {
        return skinned(file, &asset, &character, o, params);
    }
    let mut methods: Vec<Method> = match o.method.as_str() {
        "all" => Method::ALL.to_vec(),
        m => vec![
            Method::Brute,
            Method::from_name(m).with_context(|| {
                format!("unknown --method {m:?} (brute, patches, patches-mean, snch, meshlets, all)")
            })?,
        ],
    };
    methods.dedup();
    // Static geometry: every part as drawn in the rest pose, seams welded.
    let rest = skinlet::skinning::posed_positions(&asset.skeleton, &character.palette, &character.mesh, None, None)?;
    let drawn =
        skinlet::SkinnedMesh { positions: rest, triangles: character.mesh.triangles.clone(), ..Default::default() };
    let (mut mesh, _, _) = skinlet::weld::weld(&drawn);
    if let Some(ratio) = o.simplify {
        anyhow::ensure!(ratio > 0.0 && ratio <= 1.0, "--simplify must be in (0, 1]");
        (mesh.positions, mesh.triangles) = skinlet_lab::scans::decimate(&mesh.positions, &mesh.triangles, ratio);
    }
    let mut edges = Edges::build(&mesh.positions, &mesh.triangles)?;
    let (median, p90) = skinlet_lab::contour_eval::dihedral_angles(&mesh.positions, &edges);
    if o.visible_only {
        edges.drop_concave(&mesh.positions, |_| true);
    }
    let all_views = views(&mesh.positions);
    let mut params = params;
    let mut header = format!(
        "{file}: {} triangles, {} edges ({} interior, {} irregular, {} boundary{}), dihedral angles: median {median:.1}°, 90th percentile {p90:.1}°, {} views (42 directions x 6 distances)",
        mesh.triangles.len(),
        edges.len(),
        edges.quads.len(),
        edges.irregular.len(),
        edges.boundary.len(),
        if o.visible_only { format!(", {} concave dropped", edges.dropped_concave) } else { String::new() },
        all_views.len()
    );
    if o.calibrate {
        let (t_e, t_p) = skinlet_lab::contour_eval::calibrate(&mesh.positions, &edges, &all_views, o.repeats);
        write!(header, "\ncalibration: t_e {t_e:.2} ns, t_P {t_p:.2} ns, t_P/t_e {:.2}", t_p / t_e)?;
        // An explicit --cost-ratio wins over the measured one.
        if o.cost_ratio.is_none() {
            params.cost_ratio = (t_p / t_e).max(0.1);
        }
    }
    let rows = evaluate(&mesh.positions, &mesh.triangles, &edges, &methods, &params, &all_views, o.repeats);
    if let Some(path) = &o.svg {
        write_svg(path, &mesh.positions, &edges)?;
    }
    report(o, &header, &rows)
}

/// Skinned files: brute force, rigid parts (the paper) and animated bounds (ours) over frames.
fn skinned(
    file: &str,
    asset: &skinlet::Asset,
    character: &skinlet::Character,
    o: &Args,
    params: PatchParams,
) -> Result<()> {
    use skinlet::contour::skinned::SkinnedMethod;
    use skinlet_lab::contour_eval::{SkinnedInput, evaluate_skinned};
    let methods = match o.method.as_str() {
        "all" => vec![SkinnedMethod::Rigid, SkinnedMethod::Animated],
        "brute" => vec![],
        "rigid" => vec![SkinnedMethod::Rigid],
        "animated" => vec![SkinnedMethod::Animated],
        m => anyhow::bail!(
            "unknown --method {m:?} for a skinned file (brute, rigid, animated, all; --static for the static methods)"
        ),
    };
    anyhow::ensure!(!o.calibrate, "--calibrate runs on static geometry: add --static");
    anyhow::ensure!(o.simplify.is_none(), "--simplify runs on static geometry: add --static");
    anyhow::ensure!(o.budget.is_finite() && o.budget >= 0.0, "--budget must be a number of seconds >= 0");
    let clips = crate::select_clips(asset, o.clips.as_deref())?;
    let (mesh, _, _) = skinlet::weld::weld(&character.mesh);
    let edges = skinlet::contour::skinned::skinned_edges(&mesh, o.visible_only)?;
    let input = SkinnedInput {
        skeleton: &asset.skeleton,
        skin: &character.palette,
        clips: &clips,
        mesh: &mesh,
        frames_per_clip: o.frames,
    };
    let how = skinlet::contour::skinned::refinement(
        (o.budget > 0.0).then(|| std::time::Duration::from_secs_f64(o.budget)),
        o.rounds.unwrap_or(if o.budget > 0.0 { usize::MAX } else { 0 }),
    );
    let sp = skinlet::contour::skinned::SkinnedParams {
        method: SkinnedMethod::Animated,
        patches: params,
        refine: how,
        windows: o.windows,
    };
    let rows = evaluate_skinned(&input, &edges, &methods, &sp, o.repeats)?;
    if let Some(path) = &o.svg {
        write_skinned_svg(path, &input, &edges)?;
    }
    let header = format!(
        "{file}: {} triangles, {} edges ({} interior{}), {} clips x {} frames x 252 views",
        mesh.triangles.len(),
        edges.len(),
        edges.quads.len(),
        if o.visible_only { format!(", {} rigid concave dropped", edges.dropped_concave) } else { String::new() },
        clips.len(),
        o.frames
    );
    report(o, &header, &rows)
}

/// Prints the rows as JSON, or as the header and the table.
fn report(o: &Args, header: &str, rows: &[MethodResult]) -> Result<()> {
    if o.json {
        let out: Vec<_> = rows.iter().map(row_json).collect();
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("{header}");
    print_rows(rows);
    if let Some(path) = &o.svg {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The contours of the first clip's middle frame, from the front.
fn write_skinned_svg(path: &Path, input: &skinlet_lab::contour_eval::SkinnedInput, edges: &Edges) -> Result<()> {
    let inf = input.mesh.influences.as_ref().context("no skin weights")?;
    let clip = input.clips.first().copied();
    let keys = clip.map(|c| c.key_times()).unwrap_or_default();
    let t = (keys.first().copied().unwrap_or(0.0) + keys.last().copied().unwrap_or(0.0)) * 0.5;
    let mut poser = skinlet::pose::Poser::default();
    let mut m = Vec::new();
    poser.skinning_matrices(input.skeleton, input.skin, clip, t, &mut m);
    let mut p = vec![glam::Vec3::ZERO; input.mesh.positions.len()];
    skinlet::skinning::skin(inf, &input.mesh.positions, &[], &m, &mut p, &mut [])?;
    write_svg(path, &p, edges)
}

/// The table: static rows end with the mean patch radius and angle, skinned rows with the
/// quads in rigid and animated patches.
fn print_rows(rows: &[MethodResult]) {
    let skinned = rows.iter().any(|r| r.frames > 0);
    let (a, b) = if skinned { ("rigid", "animated") } else { ("mean r", "mean a") };
    println!(
        "{:<13} {:>8} {:>9} {:>9} {:>8} {:>8} {:>9} {:>8} {:>9}",
        "method", "patches", "tested %", "ms/view", "speedup", "build s", "mismatch", a, b
    );
    for r in rows {
        let (x, y) = if skinned {
            (r.rigid_quads.to_string(), r.animated_quads.to_string())
        } else {
            (format!("{:.4}", r.mean_radius), format!("{:.1}°", r.mean_angle_deg))
        };
        println!(
            "{:<13} {:>8} {:>9.2} {:>9.4} {:>7.2}x {:>8.2} {:>9} {x:>8} {y:>9}",
            r.method, r.patches, r.tested_edges_pct, r.ms_per_view, r.speedup_vs_brute, r.build_s, r.mismatched_views
        );
    }
    if let Some(r) = rows.first() {
        println!(
            "contour edges: {:.2}% of the edges over these views, boundary edges left out (no method tests fewer)",
            r.contour_edges_pct
        );
    }
    if skinned {
        println!("(rigid / animated: quads in patches of each kind; the rest are tested every time)");
    }
}

fn row_json(r: &MethodResult) -> serde_json::Value {
    let mut v = json!({
        "method": r.method, "patches": r.patches, "tested_edges_pct": r.tested_edges_pct,
        "contour_edges_pct": r.contour_edges_pct,
        "speedup_vs_brute": r.speedup_vs_brute, "build_s": r.build_s, "mismatched_views": r.mismatched_views,
        "ms_per_view": r.ms_per_view,
    });
    let extra = if r.frames > 0 {
        json!({"frames": r.frames, "rigid_quads": r.rigid_quads, "animated_quads": r.animated_quads})
    } else {
        json!({"mean_radius": r.mean_radius, "mean_angle_deg": r.mean_angle_deg})
    };
    v.as_object_mut().expect("object").extend(extra.as_object().expect("object").clone());
    v
}

/// The contour edges from a front view (slightly above, 3 model sizes away) as SVG lines.
pub fn write_svg(path: &Path, positions: &[glam::Vec3], edges: &Edges) -> Result<()> {
    let (center, size) = frame(positions);
    let eye = center + glam::Vec3::new(0.0, 0.25, 1.0).normalize() * (3.0 * size) as f32;
    let camera = Camera::perspective(eye, center, glam::Vec3::Y, 0.45, 1.0, 0.01 * size as f32, 10.0 * size as f32)?;
    let mut out = Vec::new();
    brute_force(positions, edges, Projection::Perspective { eye }, &mut out);
    let px = 800.0;
    let to_screen = |p: glam::Vec3| {
        let c = camera.view_proj * p.extend(1.0);
        let (x, y) = (c.x / c.w, c.y / c.w);
        ((x + 1.0) * 0.5 * px, (1.0 - y) * 0.5 * px)
    };
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{px}\" height=\"{px}\" viewBox=\"0 0 {px} {px}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<g stroke=\"black\" stroke-width=\"1\" stroke-linecap=\"round\">\n"
    );
    for id in out {
        let [a, b] = edges.endpoints(id).map(|v| to_screen(positions[v as usize]));
        writeln!(svg, "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\"/>", a.0, a.1, b.0, b.1)?;
    }
    svg.push_str("</g>\n</svg>\n");
    std::fs::write(path, svg).with_context(|| format!("cannot write {}", path.display()))
}
