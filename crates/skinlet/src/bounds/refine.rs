//! Adaptive refinement of meshlet bounds under a time budget (paper sections 5 and 7).
//!
//! A meshlet's sphere radius and normal cone are the extremes over a set of time pieces that
//! together cover every clip: first the key intervals (bounds never span a key), then, round
//! by round, each meshlet halves the piece that decides its worst bound. Shorter pieces give
//! smaller vertex boxes, so the extremes shrink toward what the animation really reaches.
//! Which bound a meshlet refines follows the classification thresholds (section 6): first
//! the radius while it exceeds `s_r` times the rest radius, then the cone while it keeps the
//! meshlet from "both", then both bounds in turn for tightness. A piece whose halves do not
//! improve its value by more than [`GAIN`] of its growth beyond the rest pose is flat: the
//! extreme is reached at an instant there, and halving again would not help; a bound within
//! [`CLOSE`] of the rest pose's is left alone.
//!
//! Guarantee: every piece's bounds are conservative for that piece ([`super::vertex`]), and
//! the pieces always cover every key interval, so the bounds are conservative after every
//! round; a budget only decides how tight they get. Each round is deterministic (meshlets
//! are independent), so the output depends only on the input and the number of rounds.

use super::sphere_cone::{MeshletBounds, key_intervals, piece_extent, rest_bounds, round_up};
use super::vertex::IntervalMotions;
use crate::Result;
use crate::clip::Clip;
use crate::meshlet::{Meshlet, Meshlets};
use crate::model::{Skeleton, Skin, SkinnedMesh};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::time::{Duration, Instant};

/// Smallest improvement (share of a piece's growth beyond the rest pose) that keeps halving.
pub const GAIN: f64 = 0.01;
/// Growth beyond the rest pose that is not worth refining: this share of the rest radius,
/// or this many radians of cone angle.
pub const CLOSE: f64 = 1e-3;
/// Most halvings of one key interval.
pub const MAX_DEPTH: u8 = 16;

/// What to refine for and when to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// Radius threshold (times the rest radius) of the classification.
    pub s_r: f32,
    /// Normal deviation threshold of the classification, radians.
    pub alpha_t: f32,
    /// Wall-clock limit for the whole computation, key intervals included (which always run).
    pub budget: Option<Duration>,
    /// Most refinement rounds (0: key intervals only).
    pub max_rounds: usize,
}

impl Refinement {
    /// Key intervals only.
    pub const NONE: Refinement = Refinement { s_r: 3.0, alpha_t: 0.349_065_84, budget: None, max_rounds: 0 };
}

/// Why refinement stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// No meshlet had a piece left worth halving.
    Converged,
    /// `max_rounds` reached.
    Rounds,
    /// The budget ran out (the output then depends on the machine's speed; pass the reported
    /// round count as `max_rounds` to reproduce it exactly).
    Budget,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    pub bounds: Vec<MeshletBounds>,
    /// Per meshlet, its final time pieces: together they cover every key interval of every
    /// clip, and `bounds` is their union. A caller can bound a sub-range of a clip by the
    /// pieces that overlap it (same center and axis, their largest radius and angle).
    pub extents: Vec<Vec<PieceExtent>>,
    /// Rounds completed.
    pub rounds: usize,
    pub stop: Stop,
    /// Pieces evaluated, over all meshlets.
    pub pieces: u64,
    /// Vertex-influence-intervals evaluated: per piece, the meshlet's nonzero influences.
    pub work: u64,
}

/// A meshlet's bound over one time piece of one clip, around its stored center and axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceExtent {
    pub clip: u32,
    pub t1: f32,
    pub t2: f32,
    /// Radius over the piece (not below the rest radius).
    pub radius: f64,
    /// Cosine of the widest normal around the axis over the piece (≤ 0: no useful cone),
    /// not above the rest cone's.
    pub min_cos: f64,
}

/// One time piece of one meshlet with the meshlet's bounds over it (rest pose included).
#[derive(Clone, Copy, Debug)]
struct Piece {
    clip: u32,
    t1: f32,
    t2: f32,
    depth: u8,
    radius: f64,
    /// Cosine of the widest corner normal around the axis; ≤ 0: no useful cone.
    min_cos: f64,
    flat_radius: bool,
    flat_cone: bool,
}

