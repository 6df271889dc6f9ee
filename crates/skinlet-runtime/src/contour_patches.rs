//! Run-time contour extraction with patches (Tsiapkolis & Bénard 2024, sections 3 and 4.1):
//! edges grouped into patches, each bounded by a spatialized normal cone (a sphere around
//! the edges' lines and a cone around their faces' normals); per view a patch whose cone
//! test (eq. 1) fails holds no contour edge, so its edges are not tested. The baker
//! (`skinlet::contour`) builds the patches; a bake's `CONT` section stores them, read here by
//! [`crate::bake_view::BakeView::contours`].
//!
//! Skinned characters: patch bounds live in a joint's space, valid over the baked clips (or
//! over one time window of a clip); per frame the viewer moves into each joint's space
//! (`G⁻¹·eye`; orthographic `A⁻¹·dir`), where facing, and so the contour set, is unchanged.
//!
//! Guarantee: [`Patches::extract`] and [`SkinnedPatches::extract`] return exactly the edges
//! [`brute_force`](crate::contour_edges::brute_force) returns, for positions the bounds hold
//! for (the baker's rest or static positions; a skinned pose within the baked clips). Every
//! cone test accepts [`MARGIN`] beyond eq. 1, far above the f32 rounding of the test and of
//! the stored bounds; edges are tested in f64 by the one per-edge test.

use crate::bake_view::Cursor;
use crate::camera::Projection;
use crate::contour_edges::{Edges, Tested, Viewer, extract_uncullable, quad_is_contour};
use crate::meshlet_bounds::round_up;
use crate::{Error, Result};
use glam::{DMat4, DVec3, Vec3};
use std::f64::consts::FRAC_PI_2;

/// Slack of the run-time cone test, in units of `sin`: covers the f32 rounding of the test
/// itself (≈ 1e-6) and of stored bounds, with a wide safety factor. It costs nothing
/// measurable: a patch within 1e-5 of the threshold is accepted.
pub const MARGIN: f32 = 1e-5;

/// Bounds as the run-time test reads them (f32, rounded outward).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchBounds {
    pub center: Vec3,
    pub radius: f32,
    pub axis: Vec3,
    pub sin_angle: f32,
    /// Negative for cones wider than π/2 (never culled).
    pub cos_angle: f32,
}

impl PatchBounds {
    /// Never culled.
    pub const ALWAYS: PatchBounds =
        PatchBounds { center: Vec3::ZERO, radius: 0.0, axis: Vec3::Z, sin_angle: 1.0, cos_angle: -1.0 };

    /// From f64 bounds, the radius and angle rounded up (a radius that is not finite or an
    /// angle from π/2 on: never culled, center and axis kept; a center or axis that is not
    /// finite: [`Self::ALWAYS`]).
    pub fn new(center: DVec3, radius: f64, axis: DVec3, angle: f64) -> PatchBounds {
        if !(axis.is_finite() && center.is_finite()) {
            return PatchBounds::ALWAYS;
        }
        let axis32 = axis.as_vec3().normalize();
        PatchBounds { center: center.as_vec3(), axis: axis32, ..PatchBounds::ALWAYS }.with_extent(center, radius, angle)
    }

    /// The same center and axis with another radius and angle around them (e.g. a bound over
    /// part of a clip): radius and angle rounded up; from π/2 on, never culled.
    pub fn with_extent(&self, center: DVec3, radius: f64, angle: f64) -> PatchBounds {
        if angle >= FRAC_PI_2 || !radius.is_finite() {
            return PatchBounds { sin_angle: 1.0, cos_angle: -1.0, ..*self };
        }
        // 1e-7 rad covers the f32 rounding of the stored axis and the sin/cos below.
        let angle = angle + 1e-7;
        let radius = radius * (1.0 + 1e-6) + center.distance(self.center.as_dvec3());
        PatchBounds {
            radius: round_up(radius),
            sin_angle: round_up(angle.sin()),
            cos_angle: (angle.cos() as f32).min(angle.cos() as f32 - f32::EPSILON * 0.5),
            ..*self
        }
    }

