//! What makes the checked view's "checked" mean something (issue 36, item 1): for any bytes
//! `skinlet_runtime::bake_view::BakeView` accepts, every per-meshlet decision of the runtime
//! culler (frustum, backface, both, over `BNDS` and over `ENVL`'s envelope bounds), of the
//! any-pose box test (alone and with the bounds), and every per-patch decision of the contour
//! patch test (`CONT`, over every clip and over a clip's time window) equals a plain f64
//! implementation of the formulas of `docs/FORMAT.md` and `docs/CULLING.md` applied to the same
//! stored records: module [`doc`], with its own parser of the file, written from the documents
//! (it shares no code with the runtime). A disagreement is allowed only where the f64 value lies
//! within the documented margin of the decision boundary ([`margins`]). The two runtime bugs it
//! found (a meshlet without a cone culled through a long stored axis; a far patch refused
//! through a NaN) have a deterministic test each at the end.
//!
//! The bytes: the demo character baked once with an envelope and contour patches, then per case
//! a few random overwrites of its `BNDS`, `ENVL`, `CONT` and `PART` records (whole records with
//! random content, single fields with random words: NaN, ±∞, huge, tiny, subnormal, non-unit
//! axes, angles around π/2 and π, joint numbers in and out of range, raw bytes). The world: random
//! joint matrices (the bind pose moved and bent, or anything: mirroring, shear, near-zero and
//! zero scale, far from the origin) and random cameras (perspective, orthographic, infinite
//! reverse-Z). The test prints the cases run, how many mutated bakes the view accepted, the
//! decisions compared and the disagreements allowed, by reason; `PROPTEST_CASES` runs more.

mod common;

use common::SplitMix as Rng;
use glam::{Affine3A, DMat3, DMat4, DQuat, DVec3, Mat4, Vec3};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use skinlet::bake::{add_contours, add_envelope, bake, to_bytes};
use skinlet::bounds::envelope::Envelope;
use skinlet::bounds::refine::Refinement;
use skinlet::contour::skinned::{SkinnedMethod, SkinnedParams};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet_lab::demo::{DemoParams, demo_character};
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// Cases per run (each: one mutated bake, three cameras, eight culling runs and two contour
/// extractions per camera; about 8 ms each).
const CASES: u32 = 1000;

/// The f64 reference, from `docs/FORMAT.md` (byte layout, run-time formulas) and
/// `docs/CULLING.md` (what the tests decide). Nothing here calls into the runtime.
mod doc {
    use glam::{DMat3, DVec3};
    use std::ops::Range;

    fn word(b: &[u8], at: usize) -> Option<[u8; 4]> {
        b.get(at..at.checked_add(4)?)?.try_into().ok()
    }
    pub fn u32_at(b: &[u8], at: usize) -> Option<u32> {
        word(b, at).map(u32::from_le_bytes)
    }
    /// An `f32` of the file, exactly, as f64.
    pub fn f32_at(b: &[u8], at: usize) -> Option<f64> {
        word(b, at).map(|w| f32::from_le_bytes(w) as f64)
    }
    fn vec3_at(b: &[u8], at: usize) -> Option<DVec3> {
        Some(DVec3::new(f32_at(b, at)?, f32_at(b, at + 4)?, f32_at(b, at + 8)?))
    }

    /// "Header": magic `SKINLET\0`, version 3, section count `N`, then per section tag, `u32` 0,
    /// offset `u64`, length `u64`.
    pub fn sections(bytes: &[u8]) -> Option<Vec<([u8; 4], Range<usize>)>> {
        if bytes.get(..8)? != b"SKINLET\0" || u32_at(bytes, 8)? != 3 {
            return None;
        }
        (0..u32_at(bytes, 12)? as usize)
            .map(|k| {
                let e = 16 + 24 * k;
                let tag: [u8; 4] = bytes.get(e..e + 4)?.try_into().ok()?;
                let at = |i: usize| -> Option<usize> {
                    Some(u64::from_le_bytes(bytes.get(i..i + 8)?.try_into().ok()?) as usize)
                };
                let (offset, length) = (at(e + 8)?, at(e + 16)?);
                (offset.checked_add(length)? <= bytes.len()).then_some((tag, offset..offset + length))
            })
            .collect()
    }

