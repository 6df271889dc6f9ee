//! `skinlet`: the command-line front end. The library computes; this file talks to people
//! (tables, `--json` for machines) and turns errors into messages and exit codes.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use serde_json::{Value, json};
use skinlet::clip::Clip;
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::overdraw::cluster::PatchOrder;
use skinlet::pose::Poser;
use skinlet::{Asset, Character};
use skinlet_lab::demo::{DemoParams, demo_character};
use skinlet_lab::summary::summarize;
use std::path::{Path, PathBuf};

mod bake;
mod bench;
mod contours;
mod crowd;
mod gpu_bench;
mod lod;
mod overdraw;
mod render;

#[derive(Parser)]
#[command(
    name = "skinlet",
    version,
    about = "Make skinned (skeletally animated) meshes cheap to render",
    long_about = "skinlet bakes glTF characters into GPU-ready data for culling and rendering \
skinned meshes, and checks every guarantee it makes against reference skinning.\n\n\
FILE arguments take .glb, .gltf or .obj files, or `@demo` (optionally `@demo:TRIANGLES`) \
for the built-in procedural demo character; static meshes also `@sphere` (a scan-like noisy \
sphere) and `@cup` (a thin-shelled cup), 100,000 triangles unless `:TRIANGLES` says, with \
scanner-like noise of 0.1 mean edge lengths unless `:TRIANGLES:NOISE` says.",
    after_help = "Examples:\n  skinlet demo\n  skinlet inspect character.glb\n  skinlet inspect character.glb --json\n  skinlet pose character.glb --clip walk --time 0.5 --json > pose.json"
)]
struct Cli {
    /// The glTF scene whose nodes make the character (an index into the file's `scenes`;
    /// default: the file's `scene`, else scene 0, else every root node).
    #[arg(long, global = true)]
    scene: Option<usize>,
    /// Keep only the parts drawn by this glTF node (repeat for several; `inspect` lists the
    /// parts and their nodes). Every command then works on those parts alone.
    #[arg(long, global = true)]
    node: Vec<u32>,
    /// Keep only this part (its index in `inspect`'s parts table; repeat for several).
    #[arg(long, global = true)]
    part: Vec<usize>,
    #[command(subcommand)]
    command: Command,
}

/// Which character the command works on: the scene, and the node and part filters.
#[derive(Default)]
struct Selection {
    scene: Option<usize>,
    nodes: Vec<u32>,
    parts: Vec<usize>,
}

/// `--scene`, `--node` and `--part`, set once after parsing: the one piece of CLI state every
/// command loading a character reads.
static SELECTION: std::sync::OnceLock<Selection> = std::sync::OnceLock::new();

/// The character of `asset` for the scene `--scene` chose, restricted to the parts `--node`
/// and `--part` name (all without them); a filter that names nothing is an error.
fn character_of(asset: &Asset) -> skinlet::Result<Character> {
    let sel = SELECTION.get_or_init(Selection::default);
    let character = skinlet::character::character(asset, sel.scene)?;
    if sel.nodes.is_empty() && sel.parts.is_empty() {
        return Ok(character);
    }
    let drawing: Vec<u32> = character.parts.iter().map(|p| p.node).collect();
    if let Some(n) = sel.nodes.iter().find(|n| !drawing.contains(n)) {
        return Err(skinlet::Error::Invalid {
            location: format!("--node {n}"),
            message: format!("node {n} draws no part of the character (parts are drawn by nodes {drawing:?})"),
        });
    }
    if let Some(p) = sel.parts.iter().find(|&&p| p >= drawing.len()) {
        return Err(skinlet::Error::Invalid {
            location: format!("--part {p}"),
            message: format!("the character has {} parts (0 to {})", drawing.len(), drawing.len() - 1),
        });
    }
    character.select(|i, p| sel.parts.contains(&i) || sel.nodes.contains(&p.node))
}

/// Refinement of conservative bounds and the classification thresholds it aims at.
#[derive(clap::Args, Clone, Copy)]
pub(crate) struct RefineArgs {
    /// Seconds of precomputation (key intervals always run; refinement then halves the
    /// intervals where bounds are worst until the budget is spent or nothing improves).
    /// 0: no time limit (refine for --rounds rounds).
    #[arg(long, default_value_t = 60.0)]
    budget: f64,
    /// Stop refinement after this many rounds (with --budget 0: exactly this many, so the
    /// output does not depend on the machine's speed). Default: until converged or the
    /// budget is spent; 0 with --budget 0: key intervals only.
    #[arg(long)]
    rounds: Option<usize>,
    /// Classification: largest allowed radius growth over the rest radius (s_r).
    #[arg(long, default_value_t = 3.0)]
    sr: f32,
    /// Classification: degrees the normals may turn beyond the rest cone (alpha_T).
    #[arg(long, default_value_t = 20.0)]
    alpha: f32,
}

impl RefineArgs {
    pub(crate) fn refinement(&self) -> Result<skinlet::bounds::refine::Refinement> {
        anyhow::ensure!(self.budget.is_finite() && self.budget >= 0.0, "--budget must be a number of seconds >= 0");
        anyhow::ensure!(self.sr.is_finite() && self.sr >= 1.0, "--sr must be >= 1");
        anyhow::ensure!((0.0..90.0).contains(&self.alpha), "--alpha must be in [0, 90) degrees");
        let unlimited = self.budget > 0.0 && self.rounds.is_none();
        Ok(skinlet::bounds::refine::Refinement {
            s_r: self.sr,
            alpha_t: self.alpha.to_radians(),
            budget: (self.budget > 0.0).then(|| std::time::Duration::from_secs_f64(self.budget)),
            max_rounds: if unlimited { usize::MAX } else { self.rounds.unwrap_or(0) },
        })
    }
}