    /// Eq. 1 with [`MARGIN`]: `false` means no edge bounded by this patch can be a contour.
    #[inline(always)]
    pub fn accepts(&self, view: &ViewF) -> bool {
        match view {
            ViewF::Eye(eye) => self.accepts_eye(*eye),
            ViewF::Dir(dir) => self.accepts_dir(*dir),
        }
    }

    /// [`Self::accepts`] for a perspective eye, without branches (patches are tested in
    /// batches, where a mispredicted branch per patch would cost more than the test).
    #[inline(always)]
    pub fn accepts_eye(&self, eye: Vec3) -> bool {
        let d = self.center - eye;
        let dist2 = d.length_squared();
        let r = self.radius;
        let inv = dist2.sqrt().recip();
        let sin_b = (r * inv).min(1.0);
        let cos_b = (1.0 - sin_b * sin_b).max(0.0).sqrt();
        let cos_sum = self.cos_angle * cos_b - self.sin_angle * sin_b;
        let sin_sum = self.sin_angle * cos_b + self.cos_angle * sin_b;
        // Inside the sphere (or at its center) the test says nothing: accept. So does a
        // product past f32's range (a NaN).
        let along = (self.axis.dot(d) * inv).abs();
        (dist2 <= r * r * (1.0 + 1e-4)) | (cos_sum <= MARGIN) | (along <= sin_sum + MARGIN) | along.is_nan()
    }

    /// [`Self::accepts`] for an orthographic view along unit `dir`.
    #[inline(always)]
    pub fn accepts_dir(&self, dir: Vec3) -> bool {
        let along = self.axis.dot(dir).abs();
        (self.cos_angle <= MARGIN) | (along <= self.sin_angle + MARGIN) | along.is_nan()
    }
}

/// The viewer as cone tests use it (f32).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewF {
    Eye(Vec3),
    Dir(Vec3),
}

impl ViewF {
    pub fn new(projection: Projection) -> ViewF {
        match projection {
            Projection::Perspective { eye } => ViewF::Eye(eye),
            Projection::Orthographic { dir } => ViewF::Dir(dir.normalize()),
        }
    }
}

/// Both viewers of a projection.
pub fn viewers(projection: Projection) -> (Viewer, ViewF) {
    (Viewer::new(projection), ViewF::new(projection))
}

/// A patch decomposition, ready for extraction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Patches {
    pub bounds: Vec<PatchBounds>,
    /// Per patch: first index into `order` and edge count.
    pub ranges: Vec<[u32; 2]>,
    /// Quad identifiers, patch after patch, then from `always_from` the quads tested every time.
    pub order: Vec<u32>,
    /// The quads of `order` (a copy, so extraction reads them in sequence).
    pub quads: Vec<[u32; 4]>,
    pub always_from: usize,
    /// Model size the metric used (largest side of the quads' box).
    pub size: f64,
    /// The `t_P / t_e` the decomposition was optimized for (calibrated per machine).
    pub cost_ratio: f64,
    /// Mean radius (in model sizes) and cone half-angle (degrees) of the patches.
    pub mean_radius: f64,
    pub mean_angle_deg: f64,
}

impl Patches {
    /// Contour edges (identifiers of [`Edges`], in patch order) for one view.
    pub fn extract(&self, positions: &[Vec3], edges: &Edges, projection: Projection, out: &mut Vec<u32>) -> Tested {
        let (viewer, view) = viewers(projection);
        out.clear();
        let mut tested = self.test_patches(positions, 0..self.len(), &self.bounds, Some(view), &viewer, out);
        tested += self.test_always(positions, edges, &viewer, out);
        Tested { edges: tested, bounds: self.bounds.len() }
    }

    pub fn len(&self) -> usize {
        self.bounds.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bounds.is_empty()
    }

    /// Tests the quads outside patches, the irregular edges, and adds the boundary edges;
    /// returns the edges tested.
    pub fn test_always(&self, positions: &[Vec3], edges: &Edges, viewer: &Viewer, out: &mut Vec<u32>) -> usize {
        let rest = self.always_from..self.order.len();
        test_quads(positions, &self.quads[rest.clone()], &self.order[rest.clone()], viewer, out);
        rest.len() + extract_uncullable(positions, edges, viewer, out)
    }