    pub fn section<'a>(bytes: &'a [u8], tag: &[u8; 4]) -> Option<&'a [u8]> {
        let (_, r) = sections(bytes)?.into_iter().find(|(t, _)| t == tag)?;
        bytes.get(r)
    }

    /// "`SKIN`": driver count `J`, then `J` inverse bind matrices (16 `f32`, column-major).
    pub struct Skin {
        pub drivers: usize,
        pub inverse_bind: Vec<[f64; 16]>,
    }

    pub fn skin(s: &[u8]) -> Option<Skin> {
        let drivers = u32_at(s, 0)? as usize;
        let inverse_bind = (0..drivers)
            .map(|j| {
                let mut m = [0.0; 16];
                for (i, x) in m.iter_mut().enumerate() {
                    *x = f32_at(s, 4 + 64 * j + 4 * i)?;
                }
                Some(m)
            })
            .collect::<Option<_>>()?;
        Some(Skin { drivers, inverse_bind })
    }

    /// One 48-byte bounds record ("`BNDS`", and `ENVL`'s envelope bounds "laid out like `BNDS`'s").
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Bound {
        pub center: DVec3,
        pub radius: f64,
        pub axis: DVec3,
        /// Cone half-angle; "≥ π/2: no cone (never backface-cull)".
        pub angle: f64,
        pub rest_radius: f64,
        pub rest_angle: f64,
        pub joint: u32,
        /// "0 both (frustum and backface cullable), 1 frustum only, 2 none".
        pub class: u32,
    }

    pub const BOUND: usize = 48;

    fn bound(s: &[u8], at: usize) -> Option<Bound> {
        Some(Bound {
            center: vec3_at(s, at)?,
            radius: f32_at(s, at + 12)?,
            axis: vec3_at(s, at + 16)?,
            angle: f32_at(s, at + 28)?,
            rest_radius: f32_at(s, at + 32)?,
            rest_angle: f32_at(s, at + 36)?,
            joint: u32_at(s, at + 40)?,
            class: u32_at(s, at + 44)?,
        })
    }

    /// "`BNDS`": meshlet count, 12 zero bytes, then a record per meshlet at `16 + 48·i`.
    pub fn bnds(s: &[u8]) -> Option<Vec<Bound>> {
        let m = u32_at(s, 0)? as usize;
        (0..m).map(|i| bound(s, 16 + BOUND * i)).collect()
    }

    /// Byte offsets of `ENVL`'s parts ("`ENVL`" table): node ranges at 16 (72 bytes each), morph
    /// weight ranges (8 bytes each), zero padding to a multiple of 16, `M` bounds records,
    /// `M + 1` first-box words, `B` box joints, `B` boxes of 24 bytes.
    pub struct EnvlLayout {
        pub meshlets: usize,
        pub boxes: usize,
        pub bounds_at: usize,
        pub first_box_at: usize,
        pub box_joints_at: usize,
        pub boxes_at: usize,
    }

    pub fn envl_layout(s: &[u8]) -> Option<EnvlLayout> {
        let [r, w, m, b] = [0, 4, 8, 12].map(|at| u32_at(s, at).map(|x| x as usize));
        let (r, w, meshlets, boxes) = (r?, w?, m?, b?);
        let bounds_at = (16 + 72 * r + 8 * w).next_multiple_of(16);
        let first_box_at = bounds_at + BOUND * meshlets;
        let box_joints_at = first_box_at + 4 * (meshlets + 1);
        let boxes_at = box_joints_at + 4 * boxes;
        Some(EnvlLayout { meshlets, boxes, bounds_at, first_box_at, box_joints_at, boxes_at })
    }

    /// An any-pose box: its joint, center and half extents in the joint's bind space.
    #[derive(Clone, Copy, Debug)]
    pub struct PoseBox {
        pub joint: u32,
        pub center: DVec3,
        pub half: DVec3,
    }

    pub struct Envl {
        pub bounds: Vec<Bound>,
        /// Per meshlet its first box, then `B`: meshlet `m`'s boxes are `first[m]..first[m + 1]`.
        pub first_box: Vec<u32>,
        pub boxes: Vec<PoseBox>,
    }

    pub fn envl(s: &[u8]) -> Option<Envl> {
        let l = envl_layout(s)?;
        let bounds = (0..l.meshlets).map(|i| bound(s, l.bounds_at + BOUND * i)).collect::<Option<_>>()?;
        let first_box = (0..=l.meshlets).map(|i| u32_at(s, l.first_box_at + 4 * i)).collect::<Option<_>>()?;
        let boxes = (0..l.boxes)
            .map(|i| {
                let at = l.boxes_at + 24 * i;
                Some(PoseBox {
                    joint: u32_at(s, l.box_joints_at + 4 * i)?,
                    center: vec3_at(s, at)?,
                    half: vec3_at(s, at + 12)?,
                })
            })
            .collect::<Option<_>>()?;
        Some(Envl { bounds, first_box, boxes })
    }

    /// Where `CONT`'s patch records start: `u32` ×6, `f64` ×4, 8 zero bytes.
    pub const PATCHES_AT: usize = 24 + 32 + 8;
    pub const PATCH: usize = 48;

    /// A patch record: sphere, cone (axis, `sin α`, `cos α`), joint and quad range.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Patch {
        pub center: DVec3,
        pub radius: f64,
        pub axis: DVec3,
        pub sin: f64,
        pub cos: f64,
        pub joint: u32,
        pub first: u32,
        pub count: u32,
    }

    /// A clip's windows: first and last key time, window count, first window.
    #[derive(Clone, Copy, Debug)]
    pub struct ClipWindows {
        pub start: f64,
        pub end: f64,
        pub count: u32,
        pub first: u32,
    }

    pub struct Cont {
        pub patches: Vec<Patch>,
        /// Quad indices in patch order.
        pub order: Vec<u32>,
        pub clips: Vec<ClipWindows>,
        /// Per window, per patch (`w·P + p`): radius, `sin α`, `cos α`.
        pub windows: Vec<[f64; 3]>,
    }

    /// Byte offsets of `CONT`'s parts: patches, quad indices, the clip count, the clips, the
    /// window bounds.
    pub fn cont_layout(s: &[u8]) -> Option<(usize, usize, usize, usize)> {
        let (q, p) = (u32_at(s, 4)? as usize, u32_at(s, 8)? as usize);
        let order_at = PATCHES_AT + PATCH * p;
        let clips_at = order_at + 4 * q;
        let c = u32_at(s, clips_at)? as usize;
        Some((order_at, clips_at, clips_at + 4, clips_at + 4 + 16 * c))
    }

    pub fn cont(s: &[u8]) -> Option<Cont> {
        let (q, p) = (u32_at(s, 4)? as usize, u32_at(s, 8)? as usize);
        let (order_at, clips_at, first_clip_at, windows_at) = cont_layout(s)?;
        let patches = (0..p)
            .map(|i| {
                let at = PATCHES_AT + PATCH * i;
                Some(Patch {
                    center: vec3_at(s, at)?,
                    radius: f32_at(s, at + 12)?,
                    axis: vec3_at(s, at + 16)?,
                    sin: f32_at(s, at + 28)?,
                    cos: f32_at(s, at + 32)?,
                    joint: u32_at(s, at + 36)?,
                    first: u32_at(s, at + 40)?,
                    count: u32_at(s, at + 44)?,
                })
            })
            .collect::<Option<_>>()?;
        let order = (0..q).map(|i| u32_at(s, order_at + 4 * i)).collect::<Option<_>>()?;
        let clips: Vec<ClipWindows> = (0..u32_at(s, clips_at)? as usize)
            .map(|c| {
                let at = first_clip_at + 16 * c;
                Some(ClipWindows {
                    start: f32_at(s, at)?,
                    end: f32_at(s, at + 4)?,
                    count: u32_at(s, at + 8)?,
                    first: u32_at(s, at + 12)?,
                })
            })
            .collect::<Option<_>>()?;
        let w = clips.last().map_or(0, |c| (c.first + c.count) as usize);
        let windows = (0..w * p)
            .map(|i| {
                let at = windows_at + 12 * i;
                Some([f32_at(s, at)?, f32_at(s, at + 4)?, f32_at(s, at + 8)?])
            })
            .collect::<Option<_>>()?;
        Some(Cont { patches, order, clips, windows })
    }

    /// "`PART`": part count, then 40 bytes per part.
    pub fn parts(s: &[u8]) -> Option<usize> {
        u32_at(s, 0).map(|n| n as usize)
    }

    /// A joint's world matrix `G = [A | t]`.
    #[derive(Clone, Copy, Debug)]
    pub struct Joint {
        pub a: DMat3,
        pub t: DVec3,
    }

    /// A frustum plane `(n, w)`: `n·p + w ≥ 0` inside.
    #[derive(Clone, Copy, Debug)]
    pub struct Plane {
        pub n: DVec3,
        pub w: f64,
    }

    #[derive(Clone, Copy, Debug)]
    pub enum View {
        Eye(DVec3),
        Dir(DVec3),
    }

    /// FORMAT.md, `BNDS` run-time use: "move each plane `(n, w)` to `(Aᵀn, n·t + w)`; the meshlet
    /// is outside when `Aᵀn·c + n·t + w + r·|Aᵀn| < 0`". The smallest of that over the planes:
    /// outside when negative.
    pub fn sphere_distance(center: DVec3, radius: f64, g: &Joint, planes: &[Plane]) -> f64 {
        planes
            .iter()
            .map(|p| {
                let nj = g.a.transpose() * p.n;
                nj.dot(center) + p.n.dot(g.t) + p.w + radius * nj.length()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// FORMAT.md, `BNDS`: "move the eye to `e' = G⁻¹e` …: the meshlet faces away when
    /// `s·(c − e')·a ≥ |c − e'|·sin α + r·(1 + sin α)` with `s = sign(det A)` (orthographic:
    /// the direction `A⁻¹d`, normalized, `s·a·d' ≥ sin α`)". Returns left side minus right side
    /// (faces away when ≥ 0) and the moved eye or direction; `None` for a singular `A`, which
    /// CULLING.md says is never backface-culled.
    pub fn backface(b: &Bound, g: &Joint, view: View) -> Option<(f64, DVec3)> {
        let det = g.a.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (s, inverse, sin) = (det.signum(), g.a.inverse(), b.angle.sin());
        Some(match view {
            View::Eye(e) => {
                let e = inverse * (e - g.t);
                let d = b.center - e;
                (s * d.dot(b.axis) - d.length() * sin - b.radius * (1.0 + sin), e)
            }
            View::Dir(d) => {
                let d = (inverse * d).normalize();
                (s * b.axis.dot(d) - sin, d)
            }
        })
    }

    /// FORMAT.md, `ENVL`: a box is outside a plane when `Aᵀn·c + n·t + w + |Aᵀn|·h < 0`
    /// (`|Aᵀn|` componentwise); this is the left side.
    pub fn box_distance(b: &PoseBox, g: &Joint, p: &Plane) -> f64 {
        let nj = g.a.transpose() * p.n;
        nj.dot(b.center) + p.n.dot(g.t) + p.w + nj.abs().dot(b.half)
    }

    /// FORMAT.md, `CONT` run time: "take the playing clip's window holding the time (`k =
    /// ⌊(t − start) / (end − start) · count⌋`, clamped; without a clip, the bounds above)". The
    /// window's number (`None`: the bounds over every clip), and `x` before the floor.
    pub fn window(clips: &[ClipWindows], at: Option<(usize, f64)>) -> Option<(u32, f64, ClipWindows)> {
        let (c, t) = at?;
        let w = *clips.get(c)?;
        let x = (t - w.start) / (w.end - w.start) * w.count as f64;
        let k = x.floor().clamp(0.0, (w.count - 1) as f64);
        Some((w.first + k as u32, x, w))
    }

    /// FORMAT.md, `CONT` run time: "per joint move the eye into the joint's space (`G⁻¹·eye`
    /// …; orthographic: `A⁻¹·dir`, normalized); a patch may hold a contour edge only if
    /// `|a·s| ≤ sin(α + β) + 1e-5` with `s` the unit vector from the eye to the center,
    /// `sin β = r / d` (always when `d ≤ r`)" — and always when `α + β ≥ π/2` (then some
    /// normal of the cone is perpendicular to some ray to the sphere; the document's formula
    /// alone would refuse such patches, see the report). `sin(α + β)` and `cos(α + β)` from the
    /// stored `sin α` and `cos α`. Returns what decides: `Accept` or the value
    /// `|a·s| − sin(α + β) − 1e-5` (accepted when ≤ 0) with the distance `d`.
    pub enum PatchTest {
        /// Inside the sphere (`d ≤ r`), or a cone reaching π/2.
        Always,
        Value {
            value: f64,
            d: f64,
        },
    }

    pub fn patch_test(center: DVec3, radius: f64, axis: DVec3, sin_a: f64, cos_a: f64, view: View) -> PatchTest {
        let (s, sin_b, d) = match view {
            View::Eye(e) => {
                let d = (center - e).length();
                if d <= radius {
                    return PatchTest::Always;
                }
                ((center - e) / d, radius / d, d)
            }
            View::Dir(dir) => (dir, 0.0, f64::INFINITY),
        };
        let cos_b = (1.0 - sin_b * sin_b).sqrt();
        let (sin_sum, cos_sum) = (sin_a * cos_b + cos_a * sin_b, cos_a * cos_b - sin_a * sin_b);
        if cos_sum <= 0.0 {
            return PatchTest::Always;
        }
        PatchTest::Value { value: axis.dot(s).abs() - sin_sum - 1e-5, d }
    }

    /// The document's stated constraints on stored records, for a file a reader accepted:
    /// what FORMAT.md promises a consumer. Returns the broken promise, if any.
    pub fn bound_promise(b: &Bound, drivers: usize) -> Option<String> {
        let floats = [b.center.x, b.center.y, b.center.z, b.radius, b.axis.x, b.axis.y, b.axis.z, b.angle];
        if !floats.iter().chain(&[b.rest_radius, b.rest_angle]).all(|x| x.is_finite()) {
            return Some("a float is not finite (\"every stored float is finite\")".into());
        }
        if b.joint as usize >= drivers || b.class > 2 {
            return Some(format!("joint {} of {drivers} or class {}", b.joint, b.class));
        }
        if b.angle < std::f64::consts::FRAC_PI_2 && (b.axis.length_squared() - 1.0).abs() > 1e-5 {
            return Some(format!("cone of {} rad with axis {} (not unit within 1e-5)", b.angle, b.axis));
        }
        // "in [0, π]": π as stored, the f32 nearest it (above π), which the baker writes.
        if !(0.0..=std::f32::consts::PI as f64).contains(&b.rest_angle) {
            return Some(format!("rest cone angle {} outside [0, π]", b.rest_angle));
        }
        None
    }

    pub fn patch_promise(axis: DVec3, sin: f64, cos: f64) -> Option<String> {
        if !(axis.is_finite() && sin.is_finite() && cos.is_finite()) || sin < 0.0 {
            return Some(format!("axis {axis}, sin {sin}, cos {cos}"));
        }
        if cos > 0.0 && ((sin * sin + cos * cos - 1.0).abs() > 1e-5 || (axis.length_squared() - 1.0).abs() > 1e-5) {
            return Some(format!("cone with sin {sin}, cos {cos}, axis {axis}: not unit within 1e-5"));
        }
        None
    }
}

/// The margins a disagreement may lie within, from the documents:
/// - culling (CULLING.md, "Exact tests in joint space": "margins of 1e-5 of the magnitudes
///   involved (plus 1e-6 × the joint's condition number for the moved eye)", and which
///   magnitudes): for a sphere `‖A‖·E + 2|t| + 2·max|w|`, which bounds the runtime's
///   `|Aᵀn|·E + |n·t + w| + |t| + |w|`; for the moved eye `|e'|₁ + E` (orthographic: 1), `E` the
///   largest `|c| + r` among the meshlets with the same principal joint; for a box the largest
///   column 1-norm of `A` times `Σ(|cᵢ| + hᵢ)`, plus `|t|₁` and the largest `|w|`. 1% wider here,
///   for the rounding of the margin itself.
/// - singular joints (CULLING.md: never backface-culled): `|det A| ≤ 10⁻⁹·(max column length)³`,
///   or `(det A)²` underflowing f32; within a factor of 2 (and among f32's subnormals) either
///   answer.
/// - contours (FORMAT.md, `CONT`: the "+ 1e-5" is part of the formula; "always when `d ≤ r`,
///   taken as `d² ≤ r²·(1 + 10⁻⁴)`"): the f32 rounding of the moved eye and of the test,
///   `2·10⁻⁶ + 32 ε₃₂ (|c|₁ + |e'|₁ + r) / d`.
/// - a clip's window (FORMAT.md, `CONT`: "each window's bounds hold 10⁻⁴ of a window beyond its
///   ends, which covers the f32 rounding of `k`"): the neighbouring window within that of an
///   edge; a clip with `start = end` (FORMAT.md says nothing) its first or its last window.
/// - f32's range (CULLING.md: "where these overflow f32 … the meshlet is kept"): past it (squares
///   of magnitudes, or box magnitudes, beyond 10³⁶) only the safe answer is required: keep the
///   meshlet (for contours, the same rule: accept the patch).
mod margins {
    pub const CULL: f64 = 1.01e-5;
    pub const COND: f64 = 1.01e-6;
    pub const SINGULAR: f64 = 1e-9;
    pub const WINDOW_SLACK: f64 = 1e-4;
    pub const SPHERE_INSIDE: f64 = 1e-4;
    pub const EPS32: f64 = f32::EPSILON as f64;
    /// Beyond this an f32 product or square may overflow.
    pub const F32_RANGE: f64 = 1e36;
}

/// A reference decision: `exact` is the f64 formula's answer; `surely` holds even when the
/// f64 value moves by the margin toward the boundary, `maybe` when it moves by the margin away.
/// The runtime's answer must lie between: `surely ⇒ runtime ⇒ maybe`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Decision {
    exact: bool,
    surely: bool,
    maybe: bool,
    /// Past the f32 range (then `surely` is false: only the safe answer is required).
    overflow: bool,
}

impl Decision {
    const NO: Decision = Decision { exact: false, surely: false, maybe: false, overflow: false };
    const YES: Decision = Decision { exact: true, surely: true, maybe: true, overflow: false };
    /// True when `value < 0`, within `tol`.
    fn negative(value: f64, tol: f64) -> Decision {
        Decision { exact: value < 0.0, surely: value < -tol, maybe: value < tol, ..Decision::NO }
    }
    /// True when `value ≥ 0`, within `tol`.
    fn non_negative(value: f64, tol: f64) -> Decision {
        Decision { exact: value >= 0.0, surely: value >= tol, maybe: value >= -tol, ..Decision::NO }
    }
    fn or(self, o: Decision) -> Decision {
        Decision {
            exact: self.exact || o.exact,
            surely: self.surely || o.surely,
            maybe: self.maybe || o.maybe,
            overflow: self.overflow || o.overflow,
        }
    }
    fn and(self, o: Decision) -> Decision {
        Decision {
            exact: self.exact && o.exact,
            surely: self.surely && o.surely,
            maybe: self.maybe && o.maybe,
            overflow: self.overflow || o.overflow,
        }
    }
    /// Past the f32 range the runtime may answer `false` (keep the meshlet, accept the patch).
    fn unless_overflow(self, overflow: bool) -> Decision {
        if overflow && self.surely { Decision { surely: false, overflow: true, ..self } } else { self }
    }
    fn agrees(self, runtime: bool) -> bool {
        (!self.surely || runtime) && (!runtime || self.maybe)
    }
}

/// Counts over the whole run.
struct Counts {
    cases: AtomicUsize,
    /// Every section the test reads accepted, the bytes mutated.
    accepted_mutated: AtomicUsize,
    bnds_accepted: AtomicUsize,
    envl_accepted: AtomicUsize,
    cont_accepted: AtomicUsize,
    /// The view accepted a section whose culler or patches it then refused to build.
    built_refused: AtomicUsize,
    decisions: AtomicUsize,
    culled: AtomicUsize,
    backface_culled: AtomicUsize,
    box_culled: AtomicUsize,
    patches_refused: AtomicUsize,
    within_margin: AtomicUsize,
    overflow: AtomicUsize,
    windows_wider: AtomicUsize,
    margin_by_test: [AtomicUsize; 6],
}

static COUNTS: Counts = Counts {
    cases: AtomicUsize::new(0),
    accepted_mutated: AtomicUsize::new(0),
    bnds_accepted: AtomicUsize::new(0),
    envl_accepted: AtomicUsize::new(0),
    cont_accepted: AtomicUsize::new(0),
    built_refused: AtomicUsize::new(0),
    decisions: AtomicUsize::new(0),
    culled: AtomicUsize::new(0),
    backface_culled: AtomicUsize::new(0),
    box_culled: AtomicUsize::new(0),
    patches_refused: AtomicUsize::new(0),
    within_margin: AtomicUsize::new(0),
    overflow: AtomicUsize::new(0),
    windows_wider: AtomicUsize::new(0),
    margin_by_test: [const { AtomicUsize::new(0) }; 6],
};

fn count(c: &AtomicUsize, n: usize) {
    c.fetch_add(n, Relaxed);
}

/// Small meshlets, so that many have normal cones (class "both"): 170 meshlets, 65 of them.
const LIMITS: MeshletLimits = MeshletLimits { max_vertices: 16, max_triangles: 16 };

/// The baked demo character (envelope and contour patches included) in 4-byte aligned storage,
/// and its length in bytes.
fn baked() -> &'static (Vec<u32>, usize) {
    static BAKED: OnceLock<(Vec<u32>, usize)> = OnceLock::new();
    BAKED.get_or_init(|| {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let clips: Vec<_> = asset.clips.iter().collect();
        let how = Refinement { max_rounds: 2, ..Refinement::NONE };
        let character = asset.character().unwrap();
        let mut b = bake(&asset, &character, &clips, Builder::SkinAware, LIMITS, &how, &mut |_| {}).unwrap().0;
        let envelope = Envelope::from_clips(&asset.skeleton, &b.palette(), &b.mesh, &clips, 0.1).unwrap();
        add_envelope(&mut b, &asset, envelope).unwrap();
        let how = skinlet::contour::skinned::refinement(None, 0);
        add_contours(&mut b, &asset, &SkinnedParams::new(SkinnedMethod::Animated, how), true).unwrap();
        let bytes = to_bytes(&b);
        let mut words = vec![0u32; bytes.len().div_ceil(4)];
        bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
        (words, bytes.len())
    })
}

