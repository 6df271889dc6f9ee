//! The crowd scene of Unterguggenberger et al. 2021 (fig. 10, table 1): many animated
//! instances of one character in front of a fixed camera, some on the frustum's side
//! planes, each playing a clip from a random time offset. Every frame, every instance is
//! culled per meshlet with each of the paper's three pipelines (frustum only, backface only,
//! both), then per triangle inside the surviving meshlets ([`skinlet::cull::triangle`]), and as a whole mesh by its
//! per-joint box (the baseline engines use). Optionally, every culled triangle is checked
//! by brute force on the reference-skinned mesh: outside one frustum plane, back-facing, or
//! degenerate, within the f32 rounding of the skinned positions. Deterministic for a seed.

use glam::{Affine3A, DMat4, DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;
use skinlet::Result;
use skinlet::bake::Baked;
use skinlet::clip::Clip;
use skinlet::cull::joint_aabb::{Box3, JointSpace, fold_leaves, joint_boxes, points_box};
use skinlet::cull::triangle::{TriangleCounts, cull_triangles, facing};
use skinlet::cull::{Camera, Projection};
use skinlet::model::Trs;
use skinlet::model::{Skeleton, Skin};
use skinlet::pose::{global_transforms, skinning_matrices};
use skinlet::skinning;
use skinlet_runtime::meshlet_cull::{CullCounts, JointFrame, MeshletCuller, Tests};
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrowdParams {
    pub instances: usize,
    pub frames: usize,
    pub fps: f32,
    pub seed: u64,
    pub orthographic: bool,
    pub animation: Animation,
    pub layout: Layout,
}

impl Default for CrowdParams {
    fn default() -> Self {
        CrowdParams {
            instances: 64,
            frames: 30,
            fps: 30.0,
            seed: 1,
            orthographic: false,
            animation: Animation::Clips,
            layout: Layout::Paper,
        }
    }
}

/// Where the instances stand.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layout {
    /// The conservative-bounds paper's crowd (fig. 10): a grid filling the view from above
    /// the crowd, a quarter of the instances on the view's sides.
    #[default]
    Paper,
    /// A dense crowd seen from street level: rows of instances a body apart, stretching away
    /// from a camera at chest height that looks along them (most instances hidden behind
    /// nearer ones: the scene occlusion culling is for).
    Dense,
}

/// How the instances are posed: what games do besides playing one clip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Animation {
    /// Each instance plays its clip; culling uses the clip bounds (the caller knows the pose
    /// is clip C at time t).
    Clips,
    /// Each instance crossfades its clip with a second one, with its own random weight
    /// (translations, scales and morph weights lerped, rotations slerped).
    Blend,
    /// Each instance plays its clip with an additive layer: every joint of the envelope
    /// turned by a random rotation of up to this many radians.
    Additive(f32),
    /// Each instance plays its clip and two random joints of the envelope are set by "IK":
    /// one within its range of motion, and in half the instance-frames one 20° beyond it.
    Ik,
}

impl Animation {
    pub fn name(self) -> &'static str {
        match self {
            Animation::Clips => "clips",
            Animation::Blend => "blend",
            Animation::Additive(_) => "additive",
            Animation::Ik => "ik",
        }
    }
}

/// One instance: where it stands, which clip it plays, from which time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub model: DMat4,
    pub clip: usize,
    pub offset: f32,
}

impl Placement {
    /// The time of `clip` (the instance's clip) at frame `frame` of a `fps` animation: the
    /// instance's offset into the clip plus the frame's time, wrapping around the clip.
    pub fn time(&self, clip: Option<&Clip>, frame: usize, fps: f32) -> f32 {
        clip.map_or(0.0, |c| {
            let d = c.duration().max(1e-6);
            c.start + (self.offset * d + frame as f32 / fps).rem_euclid(d)
        })
    }