    /// Tests patches `which` with `bounds` (one per patch in `which`) from `view` (`None`:
    /// accept all), then the quads of the accepted ones; returns the quads tested. Cone tests
    /// run in batches of 64 without branches, then the accepted patches' edges.
    pub fn test_patches(
        &self,
        positions: &[Vec3],
        which: std::ops::Range<usize>,
        bounds: &[PatchBounds],
        view: Option<ViewF>,
        viewer: &Viewer,
        out: &mut Vec<u32>,
    ) -> usize {
        let mut tested = 0;
        let mut flags = [true; 64];
        for (bounds, ranges) in bounds.chunks(64).zip(self.ranges[which].chunks(64)) {
            match view {
                Some(ViewF::Eye(eye)) => flags.iter_mut().zip(bounds).for_each(|(f, b)| *f = b.accepts_eye(eye)),
                Some(ViewF::Dir(dir)) => flags.iter_mut().zip(bounds).for_each(|(f, b)| *f = b.accepts_dir(dir)),
                None => {}
            }
            for (&accepted, r) in flags.iter().zip(ranges) {
                if accepted {
                    let range = r[0] as usize..(r[0] + r[1]) as usize;
                    test_quads(positions, &self.quads[range.clone()], &self.order[range], viewer, out);
                    tested += r[1] as usize;
                }
            }
        }
        tested
    }
}

#[inline(always)]
pub fn test_quads(p: &[Vec3], quads: &[[u32; 4]], ids: &[u32], viewer: &Viewer, out: &mut Vec<u32>) {
    for (q, &id) in quads.iter().zip(ids) {
        if quad_is_contour(p, *q, viewer) {
            out.push(id);
        }
    }
}

/// Patches of a skinned mesh, bounds in their joints' spaces.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinnedPatches {
    /// The patches with bounds that hold over every clip.
    pub patches: Patches,
    /// Per patch, its joint (index into the skin's joints); patches of a joint are adjacent.
    pub joints: Vec<u16>,
    /// Quads in rigid patches / in animated (non-rigid) patches.
    pub rigid_quads: usize,
    pub animated_quads: usize,
    /// Per baked clip (in the order the baker was given them), its time windows.
    pub clips: Vec<ClipWindows>,
    /// Bounds over each window, window after window (`window_bounds[w * patches + i]`); same
    /// centers and axes as `patches.bounds`, each at most as wide.
    pub window_bounds: Vec<PatchBounds>,
}

/// The windows of one clip: `count` equal parts of `[start, end]` (its first and last key
/// time; before and after, the pose stays the end keys'), numbered from `first`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipWindows {
    pub start: f32,
    pub end: f32,
    pub count: u32,
    pub first: u32,
}

impl ClipWindows {
    /// The window `[a, b]` number `k` of the clip.
    pub fn range(&self, k: u32) -> (f32, f32) {
        let d = (self.end - self.start) / self.count as f32;
        (self.start + d * k as f32, if k + 1 == self.count { self.end } else { self.start + d * (k + 1) as f32 })
    }

    /// The window holding time `t`, clamped to the clip (infinite times too; `first` for a NaN
    /// time or a clip without windows).
    pub fn at(&self, t: f32) -> u32 {
        let x = (t - self.start) / (self.end - self.start) * self.count as f32;
        // `max` drops a NaN and the cast saturates +∞.
        self.first.saturating_add((x.max(0.0) as u32).min(self.count.saturating_sub(1)))
    }
}

/// The viewer in the space of a joint whose global matrix has inverse `inverse` (`G⁻¹·eye`,
/// or `A⁻¹·dir` normalized), as patch tests read it; `None` when that matrix is singular or
/// not finite (such a joint says nothing about facing: its patches are all tested).
pub fn joint_view(inverse: &DMat4, projection: Projection) -> Option<ViewF> {
    let view = match projection {
        Projection::Perspective { eye } => ViewF::Eye(inverse.transform_point3(eye.as_dvec3()).as_vec3()),
        Projection::Orthographic { dir } => {
            ViewF::Dir(inverse.transform_vector3(dir.as_dvec3()).normalize_or_zero().as_vec3())
        }
    };
    let finite = match view {
        ViewF::Eye(e) => e.is_finite(),
        ViewF::Dir(d) => d.is_finite() && d != Vec3::ZERO,
    };
    finite.then_some(view)
}