/// Where a mutation writes.
#[derive(Clone, Copy, Debug)]
enum Section {
    Bnds,
    Envl,
    Cont,
    Part,
}

/// One overwrite of the baked bytes; record numbers are taken modulo the record count.
#[derive(Clone, Debug)]
enum Mutation {
    /// A bounds record (`BNDS` or `ENVL`) with random content.
    Bound { envl: bool, record: u32, words: [u32; 12] },
    /// A bounds record's sphere radius and normal cone made backface-cullable (class 0, unit
    /// axis, half-angle below π/2): its center and joint as baked or mutated.
    Cone { envl: bool, record: u32, radius: u32, axis: [u32; 3], angle: u32 },
    /// One word of a bounds record.
    BoundWord { envl: bool, record: u32, field: usize, word: u32 },
    /// An any-pose box: joint, center, half extents.
    PoseBox { record: u32, joint: u32, box_: [u32; 6] },
    /// One word of a box (0: its joint, 1–6: center and half extents) or of the first-box list (7).
    PoseBoxWord { record: u32, field: usize, word: u32 },
    /// Meshlet `i`'s any-pose boxes handed to meshlet `i − 1` (`first[i] := first[i + 1]`): a
    /// meshlet without boxes, and one with boxes of other joints.
    MoveBoxes { record: u32 },
    /// A contour patch's sphere, cone and joint (its quad range as baked).
    Patch { record: u32, words: [u32; 9], joint: u32 },
    /// One word of a patch record (0–11).
    PatchWord { record: u32, field: usize, word: u32 },
    /// A window bound: radius, sin, cos.
    Window { record: u32, words: [u32; 3] },
    /// A clip's windows in `CONT`: start and end time (count and first as baked).
    ClipTimes { record: u32, start: u32, end: u32 },
    /// One word of a part record (0–9).
    PartWord { record: u32, field: usize, word: u32 },
    /// A raw byte anywhere in a section (its counts included).
    Byte { section: Section, at: u32, byte: u8 },
}