    /// The instance's world-space joint matrices (`model × global`, what culling prepares
    /// from) and skinning matrices (`model × global × inverse bind`, what a renderer skins
    /// with), one per joint of `skin`, from the skeleton's global transforms.
    pub fn world_matrices(
        &self,
        skin: &Skin,
        globals: &[DMat4],
        joints: &mut Vec<Affine3A>,
        skinning: &mut Vec<Affine3A>,
    ) {
        let world = |m: DMat4| Affine3A::from_mat4((self.model * m).as_mat4());
        joints.clear();
        joints.extend(skin.joints.iter().map(|&j| world(globals[j as usize])));
        skinning.clear();
        skinning.extend(
            skin.joints.iter().zip(&skin.inverse_bind).map(|(&j, b)| world(globals[j as usize] * b.as_dmat4())),
        );
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Crowd {
    pub camera: Camera,
    pub placements: Vec<Placement>,
}

pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// [`crowd`] for `mesh` (over the joints of `skin`) posed at the start of the first of
/// `clips` (the rest pose without clips): laid out in scene space, so a centimetre, Z-up file
/// gives the same scene as a metre, Y-up one.
pub fn posed_crowd(
    skeleton: &Skeleton,
    skin: &Skin,
    mesh: &skinlet::SkinnedMesh,
    clips: &[&Clip],
    params: &CrowdParams,
) -> Result<Crowd> {
    let posed = skinlet::skinning::posed_positions(skeleton, skin, mesh, clips.first().copied(), None)?;
    crowd(&posed, clips.len(), params)
}

/// Lays out the scene for a character whose vertices (in scene space, posed) are `positions`:
/// a camera at the origin looking down −z, three quarters of the instances on a grid that
/// fills the view and spills past its sides, one quarter centered on the four side planes.
/// The instances are ordered nearest first (by the depth of their centers), as occlusion
/// culling's rounds want them.
pub fn crowd(positions: &[Vec3], clips: usize, params: &CrowdParams) -> Result<Crowd> {
    let (lo, hi) = positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), p| (l.min(p.as_dvec3()), h.max(p.as_dvec3())));
    let center = if lo.x <= hi.x { (lo + hi) / 2.0 } else { DVec3::ZERO };
    let size = if lo.x <= hi.x { ((hi - lo).length() / 2.0).max(1e-6) } else { 1.0 };
    let (fov, aspect) = (50f64.to_radians(), 16.0 / 9.0);
    let camera = if params.orthographic {
        let h = 6.0 * size;
        Camera::orthographic(
            Vec3::ZERO,
            Vec3::NEG_Z,
            Vec3::Y,
            (h * aspect) as f32,
            h as f32,
            0.0,
            (80.0 * size) as f32,
        )?
    } else {
        Camera::perspective(
            Vec3::ZERO,
            Vec3::NEG_Z,
            Vec3::Y,
            fov as f32,
            aspect as f32,
            (0.05 * size) as f32,
            (80.0 * size) as f32,
        )?
    };
    // Half extents of the view at depth z (> 0 in front of the camera).
    let half = |z: f64| {
        if params.orthographic {
            (6.0 * size * aspect, 6.0 * size)
        } else {
            ((fov / 2.0).tan() * z * aspect, (fov / 2.0).tan() * z)
        }
    };
    let mut rng = Rng(params.seed ^ 0x5EED_C0DE);
    let nearest_first = |mut placements: Vec<Placement>| {
        placements.sort_by(|a, b| b.model.transform_point3(center).z.total_cmp(&a.model.transform_point3(center).z));
        placements
    };
    if params.layout == Layout::Dense {
        return Ok(Crowd { camera, placements: nearest_first(dense(params, clips, center, size, &mut rng)) });
    }
    let on_planes = params.instances / 4;
    let grid = params.instances - on_planes;
    let cols = ((grid as f64 * 1.5).sqrt().ceil() as usize).max(1);
    let rows = grid.div_ceil(cols).max(1);
    let mut placements = Vec::with_capacity(params.instances);
    for i in 0..params.instances {
        let pos = if i < grid {
            let (r, c) = (i / cols, i % cols);
            let z = 4.0 * size + 3.0 * size * r as f64;
            let (hw, hh) = half(z);
            let x = (2.0 * (c as f64 + 0.5) / cols as f64 - 1.0) * hw * 1.5;
            DVec3::new(x, -0.5 * hh + size * 0.3 * rng.next(), -z)
        } else {
            let k = i - grid;
            let z = 4.0 * size + rng.next() * 3.0 * size * rows as f64;
            let (hw, hh) = half(z);
            let along = (rng.next() * 2.0 - 1.0) * 0.8;
            match k % 4 {
                0 => DVec3::new(-hw, along * hh, -z),
                1 => DVec3::new(hw, along * hh, -z),
                2 => DVec3::new(along * hw, -hh, -z),
                _ => DVec3::new(along * hw, hh, -z),
            }
        };
        let yaw = rng.next() * std::f64::consts::TAU;
        let model =
            DMat4::from_rotation_translation(DQuat::from_rotation_y(yaw), pos) * DMat4::from_translation(-center);
        let clip = if clips == 0 { 0 } else { (rng.next() * clips as f64) as usize % clips };
        placements.push(Placement { model, clip, offset: rng.next() as f32 });
    }
    Ok(Crowd { camera, placements: nearest_first(placements) })
}