impl Piece {
    fn angle(&self) -> f64 {
        if self.min_cos > 0.0 { self.min_cos.min(1.0).acos() } else { PI }
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Target {
    Radius,
    Cone,
}

struct State {
    pieces: Vec<Piece>,
    done: bool,
    pieces_evaluated: u64,
}

/// Where a refinement stands, reported after the key intervals and after every round.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub rounds: usize,
    /// Meshlets still refining.
    pub active: usize,
    pub elapsed: Duration,
}

/// Bounds of every meshlet over every clip in `clips` (no clip: the rest pose only), refined
/// as `how` allows.
pub fn refine(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    how: &Refinement,
) -> Result<Refined> {
    refine_with_progress(skeleton, skin, clips, mesh, meshlets, how, &mut |_| {})
}

/// [`refine`], calling `progress` after the key intervals and after every round.
pub fn refine_with_progress(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    how: &Refinement,
    progress: &mut dyn FnMut(Progress),
) -> Result<Refined> {
    let started = Instant::now();
    let Some(inf) = &mesh.influences else {
        return Err(crate::Error::invalid("meshlet bounds", "the mesh has no skin weights"));
    };
    mesh.morphs.check(mesh.positions.len())?;
    let mut bounds = rest_bounds(skin, mesh, meshlets);
    let intervals: Vec<(u32, f32, f32)> = clips
        .iter()
        .enumerate()
        .flat_map(|(i, c)| key_intervals(c).into_iter().map(move |(a, b)| (i as u32, a, b)))
        .collect();
    let motions = intervals
        .iter()
        .map(|&(c, a, b)| IntervalMotions::new(skeleton, &mesh.morphs, Some(clips[c as usize]), a, b))
        .collect::<Result<Vec<_>>>()?;
    let ctx = Ctx { skeleton, skin, mesh, meshlets };
    let mut states: Vec<State> = bounds
        .par_iter()
        .zip(&meshlets.meshlets)
        .map(|(b, m)| {
            let mut boxes = Vec::new();
            let pieces = intervals
                .iter()
                .zip(&motions)
                .map(|(&(clip, t1, t2), mo)| {
                    let (radius, min_cos) = piece_extent(&ctx, m, b, mo, &mut boxes);
                    let flat = t1 == t2;
                    Piece { clip, t1, t2, depth: 0, radius, min_cos, flat_radius: flat, flat_cone: flat }
                })
                .collect::<Vec<_>>();
            State { pieces_evaluated: pieces.len() as u64, pieces, done: false }
        })
        .collect();
    let mut rounds = 0;
    let stop = loop {
        let active = states.iter().filter(|s| !s.done).count();
        progress(Progress { rounds, active, elapsed: started.elapsed() });
        if active == 0 {
            break Stop::Converged;
        }
        if rounds >= how.max_rounds {
            break Stop::Rounds;
        }
        if how.budget.is_some_and(|b| started.elapsed() >= b) {
            break Stop::Budget;
        }
        states.par_iter_mut().zip(&bounds).zip(&meshlets.meshlets).try_for_each(|((s, b), m)| {
            if !s.done {
                s.done = !refine_once(&ctx, clips, m, b, s, how, rounds)?;
            }
            Ok::<_, crate::Error>(())
        })?;
        rounds += 1;
    };
    let mut pieces = 0;
    let mut work = 0;
    let extents = states
        .iter()
        .zip(&bounds)
        .map(|(s, b)| {
            let (r0, c0) = (b.radius as f64, (b.rest_cone_angle as f64).cos());
            s.pieces
                .iter()
                .map(|p| PieceExtent {
                    clip: p.clip,
                    t1: p.t1,
                    t2: p.t2,
                    radius: p.radius.max(r0),
                    min_cos: p.min_cos.min(c0),
                })
                .collect()
        })
        .collect();
    for ((b, s), m) in bounds.iter_mut().zip(&states).zip(&meshlets.meshlets) {
        let radius = s.pieces.iter().map(|p| p.radius).fold(b.radius as f64, f64::max);
        let min_cos = s.pieces.iter().map(|p| p.min_cos).fold((b.rest_cone_angle as f64).cos(), f64::min);
        b.radius = round_up(radius);
        b.cone_angle = if min_cos > 0.0 { round_up(min_cos.min(1.0).acos()) } else { PI as f32 };
        pieces += s.pieces_evaluated;
        let per_piece: usize = meshlets.vertices_of(m).iter().map(|&v| inf.count(v as usize)).sum();
        work += s.pieces_evaluated * per_piece as u64;
    }
    Ok(Refined { bounds, extents, rounds, stop, pieces, work })
}

/// Read-only inputs of the per-piece evaluation.
pub(crate) struct Ctx<'a> {
    pub skeleton: &'a Skeleton,
    pub skin: &'a Skin,
    pub mesh: &'a SkinnedMesh,
    pub meshlets: &'a Meshlets,
}