/// Random words: floats of every kind, joint numbers, anything.
fn any_word() -> impl Strategy<Value = u32> {
    let specials = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        std::f32::consts::FRAC_PI_2,
        std::f32::consts::FRAC_PI_2.next_down(),
        std::f32::consts::FRAC_PI_2.next_up(),
        std::f32::consts::PI,
        std::f32::consts::PI.next_up(),
        1e-30,
        1e-45,
        f32::MIN_POSITIVE,
        1e19,
        -1e19,
        1e30,
        -1e30,
        f32::MAX,
        -f32::MAX,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    prop_oneof![
        3 => (-4.0f32..4.0).prop_map(f32::to_bits),
        3 => prop::sample::select(specials.to_vec()).prop_map(f32::to_bits),
        1 => any::<f32>().prop_map(f32::to_bits),
        2 => 0u32..48,
        1 => any::<u32>(),
    ]
}

/// Coordinates: mostly the size of a character, sometimes far, huge or tiny.
fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        8 => -2.0f32..2.0,
        1 => prop::sample::select(vec![0.0f32, 1e-30, -1e-38, 1e4, -1e5, 1e19, -1e19, 1e30, -1e30, 3e38, -3e38]),
    ]
}

/// Non-negative lengths (radii, half extents), sometimes zero, huge or negative.
fn length() -> impl Strategy<Value = f32> {
    prop_oneof![
        8 => 0.0f32..1.5,
        1 => prop::sample::select(vec![0.0f32, -0.0, 1e-30, 1e19, 1e30, f32::MAX, -0.1]),
    ]
}

/// Cone axes: unit (as the format wants below π/2), sometimes not.
fn axis() -> impl Strategy<Value = [f32; 3]> {
    (prop::array::uniform3(-1.0f64..1.0), prop_oneof![8 => Just(1.0f64), 1 => 0.5f64..2.0, 1 => Just(0.0)]).prop_map(
        |(v, scale)| {
            let v = DVec3::from(v);
            let v = if v.length() < 1e-3 { DVec3::Z } else { v.normalize() };
            (v * scale).as_vec3().to_array()
        },
    )
}

/// Cone half-angles: mostly below π/2, around π/2, up to π and beyond.
fn angle() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => 0.0f32..1.5,
        1 => prop::sample::select(vec![
            0.0f32,
            std::f32::consts::FRAC_PI_2.next_down(),
            std::f32::consts::FRAC_PI_2,
            std::f32::consts::PI,
            3.2,
            -0.1,
        ]),
        2 => 1.5f32..3.2,
    ]
}

/// Joint numbers: mostly among the demo's drivers, sometimes past them.
fn joint() -> impl Strategy<Value = u32> {
    prop_oneof![9 => 0u32..40, 1 => prop::sample::select(vec![40u32, 65535, 65536, u32::MAX])]
}

fn bound_words() -> impl Strategy<Value = [u32; 12]> {
    (
        prop::array::uniform3(coordinate()),
        length(),
        axis(),
        angle(),
        length(),
        angle(),
        joint(),
        prop_oneof![9 => 0u32..3, 1 => 3u32..5],
    )
        .prop_map(|(c, r, a, angle, rest_r, rest_angle, j, class)| {
            let f = f32::to_bits;
            [f(c[0]), f(c[1]), f(c[2]), f(r), f(a[0]), f(a[1]), f(a[2]), f(angle), f(rest_r), f(rest_angle), j, class]
        })
}

/// A patch's cone as stored: `sin α`, `cos α` of a random angle (to f32), sometimes inconsistent.
fn cone() -> impl Strategy<Value = [u32; 2]> {
    prop_oneof![
        8 => angle().prop_map(|a| [(a as f64).sin().abs() as f32, (a as f64).cos() as f32]),
        1 => (0.0f32..1.0, -1.0f32..1.0).prop_map(|(s, c)| [s, c]),
        1 => (prop::sample::select(vec![0.0f32, 1.0, 1.0 - 4e-6, -0.0]), prop::sample::select(vec![0.0f32, 1.0, 1e-6, -1.0])).prop_map(|(s, c)| [s, c]),
    ]
    .prop_map(|v| v.map(f32::to_bits))
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let record = any::<u32>;
    prop_oneof![
        6 => (any::<bool>(), record(), bound_words()).prop_map(|(envl, record, words)| Mutation::Bound { envl, record, words }),
        3 => (any::<bool>(), record(), 0.0f32..0.6, axis(), 0.0f32..1.5).prop_map(|(envl, record, r, a, angle)| {
            Mutation::Cone { envl, record, radius: r.to_bits(), axis: a.map(f32::to_bits), angle: angle.to_bits() }
        }),
        2 => (any::<bool>(), record(), 0usize..12, any_word())
            .prop_map(|(envl, record, field, word)| Mutation::BoundWord { envl, record, field, word }),
        4 => (record(), joint(), prop::array::uniform3(coordinate()), prop::array::uniform3(length())).prop_map(
            |(record, joint, c, h)| Mutation::PoseBox { record, joint, box_: [c[0], c[1], c[2], h[0], h[1], h[2]].map(f32::to_bits) }
        ),
        1 => (record(), 0usize..8, any_word()).prop_map(|(record, field, word)| Mutation::PoseBoxWord { record, field, word }),
        1 => record().prop_map(|record| Mutation::MoveBoxes { record }),
        1 => record().prop_map(|record| Mutation::MoveBoxes { record }),
        5 => (record(), prop::array::uniform3(coordinate()), length(), axis(), cone(), joint()).prop_map(
            |(record, c, r, a, cone, joint)| {
                let f = f32::to_bits;
                let words = [f(c[0]), f(c[1]), f(c[2]), f(r), f(a[0]), f(a[1]), f(a[2]), cone[0], cone[1]];
                Mutation::Patch { record, words, joint }
            }
        ),
        1 => (record(), 0usize..12, any_word()).prop_map(|(record, field, word)| Mutation::PatchWord { record, field, word }),
        3 => (record(), length(), cone())
            .prop_map(|(record, r, cone)| Mutation::Window { record, words: [r.to_bits(), cone[0], cone[1]] }),
        1 => (record(), -2.0f32..4.0, -2.0f32..4.0).prop_map(|(record, a, b)| Mutation::ClipTimes {
            record,
            start: a.min(b).to_bits(),
            end: a.max(b).to_bits()
        }),
        1 => (record(), 0usize..10, any_word()).prop_map(|(record, field, word)| Mutation::PartWord { record, field, word }),
        1 => (
            prop::sample::select(vec![Section::Bnds, Section::Envl, Section::Cont, Section::Part]),
            any::<u32>(),
            any::<u8>()
        )
            .prop_map(|(section, at, byte)| Mutation::Byte { section, at, byte }),
    ]
}

/// Where the records lie in the baked bytes (absolute offsets, from [`doc`]'s layout).
struct Layout {
    sections: [std::ops::Range<usize>; 4],
    meshlets: usize,
    bnds_at: usize,
    envl_bounds_at: usize,
    first_box_at: usize,
    box_joints_at: usize,
    boxes_at: usize,
    boxes: usize,
    patches_at: usize,
    patches: usize,
    clips_at: usize,
    clips: usize,
    windows_at: usize,
    windows: usize,
    parts_at: usize,
    parts: usize,
}

impl Layout {
    fn of(bytes: &[u8]) -> Layout {
        let table = doc::sections(bytes).unwrap();
        let range = |tag: &[u8; 4]| table.iter().find(|(t, _)| t == tag).unwrap().1.clone();
        let [bnds, envl, cont, part] = [b"BNDS", b"ENVL", b"CONT", b"PART"].map(range);
        let e = doc::envl_layout(&bytes[envl.clone()]).unwrap();
        let c = doc::cont(&bytes[cont.clone()]).unwrap();
        let (_, _, clips_at, windows_at) = doc::cont_layout(&bytes[cont.clone()]).unwrap();
        Layout {
            meshlets: e.meshlets,
            bnds_at: bnds.start + 16,
            envl_bounds_at: envl.start + e.bounds_at,
            first_box_at: envl.start + e.first_box_at,
            box_joints_at: envl.start + e.box_joints_at,
            boxes_at: envl.start + e.boxes_at,
            boxes: e.boxes,
            patches_at: cont.start + doc::PATCHES_AT,
            patches: c.patches.len(),
            clips_at: cont.start + clips_at,
            clips: c.clips.len(),
            windows_at: cont.start + windows_at,
            windows: c.windows.len(),
            parts_at: part.start + 4,
            parts: doc::parts(&bytes[part.clone()]).unwrap(),
            sections: [bnds, envl, cont, part],
        }
    }