/// [`Layout::Dense`]: a square grid centered on the view axis, 0.8 `size` apart across and
/// 1.5 `size` deep (`size`: half the posed character's diagonal), jittered, the first row 3
/// `size` ahead; the characters' centers 0.35 `size` below the camera (about chest height).
fn dense(params: &CrowdParams, clips: usize, center: DVec3, size: f64, rng: &mut Rng) -> Vec<Placement> {
    let cols = (params.instances as f64).sqrt().ceil().max(1.0) as usize;
    (0..params.instances)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let jitter = |rng: &mut Rng| (rng.next() - 0.5) * 0.3 * size;
            let x = (c as f64 - (cols as f64 - 1.0) / 2.0) * 0.8 * size + jitter(rng);
            let z = 3.0 * size + 1.5 * size * r as f64 + jitter(rng);
            let pos = DVec3::new(x, -0.35 * size, -z);
            let yaw = rng.next() * std::f64::consts::TAU;
            let model =
                DMat4::from_rotation_translation(DQuat::from_rotation_y(yaw), pos) * DMat4::from_translation(-center);
            let clip = if clips == 0 { 0 } else { (rng.next() * clips as f64) as usize % clips };
            Placement { model, clip, offset: rng.next() as f32 }
        })
        .collect()
}

/// The whole-mesh bounds compared: per-joint boxes in joint space, in mesh space (Bevy's
/// choice, and the tighter on the shared assets: the one used for whole-mesh culling), joint
/// space with leaf joints folded twice (conservative for the crowd's clips), and the box
/// around the whole-mesh sphere.
pub const WHOLE_MESH_BOUNDS: [&str; 4] =
    ["joint-space boxes", "mesh-space boxes", "folded leaves (2 levels)", "sphere"];

/// Totals over all frames and instances.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CrowdStats {
    pub frames: usize,
    pub instances: usize,
    /// Meshlets, triangles and meshlet vertex references drawn without any culling.
    pub meshlets: usize,
    pub triangles: usize,
    pub vertex_refs: usize,
    /// Meshlets culled by each pipeline (the paper's table 1 columns).
    pub culled_frustum_only: usize,
    pub culled_backface_only: usize,
    /// Backface test alone: triangles and vertex references (skinning) in the meshlets it
    /// culls; and the triangles back-facing one by one over the whole skinned mesh (the
    /// limit of any backface culling: about half of a closed mesh).
    pub backface_only_triangles: usize,
    pub backface_only_vertex_refs: usize,
    pub backfacing_triangles: usize,
    pub culled_both: CullCounts,
    /// With both tests: triangles in culled meshlets, and vertex references not skinned.
    pub triangles_in_culled_meshlets: usize,
    pub vertex_refs_culled: usize,
    /// Per-triangle culling inside the meshlets both tests kept.
    pub triangle_culling: TriangleCounts,
    /// Meshlets of instances whose whole-mesh box (dynamic per-joint boxes, mesh space) is
    /// outside.
    pub whole_mesh_culled: usize,
    /// Whole-mesh bound's box diagonal ÷ the diagonal of the exact box of the skinned
    /// vertices (entity space; a diagonal, unlike a volume, is defined for flat meshes),
    /// summed over instance-frames, for [`WHOLE_MESH_BOUNDS`] in that order.
    pub looseness_sum: [f64; 4],
    /// CPU time of the per-meshlet culling with both tests (per-joint setup included),
    /// summed over instances (thread time).
    pub cull_time: Duration,
    /// With verification: culled triangles checked, and those that were visible after all.
    pub checked_triangles: usize,
    pub false_culls: usize,
    /// Instance-frames culled with the envelope bounds (the guard admitted the pose), with
    /// the any-pose boxes (it did not; frustum test only), and not culled at all (morph
    /// weights outside the envelope's ranges). Clip bounds otherwise.
    pub envelope_frames: usize,
    pub any_pose_frames: usize,
    pub unculled_frames: usize,
    /// Each bound alone where it holds, for [`CULLING_METHODS`] in that order.
    pub methods: [MethodStats; 4],
    /// CPU time of the pose guard, and of computing the joint matrices from the local
    /// transforms (global transforms and world matrices), summed over instance-frames.
    pub guard_time: Duration,
    pub matrices_time: Duration,
}