/// Halves the piece deciding the meshlet's worst bound; false when no piece is worth it.
fn refine_once(
    ctx: &Ctx,
    clips: &[&Clip],
    m: &Meshlet,
    rest: &MeshletBounds,
    s: &mut State,
    how: &Refinement,
    round: usize,
) -> Result<bool> {
    let by_radius = (0..s.pieces.len()).max_by(|&a, &b| s.pieces[a].radius.total_cmp(&s.pieces[b].radius));
    let by_cone = (0..s.pieces.len()).max_by(|&a, &b| s.pieces[a].angle().total_cmp(&s.pieces[b].angle()));
    let (Some(ir), Some(ic)) = (by_radius, by_cone) else { return Ok(false) };
    let rest_angle = rest.rest_cone_angle as f64;
    let (rest_radius, worst_angle) = (rest.radius as f64, s.pieces[ic].angle());
    let radius_open = !s.pieces[ir].flat_radius && s.pieces[ir].radius - rest_radius > CLOSE * rest_radius;
    let cone_open = rest_angle < FRAC_PI_2 && !s.pieces[ic].flat_cone && worst_angle - rest_angle > CLOSE;
    let radius_bad = s.pieces[ir].radius > how.s_r as f64 * rest.rest_radius as f64;
    let cone_bad = !(worst_angle < FRAC_PI_2 && worst_angle - rest_angle <= how.alpha_t as f64);
    let target = if radius_bad && radius_open {
        Target::Radius
    } else if cone_bad && cone_open {
        Target::Cone
    } else if radius_open && (round.is_multiple_of(2) || !cone_open) {
        Target::Radius
    } else if cone_open {
        Target::Cone
    } else {
        return Ok(false);
    };
    let i = if target == Target::Radius { ir } else { ic };
    let p = s.pieces[i];
    let mid = p.t1 + (p.t2 - p.t1) / 2.0;
    if p.depth >= MAX_DEPTH || !(p.t1 < mid && mid < p.t2) {
        let p = &mut s.pieces[i];
        match target {
            Target::Radius => p.flat_radius = true,
            Target::Cone => p.flat_cone = true,
        }
        return Ok(true);
    }
    let clip = clips[p.clip as usize];
    let mut boxes = Vec::new();
    let mut half = |t1: f32, t2: f32| -> Result<Piece> {
        let mo = IntervalMotions::new(ctx.skeleton, &ctx.mesh.morphs, Some(clip), t1, t2)?;
        let (radius, min_cos) = piece_extent(ctx, m, rest, &mo, &mut boxes);
        let mut h = Piece { t1, t2, depth: p.depth + 1, radius, min_cos, ..p };
        // A half that kept (nearly) the parent's value holds the extreme: flat for that bound.
        h.flat_radius = p.flat_radius || p.radius - h.radius <= GAIN * (p.radius - rest_radius);
        h.flat_cone = p.flat_cone || p.angle() - h.angle() <= GAIN * (p.angle() - rest_angle);
        Ok(h)
    };
    let (a, b) = (half(p.t1, mid)?, half(mid, p.t2)?);
    s.pieces[i] = a;
    s.pieces.push(b);
    s.pieces_evaluated += 2;
    Ok(true)
}