impl SkinnedPatches {
    /// The window of clip `clip` (index into the baked clips) at time `t`.
    pub fn window(&self, clip: usize, t: f32) -> Option<usize> {
        self.clips.get(clip).map(|w| w.at(t) as usize)
    }

    /// Contour edges of the skinned `positions` for joints at global (model-space) matrices
    /// `joint_globals` (one per skin joint), posed by `clip` at time `t` when `at` is given
    /// (the window's bounds are used; otherwise those over every clip).
    pub fn extract(
        &self,
        positions: &[Vec3],
        edges: &Edges,
        joint_globals: &[DMat4],
        at: Option<(usize, f32)>,
        projection: Projection,
        out: &mut Vec<u32>,
    ) -> Tested {
        let inverse = |j: usize| joint_globals.get(j).map_or(DMat4::NAN, |g| g.inverse());
        self.extract_with(positions, edges, inverse, at, projection, out)
    }

    /// [`Self::extract`] with the joints' inverse global matrices computed once per frame
    /// (`joint_inverses[j] = joint_globals[j]⁻¹`), for several views of one frame.
    pub fn extract_prepared(
        &self,
        positions: &[Vec3],
        edges: &Edges,
        joint_inverses: &[DMat4],
        at: Option<(usize, f32)>,
        projection: Projection,
        out: &mut Vec<u32>,
    ) -> Tested {
        let inverse = |j: usize| joint_inverses.get(j).copied().unwrap_or(DMat4::NAN);
        self.extract_with(positions, edges, inverse, at, projection, out)
    }

    /// Which bounds a frame uses: `w + 1` for window `w` of clip `at.0` at time `at.1` (when
    /// given and built), else 0, the bounds over every clip. See [`Self::bound_set_bounds`].
    pub fn bound_set(&self, at: Option<(usize, f32)>) -> usize {
        let n = self.patches.len();
        match at.and_then(|(c, t)| self.window(c, t)) {
            Some(w) if self.window_bounds.len() >= (w + 1) * n => w + 1,
            _ => 0,
        }
    }

    /// The bounds of set `set` (one per patch; 0: over every clip, `w + 1`: window `w`).
    pub fn bound_set_bounds(&self, set: usize) -> &[PatchBounds] {
        let n = self.patches.len();
        match set {
            0 => &self.patches.bounds,
            w => self.window_bounds.get((w - 1) * n..w * n).unwrap_or(&self.patches.bounds),
        }
    }

    /// The number of bound sets: 1 + the windows built.
    pub fn bound_sets(&self) -> usize {
        1 + self.window_bounds.len().checked_div(self.patches.len()).unwrap_or(0)
    }

    fn extract_with(
        &self,
        positions: &[Vec3],
        edges: &Edges,
        inverse: impl Fn(usize) -> DMat4,
        at: Option<(usize, f32)>,
        projection: Projection,
        out: &mut Vec<u32>,
    ) -> Tested {
        let all_bounds = self.bound_set_bounds(self.bound_set(at));
        let viewer = Viewer::new(projection);
        out.clear();
        let p = &self.patches;
        let mut tested = 0;
        let mut start = 0;
        while start < self.joints.len() {
            let j = self.joints[start];
            let end = start + self.joints[start..].iter().take_while(|&&x| x == j).count();
            let view = joint_view(&inverse(j as usize), projection);
            tested += p.test_patches(positions, start..end, &all_bounds[start..end], view, &viewer, out);
            start = end;
        }
        tested += p.test_always(positions, edges, &viewer, out);
        Tested { edges: tested, bounds: p.len() }
    }
}