/// The bounds measured one by one: the clip bounds (where the pose is a clip's), the
/// envelope bounds (where the guard admits it), the any-pose boxes, and the whole-mesh box
/// from per-joint boxes (mesh space; any pose).
pub const CULLING_METHODS: [&str; 4] =
    ["clip bounds", "envelope bounds", "any-pose boxes", "whole-mesh per-joint boxes"];

/// One bound's results over the instance-frames where it holds: meshlets tested, culled
/// (both tests for meshlet bounds, the frustum for boxes), CPU time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MethodStats {
    pub meshlets: usize,
    pub culled: usize,
    pub time: Duration,
}

impl MethodStats {
    /// Share culled, `None` where the bound never held.
    pub fn culled_pct(&self) -> Option<f64> {
        (self.meshlets > 0).then(|| 100.0 * self.culled as f64 / self.meshlets as f64)
    }
    pub fn ns_per_meshlet(&self) -> Option<f64> {
        (self.meshlets > 0).then(|| self.time.as_secs_f64() * 1e9 / self.meshlets as f64)
    }
}

impl CrowdStats {
    fn add(&mut self, o: &CrowdStats) {
        self.meshlets += o.meshlets;
        self.triangles += o.triangles;
        self.vertex_refs += o.vertex_refs;
        self.culled_frustum_only += o.culled_frustum_only;
        self.culled_backface_only += o.culled_backface_only;
        self.backface_only_triangles += o.backface_only_triangles;
        self.backface_only_vertex_refs += o.backface_only_vertex_refs;
        self.backfacing_triangles += o.backfacing_triangles;
        self.culled_both.add(&o.culled_both);
        self.triangles_in_culled_meshlets += o.triangles_in_culled_meshlets;
        self.vertex_refs_culled += o.vertex_refs_culled;
        self.triangle_culling.add(&o.triangle_culling);
        self.whole_mesh_culled += o.whole_mesh_culled;
        for (a, b) in self.looseness_sum.iter_mut().zip(&o.looseness_sum) {
            *a += b;
        }
        self.cull_time += o.cull_time;
        self.checked_triangles += o.checked_triangles;
        self.false_culls += o.false_culls;
        self.envelope_frames += o.envelope_frames;
        self.any_pose_frames += o.any_pose_frames;
        self.unculled_frames += o.unculled_frames;
        for (a, b) in self.methods.iter_mut().zip(&o.methods) {
            (a.meshlets, a.culled, a.time) = (a.meshlets + b.meshlets, a.culled + b.culled, a.time + b.time);
        }
        self.guard_time += o.guard_time;
        self.matrices_time += o.matrices_time;
    }

    fn pct(&self, n: usize, of: usize) -> f64 {
        100.0 * n as f64 / of.max(1) as f64
    }
    pub fn frustum_only_pct(&self) -> f64 {
        self.pct(self.culled_frustum_only, self.meshlets)
    }
    pub fn backface_only_pct(&self) -> f64 {
        self.pct(self.culled_backface_only, self.meshlets)
    }
    /// Triangles in meshlets the backface test alone culls.
    pub fn backface_only_triangles_pct(&self) -> f64 {
        self.pct(self.backface_only_triangles, self.triangles)
    }
    /// Vertex skinning saved by the backface test alone.
    pub fn backface_only_skinning_pct(&self) -> f64 {
        self.pct(self.backface_only_vertex_refs, self.vertex_refs)
    }
    /// Triangles back-facing one by one: what per-triangle backface culling removes.
    pub fn backfacing_triangles_pct(&self) -> f64 {
        self.pct(self.backfacing_triangles, self.triangles)
    }
    pub fn both_pct(&self) -> f64 {
        self.pct(self.culled_both.frustum + self.culled_both.backface, self.meshlets)
    }
    /// Triangles not rasterized: in culled meshlets or culled one by one.
    pub fn triangles_saved_pct(&self) -> f64 {
        let t = self.triangle_culling;
        self.pct(self.triangles_in_culled_meshlets + t.backfacing + t.degenerate, self.triangles)
    }
    pub fn skinning_saved_pct(&self) -> f64 {
        self.pct(self.vertex_refs_culled, self.vertex_refs)
    }
    /// Meshlet vertex references skinned per instance-frame without culling and after
    /// culling with both tests: absolute counts, comparable across builders (a builder with
    /// more, narrower meshlets shares fewer vertices, so a larger culled share can still
    /// leave more to skin).
    pub fn vertex_refs_per_instance_frame(&self) -> [f64; 2] {
        let n = (self.instances * self.frames).max(1) as f64;
        [self.vertex_refs as f64 / n, (self.vertex_refs - self.vertex_refs_culled) as f64 / n]
    }
    pub fn whole_mesh_pct(&self) -> f64 {
        self.pct(self.whole_mesh_culled, self.meshlets)
    }
    /// Mean looseness of each of [`WHOLE_MESH_BOUNDS`].
    pub fn looseness(&self) -> [f64; 4] {
        self.looseness_sum.map(|x| x / (self.frames * self.instances).max(1) as f64)
    }
    /// Instance-frames the guard sent to a fallback (any-pose boxes or no culling).
    pub fn guard_fallback_pct(&self) -> f64 {
        self.pct(self.any_pose_frames + self.unculled_frames, self.frames * self.instances)
    }
    pub fn ns_per_meshlet(&self) -> f64 {
        self.cull_time.as_secs_f64() * 1e9 / self.meshlets.max(1) as f64
    }
}