    /// Applies `m` to `bytes` (a mutation of records a section lacks does nothing).
    fn apply(&self, bytes: &mut [u8], m: &Mutation) {
        let mut put = |at: usize, w: u32| bytes[at..at + 4].copy_from_slice(&w.to_le_bytes());
        let nth = |record: u32, n: usize| (n > 0).then(|| record as usize % n);
        let bounds_at = |envl: bool| if envl { self.envl_bounds_at } else { self.bnds_at };
        match *m {
            Mutation::Bound { envl, record, words } => {
                if let Some(i) = nth(record, self.meshlets) {
                    words.iter().enumerate().for_each(|(k, &w)| put(bounds_at(envl) + doc::BOUND * i + 4 * k, w));
                }
            }
            Mutation::Cone { envl, record, radius, axis, angle } => {
                if let Some(i) = nth(record, self.meshlets) {
                    let at = bounds_at(envl) + doc::BOUND * i;
                    [radius, axis[0], axis[1], axis[2], angle]
                        .iter()
                        .enumerate()
                        .for_each(|(k, &w)| put(at + 12 + 4 * k, w));
                    put(at + 44, 0);
                }
            }
            Mutation::BoundWord { envl, record, field, word } => {
                if let Some(i) = nth(record, self.meshlets) {
                    put(bounds_at(envl) + doc::BOUND * i + 4 * field, word);
                }
            }
            Mutation::PoseBox { record, joint, box_ } => {
                if let Some(i) = nth(record, self.boxes) {
                    put(self.box_joints_at + 4 * i, joint);
                    box_.iter().enumerate().for_each(|(k, &w)| put(self.boxes_at + 24 * i + 4 * k, w));
                }
            }
            Mutation::PoseBoxWord { record, field, word } => match field {
                0 => nth(record, self.boxes).into_iter().for_each(|i| put(self.box_joints_at + 4 * i, word)),
                1..=6 => nth(record, self.boxes)
                    .into_iter()
                    .for_each(|i| put(self.boxes_at + 24 * i + 4 * (field - 1), word)),
                _ => nth(record, self.meshlets + 1).into_iter().for_each(|i| put(self.first_box_at + 4 * i, word)),
            },
            Mutation::MoveBoxes { record } => {
                if let Some(i) = nth(record, self.meshlets.saturating_sub(1)) {
                    let next = self.first_box_at + 4 * (i + 2);
                    bytes.copy_within(next..next + 4, next - 4);
                }
            }
            Mutation::Patch { record, words, joint } => {
                if let Some(i) = nth(record, self.patches) {
                    let at = self.patches_at + doc::PATCH * i;
                    words.iter().enumerate().for_each(|(k, &w)| put(at + 4 * k, w));
                    put(at + 36, joint);
                }
            }
            Mutation::PatchWord { record, field, word } => {
                if let Some(i) = nth(record, self.patches) {
                    put(self.patches_at + doc::PATCH * i + 4 * field, word);
                }
            }
            Mutation::Window { record, words } => {
                if let Some(i) = nth(record, self.windows) {
                    words.iter().enumerate().for_each(|(k, &w)| put(self.windows_at + 12 * i + 4 * k, w));
                }
            }
            Mutation::ClipTimes { record, start, end } => {
                if let Some(c) = nth(record, self.clips) {
                    put(self.clips_at + 16 * c, start);
                    put(self.clips_at + 16 * c + 4, end);
                }
            }
            Mutation::PartWord { record, field, word } => {
                if let Some(i) = nth(record, self.parts) {
                    put(self.parts_at + 40 * i + 4 * field, word);
                }
            }
            Mutation::Byte { section, at, byte } => {
                let r = &self.sections[section as usize];
                if !r.is_empty() {
                    bytes[r.start + at as usize % r.len()] = byte;
                }
            }
        }
    }
}

/// Directions and rotations for the world of a case.
impl Rng {
    fn dir(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }
    fn rotation(&mut self, max: f64) -> DQuat {
        let axis = self.dir();
        DQuat::from_axis_angle(axis, self.range(-max, max))
    }
}

/// The joints' world matrices of a case: the bind pose moved (uniformly scaled, possibly
/// mirrored) and bent at every joint, or any matrices (shear, non-uniform, negative, near-zero
/// and zero scale); sometimes far from the origin.
fn joint_matrices(rng: &mut Rng, skin: &doc::Skin) -> (Vec<Affine3A>, DVec3) {
    let far = if rng.below(4) == 0 {
        DVec3::new(rng.range(-1e5, 1e5), rng.range(-1e4, 1e4), rng.range(-1e5, 1e5))
    } else {
        DVec3::ZERO
    };
    let style = rng.below(3);
    let mirror = if rng.below(4) == 0 { -1.0 } else { 1.0 };
    let model = DMat4::from_scale_rotation_translation(
        DVec3::new(mirror, 1.0, 1.0) * rng.range(0.5, 2.0),
        rng.rotation(std::f64::consts::PI),
        far + DVec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)),
    );
    let matrices = (0..skin.drivers)
        .map(|j| {
            let (a, t) = if style < 2 {
                let bind = DMat4::from_cols_array(&skin.inverse_bind[j]).inverse();
                let bend = DMat4::from_quat(rng.rotation(if style == 0 { 0.6 } else { 0.05 }));
                let g = model * bind * bend;
                (DMat3::from_mat4(g), g.w_axis.truncate())
            } else {
                let mut scale = [0.0; 3].map(|_| match rng.below(10) {
                    0 => rng.range(-3.0, -0.3),
                    1 => rng.range(-0.01, 0.01),
                    2 => [1e-4, -1e-5, 0.0, 1e-3, 1e-8, -3e-8, 1e-12, 1e4][rng.below(8)],
                    _ => rng.range(0.3, 3.0),
                });
                if rng.below(2) == 0 {
                    scale = [scale[0]; 3];
                }
                let mut a = DMat3::from_quat(rng.rotation(std::f64::consts::PI)) * DMat3::from_diagonal(scale.into());
                a.x_axis.y += rng.range(-1.0, 1.0) * (rng.below(2) as f64);
                let t = far + DVec3::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), rng.range(-4.0, 4.0));
                (a, t)
            };
            if !(a.is_finite() && t.is_finite()) {
                return Affine3A::IDENTITY;
            }
            Affine3A::from_mat3_translation(a.as_mat3(), t.as_vec3())
        })
        .collect();
    (matrices, far)
}

/// A random camera looking near `around`: perspective, orthographic, or infinite reverse-Z.
fn camera(rng: &mut Rng, around: DVec3) -> Option<Camera> {
    let target = around + rng.dir() * rng.range(0.0, 1.5);
    let eye = target + rng.dir() * rng.range(0.5, 15.0);
    let (eye, target, up) = (eye.as_vec3(), target.as_vec3(), rng.dir().as_vec3());
    let (fov, aspect, near) = (rng.range(0.3, 2.5) as f32, rng.range(0.5, 2.0) as f32, rng.range(0.05, 1.0) as f32);
    match rng.below(3) {
        0 => Camera::perspective(eye, target, up, fov, aspect, near, near + rng.range(0.5, 100.0) as f32).ok(),
        1 => {
            let (w, h, near) = (rng.range(0.3, 3.0) as f32, rng.range(0.3, 3.0) as f32, rng.range(-3.0, 1.0) as f32);
            Camera::orthographic(eye, target, up, w, h, near, near + rng.range(0.5, 30.0) as f32).ok()
        }
        _ => {
            if (target - eye).cross(up).length_squared() <= 1e-6 * (target - eye).length_squared() {
                return None;
            }
            let vp = Mat4::perspective_infinite_reverse_rh(fov, aspect, near) * Mat4::look_at_rh(eye, target, up);
            Camera::from_view_proj(vp, Projection::Perspective { eye }).ok()
        }
    }
}

/// A time to extract contours at: a clip (or one past the last: no clip) and a time around its
/// keys, often exactly on a window's edge, sometimes infinite.
fn clip_time(rng: &mut Rng, clips: &[doc::ClipWindows]) -> Option<(usize, f32)> {
    let c = rng.below(clips.len() + 1);
    let Some(w) = clips.get(c) else { return Some((c, 0.5)) };
    let len = w.end - w.start;
    let t = match rng.below(8) {
        0 => w.start + len * rng.below(w.count as usize + 1) as f64 / w.count as f64,
        1 => [f64::INFINITY, f64::NEG_INFINITY, w.start, w.end][rng.below(4)],
        _ => rng.range(w.start - 0.2 * len - 0.1, w.end + 0.2 * len + 0.1),
    };
    Some((c, t as f32))
}

fn joint_f64(g: &Affine3A) -> doc::Joint {
    let c = g.to_cols_array().map(|x| x as f64);
    doc::Joint { a: DMat3::from_cols_slice(&c[..9]), t: DVec3::from_slice(&c[9..]) }
}

fn frobenius(a: &DMat3) -> f64 {
    (a.x_axis.length_squared() + a.y_axis.length_squared() + a.z_axis.length_squared()).sqrt()
}

/// Per joint, the largest `|c| + r` of the records with that principal joint.
fn extents(records: &[doc::Bound], drivers: usize) -> Vec<f64> {
    let mut e = vec![0.0f64; drivers];
    for b in records.iter().filter(|b| (b.joint as usize) < drivers) {
        e[b.joint as usize] = e[b.joint as usize].max(b.center.length() + b.radius);
    }
    e
}

/// The scene of one camera as the reference sees it.
struct Scene<'a> {
    joints: &'a [doc::Joint],
    planes: Vec<doc::Plane>,
    view: doc::View,
    /// Largest `|w|` of the planes.
    omega: f64,
}