/// Per vertex, the joint that carries all its weight (a single influence of weight exactly
/// 1; with any other weight `w`, `w·G·x` is not fixed in the joint's space), unless
/// `morphed(v)` (a morph target moves it). Influences as a bake stores them: `stride` slots
/// per vertex (0: no skin, no vertex rigid), a zero weight ends a vertex's list.
pub fn rigid_vertices(
    vertices: usize,
    stride: usize,
    joints: &[u16],
    weights: &[f32],
    morphed: impl Fn(usize) -> bool,
) -> Vec<Option<u16>> {
    (0..vertices)
        .map(|v| {
            let slots = v * stride..(v + 1) * stride;
            let (Some(j), Some(w)) = (joints.get(slots.clone()), weights.get(slots)) else { return None };
            if stride == 0 || morphed(v) {
                return None;
            }
            let mut used = j.iter().zip(w).take_while(|(_, w)| **w != 0.0);
            match (used.next(), used.next()) {
                (Some((&j, 1.0)), None) => Some(j),
                _ => None,
            }
        })
        .collect()
}

/// A quad is rigid when its four vertices follow one joint rigidly.
pub fn rigid_quad(rigid: &[Option<u16>], q: &[u32; 4]) -> bool {
    let r = rigid[q[0] as usize];
    r.is_some() && q.iter().all(|&v| rigid[v as usize] == r)
}

/// The edges contour patches of a skinned mesh index: [`Edges::build`], and with `rigid`
/// (visible-only patches) minus the concave rigid quads, whose concavity cannot change, so
/// their contours are always hidden.
pub fn skinned_edges(positions: &[Vec3], triangles: &[[u32; 3]], rigid: Option<&[Option<u16>]>) -> Result<Edges> {
    let mut edges = Edges::build(positions, triangles)?;
    if let Some(rigid) = rigid {
        if rigid.len() != positions.len() {
            return Err(Error::invalid(
                "contour edges",
                format!("{} rigid flags for {} vertices", rigid.len(), positions.len()),
            ));
        }
        edges.drop_concave(positions, |q| rigid_quad(rigid, q));
    }
    Ok(edges)
}

/// A bake's contour patches (section `CONT`, `docs/FORMAT.md`); their quads index the edges
/// [`skinned_edges`] rebuilds from the bake's vertices and triangles (the file does not store
/// edges, so this section is read into arrays rather than viewed in place).
#[derive(Clone, Debug, PartialEq)]
pub struct BakedContours {
    pub visible_only: bool,
    pub patches: SkinnedPatches,
}

/// Bytes of one patch record in `CONT`.
const PATCH_RECORD: usize = 48;

impl BakedContours {
    /// The visible-only flag of `CONT` bytes: whether [`Self::read`] needs the edges without
    /// the concave rigid quads.
    pub fn visible_only(section: &[u8]) -> Result<bool> {
        let mut s = Cursor::new("CONT", section);
        match s.u32()? {
            0 => Ok(false),
            1 => Ok(true),
            x => Err(s.err(format!("visible-only flag {x}"))),
        }
    }

