//! The comparison of Han & Sander 2016, table 2: ACMR and overdraw of four ways to order an
//! animated mesh's triangles.
//!
//! - `original`: one buffer in vertex-cache order only.
//! - `tipsify-per-frame`: Sander et al. 2007 on each keyframe (the view-independent
//!   occlusion order of the same patches the clustering uses): one buffer per keyframe.
//! - `single`: [`super::cluster`] per clip, `k` buffers each, chosen by the lookup table.
//! - `joint`: one clustering over every keyframe of every clip, `k` buffers.
//!
//! OVR is the mean over samples of (keyframe, viewpoint) of each render's overdraw ratio;
//! the samples are uniform random pairs, `views` per clip (the paper renders every keyframe
//! from 300 random viewpoints; pairing them at random samples the same population at a
//! fraction of the cost). Viewpoints lie at 3 × the bounding-sphere radius. ACMR is the mean
//! over a method's buffers (FIFO cache of `cache_size`). Deterministic for a seed.

use super::cluster::{ClusterParams, Framing, Patches, cluster, cut, lookup};
use super::measure::{Raster, acmr};
use super::tipsify::occlusion_order;
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalParams {
    pub cluster: ClusterParams,
    /// Raster resolution of the evaluation renders.
    pub resolution: u32,
    /// Random (keyframe, viewpoint) samples per clip.
    pub views: usize,
}

impl Default for EvalParams {
    fn default() -> Self {
        EvalParams { cluster: ClusterParams::default(), resolution: 128, views: 300 }
    }
}

/// One row of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodResult {
    pub method: &'static str,
    /// The patch rule the buffers were built with.
    pub patches: Patches,
    /// Index buffers the method needs (per clip for `single`).
    pub buffers: usize,
    pub acmr: f64,
    pub ovr: f64,
    /// Preprocessing wall-clock seconds (per clip for `single`, in total otherwise).
    pub preprocess_s: f64,
}

/// Up to `max` evenly chosen key times of `clip` and the skinned positions of `mesh` (over
/// the joints of `skin`, e.g. a [`crate::Character`]'s palette) at each.
pub fn keyframes(
    skeleton: &crate::Skeleton,
    skin: &crate::Skin,
    mesh: &crate::SkinnedMesh,
    clip: &crate::clip::Clip,
    max: usize,
) -> crate::Result<(Vec<f32>, Vec<Vec<Vec3>>)> {
    let keys = clip.key_times();
    let times: Vec<f32> = if keys.len() <= max {
        keys
    } else {
        (0..max).map(|i| keys[i * (keys.len() - 1) / (max - 1).max(1)]).collect()
    };
    let positions = (times.iter())
        .map(|&t| crate::skinning::posed_positions(skeleton, skin, mesh, Some(clip), Some(t)))
        .collect::<crate::Result<Vec<_>>>()?;
    Ok((times, positions))
}

/// Picks the buffer for (clip, keyframe, eye).
type Pick<'a> = dyn Fn(usize, usize, Vec3) -> &'a [[u32; 3]] + Sync + 'a;

fn mean_ovr<'a>(
    samples: &[(usize, usize, Vec3)],
    clips: &[Vec<Vec<Vec3>>],
    framing: &Framing,
    resolution: u32,
    pick: &Pick<'a>,
) -> f64 {
    let ratios: Vec<f64> = samples
        .par_iter()
        .map_init(
            || Raster::new(resolution, resolution),
            |r, &(c, f, eye)| r.render(&clips[c][f], pick(c, f, eye), &framing.view_proj(eye)).ratio(),
        )
        .collect();
    let seen: Vec<f64> = ratios.into_iter().filter(|&x| x > 0.0).collect();
    seen.iter().sum::<f64>() / seen.len().max(1) as f64
}