/// One of the culler's `prepare` methods.
type Prepare = fn(&MeshletCuller, &[Affine3A], &Camera, Tests, &mut JointFrame);

/// Scratch space of one worker.
#[derive(Default)]
struct Scratch {
    locals: Vec<Trs>,
    other: (Vec<Trs>, Vec<f32>),
    globals: Vec<DMat4>,
    joint_to_world: Vec<Affine3A>,
    joint_to_model: Vec<Affine3A>,
    skinning: Vec<Affine3A>,
    morph_weights: Vec<f32>,
    frame: JointFrame,
    flags: Vec<u8>,
    visible: Vec<u32>,
    all: Vec<u32>,
    skinned: Vec<Vec3>,
    world: Vec<Vec3>,
}

/// Runs the crowd for `frames` frames. `clips` are the character's clips (placements index
/// them); with `verify`, every culled triangle is checked by brute force.
pub fn run(
    baked: &Baked,
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    crowd: &Crowd,
    params: &CrowdParams,
    verify: bool,
) -> Result<CrowdStats> {
    // Every culler also holds the any-pose boxes where the bake has them.
    let culler = |bounds, classes| -> Result<MeshletCuller> {
        let c = MeshletCuller::new(bounds, classes, skin.joints.len())?;
        Ok(match &baked.envelope {
            Some(e) => c.with_any_pose(&e.any_pose)?,
            None => c,
        })
    };
    let clip_culler = culler(&baked.bounds, &baked.classes)?;
    // Poses that are not clips are culled with the envelope bounds where the guard admits them.
    let envelope_culler = match (params.animation, &baked.envelope) {
        (Animation::Clips, _) => None,
        (_, Some(e)) => Some(culler(&e.bounds, &e.classes)?),
        (a, None) => {
            return Err(skinlet::Error::Invalid {
                location: "crowd".into(),
                message: format!("{} animation needs a bake with a pose envelope (skinlet bake --envelope)", a.name()),
            });
        }
    };
    let guard = baked.envelope.as_ref().map(|e| e.envelope.guard()).transpose()?;
    let boxes = joint_boxes(&baked.mesh, skin, JointSpace::Joint, clips)?;
    let mesh_boxes = joint_boxes(&baked.mesh, skin, JointSpace::Mesh, clips)?;
    let folded = fold_leaves(&boxes, skeleton, skin, &baked.mesh, clips, 2)?;
    let meshlets = &baked.meshlets;
    let per_meshlet_refs: Vec<usize> = meshlets.meshlets.iter().map(|m| m.vertex_count as usize).collect();
    let per_meshlet_tris: Vec<usize> = meshlets.meshlets.iter().map(|m| m.triangle_count as usize).collect();
    let mut total = CrowdStats { frames: params.frames, instances: crowd.placements.len(), ..CrowdStats::default() };
    for f in 0..params.frames {
        let stats = crowd
            .placements
            .par_iter()
            .enumerate()
            .map_init(Scratch::default, |s, (i, pl)| -> Result<CrowdStats> {
                let clip = clips.get(pl.clip).copied();
                let t = pl.time(clip, f, params.fps);
                let mut rng = instance_rng(params, i, f);
                let pose_out = (&mut s.locals, &mut s.morph_weights);
                pose(skeleton, clips, pl, (clip, t), f, params, baked, &mut rng, pose_out, &mut s.other);
                let mut st = CrowdStats::default();
                // The joint matrices a game computes from the pose (timed: the guard's cost
                // is measured against it).
                let started = Instant::now();
                global_transforms(skeleton, &s.locals, &mut s.globals);
                s.joint_to_model.clear();
                s.joint_to_world.clear();
                for &j in &skin.joints {
                    let g = s.globals[j as usize];
                    s.joint_to_model.push(Affine3A::from_mat4(g.as_mat4()));
                    s.joint_to_world.push(Affine3A::from_mat4((pl.model * g).as_mat4()));
                }
                st.matrices_time = started.elapsed();
                skinning_matrices(skin, &s.globals, &mut s.skinning);
                // Which bounds hold for this pose: the clip's (the caller says it is clip C at
                // time t), the envelope's (the guard admits it), the any-pose boxes (morph
                // weights inside the envelope's ranges; also whenever the others hold).
                let started = Instant::now();
                let inside =
                    envelope_culler.is_some() && guard.as_ref().is_some_and(|g| g.admits(&s.locals, &s.morph_weights));
                st.guard_time = started.elapsed();
                let weights_inside = guard.as_ref().is_some_and(|g| g.admits_weights(&s.morph_weights));
                let culler = envelope_culler.as_ref().unwrap_or(&clip_culler);
                let bounds_hold = envelope_culler.is_none() || inside;
                // The any-pose boxes hold whenever the morph weights are inside their ranges.
                let boxes_hold = weights_inside && !culler.any_pose_boxes().1.is_empty();
                match (bounds_hold, boxes_hold) {
                    (true, _) if envelope_culler.is_some() => st.envelope_frames = 1,
                    (true, _) => {}
                    (false, true) => st.any_pose_frames = 1,
                    (false, false) => st.unculled_frames = 1,
                }
                st.meshlets = meshlets.len();
                st.triangles = per_meshlet_tris.iter().sum();
                st.vertex_refs = per_meshlet_refs.iter().sum();
                // Each valid bound alone, timed (the table of docs/CULLING.md), then the three
                // pipelines with the tightest valid bounds; with both tests, the any-pose boxes
                // cull what they can of the rest.
                let n = meshlets.len();
                let mut run = |prepare: Prepare, tests| {
                    s.visible.clear();
                    let started = Instant::now();
                    prepare(culler, &s.joint_to_world, &crowd.camera, tests, &mut s.frame);
                    let counts = culler.cull(&s.frame, &mut s.flags, &mut s.visible);
                    let time = started.elapsed();
                    // Triangles and vertex references kept (the list is in the culler's order).
                    let kept = s.visible.iter().fold((0, 0), |(t, r), &m| {
                        (t + per_meshlet_tris[m as usize], r + per_meshlet_refs[m as usize])
                    });
                    (counts, time, kept)
                };
                let alone = |(counts, time, _): (CullCounts, _, _)| MethodStats {
                    meshlets: n,
                    culled: n - counts.visible,
                    time,
                };
                if boxes_hold {
                    st.methods[2] = alone(run(MeshletCuller::prepare_boxes_only, Tests::Both));
                }
                if bounds_hold {
                    st.culled_frustum_only = run(MeshletCuller::prepare, Tests::Frustum).0.frustum;
                    let (counts, _, (tris, refs)) = run(MeshletCuller::prepare, Tests::Backface);
                    st.culled_backface_only = counts.backface;
                    st.backface_only_triangles = st.triangles - tris;
                    st.backface_only_vertex_refs = st.vertex_refs - refs;
                    // Clip bounds without an envelope culler, envelope bounds with one.
                    st.methods[envelope_culler.is_some() as usize] = alone(run(MeshletCuller::prepare, Tests::Both));
                }
                let (kept_tris, kept_refs) = if bounds_hold || boxes_hold {
                    let best: Prepare = match (bounds_hold, boxes_hold) {
                        (true, true) => MeshletCuller::prepare_with_boxes,
                        (true, false) => MeshletCuller::prepare,
                        _ => MeshletCuller::prepare_boxes_only,
                    };
                    let kept;
                    (st.culled_both, st.cull_time, kept) = run(best, Tests::Both);
                    kept
                } else {
                    s.visible.clear();
                    s.visible.extend(0..n as u32);
                    st.culled_both = CullCounts { meshlets: n, visible: n, ..Default::default() };
                    (st.triangles, st.vertex_refs)
                };
                if !bounds_hold {
                    st.culled_frustum_only = st.culled_both.frustum;
                }
                st.triangles_in_culled_meshlets = st.triangles - kept_tris;
                st.vertex_refs_culled = st.vertex_refs - kept_refs;
                // Skin, move to world and clip space; per-triangle culling in kept meshlets.
                s.skinned.resize(baked.mesh.positions.len(), Vec3::ZERO);
                skinning::skin_mesh(&baked.mesh, &s.morph_weights, &s.skinning, &mut s.skinned, &mut [])?;
                let model = Affine3A::from_mat4(pl.model.as_mat4());
                s.world.clear();
                s.world.extend(s.skinned.iter().map(|&p| model.transform_point3(p)));
                st.triangle_culling = cull_triangles(meshlets, &s.visible, &s.world, crowd.camera.projection, None);
                if bounds_hold {
                    s.all.clear();
                    s.all.extend(0..n as u32);
                    let whole = cull_triangles(meshlets, &s.all, &s.world, crowd.camera.projection, None);
                    st.backfacing_triangles = whole.backfacing + whole.degenerate;
                }
                // Whole-mesh culling by the dynamic box, moved from entity to world space.
                let started = Instant::now();
                let mesh_box = mesh_boxes.update(&s.skinning);
                if outside(&crowd.camera, &mesh_box.transformed(&model)) {
                    st.whole_mesh_culled = meshlets.len();
                }
                st.methods[3] = MethodStats { meshlets: n, culled: st.whole_mesh_culled, time: started.elapsed() };
                let exact = points_box(&s.skinned).diagonal().max(f32::MIN_POSITIVE);
                let (sc, sr) = boxes.sphere(&s.joint_to_model);
                let sphere = Box3 { min: sc - sr, max: sc + sr };
                let all = [boxes.update(&s.joint_to_model), mesh_box, folded.update(&s.joint_to_model), sphere];
                st.looseness_sum = all.map(|b| (b.diagonal() / exact) as f64);
                if verify {
                    let mut kept = vec![false; meshlets.len()];
                    for &m in &s.visible {
                        kept[m as usize] = true;
                    }
                    let (checked, false_culls) = check_culls(baked, &kept, &s.world, &crowd.camera);
                    st.checked_triangles = checked;
                    st.false_culls = false_culls;
                }
                Ok(st)
            })
            .collect::<Result<Vec<_>>>()?;
        for st in &stats {
            total.add(st);
        }
    }
    Ok(total)
}