    /// Reads and checks `CONT` bytes against `edges` (rebuilt with [`skinned_edges`] as
    /// [`Self::visible_only`] says) and the bake's `joints`: every quad in exactly one place,
    /// patch ranges contiguous from 0, joints in range, radii and angles valid, window lists
    /// consecutive. Errors name the byte.
    pub fn read(section: &[u8], edges: &Edges, joints: usize) -> Result<BakedContours> {
        let visible_only = BakedContours::visible_only(section)?;
        let mut s = Cursor::new("CONT", section);
        s.at = 4;
        let (quads, n, always_from) = (s.u32()? as usize, s.u32()? as usize, s.u32()? as usize);
        let (rigid_quads, animated_quads) = (s.u32()? as usize, s.u32()? as usize);
        let mut stats = [0.0; 4];
        for x in &mut stats {
            *x = f64::from_le_bytes(s.bytes(8)?.try_into().expect("8 bytes"));
            if !x.is_finite() {
                return Err(s.err("non-finite statistic"));
            }
        }
        s.align(64)?;
        if quads != edges.quads.len() || always_from > quads || n.saturating_mul(PATCH_RECORD) > section.len() {
            return Err(
                s.err(format!("{quads} quads ({} in the mesh), {always_from} in {n} patches", edges.quads.len()))
            );
        }
        let mut p = Patches {
            always_from,
            size: stats[0],
            mean_radius: stats[1],
            mean_angle_deg: stats[2],
            cost_ratio: stats[3],
            ..Patches::default()
        };
        let mut patch_joints = Vec::with_capacity(n);
        for i in 0..n {
            let (center, radius, axis, sin_angle, cos_angle) = (s.vec3()?, s.f32()?, s.vec3()?, s.f32()?, s.f32()?);
            let (joint, first, count) = (s.u32()?, s.u32()?, s.u32()?);
            let at = p.ranges.last().map_or(0, |r: &[u32; 2]| r[0] as usize + r[1] as usize);
            if joint as usize >= joints.min(1 << 16)
                || first as usize != at
                || count == 0
                || radius < 0.0
                || !cone_ok(axis, sin_angle, cos_angle)
            {
                return Err(s.err(format!(
                    "patch {i}: joint {joint}, edges {first}+{count}, radius {radius}, sin/cos {sin_angle}/{cos_angle}"
                )));
            }
            p.bounds.push(PatchBounds { center, radius, axis, sin_angle, cos_angle });
            p.ranges.push([first, count]);
            patch_joints.push(joint as u16);
        }
        if p.ranges.last().map_or(0, |r| r[0] as usize + r[1] as usize) != always_from {
            return Err(s.err(format!("patches hold other than {always_from} quads")));
        }
        if quads.saturating_mul(4) > section.len() - s.at {
            return Err(s.err(format!("{quads} quad indices do not fit in the section")));
        }
        p.order = (0..quads).map(|_| s.u32()).collect::<Result<Vec<_>>>()?;
        let mut seen = vec![false; quads];
        for &q in &p.order {
            if std::mem::replace(seen.get_mut(q as usize).ok_or_else(|| s.err(format!("quad {q} of {quads}")))?, true) {
                return Err(s.err(format!("quad {q} appears twice")));
            }
        }
        let n_clips = s.u32()? as usize;
        if n_clips.saturating_mul(16) > section.len() - s.at {
            return Err(s.err(format!("{n_clips} clip window lists do not fit in the section")));
        }
        let mut clips = Vec::with_capacity(n_clips);
        let mut total = 0u32;
        for c in 0..n_clips {
            let w = ClipWindows { start: s.f32()?, end: s.f32()?, count: s.u32()?, first: s.u32()? };
            if w.first != total || w.count == 0 || w.end < w.start {
                return Err(s.err(format!("clip {c}: windows {}+{} over [{}, {}]", w.first, w.count, w.start, w.end)));
            }
            total = w.first.saturating_add(w.count);
            clips.push(w);
        }
        let cells = (total as usize).checked_mul(n).filter(|c| c.saturating_mul(12) <= section.len() - s.at);
        let cells = cells.ok_or_else(|| s.err(format!("{total} windows x {n} patches do not fit in the section")))?;
        let mut window_bounds = Vec::with_capacity(cells);
        for i in 0..cells {
            let (radius, sin_angle, cos_angle) = (s.f32()?, s.f32()?, s.f32()?);
            if radius < 0.0 || !cone_ok(p.bounds[i % n].axis, sin_angle, cos_angle) {
                return Err(s.err(format!("window bound {i}: radius {radius}, sin/cos {sin_angle}/{cos_angle}")));
            }
            window_bounds.push(PatchBounds { radius, sin_angle, cos_angle, ..p.bounds[i % n] });
        }
        s.end()?;
        p.quads = p.order.iter().map(|&q| edges.quads[q as usize]).collect();
        Ok(BakedContours {
            visible_only,
            patches: SkinnedPatches {
                patches: p,
                joints: patch_joints,
                rigid_quads,
                animated_quads,
                clips,
                window_bounds,
            },
        })
    }
}