#[derive(Subcommand)]
enum Command {
    /// Show what a file holds: meshes, skins, influences, import fixes and clips.
    ///
    /// Counts are as stored: every glTF mesh is counted once however many nodes draw it.
    /// The influence histogram counts vertices by their number of non-zero weights.
    Inspect {
        /// .glb, .gltf or .obj file, or @demo[:TRIANGLES].
        file: String,
        /// Print one JSON object with stable field names instead of tables.
        #[arg(long)]
        json: bool,
    },
    /// Skin every vertex at one time of a clip and print positions and normals.
    ///
    /// Output is in scene space, as glTF draws the file: a skinned primitive by its skin's
    /// joints (the transform of the node that draws it is ignored), a rigid one by its node's
    /// global transform. One entry per node of the default scene that draws a triangle mesh,
    /// and per primitive, one vertex per input vertex in accessor order (no welding).
    /// `normals` is null for primitives without normals.
    Pose {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        /// Clip name or index (default: the first clip). Without clips the rest pose is used.
        #[arg(long)]
        clip: Option<String>,
        /// Time in seconds on the clip's own timeline (key times as stored in the file).
        #[arg(long)]
        time: f32,
        /// Print JSON (the default prints a short summary per primitive).
        #[arg(long)]
        json: bool,
    },
    /// Split a character into meshlets with one or all builders and compare them.
    ///
    /// Every part of the character (every node of the default scene that draws a triangle
    /// mesh) is welded (equal position + skin data) and vertex-cache ordered, then split;
    /// no meshlet mixes two parts.
    /// Builders: scan (index order, thesis listing 4.1), common-influences (per shared joint
    /// set, thesis listing 4.2), meshopt, meshopt-flex and meshopt-spatial (meshoptimizer's
    /// greedy, flexible-size and spatial builders), skin-aware (ours: meshlets that move with
    /// one joint), cone-split (ours: skin-aware meshlets cut by face normal where that saves
    /// skinning over the views backface culling skips, cones taken over poses sampled from
    /// the clips, within 1.3x meshopt's count). Columns: meshlet count, average vertices and
    /// triangles, vertex references per unique vertex, % meshlets whose vertices share one
    /// joint set, % with one joint carrying >= 0.9 of the weight, bytes of meshlet data +
    /// vertices (slim vertices where possible; fat in parentheses), % backface-culled by
    /// meshoptimizer's cone from 6 axis views in the rest pose, build time, and "anim r": the
    /// mean over meshlets of the radius their vertices sweep in the principal joint's space
    /// over 32 sampled poses per clip, divided by the rest radius (a sampled preview of how
    /// tight animated bounds can get; 1.0 = rigid).
    Meshlets {
        /// .glb, .gltf or .obj file, or @demo[:TRIANGLES].
        file: String,
        #[arg(long, default_value = "all", value_parser = builder_names(true))]
        builder: String,
        /// At most this many vertices per meshlet (<= 256).
        #[arg(long, default_value_t = 64)]
        max_vertices: usize,
        /// At most this many triangles per meshlet (<= 512; the meshoptimizer-based builders
        /// fill to the multiple of 4 at or below it, e.g. 124 for 126).
        #[arg(long, default_value_t = 124)]
        max_triangles: usize,
        /// Print a JSON array, one object per builder.
        #[arg(long)]
        json: bool,
    },
    /// Conservative animated meshlet bounds and their culling classes (paper table 2).
    ///
    /// Per builder: meshlets are given a sphere and a normal cone in their principal joint's
    /// space that provably hold over every key interval of the chosen clips, then refined on
    /// halved intervals until --budget runs out or nothing improves. A meshlet is
    /// "both" (frustum- and backface-cullable) when its radius grows at most --sr times over
    /// the rest radius and its normals turn at most alpha beyond the rest cone, "frustum-only"
    /// when only the radius holds, else "none". Columns give % both / frustum-only at alpha =
    /// 10, 20, 30 degrees, % none, the precomputation time and the refinement rounds. Then,
    /// over 64 random views (random clip and time, direction even over the sphere, at three
    /// radii) culled by the backface test alone with the classes at --alpha: the meshlets,
    /// triangles and vertex skinning in culled meshlets, against the triangles that face away
    /// one by one (what per-triangle culling removes).
    Bounds {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        #[arg(long, default_value = "all", value_parser = builder_names(true))]
        builder: String,
        /// Clip names or indices, comma-separated (default: all clips, as one union).
        #[arg(long)]
        clips: Option<String>,
        #[command(flatten)]
        refine: RefineArgs,
        #[arg(long)]
        json: bool,
    },
    /// Bake a character: meshlets, conservative bounds and classes, vertices, in one file.
    ///
    /// Builds meshlets for the whole character (every node of the default scene that draws a
    /// triangle mesh: skinned, rigid and static parts), computes bounds that hold over the
    /// union of the chosen clips (key intervals, then refinement within --budget), classifies
    /// each meshlet at --sr and --alpha, and writes the bake file (layout: docs/FORMAT.md)
    /// atomically. Same input and options give the same bytes unless the budget cuts the
    /// refinement short (the summary then says how to reproduce it).
    Bake {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        /// Output bake file.
        #[arg(short, long)]
        out: PathBuf,
        /// The meshlet builder: skin-aware (meshlets that move with one joint: the tightest
        /// animated bounds) or cone-split (built for backface culling: skin-aware meshlets cut
        /// by face normal, over poses sampled from the clips, where the cut saves skinning;
        /// 11-22% more meshlets, docs/BOUNDS.md). `skinlet meshlets FILE` compares all seven.
        #[arg(long, default_value = "skin-aware", value_parser = builder_names(false))]
        builder: String,
        /// Clip names or indices, comma-separated (default: all clips, as one union).
        #[arg(long)]
        clips: Option<String>,
        #[command(flatten)]
        refine: RefineArgs,
        /// Also store 5 overdraw-reducing index buffers and their lookup table (Han & Sander's
        /// "joint" clustering over up to 16 key times per clip, compact patches of 32; see
        /// `skinlet overdraw`).
        #[arg(long)]
        overdraw: bool,
        /// Also store contour patches with bounds over the clips (see `skinlet contours`):
        /// `all` for every contour, `visible` without the concave rigid edges whose contours
        /// are always hidden.
        #[arg(long, value_parser = ["all", "visible"])]
        contours: Option<String>,
        /// Also store bounds for poses that are not the clips played alone (crossfades,
        /// additive layers, IK): a pose envelope, i.e. per joint a cap of rotations around a
        /// centre and translation and scale boxes, with meshlet bounds for every pose inside
        /// it, and any-pose boxes for the poses outside. `clips` makes the envelope around the
        /// baked clips (between keys too), `clips:MARGIN_DEG` widens every cap by the margin
        /// (for additive layers and IK), and a .json file of joint limits replaces the caps of
        /// the joints it names (format: docs/FORMAT.md, `ENVL`).
        #[arg(long, value_name = "clips[:MARGIN_DEG]|FILE.json")]
        envelope: Option<String>,
        /// Also store a cluster LOD hierarchy per part (docs/FORMAT.md, `LODC`): groups of 8
        /// adjacent clusters simplified to about half with their borders locked and the
        /// vertices' positions at 8 poses of the clips as attributes, level by level; each
        /// group's error bounds how far its clusters get from the full detail mesh at every
        /// pose of the clips, and its clusters get conservative bounds like the meshlets'. With
        /// --envelope, also errors and cluster bounds that hold at every pose inside the
        /// envelope (`LODE`: for crossfades, additive layers and IK).
        #[arg(long)]
        lod: bool,
        /// Print a JSON summary: meshlets, both_pct, frustum_only_pct, none_pct, precompute_s, ...
        #[arg(long)]
        json: bool,
    },
    /// Check conservative bounds against densely sampled reference skinning.
    ///
    /// Samples every chosen clip at --samples evenly spaced times plus every key time and
    /// every key-interval midpoint, skins every vertex, and checks every vertex against its
    /// meshlet's sphere and every triangle's normal against its cone, in the meshlet's joint
    /// space as the runtime culls. A bake's pose envelope (`bake --envelope`) is checked at
    /// --samples poses inside it, half on its boundary; the parts' boxes per clip window at
    /// every sample time; a bake's cluster LOD hierarchy (`bake --lod`): its clusters' bounds like
    /// the meshlets', its errors at up to 16 evenly spaced times per clip (every point of every
    /// group's clusters within the group's error of the full detail mesh, the full detail mesh
    /// within three cuts' errors of the cuts), and with an envelope the same within it. The bounds are computed afresh, or read from a bake file (--baked; its
    /// clips are checked, and FILE must be the file it was baked from). Exits with status 1 on
    /// any violation beyond float rounding.
    Verify {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        /// Check the bounds stored in this bake file instead of computing them.
        #[arg(long)]
        baked: Option<PathBuf>,
        #[arg(long, default_value = "skin-aware", value_parser = builder_names(false))]
        builder: String,
        /// Clip names or indices, comma-separated (default: all clips, as one union).
        #[arg(long)]
        clips: Option<String>,
        #[command(flatten)]
        refine: RefineArgs,
        /// Evenly spaced samples per clip (key times and midpoints are added).
        #[arg(long, default_value_t = 2000)]
        samples: usize,
        #[arg(long)]
        json: bool,
    },
    /// Cull a crowd of animated instances on the CPU and report what culling saves.
    ///
    /// The scene of the conservative-bounds paper (fig. 10): instances on a grid that fills
    /// and overflows the view, a quarter of them on the frustum's side planes, each playing a
    /// clip from a random offset, a fixed camera. Per frame and instance: per-meshlet culling
    /// with the baked bounds by each pipeline (backface only, frustum only, both), per-triangle
    /// culling in the kept meshlets, whole-mesh culling by per-joint boxes. --check verifies
    /// every culled triangle by brute force on the reference-skinned mesh (exit 1 if one was
    /// visible).
    ///
    /// FILE is a bake (`skinlet bake`; then --gltf names the glTF file it was baked from,
    /// for the skeleton and clips) or a glTF file, baked first.
    #[command(alias = "crowd")]
    Cull {
        /// A bake file, a .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        /// The glTF file a bake was made from (required with a bake file).
        #[arg(long)]
        gltf: Option<String>,
        /// The layout: the paper's crowd.
        #[arg(long, default_value = "crowd", value_parser = ["crowd"])]
        layout: String,
        /// The meshlet builder a glTF file is baked with (default skin-aware). A bake keeps
        /// its own: naming another builder with a bake file is an error.
        #[arg(long, value_parser = builder_names(false))]
        builder: Option<String>,
        #[arg(long, default_value_t = 64)]
        instances: usize,
        #[arg(long, default_value_t = 30)]
        frames: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// An orthographic camera instead of a perspective one.
        #[arg(long)]
        ortho: bool,
        /// Check every culled triangle by brute force (reports false_culls).
        #[arg(long, alias = "verify")]
        check: bool,
        /// How the instances are posed. `clips`: each plays its clip, culled with the clip
        /// bounds. The others need a pose envelope (a glTF file is baked with
        /// `--envelope clips:ADDITIVE_DEG`; a bake must have one) and cull each instance-frame
        /// with the envelope bounds when the guard admits its pose, else with the any-pose
        /// boxes (frustum only): `blend` crossfades random clip pairs with random weights,
        /// `additive` turns every joint by a random rotation of up to --additive-deg, `ik`
        /// sets two random joints, one inside its range of motion and in half the frames
        /// one 20° beyond it.
        #[arg(long, default_value = "clips", value_parser = ["clips", "blend", "additive", "ik"])]
        animation: String,
        /// Largest rotation of the additive layer, degrees (and the envelope margin when a
        /// glTF file is baked here).
        #[arg(long, default_value_t = 10.0)]
        additive_deg: f32,
        #[command(flatten)]
        refine: RefineArgs,
        #[arg(long)]
        json: bool,
    },
    /// Compare triangle orders for overdraw and vertex-cache use (Han & Sander 2016, table 2).
    ///
    /// Methods: original (vertex-cache order only), tipsify-per-frame (Sander 2007 per
    /// keyframe: one buffer per keyframe), single (k buffers per clip from clustering
    /// keyframe x viewpoint nodes), joint (k buffers for all clips). ACMR for a 16-entry FIFO
    /// cache; OVR averaged over random (keyframe, viewpoint) pairs at 3x the bounding radius,
    /// rendered by skinlet's software rasterizer. `skinlet bake --overdraw` stores the joint
    /// clustering's buffers and their lookup in the bake.
    Overdraw {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        /// Clip names or indices, comma-separated (default: all clips).
        #[arg(long)]
        clips: Option<String>,
        /// Index buffers per clustering.
        #[arg(long, default_value_t = 5)]
        k: usize,
        /// Cut the patches the paper's way (fast linear clustering of the Tipsify order) at
        /// this threshold: 0.85 in the paper, 3 ignores the vertex cache. Default: compact
        /// patches (--patch-size).
        #[arg(long, conflicts_with = "patch_size")]
        lambda: Option<f32>,
        /// Compact patches (meshlets with a normal-cone weight, each in Tipsify order) of at
        /// most this many vertices and triangles (4 to 256): the default patch rule. The size
        /// grows by a quarter while the patches' ACMR (cache emptied at every patch) is above 0.9.
        #[arg(long, default_value_t = 32)]
        patch_size: u32,
        /// At most this many keyframes per clip (evenly chosen key times).
        #[arg(long, default_value_t = 32)]
        max_keyframes: usize,
        /// Random (keyframe, viewpoint) samples per clip for the OVR column.
        #[arg(long, default_value_t = 300)]
        views: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// How clusters order their patches: by measured occlusion between patches (ours), or
        /// by mean distance to the eye (the paper's).
        #[arg(long, default_value = "occlusion", value_parser = ["occlusion", "distance"])]
        order: String,
        /// Also write an overdraw heat map (PNG): keyframe 0 of the first clip from the front,
        /// original order left, clustered order right (blue 1, green 2, yellow 3, red 5+).
        #[arg(long)]
        heatmap: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Find mesh contours (edges between front- and back-facing faces) and compare
    /// extractors (Tsiapkolis & Bénard 2024).
    ///
    /// Skinned files (with clips) are evaluated over sampled frames of their clips with the
    /// skinned methods; static files (and --static) in one pose with the static methods.
    /// Methods: brute (every edge), patches (ours: greedy patch decomposition, Reduced
    /// Sphere), patches-mean (Mean Sphere), snch (Johnson & Cohen's normal cone hierarchy),
    /// meshlets (meshoptimizer 16-face meshlets as patches, with a correct cone). Each runs
    /// from 42 directions x 6 distances (5 to 100 model sizes); columns: patches or nodes, %
    /// of edges tested, ms per view and speed-up over brute force (timed in the same run),
    /// build time, views whose edge set differs from brute force (must be 0), mean patch
    /// radius (model sizes) and cone half-angle.
    Contours {
        /// .glb, .gltf or .obj file, or @demo[:TRIANGLES].
        file: String,
        #[command(flatten)]
        args: contours::Args,
    },
    /// Render a posed character offscreen on the GPU (wgpu, Vulkan; Mesa's lavapipe where
    /// there is no GPU) and write a PNG.
    ///
    /// --view shaded draws the posed character by the pipeline --skinning picks (all give the
    /// same image); --view meshlets colors its skin-aware meshlets, --view classes their
    /// culling classes; --view culled shows what the conservative bounds cull for a close
    /// camera, seen by an observer; --view contours draws the contour edges extracted on the
    /// GPU; --view overdraw compares heat maps of two triangle orders. Views are framed on the
    /// posed character; the shading is faceted (flat per triangle).
    Render {
        /// .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        #[command(flatten)]
        args: render::Args,
    },
    /// Time the paper's crowd scene on the GPU through every pipeline.
    ///
    /// Skinning pipelines: VS (vertex shader), CS (compute pass, then drawn), MS (mesh shader,
    /// one workgroup per skin-aware meshlet), MS-CI (mesh shader, common-influences meshlets
    /// with their joints once per meshlet and weight-only vertices). Culling: none, frustum,
    /// backface or both, per meshlet with the bake's conservative bounds, in a task shader
    /// (MS) or a compute pass writing indirect draws (VS). Reports the median GPU time per
    /// frame (timestamp queries), wall-clock time, meshlets culled and triangles drawn.
    GpuBench {
        /// A bake file, a .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        #[command(flatten)]
        args: gpu_bench::Args,
    },
    /// What cluster LOD saves on a crowd: triangles and vertex references drawn.
    ///
    /// Bakes the character with its cluster LOD hierarchy (`bake --lod`; a bake file keeps
    /// its own), lays out the crowd of `gpu-bench` at the image size, poses every instance
    /// for a few frames, and gives each the cut at the pixel threshold projected at the
    /// nearest point of the box around its parts' boxes: no point moves more than that many
    /// pixels from where full detail draws it (docs/LOD.md). Counts the cuts' triangles and
    /// vertex references against full detail, on the CPU and before any culling.
    Lod {
        /// A bake file, a .glb or .gltf file, or @demo[:TRIANGLES].
        file: String,
        #[command(flatten)]
        args: lod::Args,
    },
    /// Measure skinlet's speed against a baseline, in the same run.
    Bench {
        #[command(subcommand)]
        what: bench::What,
    },
    /// Describe the built-in demo character and pose it through each clip.
    Demo {
        /// Approximate triangle count (1000 to 1000000).
        #[arg(long, default_value_t = 20_000)]
        triangles: usize,
        /// Seed of the procedural generator.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Also write the character as a glTF binary (.glb) for other glTF tools.
        #[arg(long)]
        glb: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
}

fn main() {
    // Die quietly when the reader of our output goes away (`skinlet inspect x.glb | head`),
    // as Unix tools do, instead of panicking on a broken pipe.
    #[cfg(unix)]
    // SAFETY: restoring the default action of SIGPIPE before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    SELECTION.get_or_init(|| Selection { scene: cli.scene, nodes: cli.node.clone(), parts: cli.part.clone() });
    let result = match cli.command {
        Command::Inspect { file, json } => inspect(&file, json),
        Command::Pose { file, clip, time, json } => pose(&file, clip.as_deref(), time, json),
        Command::Meshlets { file, builder, max_vertices, max_triangles, json } => {
            meshlets(&file, &builder, MeshletLimits { max_vertices, max_triangles }, json)
        }
        Command::Bounds { file, builder, clips, refine, json } => {
            bounds(&file, &builder, clips.as_deref(), refine, json)
        }
        Command::Bake { file, out, builder, clips, refine, overdraw, contours, envelope, lod, json } => bake::run(
            &file,
            &out,
            &builder,
            clips.as_deref(),
            refine,
            bake::Extras { overdraw, contours: contours.as_deref(), envelope: envelope.as_deref(), lod },
            json,
        ),
        Command::Verify { file, baked, builder, clips, refine, samples, json } => {
            verify(&file, baked.as_deref(), &builder, clips.as_deref(), refine, samples, json)
        }
        Command::Cull {
            file,
            gltf,
            layout: _,
            builder,
            instances,
            frames,
            seed,
            ortho,
            check,
            animation,
            additive_deg,
            refine,
            json,
        } => {
            use skinlet_lab::crowd::Animation;
            let animation = match animation.as_str() {
                "blend" => Animation::Blend,
                "additive" => Animation::Additive(additive_deg.to_radians()),
                "ik" => Animation::Ik,
                _ => Animation::Clips,
            };
            let params = skinlet_lab::crowd::CrowdParams {
                instances,
                frames,
                seed,
                orthographic: ortho,
                animation,
                ..Default::default()
            };
            crowd::command(&file, gltf.as_deref(), builder.as_deref(), &params, check, additive_deg, refine, json)
        }
        Command::Overdraw { file, clips, k, lambda, patch_size, max_keyframes, views, seed, order, heatmap, json } => {
            let order = if order == "distance" { PatchOrder::Distance } else { PatchOrder::Occlusion };
            let params = skinlet::overdraw::cluster::ClusterParams { k, seed, order, ..Default::default() };
            overdraw::patch_rule(lambda, patch_size).and_then(|patches| {
                let params = skinlet::overdraw::cluster::ClusterParams { patches, ..params };
                overdraw::command(&file, clips.as_deref(), max_keyframes, views, &params, heatmap.as_deref(), json)
            })
        }
        Command::Contours { file, args } => contours::command(&file, &args),
        Command::Bench { what } => bench::command(&what),
        Command::Render { file, args } => render::command(&file, &args),
        Command::GpuBench { file, args } => gpu_bench::command(&file, &args),
        Command::Lod { file, args } => lod::command(&file, &args),
        Command::Demo { triangles, seed, glb, json } => demo(triangles, seed, glb.as_deref(), json),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(2);
    }
}

/// Loads a file, or a built-in: the demo character (`@demo[:TRIANGLES]`), a scan-like noisy
/// sphere (`@sphere[:TRIANGLES[:NOISE]]`) or a thin-shelled cup (`@cup[:TRIANGLES[:NOISE]]`).
fn load(file: &str) -> Result<Asset> {
    use skinlet_lab::scans::{Noise, noisy_sphere, thin_shell_cup};
    let Some(builtin) = file.strip_prefix('@') else {
        return Ok(skinlet::import::load(Path::new(file))?);
    };
    let mut fields = builtin.split(':');
    let name = fields.next().unwrap_or_default();
    let mut number = |what: &str| -> Result<Option<f64>> {
        let Some(f) = fields.next() else { return Ok(None) };
        let x: f64 = f.parse().with_context(|| format!("bad {what} {f:?} in {file:?}"))?;
        anyhow::ensure!(x.is_finite() && x >= 0.0, "{file:?}: the {what} must be a number >= 0");
        Ok(Some(x))
    };
    let triangles = number("triangle count")?;
    anyhow::ensure!(triangles.is_none_or(|t| t <= 2e7), "{file:?}: at most 20,000,000 triangles");
    let noise = number("noise")?;
    anyhow::ensure!(fields.next().is_none(), "{file:?}: too many fields (NAME[:TRIANGLES[:NOISE]])");
    let noise = match noise {
        Some(_) if name == "demo" => bail!("{file:?}: the demo takes no noise (@demo[:TRIANGLES])"),
        Some(n) => Noise { amount: n as f32, ..Noise::default() },
        None => Noise::default(),
    };
    let (positions, tris) = match name {
        "demo" => {
            let triangles = triangles.map_or(DemoParams::default().triangles, |t| t as usize);
            return Ok(demo_character(&DemoParams { triangles, ..DemoParams::default() }));
        }
        "sphere" => noisy_sphere(triangles.map_or(100_000, |t| t as usize), &noise),
        "cup" => thin_shell_cup(triangles.map_or(100_000, |t| t as usize), 0.02, &noise),
        _ => bail!("unknown built-in {file:?} (@demo, @sphere or @cup, optionally with :TRIANGLES)"),
    };
    Ok(Asset::from_static(file, positions, tris)?)
}

fn interp_names(c: &skinlet_lab::summary::ClipSummary) -> Vec<&'static str> {
    c.interpolation.iter().map(|i| i.name()).collect()
}

/// What `inspect` says of each part: node, its name, mesh, primitive, kind, vertices, triangles.
fn part_rows(asset: &Asset, character: &Character) -> Vec<(u32, String, u32, u32, String, usize, usize)> {
    let animated = |node| asset.clips.iter().any(|c| !c.key_times_affecting(&asset.skeleton, node).is_empty());
    (character.parts.iter())
        .map(|p| {
            let mut kind = match p.kind {
                skinlet::PartKind::Skinned { skin } => format!("skinned by skin {skin}"),
                skinlet::PartKind::Rigid if animated(p.node) => "rigid, animated".to_string(),
                skinlet::PartKind::Rigid => "rigid, static".to_string(),
            };
            let targets = asset.meshes[p.mesh as usize].morph_targets();
            if targets > 0 {
                let animated = asset.clips.iter().any(|c| c.weights.iter().any(|w| w.channel.node == p.node));
                kind += &format!(", {targets} morph targets{}", if animated { " (animated)" } else { "" });
            }
            let name = asset.skeleton.nodes[p.node as usize].name.clone();
            (p.node, name, p.mesh, p.primitive, kind, p.vertices.len(), p.triangles.len())
        })
        .collect()
}

fn inspect(file: &str, json: bool) -> Result<()> {
    let asset = load(file)?;
    let s = summarize(&asset);
    let r = &asset.report;
    let character = character_of(&asset);
    let parts = character.as_ref().map(|c| part_rows(&asset, c)).unwrap_or_default();
    let character_error = character.as_ref().err().map(|e| e.to_string());
    if json {
        let out = json!({
            "file": file,
            "parts": parts.iter().map(|(node, name, mesh, prim, kind, v, t)| json!({
                "node": node, "name": name, "mesh": mesh, "primitive": prim, "kind": kind, "vertices": v, "triangles": t,
            })).collect::<Vec<_>>(),
            "drawn_triangles": character.as_ref().map(|c| c.triangle_count()).ok(),
            "drivers": character.as_ref().map(|c| c.palette.joints.len()).ok(),
            "character_error": character_error,
            "vertices": s.vertices,
            "welded_vertices": s.welded_vertices,
            "triangles": s.triangles,
            "joints": s.joints,
            "instances": s.instances,
            "meshes": s.meshes.iter().map(|m| json!({
                "name": m.name,
                "primitives": m.primitives.iter().map(|p| json!({
                    "index": p.index, "vertices": p.vertices, "welded_vertices": p.welded_vertices,
                    "triangles": p.triangles, "skinned": p.skinned, "morph_targets": p.morph_targets,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "skins": s.skins.iter().map(|k| json!({"name": k.name, "joints": k.joints, "depth": k.depth})).collect::<Vec<_>>(),
            "influence_histogram": s.influence_histogram,
            "renormalized_vertices": r.renormalized_vertices,
            "zero_weight_vertices": r.zero_weight_vertices,
            "degenerate_triangles": r.degenerate_triangles,
            "warnings": r.warnings,
            "clips": s.clips.iter().map(|c| json!({
                "name": c.name,
                "start": c.start,
                "end": c.end,
                "duration": c.duration,
                "keys": c.keys,
                "max_channel_keys": c.max_channel_keys,
                "channels": {"translation": c.channels[0], "rotation": c.channels[1], "scale": c.channels[2], "weights": c.channels[3]},
                "animated_nodes": c.animated_nodes,
                "interpolation": interp_names(c),
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("{file}");
    println!(
        "  {} vertices, {} triangles, {} joints, {} mesh instances",
        s.vertices, s.triangles, s.joints, s.instances
    );
    for (i, m) in s.meshes.iter().enumerate() {
        println!("  mesh {i} {:?}", m.name);
        for p in &m.primitives {
            let extra =
                if p.morph_targets > 0 { format!(", {} morph targets", p.morph_targets) } else { String::new() };
            println!(
                "    primitive {}: {} vertices ({} after welding position + skin), {} triangles{}{extra}",
                p.index,
                p.vertices,
                p.welded_vertices,
                p.triangles,
                if p.skinned { ", skinned" } else { "" }
            );
        }
    }
    for (i, k) in s.skins.iter().enumerate() {
        println!("  skin {i} {:?}: {} joints, hierarchy depth {}", k.name, k.joints, k.depth);
    }
    match &character {
        Ok(c) => {
            println!(
                "  the character: {} parts, {} triangles drawn, {} drivers (joints and rigid nodes)",
                c.parts.len(),
                c.triangle_count(),
                c.palette.joints.len()
            );
            for (node, name, mesh, prim, kind, v, t) in &parts {
                println!(
                    "    node {node:>4} {name:<24} mesh {mesh} primitive {prim}: {kind}, {v} vertices, {t} triangles"
                );
            }
        }
        Err(e) => println!("  the character cannot be built: {e}"),
    }
    if s.influence_histogram.iter().any(|&c| c > 0) {
        let h: Vec<String> = s
            .influence_histogram
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(k, c)| format!("{}:{c}", k + 1))
            .collect();
        println!("  influences per vertex (count:vertices): {}", h.join("  "));
    }
    println!(
        "  weights renormalized: {} vertices; all-zero weights: {} vertices; degenerate triangles: {}",
        r.renormalized_vertices, r.zero_weight_vertices, r.degenerate_triangles
    );
    if !s.clips.is_empty() {
        println!("  clips:");
        println!(
            "    {:<32} {:>9} {:>9} {:>6} {:>16}  interpolation",
            "name", "start s", "dur s", "keys", "channels T/R/S/W"
        );
        for (i, c) in s.clips.iter().enumerate() {
            let name = if c.name.is_empty() { format!("(unnamed #{i})") } else { c.name.clone() };
            let ch = format!("{}/{}/{}/{}", c.channels[0], c.channels[1], c.channels[2], c.channels[3]);
            println!(
                "    {:<32} {:>9.4} {:>9.4} {:>6} {:>16}  {}",
                name,
                c.start,
                c.duration,
                c.keys,
                ch,
                interp_names(c).join(",")
            );
        }
    }
    for w in &r.warnings {
        println!("  warning: {w}");
    }
    Ok(())
}

/// Writes an 8-bit PNG (`data`: rows top to bottom, `color`'s channels per pixel).
fn write_png(path: &Path, width: u32, height: u32, color: png::ColorType, data: &[u8]) -> Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(data)?;
    Ok(())
}

fn find_clip<'a>(asset: &'a Asset, name: Option<&str>) -> Result<Option<&'a Clip>> {
    let Some(name) = name else { return Ok(asset.clips.first()) };
    if let Some(c) = asset.clips.iter().find(|c| c.name == name) {
        return Ok(Some(c));
    }
    if let Some(c) = name.parse::<usize>().ok().and_then(|i| asset.clips.get(i)) {
        return Ok(Some(c));
    }
    let names: Vec<String> = asset.clips.iter().enumerate().map(|(i, c)| format!("{i}: {:?}", c.name)).collect();
    bail!("no clip {name:?}; the file has {}", if names.is_empty() { "no clips".into() } else { names.join(", ") })
}

fn vec3_rows(v: &[glam::Vec3]) -> Value {
    Value::Array(v.iter().map(|p| json!([p.x, p.y, p.z])).collect())
}

fn pose(file: &str, clip: Option<&str>, time: f32, json: bool) -> Result<()> {
    if !time.is_finite() {
        bail!("--time must be a finite number of seconds");
    }
    let (asset, character) = load_character(file)?;
    let clip = find_clip(&asset, clip)?;
    // Morphs, then skinning, of every part at once.
    let (positions, normals) = character.posed(&asset.skeleton, clip, time)?;
    let mut entries = Vec::new();
    for part in &character.parts {
        let source = asset.meshes[part.mesh as usize].primitives.iter().find(|p| p.index == part.primitive as usize);
        let has_normals = source.is_some_and(|p| !p.geometry.normals.is_empty());
        let range = part.vertices.start as usize..part.vertices.end as usize;
        let n = if has_normals { normals[range.clone()].to_vec() } else { Vec::new() };
        entries.push((part.node, part.mesh, part.primitive, positions[range].to_vec(), n));
    }
    if json {
        let prims: Vec<Value> = entries
            .iter()
            .map(|(node, mesh, prim, p, n)| {
                json!({
                    "node": node, "mesh": mesh, "primitive": prim,
                    "positions": vec3_rows(p),
                    "normals": if n.is_empty() { Value::Null } else { vec3_rows(n) },
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::to_string(&json!({ "clip": clip.map(|c| c.name.clone()), "time": time, "primitives": prims }))?
        );
        return Ok(());
    }
    let clip_name = clip.map_or("(rest pose)".to_string(), |c| format!("{:?}", c.name));
    println!("{file}: clip {clip_name} at t = {time} s");
    for (node, mesh, prim, p, _) in &entries {
        let (lo, hi) = bbox(p);
        println!("  node {node} mesh {mesh} primitive {prim}: {} vertices, bounds {lo:.4} .. {hi:.4}", p.len());
    }
    Ok(())
}

fn bbox(p: &[glam::Vec3]) -> (glam::Vec3, glam::Vec3) {
    p.iter().fold((glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

fn demo(triangles: usize, seed: u64, glb: Option<&Path>, json: bool) -> Result<()> {
    if !(100..=5_000_000).contains(&triangles) {
        bail!("--triangles must be between 100 and 5000000");
    }
    let started = std::time::Instant::now();
    let asset = demo_character(&DemoParams { seed, triangles });
    let build_s = started.elapsed().as_secs_f64();
    if let Some(path) = glb {
        std::fs::write(path, skinlet::export::to_glb(&asset)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let s = summarize(&asset);
    let character = character_of(&asset)?;
    let skin = &character.palette;
    let posed = |clip, t| skinlet::skinning::posed_positions(&asset.skeleton, skin, &character.mesh, clip, t);
    let (rest_lo, rest_hi) = bbox(&posed(None, None)?);
    let mut clips = Vec::new();
    for clip in &asset.clips {
        // Pose at 33 evenly spaced times and report the swept bounding box.
        let (mut lo, mut hi) = (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY);
        for k in 0..=32 {
            let t = clip.start + clip.duration() * k as f32 / 32.0;
            let (a, b) = bbox(&posed(Some(clip), Some(t))?);
            lo = lo.min(a);
            hi = hi.max(b);
        }
        clips.push((clip, lo, hi));
    }
    // The bake: meshlets, conservative bounds over all clips (refined until nothing improves,
    // at most 60 s), classification, then a dense check against reference skinning.
    let all: Vec<&Clip> = asset.clips.iter().collect();
    let how = skinlet::bounds::refine::Refinement {
        budget: Some(std::time::Duration::from_secs(60)),
        max_rounds: usize::MAX,
        ..skinlet::bounds::refine::Refinement::NONE
    };
    let (baked, stats) =
        skinlet::bake::bake(&asset, &character, &all, Builder::SkinAware, MeshletLimits::NVIDIA, &how, &mut |_| {})?;
    let (meshlets, bounds) = (&baked.meshlets, &baked.bounds);
    let precompute_s = stats.precompute.as_secs_f64();
    let (both, frustum, none) = bake::class_shares(&baked);
    let check =
        skinlet::bounds::verify::verify_bounds(&asset.skeleton, skin, &all, &baked.mesh, meshlets, bounds, 200)?;
    let bake_bytes = skinlet::bake::to_bytes(&baked).len();
    // A small crowd scene: 16 instances, 10 frames, every culled triangle checked.
    let crowd_params = skinlet_lab::crowd::CrowdParams { instances: 16, frames: 10, ..Default::default() };
    let scene = skinlet_lab::crowd::posed_crowd(&asset.skeleton, skin, &baked.mesh, &all, &crowd_params)?;
    let crowd_stats = skinlet_lab::crowd::run(&baked, &asset.skeleton, skin, &all, &scene, &crowd_params, true)?;
    // Game poses: the same crowd with IK on top of the clips, culled with a pose envelope
    // (the clips widened by 10°) where the guard admits the pose, else the any-pose boxes.
    let mut with_envelope = baked.clone();
    let envelope = bake::envelope_of("clips:10", &asset, &with_envelope)?;
    skinlet::bake::add_envelope(&mut with_envelope, &asset, envelope)?;
    let ik_params = skinlet_lab::crowd::CrowdParams { animation: skinlet_lab::crowd::Animation::Ik, ..crowd_params };
    let ik_stats = skinlet_lab::crowd::run(&with_envelope, &asset.skeleton, skin, &all, &scene, &ik_params, true)?;
    if json {
        let out = json!({
            "meshlets": meshlets.len(), "both_pct": both, "frustum_only_pct": frustum, "none_pct": none,
            "precompute_s": precompute_s, "refine_rounds": baked.settings.rounds, "bake_bytes": bake_bytes,
            "verify_samples": check.samples, "violations": check.violations(),
            "crowd": crowd::to_json(&crowd_stats, true),
            "ik_crowd": crowd::to_json(&ik_stats, true),
            "seed": seed,
            "vertices": s.vertices,
            "triangles": s.triangles,
            "joints": s.joints,
            "influence_histogram": s.influence_histogram,
            "build_s": build_s,
            "clips": clips.iter().map(|(c, lo, hi)| json!({
                "name": c.name, "duration": c.duration(), "keys": c.key_times().len(),
                "interpolation": c.interpolations().iter().map(|i| i.name()).collect::<Vec<_>>(),
                "swept_min": lo.to_array(), "swept_max": hi.to_array(),
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("skinlet demo character (seed {seed}), built in {:.2} s", build_s);
    println!(
        "  a procedural creature: {} joints in a branching skeleton, {} vertices, {} triangles",
        s.joints, s.vertices, s.triangles
    );
    let rigid = character.parts.iter().filter(|p| p.kind == skinlet::PartKind::Rigid).count();
    println!(
        "  a whole character: {} parts ({} skinned by {} skins, {rigid} rigid), {} drivers, {} triangles drawn",
        character.parts.len(),
        character.parts.len() - rigid,
        asset.skins.len(),
        character.palette.joints.len(),
        character.triangle_count()
    );
    let morphs = &character.mesh.morphs;
    let morphed = (0..character.mesh.positions.len()).filter(|&v| !morphs.of(v).is_empty()).count();
    println!(
        "  a morph face: {} morph weights animated by every clip, moving {morphed} vertices before skinning",
        morphs.weights.len()
    );
    let h: Vec<String> =
        s.influence_histogram.iter().take(4).enumerate().map(|(k, c)| format!("{}:{c}", k + 1)).collect();
    println!("  soft skinning, vertices by influence count: {}", h.join("  "));
    println!("  rest-pose bounds {rest_lo:.3} .. {rest_hi:.3}");
    println!("  clips (bounds swept over 33 poses per clip):");
    for (c, lo, hi) in &clips {
        let modes: Vec<&str> = c.interpolations().iter().map(|i| i.name()).collect();
        println!(
            "    {:<8} {:>5.2} s, {:>3} keys, {:<12} swept {lo:.3} .. {hi:.3}",
            c.name,
            c.duration(),
            c.key_times().len(),
            modes.join(","),
        );
    }
    println!(
        "  baked ({bake_bytes} bytes): {} skin-aware meshlets, conservative bounds over all clips in {precompute_s:.2} s ({} refinement rounds)",
        meshlets.len(),
        baked.settings.rounds
    );
    println!(
        "  classes (s_r 3, 20°): {both:.0}% frustum+backface cullable, {frustum:.0}% frustum only, {none:.0}% none"
    );
    println!(
        "  verified against reference skinning at {} times: {} vertex and {} normal checks, {} violations",
        check.samples,
        check.vertex_checks,
        check.normal_checks,
        check.violations()
    );
    println!("  crowd scene (CPU culling with the baked bounds):");
    crowd::print(&crowd_stats, true);
    println!("  the same crowd with IK on top (pose envelope: the clips widened by 10°):");
    crowd::print(&ik_stats, true);
    println!(
        "  next: `skinlet inspect @demo`, `skinlet meshlets @demo`, `skinlet bounds @demo`, `skinlet bake @demo -o demo.skinlet`, `skinlet verify @demo --baked demo.skinlet`, `skinlet cull demo.skinlet --gltf @demo`"
    );
    Ok(())
}

fn meshlets(file: &str, builder: &str, limits: MeshletLimits, json: bool) -> Result<()> {
    let (asset, character, prepared) = prepared_character(file)?;
    if prepared.mesh.triangles.is_empty() {
        bail!("{file} has no triangles to split");
    }
    let poses = clip_poses(&asset, &character.palette, 32);
    let builders: Vec<Builder> = match Builder::from_name(builder) {
        Some(b) => vec![b],
        None => Builder::ALL.to_vec(),
    };
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let mut rows = Vec::new();
    for b in builders {
        let started = std::time::Instant::now();
        let motion = skinlet::meshlet::motion_for(b, &asset.skeleton, &character.palette, &prepared.mesh, &clips)?;
        let m = skinlet::meshlet::build_moving(&prepared, b, limits, motion.as_ref())?;
        let build_ms = started.elapsed().as_secs_f64() * 1e3;
        m.validate(&prepared.mesh.triangles, limits)?;
        let spread = skinlet::meshlet::stats::animated_radius_ratio(&prepared.mesh, &m, &poses);
        rows.push((b, skinlet::meshlet::stats::compute(&prepared.mesh, &m), build_ms, spread));
    }
    if json {
        let out: Vec<Value> = rows
            .iter()
            .map(|(b, s, ms, spread)| {
                json!({
                    "builder": b.name(), "meshlets": s.meshlets, "avg_vertices": s.avg_vertices,
                    "avg_triangles": s.avg_triangles, "vertex_refs_ratio": s.vertex_refs_ratio,
                    "single_joint_set_pct": s.single_joint_set_pct, "dominant_joint_pct": s.dominant_joint_pct,
                    "bytes": s.bytes, "bytes_fat": s.bytes_fat, "cone_cull_pct": s.cone_cull_pct, "build_ms": ms,
                    "animated_radius_ratio": spread,
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let w = &prepared.weld;
    println!(
        "{file}: {} triangles, {} vertices ({} after welding), limits {}/{}",
        prepared.mesh.triangles.len(),
        w.input_vertices,
        w.output_vertices,
        limits.max_vertices,
        limits.max_triangles
    );
    println!(
        "  {:<18} {:>8} {:>7} {:>7} {:>6} {:>9} {:>9} {:>22} {:>8} {:>9} {:>7}",
        "builder",
        "meshlets",
        "avg v",
        "avg t",
        "refs",
        "1 set %",
        "dom. %",
        "bytes slim (fat)",
        "cone %",
        "build ms",
        "anim r"
    );
    for (b, s, ms, spread) in &rows {
        println!(
            "  {:<18} {:>8} {:>7.1} {:>7.1} {:>6.2} {:>9.1} {:>9.1} {:>22} {:>8.1} {:>9.1} {:>7.3}",
            b.name(),
            s.meshlets,
            s.avg_vertices,
            s.avg_triangles,
            s.vertex_refs_ratio,
            s.single_joint_set_pct,
            s.dominant_joint_pct,
            format!("{} ({})", s.bytes, s.bytes_fat),
            s.cone_cull_pct,
            ms,
            spread
        );
    }
    Ok(())
}

/// Skinning matrices of `skin` at `per_clip` evenly spaced times of every clip.
fn clip_poses(asset: &Asset, skin: &skinlet::Skin, per_clip: usize) -> Vec<Vec<glam::Affine3A>> {
    let mut poser = Poser::default();
    let mut poses = Vec::new();
    for clip in &asset.clips {
        for k in 0..per_clip {
            let t = clip.start + clip.duration() * k as f32 / (per_clip - 1).max(1) as f32;
            let mut mats = Vec::new();
            poser.skinning_matrices(&asset.skeleton, skin, Some(clip), t, &mut mats);
            poses.push(mats);
        }
    }
    poses
}

/// The clips named in a comma-separated list (names or indices), or all of them.
fn select_clips<'a>(asset: &'a Asset, list: Option<&str>) -> Result<Vec<&'a Clip>> {
    match list {
        None => Ok(asset.clips.iter().collect()),
        Some(list) => list.split(',').map(|c| Ok(find_clip(asset, Some(c.trim()))?.expect("named clip"))).collect(),
    }
}

/// Loads a file and builds its whole character: every node of the default scene that draws
/// a triangle mesh. What the import changed or left out is printed to stderr.
fn load_character(file: &str) -> Result<(Asset, Character)> {
    let asset = load(file)?;
    for w in &asset.report.warnings {
        eprintln!("warning: {file}: {w}");
    }
    let character = character_of(&asset).with_context(|| format!("{file}: cannot build the character"))?;
    Ok((asset, character))
}

/// [`load_character`], and the character prepared for meshlets (parts kept apart).
fn prepared_character(file: &str) -> Result<(Asset, Character, skinlet::meshlet::PreparedMesh)> {
    let (asset, character) = load_character(file)?;
    let prepared = skinlet::bake::prepare_character(&character)?;
    Ok((asset, character, prepared))
}

fn bounds(file: &str, builder: &str, clips: Option<&str>, args: RefineArgs, json: bool) -> Result<()> {
    use skinlet::bounds::sphere_cone::{Class, classify};
    use skinlet_lab::backface_views::backface_savings;
    let how = args.refinement()?;
    let (asset, character, prepared) = prepared_character(file)?;
    let clips = select_clips(&asset, clips)?;
    let builders: Vec<Builder> = Builder::from_name(builder).map_or(Builder::ALL.to_vec(), |b| vec![b]);
    let sr = args.sr;
    let mut rows = Vec::new();
    for b in builders {
        let motion = skinlet::meshlet::motion_for(b, &asset.skeleton, &character.palette, &prepared.mesh, &clips)?;
        let meshlets = skinlet::meshlet::build_moving(&prepared, b, MeshletLimits::NVIDIA, motion.as_ref())?;
        let started = std::time::Instant::now();
        let refined = skinlet::bounds::refine::refine(
            &asset.skeleton,
            &character.palette,
            &clips,
            &prepared.mesh,
            &meshlets,
            &how,
        )?;
        let precompute_s = started.elapsed().as_secs_f64();
        let bounds = &refined.bounds;
        let pct = |alpha: f32, class: Class| {
            let n = bounds.iter().filter(|m| classify(m, sr, alpha.to_radians()) == class).count();
            100.0 * n as f64 / bounds.len().max(1) as f64
        };
        let by_alpha: Vec<(f32, f64, f64)> =
            [10.0, 20.0, 30.0].iter().map(|&a| (a, pct(a, Class::Both), pct(a, Class::FrustumOnly))).collect();
        let at_alpha =
            (pct(args.alpha, Class::Both), pct(args.alpha, Class::FrustumOnly), pct(args.alpha, Class::None));
        let classes: Vec<Class> = bounds.iter().map(|m| classify(m, sr, args.alpha.to_radians())).collect();
        let (skeleton, palette, mesh) = (&asset.skeleton, &character.palette, &prepared.mesh);
        let views = backface_savings(skeleton, palette, &clips, mesh, &meshlets, bounds, &classes, 64, 1)?;
        rows.push((b, bounds.len(), by_alpha, at_alpha, precompute_s, refined.rounds, refined.stop, views));
    }
    if json {
        let out: Vec<Value> = rows
            .iter()
            .map(|(b, n, by_alpha, at, secs, rounds, stop, v)| {
                json!({
                    "builder": b.name(), "meshlets": n, "sr": sr, "alpha_deg": args.alpha,
                    "both_pct": at.0, "frustum_only_pct": at.1, "none_pct": at.2, "precompute_s": secs,
                    "rounds": rounds, "stop": stop_name(*stop),
                    "by_alpha": by_alpha.iter().map(|(a, both, fo)| json!({"alpha_deg": a, "both_pct": both, "frustum_only_pct": fo})).collect::<Vec<_>>(),
                    "backface_views": json!({"views": v.views, "meshlets_culled_pct": v.meshlets_pct,
                        "triangles_culled_pct": v.triangles_pct, "skinning_saved_pct": v.skinning_pct,
                        "vertex_refs_skinned_per_view": v.vertex_refs_skinned,
                        "backfacing_triangles_pct": v.backfacing_triangles_pct}),
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let names: Vec<&str> = clips.iter().map(|c| c.name.as_str()).collect();
    println!("{file}: {} clips ({}), s_r = {sr}", clips.len(), names.join(", "));
    println!(
        "  {:<18} {:>8} {:>14} {:>14} {:>14} {:>7} {:>12} {:>16}",
        "builder", "meshlets", "10°: both/fr", "20°: both/fr", "30°: both/fr", "none", "precompute s", "rounds"
    );
    for (b, n, by_alpha, at, secs, rounds, stop, _) in &rows {
        let cell = |i: usize| format!("{:.0}% / {:.0}%", by_alpha[i].1, by_alpha[i].2);
        println!(
            "  {:<18} {:>8} {:>14} {:>14} {:>14} {:>6.0}% {:>12.2} {:>16}",
            b.name(),
            n,
            cell(0),
            cell(1),
            cell(2),
            at.2,
            secs,
            format!("{rounds} ({})", stop_name(*stop))
        );
    }
    println!("  backface test alone, {} random views (classes at alpha = {}°):", rows[0].7.views, args.alpha);
    println!(
        "  {:<18} {:>10} {:>10} {:>10} {:>16} {:>22}",
        "builder", "meshlets", "triangles", "skinning", "vertices skinned", "back-facing triangles"
    );
    for (b, .., v) in &rows {
        println!(
            "  {:<18} {:>9.1}% {:>9.1}% {:>9.1}% {:>16.0} {:>21.1}%",
            b.name(),
            v.meshlets_pct,
            v.triangles_pct,
            v.skinning_pct,
            v.vertex_refs_skinned,
            v.backfacing_triangles_pct
        );
    }
    Ok(())
}

/// The builders' names for `--builder`, and `all` where every builder is compared.
fn builder_names(all: bool) -> clap::builder::PossibleValuesParser {
    let names = Builder::ALL.iter().map(|b| b.name()).chain(all.then_some("all"));
    clap::builder::PossibleValuesParser::new(names)
}

fn stop_name(stop: skinlet::bounds::refine::Stop) -> &'static str {
    use skinlet::bounds::refine::Stop;
    match stop {
        Stop::Converged => "converged",
        Stop::Rounds => "rounds",
        Stop::Budget => "budget",
    }
}

fn verify(
    file: &str,
    baked: Option<&Path>,
    builder: &str,
    clips: Option<&str>,
    args: RefineArgs,
    samples: usize,
    json: bool,
) -> Result<()> {
    let builder = Builder::from_name(builder).context("unknown builder")?;
    let (asset, character) = load_character(file)?;
    let b = match baked {
        Some(path) => {
            anyhow::ensure!(clips.is_none(), "--clips cannot be combined with --baked (the bake names its clips)");
            skinlet::bake::read(path)?
        }
        None => bake::bake_asset(&asset, &character, clips, builder, args, json)?.0,
    };
    let skin = &character.palette;
    let clips = bake::clips_of(&b, &asset, file)?;
    if let Some(path) = baked {
        bake::check_source(&b, &character, file, path)?;
    }
    let builder = b.settings.builder;
    let (meshlets, bounds) = (&b.meshlets, &b.bounds);
    let r = skinlet::bounds::verify::verify_bounds(
        &asset.skeleton,
        skin,
        &clips,
        &b.mesh,
        meshlets,
        bounds,
        samples.max(2),
    )?;
    // A bake's pose envelope: its bounds at as many poses inside it, half on its boundary.
    let envelope = match &b.envelope {
        Some(e) => {
            let poses = e.envelope.sample_poses(&asset.skeleton, samples.max(2), 1);
            let meshlets = &b.meshlets;
            Some(skinlet::bounds::verify::verify_poses(&asset.skeleton, skin, &poses, &b.mesh, meshlets, &e.bounds)?)
        }
        None => None,
    };
    // The parts' boxes per clip window: every vertex at every sample time.
    let part_windows = b.part_windows.as_ref().map(|w| {
        let parts: Vec<_> = b.parts.iter().map(|p| p.vertices.clone()).collect();
        skinlet::bounds::part_windows::verify_part_windows(
            &asset.skeleton,
            skin,
            &clips,
            &b.mesh,
            &parts,
            w,
            samples.max(2),
        )
    });
    // The cluster LOD hierarchy: its clusters' bounds like the meshlets', its errors against
    // the full detail mesh at the evenly spaced sample times.
    let lod = match &b.lod {
        Some(l) => {
            let bounds = skinlet::bounds::verify::verify_bounds(
                &asset.skeleton,
                skin,
                &clips,
                &b.mesh,
                &l.meshlets,
                &l.bounds,
                samples.max(2),
            )?;
            let hierarchies = l.hierarchies(&b.meshlets, &b.parts);
            let parts: Vec<_> = hierarchies.iter().map(|(r, h)| (r.clone(), h)).collect();
            let per_clip = samples.clamp(2, 16);
            let poses: Vec<_> = (clips.iter())
                .flat_map(|&c| {
                    (0..per_clip).map(move |k| (Some(c), c.start + c.duration() * k as f32 / (per_clip - 1) as f32))
                })
                .collect();
            let poses = if poses.is_empty() { vec![(None, 0.0)] } else { poses };
            let poses = skinlet::bounds::lod_verify::clip_poses(&asset.skeleton, &b.mesh, &poses);
            let errors = skinlet::bounds::lod_verify::verify_errors(&asset.skeleton, skin, &poses, &b.mesh, &parts)?;
            // Within the pose envelope: the clusters' bounds and the errors there, at poses
            // inside it (as many as per clip above, half on its boundary).
            let within_envelope = match (&b.envelope, &l.envelope, l.envelope_hierarchies(&b.meshlets, &b.parts)) {
                (Some(e), Some(le), Some(hierarchies)) => {
                    let poses = e.envelope.sample_poses(&asset.skeleton, per_clip, 1);
                    let bounds = skinlet::bounds::verify::verify_poses(
                        &asset.skeleton,
                        skin,
                        &poses,
                        &b.mesh,
                        &l.meshlets,
                        &le.bounds,
                    )?;
                    let parts: Vec<_> = hierarchies.iter().map(|(r, h)| (r.clone(), h)).collect();
                    let verify = skinlet::bounds::lod_verify::verify_errors;
                    Some((bounds, verify(&asset.skeleton, skin, &poses, &b.mesh, &parts)?))
                }
                _ => None,
            };
            Some((bounds, errors, within_envelope))
        }
        None => None,
    };
    let violations = r.violations()
        + envelope.map_or(0, |e| e.violations())
        + part_windows.map_or(0, |w| w.1)
        + lod.as_ref().map_or(0, |(b, e, within)| {
            b.violations() + e.violations + within.as_ref().map_or(0, |(b, e)| b.violations() + e.violations)
        });
    if json {
        let out = json!({
            "samples": r.samples, "vertex_checks": r.vertex_checks, "normal_checks": r.normal_checks,
            "violations": r.violations(), "vertex_violations": r.vertex_violations, "normal_violations": r.normal_violations,
            "singular_vertex_checks": r.singular, "max_violation": r.max_violation, "mean_radius_ratio": r.mean_radius_ratio, "mean_angle_ratio": r.mean_angle_ratio,
            "envelope": envelope.map(|e| json!({"poses": e.samples, "vertex_checks": e.vertex_checks,
                "normal_checks": e.normal_checks, "violations": e.violations(), "mean_radius_ratio": e.mean_radius_ratio})),
            "part_windows": part_windows.map(|(checks, violations)| json!({"vertex_checks": checks, "violations": violations})),
            "lod": lod.as_ref().map(|(b, e, within)| json!({"cluster_vertex_checks": b.vertex_checks, "cluster_normal_checks": b.normal_checks,
                "cluster_violations": b.violations(), "error_poses": e.poses, "error_points": e.points, "error_violations": e.violations,
                "max_distance_per_error": e.max_ratio, "median_distance_per_error": e.median_ratio,
                "envelope": within.as_ref().map(|(b, e)| json!({"cluster_vertex_checks": b.vertex_checks,
                    "cluster_normal_checks": b.normal_checks, "cluster_violations": b.violations(), "error_poses": e.poses,
                    "error_points": e.points, "error_violations": e.violations, "max_distance_per_error": e.max_ratio,
                    "median_distance_per_error": e.median_ratio}))})),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "{file}: {} meshlets ({}), {} clips, {} sample times",
            meshlets.len(),
            builder.name(),
            clips.len(),
            r.samples
        );
        println!(
            "  {} vertex checks, {} normal checks, in each meshlet's joint space as the culler tests them",
            r.vertex_checks, r.normal_checks
        );
        if r.singular > 0 {
            println!("  {} vertex checks skipped: the joint's matrix had no inverse (a zero scale)", r.singular);
        }
        println!(
            "  violations: {} (vertices {}, normals {})",
            r.violations(),
            r.vertex_violations,
            r.normal_violations
        );
        println!(
            "  tightness: stored radius / needed radius {:.4}, stored angle / needed angle {:.4} (means over meshlets)",
            r.mean_radius_ratio, r.mean_angle_ratio
        );
        if let Some(e) = envelope {
            println!(
                "  pose envelope: {} poses inside it (half on its boundary), {} vertex and {} normal checks, {} violations",
                e.samples,
                e.vertex_checks,
                e.normal_checks,
                e.violations()
            );
        }
        if let Some((checks, violations)) = part_windows {
            println!(
                "  part boxes per clip window: {checks} vertex checks in each part's anchor space, {violations} violations"
            );
        }
        if let Some((b, e, within)) = &lod {
            for (what, (b, e)) in std::iter::once(("cluster LOD", (b, e)))
                .chain(within.as_ref().map(|(b, e)| ("cluster LOD within the pose envelope", (b, e))))
            {
                println!(
                    "  {what}: clusters' bounds {} vertex and {} normal checks, {} violations; errors at {} poses, {} points, {} violations (largest distance ÷ error {:.3})",
                    b.vertex_checks,
                    b.normal_checks,
                    b.violations(),
                    e.poses,
                    e.points,
                    e.violations,
                    e.max_ratio
                );
            }
        }
    }
    if violations > 0 {
        std::process::exit(1);
    }
    Ok(())
}