/// The pose of instance `i` (placement `pl`) at frame `frame` as `params.animation` says,
/// as [`run`] draws it: every node's local transform into `locals`, the morph weights into
/// `weights`. The additive and IK modes move the nodes of `baked`'s pose envelope.
#[allow(clippy::too_many_arguments)]
pub fn instance_pose(
    skeleton: &Skeleton,
    clips: &[&Clip],
    baked: &Baked,
    params: &CrowdParams,
    i: usize,
    pl: &Placement,
    frame: usize,
    locals: &mut Vec<Trs>,
    weights: &mut Vec<f32>,
) {
    let clip = clips.get(pl.clip).copied();
    let t = pl.time(clip, frame, params.fps);
    let mut rng = instance_rng(params, i, frame);
    pose(skeleton, clips, pl, (clip, t), frame, params, baked, &mut rng, (locals, weights), &mut Default::default());
}

fn instance_rng(params: &CrowdParams, i: usize, frame: usize) -> Rng {
    Rng(params.seed ^ (i as u64).wrapping_mul(0x9E37_79B9) ^ (frame as u64) << 40)
}

/// Poses instance `pl` at frame `frame` (its clip at time `at`) as `params.animation` says:
/// every node's local transform into `locals`, the morph weights into `weights`; `other` is
/// scratch space for a blend's second pose.
#[allow(clippy::too_many_arguments)]
fn pose(
    skeleton: &Skeleton,
    clips: &[&Clip],
    pl: &Placement,
    (clip, t): (Option<&Clip>, f32),
    frame: usize,
    params: &CrowdParams,
    baked: &Baked,
    rng: &mut Rng,
    (locals, weights): (&mut Vec<Trs>, &mut Vec<f32>),
    other: &mut (Vec<Trs>, Vec<f32>),
) {
    let sample = |clip: Option<&Clip>, t: f32, locals: &mut Vec<Trs>, weights: &mut Vec<f32>| {
        match clip {
            Some(c) => c.sample_locals(skeleton, t, locals),
            None => {
                locals.clear();
                locals.extend(skeleton.nodes.iter().map(|n| n.rest));
            }
        }
        baked.mesh.morphs.weights_at(clip, t, weights);
    };
    sample(clip, t, locals, weights);
    let nodes = baked.envelope.as_ref().map_or(&[][..], |e| &e.envelope.nodes[..]);
    let axis = |rng: &mut Rng| loop {
        let v = Vec3::new(rng.next() as f32 * 2.0 - 1.0, rng.next() as f32 * 2.0 - 1.0, rng.next() as f32 * 2.0 - 1.0);
        if v.length() > 0.1 && v.length() <= 1.0 {
            break v.normalize();
        }
    };
    match params.animation {
        Animation::Clips => {}
        Animation::Blend => {
            // The instance's second clip and weight stay the same over the frames.
            let mut fixed = Rng(params.seed ^ pl.offset.to_bits() as u64);
            // Another clip where there is one.
            let n = clips.len().max(1);
            let second =
                clips.get((pl.clip + 1 + (fixed.next() * (n - 1) as f64) as usize % n.saturating_sub(1).max(1)) % n);
            let w = fixed.next() as f32;
            let t2 = pl.time(second.copied(), frame, params.fps);
            sample(second.copied(), t2, &mut other.0, &mut other.1);
            for (a, b) in locals.iter_mut().zip(&other.0) {
                a.translation = a.translation.lerp(b.translation, w);
                a.rotation = a.rotation.slerp(b.rotation, w);
                a.scale = a.scale.lerp(b.scale, w);
            }
            for (a, b) in weights.iter_mut().zip(&other.1) {
                *a += (*b - *a) * w;
            }
        }
        Animation::Additive(max) => {
            for r in nodes {
                let q = Quat::from_axis_angle(axis(rng), max * rng.next() as f32);
                if let Some(l) = locals.get_mut(r.node as usize) {
                    l.rotation = (q * l.rotation).normalize();
                }
            }
        }
        Animation::Ik => {
            if nodes.is_empty() {
                return;
            }
            for beyond in [false, rng.next() < 0.5] {
                let r = &nodes[(rng.next() * nodes.len() as f64) as usize % nodes.len()];
                let angle = if beyond { r.angle + 20f32.to_radians() } else { r.angle * 0.99 * rng.next() as f32 };
                if let Some(l) = locals.get_mut(r.node as usize) {
                    l.rotation = (Quat::from_axis_angle(axis(rng), angle) * r.centre).normalize();
                }
            }
        }
    }
}