/// A stored cone as the patch tests read it: a half-angle in [0, π] by its sine (≥ 0) and
/// cosine; where the cone is used (`cos α > 0`; at 90° or more every patch is accepted) the
/// two agree (`sin² + cos² = 1` within f32 rounding) and the axis is a unit vector.
fn cone_ok(axis: Vec3, sin_angle: f32, cos_angle: f32) -> bool {
    let unit = |x: f32| (x - 1.0).abs() <= crate::bake_view::UNIT;
    (0.0..=1.0).contains(&sin_angle)
        && (-1.0..=1.0).contains(&cos_angle)
        && (cos_angle <= 0.0 || (unit(sin_angle * sin_angle + cos_angle * cos_angle) && unit(axis.length_squared())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_of_a_caller_never_panic() {
        // No windows at all: the first (there is nothing better to say); NaN times too.
        let none = ClipWindows { start: 0.0, end: 1.0, count: 0, first: 3 };
        assert_eq!((none.at(0.5), none.at(f32::NAN)), (3, 3));
        // Times past either end are the end windows' (the pose holds the end keys).
        let w = ClipWindows { start: 0.0, end: 1.0, count: 4, first: 2 };
        assert_eq!([-f32::INFINITY, -1.0, 0.3, 1.0, 7.0, f32::INFINITY].map(|t| w.at(t)), [2, 2, 3, 5, 5, 5]);
        let instant = ClipWindows { start: 1.0, end: 1.0, count: 1, first: 0 };
        assert_eq!([0.0, 1.0, 2.0].map(|t| instant.at(t)), [0, 0, 0]);
    }

    #[test]
    fn rigid_vertices_need_one_whole_weight_and_no_morph() {
        // Stride 2: [j3 w1] rigid; [j1 .5, j2 .5] not; [j4 1, j5 0] rigid (a zero ends the
        // list); [j6 1] moved by a morph target; [j7 0.999] not.
        let joints = [3, 0, 1, 2, 4, 5, 6, 0, 7, 0];
        let weights = [1.0, 0.0, 0.5, 0.5, 1.0, 0.0, 1.0, 0.0, 0.999, 0.0];
        let rigid = rigid_vertices(5, 2, &joints, &weights, |v| v == 3);
        assert_eq!(rigid, [Some(3), None, Some(4), None, None]);
        assert_eq!(rigid_vertices(2, 0, &[], &[], |_| false), [None, None]);
        // Too few slots for the vertex count: not rigid, no panic.
        assert_eq!(rigid_vertices(2, 2, &joints[..2], &weights[..2], |_| false), [Some(3), None]);
        assert!(rigid_quad(&[Some(1), Some(1), Some(1), Some(1)], &[0, 1, 2, 3]));
        assert!(!rigid_quad(&[Some(1), Some(1), Some(2), Some(1)], &[0, 1, 2, 3]));
        assert!(!rigid_quad(&[None; 4], &[0, 1, 2, 3]));
    }

    #[test]
    fn bad_contour_sections_are_errors_that_say_where() {
        let edges = Edges::default();
        let read = |b: &[u8]| BakedContours::read(b, &edges, 1).unwrap_err().to_string();
        assert!(read(&[]).contains("CONT") && read(&[]).contains("truncated"));
        let mut b = vec![0u8; 64];
        b[0] = 2;
        assert!(read(&b).contains("visible-only flag 2"));
        // An empty patch set over an edgeless mesh reads; one more quad than the mesh has does not.
        let mut ok = vec![0u8; 64];
        ok.extend_from_slice(&0u32.to_le_bytes()); // no clips
        let c = BakedContours::read(&ok, &edges, 1).unwrap();
        assert_eq!((c.visible_only, c.patches.patches.len(), c.patches.bound_sets()), (false, 0, 1));
        let mut more = ok.clone();
        more[4] = 1;
        assert!(read(&more).contains("1 quads (0 in the mesh)"));
        let mut trailing = ok.clone();
        trailing.push(0);
        assert!(read(&trailing).contains("unexpected bytes"));
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let e = skinned_edges(&positions, &[[0, 1, 2]], Some(&[None])).unwrap_err().to_string();
        assert!(e.contains("1 rigid flags for 3 vertices"), "{e}");
    }
}