impl Scene<'_> {
    /// FORMAT.md's frustum test of a bounds record ("class … 2 none": never culled).
    fn frustum(&self, b: &doc::Bound, extent: f64) -> Decision {
        if b.class > 1 {
            return Decision::NO;
        }
        let g = &self.joints[b.joint as usize];
        let value = doc::sphere_distance(b.center, b.radius, g, &self.planes);
        let magnitude = frobenius(&g.a) * extent + 2.0 * g.t.length() + 2.0 * self.omega;
        // The runtime's per-joint scale squares `|c|` (`center.length()`).
        let overflow = magnitude.max(extent).powi(2) > margins::F32_RANGE;
        Decision::negative(value, margins::CULL * magnitude).unless_overflow(overflow)
    }

    /// FORMAT.md's backface test ("class 0 both"; "≥ π/2: no cone"); CULLING.md: singular joints
    /// are never backface-culled.
    fn backface(&self, b: &doc::Bound, extent: f64) -> Decision {
        if b.class != 0 || b.angle >= std::f64::consts::FRAC_PI_2 {
            return Decision::NO;
        }
        let g = &self.joints[b.joint as usize];
        let Some((value, moved)) = doc::backface(b, g, self.view) else { return Decision::NO };
        let cond = frobenius(&g.a) * frobenius(&g.a.inverse());
        let (scale, overflow) = match self.view {
            doc::View::Eye(_) => {
                let m = moved.abs().element_sum() + extent;
                (m, m * m > margins::F32_RANGE)
            }
            doc::View::Dir(_) => (1.0, false),
        };
        let d = Decision::non_negative(value, (margins::CULL + margins::COND * cond) * scale);
        let max_col = [g.a.x_axis, g.a.y_axis, g.a.z_axis].map(|c| c.length()).into_iter().fold(0.0, f64::max);
        let det = g.a.determinant().abs();
        let singular = det / max_col.powi(3);
        // The runtime squares `det A` in f32: below ~1e-45 it is 0 (singular), among the
        // subnormals either.
        let (underflow, subnormal) = (det * det < 1e-46, det * det < 2.0 * f32::MIN_POSITIVE as f64);
        if singular <= 0.5 * margins::SINGULAR || underflow {
            Decision::NO
        } else if singular <= 2.0 * margins::SINGULAR || subnormal {
            Decision { surely: false, ..d }
        } else {
            d.unless_overflow(overflow)
        }
    }

    /// FORMAT.md's any-pose box test: every box of the meshlet outside one and the same plane
    /// (a meshlet without boxes is never culled).
    fn boxes(&self, boxes: &[doc::PoseBox]) -> Decision {
        if boxes.is_empty() {
            return Decision::NO;
        }
        let mut out = Decision::NO;
        let mut overflow = false;
        for p in &self.planes {
            let mut plane = Decision::YES;
            for b in boxes {
                let g = &self.joints[b.joint as usize];
                let max_col = [g.a.x_axis, g.a.y_axis, g.a.z_axis].map(|c| c.abs().element_sum());
                let size = (b.center.abs() + b.half).element_sum();
                let magnitude = max_col.into_iter().fold(0.0, f64::max) * size + g.t.abs().element_sum() + self.omega;
                // The runtime sums `Σ(|cᵢ| + hᵢ)` on its own too.
                overflow |= magnitude.max(size) > margins::F32_RANGE;
                let d = Decision::negative(doc::box_distance(b, g, p), margins::CULL * magnitude);
                plane = plane.and(d);
            }
            out = out.or(plane);
        }
        out.unless_overflow(overflow)
    }

    /// FORMAT.md's contour patch test: whether the patch is refused (holds no contour edge).
    fn patch_refused(&self, p: &doc::Patch, [radius, sin, cos]: [f64; 3]) -> Decision {
        let g = &self.joints[p.joint as usize];
        let det = g.a.determinant();
        if det == 0.0 || !det.is_finite() {
            return Decision::NO;
        }
        let inverse = g.a.inverse();
        let view = match self.view {
            doc::View::Eye(e) => doc::View::Eye(inverse * (e - g.t)),
            doc::View::Dir(d) => doc::View::Dir((inverse * d).normalize()),
        };
        let (moved, overflow_view) = match view {
            doc::View::Eye(e) => (e, e.abs().max_element() > f32::MAX as f64),
            doc::View::Dir(d) => (DVec3::ZERO, !d.is_finite()),
        };
        let size = p.center.abs().element_sum() + moved.abs().element_sum() + radius;
        let overflow = overflow_view || size * size > margins::F32_RANGE;
        match doc::patch_test(p.center, radius, p.axis, sin, cos, view) {
            doc::PatchTest::Always => Decision::NO,
            doc::PatchTest::Value { value, d } => {
                let tol = 2e-6 + 32.0 * margins::EPS32 * size / d;
                let outside_sphere = d * d > radius * radius * (1.0 + margins::SPHERE_INSIDE) * (1.0 + tol);
                let d = Decision {
                    exact: value > 0.0,
                    surely: value > tol && outside_sphere,
                    maybe: value > -tol,
                    ..Decision::NO
                };
                d.unless_overflow(overflow)
            }
        }
    }
}

/// Which `prepare` a culling run uses.
#[derive(Clone, Copy, Debug)]
enum Prepare {
    Bounds(Tests),
    WithBoxes,
    BoxesOnly,
}

/// Runs the runtime culler; per meshlet (original index) its flag: bit 0 frustum (or boxes),
/// bit 1 backface. Checks that the visible list is the meshlets with no flag.
fn run_culler(culler: &MeshletCuller, joints: &[Affine3A], camera: &Camera, how: Prepare) -> Vec<u8> {
    let mut frame = JointFrame::default();
    match how {
        Prepare::Bounds(tests) => culler.prepare(joints, camera, tests, &mut frame),
        Prepare::WithBoxes => culler.prepare_with_boxes(joints, camera, Tests::Both, &mut frame),
        Prepare::BoxesOnly => culler.prepare_boxes_only(joints, camera, Tests::Both, &mut frame),
    }
    let (mut flags, mut visible) = (Vec::new(), Vec::new());
    culler.cull(&frame, &mut flags, &mut visible);
    let mut out = vec![0u8; culler.len()];
    for (slot, s) in culler.slots().iter().enumerate() {
        out[s.id as usize] = flags[slot];
    }
    visible.sort_unstable();
    let kept: Vec<u32> = (0..out.len() as u32).filter(|&m| out[m as usize] == 0).collect();
    assert_eq!(visible, kept, "the visible list is not the meshlets without a flag");
    out
}

/// Compares one run's decisions; returns the first disagreement.
fn compare(
    what: &str,
    runtime: impl Fn(usize) -> bool,
    reference: impl Fn(usize) -> Decision,
    describe: impl Fn(usize) -> String,
    n: usize,
) -> Result<(), String> {
    for m in 0..n {
        let (r, d) = (runtime(m), reference(m));
        count(&COUNTS.decisions, 1);
        if !d.agrees(r) {
            return Err(format!("{what}, number {m}: runtime {r}, reference {d:?}\n{}", describe(m)));
        }
        if r != d.exact {
            count(
                match d.overflow {
                    true => &COUNTS.overflow,
                    false => {
                        let k = ["frustum", "backface", "both", "any-pose", "and boxes", "CONT"]
                            .iter()
                            .position(|k| what.contains(k))
                            .unwrap_or(0);
                        count(&COUNTS.margin_by_test[k], 1);
                        &COUNTS.within_margin
                    }
                },
                1,
            );
        }
    }
    Ok(())
}