/// True when the box is entirely outside one of the camera's planes.
pub fn outside(camera: &Camera, b: &Box3) -> bool {
    let (c, h) = ((b.min + b.max) / 2.0, (b.max - b.min) / 2.0);
    camera.planes.iter().any(|p| p.truncate().dot(c) + p.truncate().abs().dot(h) + p.w < 0.0)
}

/// Brute force: every triangle of a culled meshlet must be outside one plane (all three
/// vertices) or face away from the eye; every triangle culled one by one in a kept meshlet
/// must face away or be degenerate. Tolerances: the f32 rounding of the skinned positions.
fn check_culls(baked: &Baked, kept: &[bool], world: &[Vec3], camera: &Camera) -> (usize, usize) {
    let meshlets = &baked.meshlets;
    let (mut checked, mut false_culls) = (0, 0);
    let eye_mag = camera.eye().map_or(0.0, |e| e.as_dvec3().abs().max_element());
    for (m, meshlet) in meshlets.meshlets.iter().enumerate() {
        for t in meshlets.mesh_triangles(meshlet) {
            let w = t.map(|i| world[i as usize]);
            let by_triangle = kept[m] && facing(w[0], w[1], w[2], camera.projection) >= 0.0;
            if kept[m] && !by_triangle {
                continue;
            }
            checked += 1;
            let p = w.map(|q| q.as_dvec3());
            let magnitude = p.iter().map(|q| q.abs().max_element()).fold(0.0, f64::max);
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let n = e1.cross(e2);
            let (facing, reach) = match camera.projection {
                Projection::Perspective { eye } => {
                    let to = p[0] - eye.as_dvec3();
                    (to.dot(n), to.length())
                }
                Projection::Orthographic { dir } => (dir.as_dvec3().dot(n), 1.0),
            };
            let delta = 1e-6 * (magnitude + eye_mag);
            let tol = reach * 2.0 * delta * (e1.length() + e2.length()) + delta * n.length();
            let away = facing >= -tol;
            let out = camera.planes.iter().any(|pl| {
                let (nn, w) = (pl.truncate().as_dvec3(), pl.w as f64);
                p.iter().all(|q| nn.dot(*q) + w <= 1e-5 * (magnitude + w.abs()))
            });
            if !(away || (!by_triangle && out)) {
                false_culls += 1;
            }
        }
    }
    (checked, false_culls)
}