/// Evaluates the four methods. `clips[c][f]` are the skinned positions of keyframe `f` of
/// clip `c`; `original` is the vertex-cache-ordered triangle list.
pub fn evaluate(clips: &[Vec<Vec<Vec3>>], original: &[[u32; 3]], params: &EvalParams) -> Vec<MethodResult> {
    let vertex_count = clips.iter().flatten().next().map_or(0, |k| k.len());
    let all: Vec<Vec<Vec3>> = clips.iter().flatten().cloned().collect();
    let framing = Framing::of(&all);
    let cache = params.cluster.cache_size;
    // Samples: (clip, keyframe, eye), the same for every method.
    let mut state = params.cluster.seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut samples = Vec::new();
    for (c, keys) in clips.iter().enumerate() {
        for _ in 0..params.views {
            let f = ((next() * keys.len() as f64) as usize).min(keys.len().saturating_sub(1));
            let z = 2.0 * next() - 1.0;
            let phi = next() * std::f64::consts::TAU;
            let r = (1.0 - z * z).sqrt();
            let dir = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            samples.push((c, f, framing.eye(dir, 3.0)));
        }
    }
    let ovr = |pick: &Pick| mean_ovr(&samples, clips, &framing, params.resolution, pick);
    let mean_acmr = |bufs: &[Vec<[u32; 3]>]| -> f64 {
        bufs.iter().map(|b| acmr(b, vertex_count, cache) as f64).sum::<f64>() / bufs.len().max(1) as f64
    };
    let first = clips.iter().flatten().next().map_or(&[][..], |k| k);
    let started = Instant::now();
    let (order, starts, patches) = cut(original, first, params.cluster.patches, cache);
    let cut_s = started.elapsed().as_secs_f64();
    let mut rows = vec![MethodResult {
        method: "original",
        patches,
        buffers: 1,
        acmr: acmr(original, vertex_count, cache) as f64,
        ovr: ovr(&|_, _, _| original),
        preprocess_s: 0.0,
    }];

    let started = Instant::now();
    let per_frame: Vec<Vec<Vec<[u32; 3]>>> =
        clips.iter().map(|keys| keys.par_iter().map(|pos| occlusion_order(pos, &order, &starts)).collect()).collect();
    let preprocess_s = cut_s + started.elapsed().as_secs_f64();
    let flat: Vec<Vec<[u32; 3]>> = per_frame.iter().flatten().cloned().collect();
    rows.push(MethodResult {
        method: "tipsify-per-frame",
        patches,
        buffers: flat.len(),
        acmr: mean_acmr(&flat),
        ovr: ovr(&|c, f, _| &per_frame[c][f]),
        preprocess_s,
    });

    let direction = |eye: Vec3, f: &Framing| (eye - f.center).normalize_or(Vec3::Z);
    let started = Instant::now();
    let single: Vec<_> = clips
        .iter()
        .map(|keys| {
            let c = cluster(keys, original, &params.cluster);
            let lookup = lookup(&c, 37, 72);
            (c, lookup)
        })
        .collect();
    let single_s = started.elapsed().as_secs_f64() / clips.len().max(1) as f64;
    let bufs: Vec<Vec<[u32; 3]>> = single.iter().flat_map(|(c, _)| c.buffers.clone()).collect();
    rows.push(MethodResult {
        method: "single",
        patches,
        buffers: params.cluster.k,
        acmr: mean_acmr(&bufs),
        ovr: ovr(&|c, f, eye| {
            let (cl, lookup) = &single[c];
            &cl.buffers[lookup.get(f, direction(eye, &cl.framing)) as usize]
        }),
        preprocess_s: single_s,
    });

    // One clip: "joint" is the same clustering as "single" (same nodes, parameters, seed).
    let started = Instant::now();
    let (joint, lookup) = match &single[..] {
        [one] => one.clone(),
        _ => {
            let joint = cluster(&all, original, &params.cluster);
            let lookup = lookup(&joint, 37, 72);
            (joint, lookup)
        }
    };
    let preprocess_s = if clips.len() == 1 { single_s } else { started.elapsed().as_secs_f64() };
    let offsets: Vec<usize> = clips.iter().scan(0, |acc, k| Some(std::mem::replace(acc, *acc + k.len()))).collect();
    rows.push(MethodResult {
        method: "joint",
        patches,
        buffers: joint.buffers.len(),
        acmr: mean_acmr(&joint.buffers),
        ovr: ovr(&|c, f, eye| &joint.buffers[lookup.get(offsets[c] + f, direction(eye, &joint.framing)) as usize]),
        preprocess_s,
    });
    rows
}