/// One case: the mutated bytes, and every decision on what the view accepts.
fn check_case(original: &[u8], layout: &Layout, mutations: &[Mutation], seed: u64) -> Result<(), TestCaseError> {
    count(&COUNTS.cases, 1);
    let mut words = vec![0u32; original.len().div_ceil(4)];
    let bytes = &mut bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..original.len()];
    bytes.copy_from_slice(original);
    mutations.iter().for_each(|m| layout.apply(bytes, m));
    let bytes: &[u8] = bytes;
    let mutated = bytes != original;
    let Ok(view) = BakeView::new(bytes) else { return Ok(()) };
    let drivers = view.joint_count();
    let skin = doc::skin(doc::section(bytes, b"SKIN").unwrap()).unwrap();
    prop_assert_eq!(skin.drivers, drivers);

    // What the view accepts, and the reference's reading of the same bytes.
    let bnds = Some(doc::bnds(doc::section(bytes, b"BNDS").unwrap()).unwrap());
    let bnds_culler = bnds.as_ref().and_then(|_| match view.culler() {
        Ok(c) => Some(c),
        Err(e) => {
            if COUNTS.built_refused.load(Relaxed) < 3 {
                eprintln!("BNDS accepted, its culler refused: {e}; mutations {mutations:?}");
            }
            None
        }
    });
    let envl = (view.envelope())
        .map(|ev| (doc::envl(doc::section(bytes, b"ENVL").unwrap()).unwrap(), ev.culler(drivers).ok()));
    let cont = view.contours().map(|(c, edges)| (doc::cont(doc::section(bytes, b"CONT").unwrap()).unwrap(), c, edges));
    let parts = !view.parts().is_empty();
    let built_refused =
        (bnds.is_some() && bnds_culler.is_none()) as usize + envl.as_ref().is_some_and(|(_, c)| c.is_none()) as usize;
    count(&COUNTS.built_refused, built_refused);
    count(&COUNTS.bnds_accepted, bnds_culler.is_some() as usize);
    count(&COUNTS.envl_accepted, envl.as_ref().is_some_and(|(_, c)| c.is_some()) as usize);
    count(&COUNTS.cont_accepted, cont.is_some() as usize);
    if mutated && parts && bnds_culler.is_some() && envl.as_ref().is_some_and(|(_, c)| c.is_some()) && cont.is_some() {
        count(&COUNTS.accepted_mutated, 1);
    }

    // The document's promises about what a reader accepted.
    let mut promises: Vec<String> = Vec::new();
    for b in bnds.iter().flatten().chain(envl.iter().flat_map(|(e, _)| &e.bounds)) {
        promises.extend(doc::bound_promise(b, drivers));
    }
    if let Some((e, _)) = &envl {
        let ok = e.first_box.windows(2).all(|w| w[0] <= w[1]) && e.first_box.last() == Some(&(e.boxes.len() as u32));
        let boxes_ok = e.boxes.iter().all(|b| {
            (b.joint as usize) < drivers
                && b.center.is_finite()
                && b.half.is_finite()
                && b.half.cmpge(DVec3::ZERO).all()
        });
        if !(ok && boxes_ok) {
            promises.push("ENVL boxes: offsets, joints or extents".into());
        }
    }
    if let Some((c, _, _)) = &cont {
        for p in &c.patches {
            promises.extend(doc::patch_promise(p.axis, p.sin, p.cos));
            if p.joint as usize >= drivers || !(p.center.is_finite() && p.radius >= 0.0) {
                promises.push(format!("patch joint {} or sphere {} {}", p.joint, p.center, p.radius));
            }
        }
        for (i, w) in c.windows.iter().enumerate() {
            promises.extend(doc::patch_promise(c.patches[i % c.patches.len()].axis, w[1], w[2]));
            // "at most as wide": not checked by the reader; counted, not required.
            let p = &c.patches[i % c.patches.len()];
            // (An overall bound with `cos α ≤ 0` accepts always: any window is narrower.)
            if p.cos > 0.0 && (w[0] > p.radius || w[1].atan2(w[2]) > p.sin.atan2(p.cos)) {
                count(&COUNTS.windows_wider, 1);
            }
        }
    }
    prop_assert!(promises.is_empty(), "the view accepted what FORMAT.md rules out: {:?}", promises);

    // The world: joint matrices and three cameras.
    let mut rng = Rng(seed);
    let (matrices, far) = joint_matrices(&mut rng, &skin);
    let joints: Vec<doc::Joint> = matrices.iter().map(joint_f64).collect();
    let globals: Vec<DMat4> = joints.iter().map(|g| DMat4::from_mat3_translation(g.a, g.t)).collect();
    let mut cameras = Vec::new();
    while cameras.len() < 3 {
        let around = matrices[rng.below(matrices.len())].translation.as_dvec3();
        let around = if around.is_finite() && rng.below(3) > 0 { around } else { far };
        cameras.extend(camera(&mut rng, around));
    }
    let times: Vec<Option<(usize, f32)>> =
        (0..cameras.len()).map(|_| cont.as_ref().and_then(|(c, _, _)| clip_time(&mut rng, &c.clips))).collect();

    for (camera, &at) in cameras.iter().zip(&times) {
        let planes: Vec<doc::Plane> =
            camera.planes.iter().map(|p| doc::Plane { n: p.truncate().as_dvec3(), w: p.w as f64 }).collect();
        let view = match camera.projection {
            Projection::Perspective { eye } => doc::View::Eye(eye.as_dvec3()),
            Projection::Orthographic { dir } => doc::View::Dir(dir.as_dvec3()),
        };
        let omega = planes.iter().map(|p| p.w.abs()).fold(0.0, f64::max);
        let scene = Scene { joints: &joints, planes, view, omega };
        let check = |name: &str, culler: &MeshletCuller, records: &[doc::Bound], boxes: Option<&doc::Envl>| {
            let extent = extents(records, drivers);
            let n = records.len();
            let f = |m: usize| scene.frustum(&records[m], extent[records[m].joint as usize]);
            let b = |m: usize| scene.backface(&records[m], extent[records[m].joint as usize]);
            let describe = |m: usize| {
                let r = &records[m];
                let g = &joints[r.joint as usize];
                let extent = extent[r.joint as usize];
                let value = doc::sphere_distance(r.center, r.radius, g, &scene.planes);
                format!(
                    "record {r:?}\njoint {g:?}, extent {extent}\nsphere value {value}, backface value {:?}",
                    doc::backface(r, g, scene.view)
                )
            };
            let flags = run_culler(culler, &matrices, camera, Prepare::Bounds(Tests::Frustum));
            count(&COUNTS.culled, flags.iter().filter(|&&x| x != 0).count());
            compare(&format!("{name} frustum"), |m| flags[m] & 1 != 0, f, describe, n)?;
            let flags = run_culler(culler, &matrices, camera, Prepare::Bounds(Tests::Backface));
            count(&COUNTS.backface_culled, flags.iter().filter(|&&x| x & 2 != 0).count());
            compare(&format!("{name} backface"), |m| flags[m] & 2 != 0, b, describe, n)?;
            let flags = run_culler(culler, &matrices, camera, Prepare::Bounds(Tests::Both));
            compare(&format!("{name} both"), |m| flags[m] != 0, |m| f(m).or(b(m)), describe, n)?;
            if let Some(e) = boxes {
                let of = |m: usize| &e.boxes[e.first_box[m] as usize..e.first_box[m + 1] as usize];
                let x = |m: usize| scene.boxes(of(m));
                let describe_boxes = |m: usize| {
                    let mut s = String::new();
                    for b in of(m) {
                        let g = &joints[b.joint as usize];
                        let v: Vec<f64> = scene.planes.iter().map(|p| doc::box_distance(b, g, p)).collect();
                        s += &format!("\nbox {b:?}\n  joint {g:?}\n  plane values {v:?}");
                    }
                    s
                };
                let flags = run_culler(culler, &matrices, camera, Prepare::BoxesOnly);
                count(&COUNTS.box_culled, flags.iter().filter(|&&x| x != 0).count());
                compare(&format!("{name} any-pose boxes"), |m| flags[m] != 0, x, describe_boxes, n)?;
                let flags = run_culler(culler, &matrices, camera, Prepare::WithBoxes);
                compare(
                    &format!("{name} bounds and boxes"),
                    |m| flags[m] != 0,
                    |m| f(m).or(b(m)).or(x(m)),
                    |m| describe(m) + &describe_boxes(m),
                    n,
                )?;
            }
            Ok::<(), String>(())
        };
        let context = |e: String| TestCaseError::fail(format!("{e}\ncamera {camera:?}"));
        if let (Some(records), Some(culler)) = (&bnds, &bnds_culler) {
            check("BNDS", culler, records, None).map_err(context)?;
        }
        if let Some((e, Some(culler))) = &envl {
            check("ENVL", culler, &e.bounds, Some(e)).map_err(context)?;
        }
        if let Some((c, baked, edges)) = &cont {
            for at in [None, at] {
                let mut out = Vec::new();
                baked.patches.extract(&[], edges, &globals, at, camera.projection, &mut out);
                let mut hit = vec![false; edges.len()];
                out.iter().for_each(|&e| hit[e as usize] = true);
                let accepted = |p: usize| hit[c.order[c.patches[p].first as usize] as usize];
                count(&COUNTS.patches_refused, (0..c.patches.len()).filter(|&p| !accepted(p)).count());
                // The window's bounds (FORMAT.md) and the neighbouring window where the runtime's
                // f32 rounding of k may pick it.
                let n = c.patches.len();
                let sets: Vec<Option<u32>> = match doc::window(&c.clips, at.map(|(k, t)| (k, t as f64))) {
                    None => vec![None],
                    Some((_, _, w)) if w.start == w.end => vec![Some(w.first), Some(w.first + w.count - 1)],
                    Some((k, x, _)) if !x.is_finite() => vec![Some(k)],
                    Some((k, x, w)) => {
                        let t = at.unwrap().1 as f64;
                        let len = w.end - w.start;
                        let band = margins::WINDOW_SLACK
                            + 8.0
                                * margins::EPS32
                                * ((t.abs() + w.start.abs() + w.end.abs()) / len * w.count as f64 + x.abs());
                        let clamp = |x: f64| w.first + x.floor().clamp(0.0, (w.count - 1) as f64) as u32;
                        let mut s = vec![Some(k)];
                        s.extend([clamp(x - band), clamp(x + band)].into_iter().filter(|&c| c != k).map(Some));
                        s
                    }
                };
                let mut errors = Vec::new();
                for set in &sets {
                    let bounds = |p: usize| match set {
                        None => [c.patches[p].radius, c.patches[p].sin, c.patches[p].cos],
                        Some(w) => c.windows[*w as usize * n + p],
                    };
                    let r = compare(
                        &format!("CONT patches at {at:?} (bounds of window {set:?})"),
                        |p| !accepted(p),
                        |p| scene.patch_refused(&c.patches[p], bounds(p)),
                        |p| {
                            format!(
                                "patch {:?}, bounds {:?}, joint {:?}",
                                c.patches[p],
                                bounds(p),
                                joints[c.patches[p].joint as usize]
                            )
                        },
                        n,
                    );
                    match r {
                        Ok(()) => break,
                        Err(e) => errors.push(e),
                    }
                }
                if errors.len() == sets.len() {
                    return Err(context(errors.join("\n")));
                }
            }
        }
    }
    Ok(())
}

#[test]
fn the_documents_layout_reads_the_records_the_view_hands_out() {
    let (words, len) = baked();
    let bytes = &bytemuck::cast_slice::<u32, u8>(words)[..*len];
    let view = BakeView::new(bytes).unwrap();
    let bnds = doc::bnds(doc::section(bytes, b"BNDS").unwrap()).unwrap();
    let records = view.meshlet_bounds();
    assert_eq!(bnds.len(), records.len());
    for (d, r) in bnds.iter().zip(records) {
        assert_eq!(d.center, Vec3::from(r.center).as_dvec3());
        assert_eq!((d.radius, d.angle, d.joint, d.class), (r.radius as f64, r.cone_angle as f64, r.joint, r.class));
    }
    let ev = view.envelope().unwrap();
    let e = doc::envl(doc::section(bytes, b"ENVL").unwrap()).unwrap();
    assert_eq!(e.first_box, ev.box_offsets);
    assert!(
        e.boxes
            .iter()
            .zip(ev.boxes)
            .all(|(d, r)| d.center.as_vec3().to_array() == r[..3] && d.half.as_vec3().to_array() == r[3..])
    );
    assert!(e.bounds.iter().zip(ev.bounds).all(|(d, r)| d.radius == r.radius as f64 && d.joint == r.joint));
    let (c, _) = view.contours().unwrap();
    let cont = doc::cont(doc::section(bytes, b"CONT").unwrap()).unwrap();
    let p = &c.patches.patches;
    assert_eq!(cont.patches.len(), p.len());
    for (i, d) in cont.patches.iter().enumerate() {
        let b = p.bounds[i];
        assert_eq!((d.center.as_vec3(), d.radius as f32, d.axis.as_vec3()), (b.center, b.radius, b.axis), "patch {i}");
        assert_eq!(
            (d.sin as f32, d.cos as f32, d.first, d.count),
            (b.sin_angle, b.cos_angle, p.ranges[i][0], p.ranges[i][1])
        );
    }
    assert_eq!(cont.order, p.order);
    assert_eq!(cont.windows.len(), c.patches.window_bounds.len());
}

#[test]
fn every_decision_on_accepted_bytes_is_the_documents_in_f64() {
    let start = std::time::Instant::now();
    let (words, len) = baked();
    let original = &bytemuck::cast_slice::<u32, u8>(words)[..*len];
    let layout = Layout::of(original);
    eprintln!(
        "baked in {:.1?}: {} meshlets, {} any-pose boxes, {} patches, {} window bounds, {} parts",
        start.elapsed(),
        layout.meshlets,
        layout.boxes,
        layout.patches,
        layout.windows,
        layout.parts
    );
    // `PROPTEST_CASES` runs more (or fewer) cases, as for the other property tests.
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(CASES);
    let mut runner = TestRunner::new(Config { cases, failure_persistence: None, ..Config::default() });
    let strategy = (prop::collection::vec(mutation(), 1..4), any::<u64>());
    let result = runner.run(&strategy, |(mutations, seed)| check_case(original, &layout, &mutations, seed));
    let c = |a: &AtomicUsize| a.load(Relaxed);
    let run = c(&COUNTS.cases);
    eprintln!(
        "f64 reference: {run} cases run ({cases} passing cases asked), {} accepted-but-mutated bakes \
         (BNDS {}, ENVL {}, CONT {} accepted; {} sections accepted but not built); {} decisions compared: \
         {} meshlets culled by bounds, {} backface-culled, {} by any-pose boxes, {} patches refused; \
         {} disagreements within the documented margins, {} past the f32 range (safe side); \
         {} window bounds wider than their patch; {:.1?}",
        c(&COUNTS.accepted_mutated),
        c(&COUNTS.bnds_accepted),
        c(&COUNTS.envl_accepted),
        c(&COUNTS.cont_accepted),
        c(&COUNTS.built_refused),
        c(&COUNTS.decisions),
        c(&COUNTS.culled),
        c(&COUNTS.backface_culled),
        c(&COUNTS.box_culled),
        c(&COUNTS.patches_refused),
        c(&COUNTS.within_margin),
        c(&COUNTS.overflow),
        c(&COUNTS.windows_wider),
        start.elapsed()
    );
    eprintln!(
        "within margins, by test (frustum, backface, both, boxes, bounds and boxes, patches): {:?}",
        COUNTS.margin_by_test.each_ref().map(c)
    );
    if let Err(e) = result {
        panic!("{e}");
    }
    let accepted = c(&COUNTS.accepted_mutated);
    assert!(4 * accepted > run, "only {accepted} of {run} mutated bakes accepted: the property says little");
    for (what, n) in [
        ("frustum culls", c(&COUNTS.culled)),
        ("backface culls", c(&COUNTS.backface_culled)),
        ("box culls", c(&COUNTS.box_culled)),
        ("refused patches", c(&COUNTS.patches_refused)),
    ] {
        assert!(n > 100, "only {n} {what}: the cameras do not exercise the tests");
    }
}

/// The baked bytes with `mutations` applied, in aligned storage.
fn mutated(mutations: &[Mutation]) -> Vec<u32> {
    let (words, len) = baked();
    let layout = Layout::of(&bytemuck::cast_slice::<u32, u8>(words)[..*len]);
    let mut w = words.clone();
    mutations.iter().for_each(|m| layout.apply(&mut bytemuck::cast_slice_mut::<u32, u8>(&mut w)[..*len], m));
    w
}

/// Found by the f64 reference: a "frustum only" meshlet without a cone (half-angle π) whose
/// stored axis has length 3 (FORMAT.md asks for a unit axis only below π/2, and the view accepts
/// it) was backface-culled when it shared its joint with a meshlet that has a cone.
#[test]
fn a_meshlet_without_a_cone_is_never_backface_culled() {
    let (words, len) = baked();
    let records = doc::bnds(doc::section(&bytemuck::cast_slice::<u32, u8>(words)[..*len], b"BNDS").unwrap()).unwrap();
    let i = records.iter().position(|b| b.class == 1 && b.angle >= std::f64::consts::FRAC_PI_2).unwrap();
    let other = (i + 1) % records.len();
    let f = f32::to_bits;
    let w = mutated(&[
        // Meshlet i: axis 3·x̂ (no cone: its half-angle stays π).
        Mutation::BoundWord { envl: false, record: i as u32, field: 4, word: f(3.0) },
        Mutation::BoundWord { envl: false, record: i as u32, field: 5, word: f(0.0) },
        Mutation::BoundWord { envl: false, record: i as u32, field: 6, word: f(0.0) },
        // Another meshlet on its joint with a cone, so that the joint gets a backface test.
        Mutation::Cone {
            envl: false,
            record: other as u32,
            radius: f(0.1),
            axis: [f(0.0), f(0.0), f(1.0)],
            angle: f(0.3),
        },
        Mutation::BoundWord { envl: false, record: other as u32, field: 10, word: records[i].joint },
    ]);
    let bytes = &bytemuck::cast_slice::<u32, u8>(&w)[..*len];
    let view = BakeView::new(bytes).unwrap();
    let culler = view.culler().expect("the view accepts the mutated bounds");
    let c = records[i].center.as_vec3();
    // Identity joints; the eye 10 units from the center against the axis: `(c − e)·a = 30 ≥ 2·10 + 3r`.
    let camera = Camera::perspective(c - 10.0 * Vec3::X, c, Vec3::Y, 1.0, 1.0, 0.1, 100.0).unwrap();
    let joints = vec![Affine3A::IDENTITY; view.joint_count()];
    let flags = run_culler(&culler, &joints, &camera, Prepare::Bounds(Tests::Backface));
    assert_eq!(flags[i] & 2, 0, "meshlet {i} (class 1, no cone) was backface-culled");
}

/// Found by the f64 reference: a patch centred at (f32::MAX, f32::MAX, f32::MAX), whose cone
/// (sin α = 0.95) the view direction meets at |a·s| = 0.9, may hold a contour edge (FORMAT.md
/// accepts it), but the runtime refused it through a NaN.
#[test]
fn a_far_patch_is_not_refused_through_a_nan() {
    let s = DVec3::ONE.normalize();
    let axis = 0.9 * s + (1.0f64 - 0.81).sqrt() * DVec3::new(1.0, -1.0, 0.0).normalize();
    let (sin, cos) = (0.95f64, (1.0f64 - 0.95 * 0.95).sqrt());
    let f = f32::to_bits;
    let words = [f(f32::MAX), f(f32::MAX), f(f32::MAX), f(0.0), f(axis.x as f32), f(axis.y as f32), f(axis.z as f32)];
    let words = [words[0], words[1], words[2], words[3], words[4], words[5], words[6], f(sin as f32), f(cos as f32)];
    let w = mutated(&[Mutation::Patch { record: 0, words, joint: 0 }]);
    let (_, len) = baked();
    let bytes = &bytemuck::cast_slice::<u32, u8>(&w)[..*len];
    let view = BakeView::new(bytes).unwrap();
    let (contours, edges) = view.contours().expect("the view accepts the mutated patch");
    let cont = doc::cont(doc::section(bytes, b"CONT").unwrap()).unwrap();
    let p = cont.patches[0];
    let eye = doc::View::Eye(DVec3::ZERO);
    assert!(
        matches!(doc::patch_test(p.center, p.radius, p.axis, p.sin, p.cos, eye), doc::PatchTest::Value { value, .. } if value < -0.04)
    );
    let globals = vec![DMat4::IDENTITY; view.joint_count()];
    let mut out = Vec::new();
    contours.patches.extract(&[], edges, &globals, None, Projection::Perspective { eye: Vec3::ZERO }, &mut out);
    assert!(out.contains(&cont.order[p.first as usize]), "patch 0 was refused");
}
