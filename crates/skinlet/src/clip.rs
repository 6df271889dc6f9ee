//! Animation clips and their sampling, exactly as glTF 2.0 (section 3.11 and appendix C)
//! specifies: STEP holds the key value, LINEAR lerps translations and scales and slerps
//! rotations along the shorter arc, CUBICSPLINE evaluates the Hermite spline from the
//! stored in/out tangents (scaled by the key interval) and normalizes rotations after.
//! Times before the first key take the first value, after the last key the last value.
//!
//! Guarantee: at a key time the sampled value is the stored key value, bit for bit.
//! Later bounds work needs the exact interpolation path between keys: [`Channel::segment`]
//! exposes it, and [`Clip::key_times_affecting`] lists every key time that can move a node.

use crate::model::{Skeleton, Trs};
use glam::{DQuat, Quat, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

impl Interpolation {
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Step => "STEP",
            Interpolation::Linear => "LINEAR",
            Interpolation::CubicSpline => "CUBICSPLINE",
        }
    }
}

/// A value that can be keyframed: `Vec3` (translation, scale), `Quat` (rotation) or `f32`
/// (one morph target's weight).
pub trait Keyable: Copy + PartialEq + std::fmt::Debug {
    /// LINEAR interpolation between `a` and `b`, `s` in [0, 1].
    fn linear(a: Self, b: Self, s: f32) -> Self;
    /// Cubic Hermite: `v0`, its out-tangent `b0`, `v1`, its in-tangent `a1`, interval `dt`.
    fn hermite(v0: Self, b0: Self, v1: Self, a1: Self, dt: f32, s: f32) -> Self;
}

fn hermite_weights(s: f32) -> [f32; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2]
}

impl Keyable for Vec3 {
    fn linear(a: Self, b: Self, s: f32) -> Self {
        a * (1.0 - s) + b * s
    }
    fn hermite(v0: Self, b0: Self, v1: Self, a1: Self, dt: f32, s: f32) -> Self {
        let [h00, h10, h01, h11] = hermite_weights(s);
        v0 * h00 + b0 * (dt * h10) + v1 * h01 + a1 * (dt * h11)
    }
}

impl Keyable for f32 {
    fn linear(a: Self, b: Self, s: f32) -> Self {
        a * (1.0 - s) + b * s
    }
    fn hermite(v0: Self, b0: Self, v1: Self, a1: Self, dt: f32, s: f32) -> Self {
        let [h00, h10, h01, h11] = hermite_weights(s);
        v0 * h00 + b0 * (dt * h10) + v1 * h01 + a1 * (dt * h11)
    }
}

impl Keyable for Quat {
    fn linear(a: Self, b: Self, s: f32) -> Self {
        slerp(a, b, s)
    }
    fn hermite(v0: Self, b0: Self, v1: Self, a1: Self, dt: f32, s: f32) -> Self {
        let [h00, h10, h01, h11] = hermite_weights(s);
        let v = glam::Vec4::from(v0) * h00
            + glam::Vec4::from(b0) * (dt * h10)
            + glam::Vec4::from(v1) * h01
            + glam::Vec4::from(a1) * (dt * h11);
        Quat::from_vec4(v).normalize()
    }
}

/// glTF slerp: the shorter arc (the second key is negated when the dot product is
/// negative), constant angular speed. Computed in double precision. The result is a
/// rotation about one fixed axis whose angle grows linearly with `s`; bounds rely on that.
pub fn slerp(a: Quat, b: Quat, s: f32) -> Quat {
    if s == 0.0 {
        return a;
    }
    let (qa, mut qb) = (a.as_dquat(), b.as_dquat());
    let mut d = qa.dot(qb);
    if d < 0.0 {
        qb = -qb;
        d = -d;
    }
    let s = s as f64;
    let theta = d.min(1.0).acos();
    let q = if theta < 1e-9 {
        DQuat::from_vec4(qa.to_array().into()) * (1.0 - s) + qb * s
    } else {
        let st = theta.sin();
        qa * (((1.0 - s) * theta).sin() / st) + qb * ((s * theta).sin() / st)
    };
    q.normalize().as_quat()
}

/// The keys of one channel between two consecutive key times, with everything needed to
/// evaluate (or bound) the value anywhere in `[t0, t1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<T> {
    pub t0: f32,
    pub t1: f32,
    pub interpolation: Interpolation,
    pub v0: T,
    pub v1: T,
    /// CUBICSPLINE only (else equal to `v0`/`v1`): out-tangent of key 0, in-tangent of key 1.
    pub out_tangent0: T,
    pub in_tangent1: T,
}

impl<T: Keyable> Segment<T> {
    /// Value at time `t` (clamped to the segment).
    pub fn eval(&self, t: f32) -> T {
        if t <= self.t0 || t.is_nan() {
            return self.v0;
        }
        if t >= self.t1 {
            return self.v1;
        }
        let dt = self.t1 - self.t0;
        let s = (t - self.t0) / dt;
        match self.interpolation {
            Interpolation::Step => self.v0,
            Interpolation::Linear => T::linear(self.v0, self.v1, s),
            Interpolation::CubicSpline => T::hermite(self.v0, self.out_tangent0, self.v1, self.in_tangent1, dt, s),
        }
    }
}

/// Keyframes for one property of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel<T> {
    pub node: u32,
    pub interpolation: Interpolation,
    /// Non-decreasing key times, in seconds.
    pub times: Vec<f32>,
    /// One value per key; for CUBICSPLINE three per key: in-tangent, value, out-tangent.
    pub values: Vec<T>,
}

impl<T: Keyable> Channel<T> {
    fn value(&self, k: usize) -> T {
        match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        }
    }

    /// The segment containing `t`: keys `k` and `k + 1` with `times[k] <= t < times[k + 1]`.
    /// Before the first key (after the last) a constant segment at the first (last) key.
    pub fn segment(&self, t: f32) -> Segment<T> {
        let n = self.times.len();
        let k = self.times.partition_point(|&x| x <= t);
        let constant = |k: usize, t0: f32, t1: f32| {
            let v = self.value(k);
            Segment { t0, t1, interpolation: Interpolation::Step, v0: v, v1: v, out_tangent0: v, in_tangent1: v }
        };
        if k == 0 {
            return constant(0, f32::NEG_INFINITY, self.times[0]);
        }
        if k >= n {
            return constant(n - 1, self.times[n - 1], f32::INFINITY);
        }
        let (a, b) = (k - 1, k);
        let (out_tangent0, in_tangent1) = match self.interpolation {
            Interpolation::CubicSpline => (self.values[3 * a + 2], self.values[3 * b]),
            _ => (self.value(a), self.value(b)),
        };
        Segment {
            t0: self.times[a],
            t1: self.times[b],
            interpolation: self.interpolation,
            v0: self.value(a),
            v1: self.value(b),
            out_tangent0,
            in_tangent1,
        }
    }

    /// The channel's value at time `t`.
    pub fn sample(&self, t: f32) -> T {
        self.segment(t).eval(t)
    }
}

/// The weight of morph target `target` of the mesh that node `channel.node` draws.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightChannel {
    pub target: u32,
    pub channel: Channel<f32>,
}

/// One animation: channels per node and property; a glTF `weights` channel is one
/// [`WeightChannel`] per morph target.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clip {
    pub name: String,
    pub translations: Vec<Channel<Vec3>>,
    pub rotations: Vec<Channel<Quat>>,
    pub scales: Vec<Channel<Vec3>>,
    pub weights: Vec<WeightChannel>,
    /// First and last key time over all channels.
    pub start: f32,
    pub end: f32,
}

impl Clip {
    pub fn duration(&self) -> f32 {
        self.end - self.start
    }

    /// Sorted distinct key times over all channels.
    pub fn key_times(&self) -> Vec<f32> {
        let mut t: Vec<f32> = self.all_channel_times().flatten().copied().collect();
        sort_dedup(&mut t);
        t
    }

    fn all_channel_times(&self) -> impl Iterator<Item = &Vec<f32>> {
        let t = self.translations.iter().map(|c| &c.times);
        let r = self.rotations.iter().map(|c| &c.times);
        let w = self.weights.iter().map(|c| &c.channel.times);
        t.chain(r).chain(self.scales.iter().map(|c| &c.times)).chain(w)
    }

    /// Largest key count of any channel.
    pub fn max_channel_keys(&self) -> usize {
        self.all_channel_times().map(Vec::len).max().unwrap_or(0)
    }

    /// Interpolation modes used, in the order STEP, LINEAR, CUBICSPLINE.
    pub fn interpolations(&self) -> Vec<Interpolation> {
        let t = self.translations.iter().map(|c| c.interpolation);
        let r = self.rotations.iter().map(|c| c.interpolation);
        let w = self.weights.iter().map(|c| c.channel.interpolation);
        let used: Vec<Interpolation> = t.chain(r).chain(self.scales.iter().map(|c| c.interpolation)).chain(w).collect();
        [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline]
            .into_iter()
            .filter(|m| used.contains(m))
            .collect()
    }

    /// Sorted distinct key times of every channel on `node` or any of its ancestors: the
    /// times at which the node's global transform may change its interpolation segment.
    pub fn key_times_affecting(&self, skeleton: &Skeleton, node: u32) -> Vec<f32> {
        let path: Vec<u32> = skeleton.ancestry(node).collect();
        let on = |n: u32| path.contains(&n);
        let mut t: Vec<f32> = Vec::new();
        self.translations.iter().filter(|c| on(c.node)).for_each(|c| t.extend(&c.times));
        self.rotations.iter().filter(|c| on(c.node)).for_each(|c| t.extend(&c.times));
        self.scales.iter().filter(|c| on(c.node)).for_each(|c| t.extend(&c.times));
        sort_dedup(&mut t);
        t
    }

    /// The local segments of `node` at time `t`: per property the channel's segment, or
    /// `None` where the property is not animated (it stays at the rest value).
    pub fn local_segments(&self, node: u32, t: f32) -> LocalSegments {
        LocalSegments {
            translation: self.translations.iter().find(|c| c.node == node).map(|c| c.segment(t)),
            rotation: self.rotations.iter().find(|c| c.node == node).map(|c| c.segment(t)),
            scale: self.scales.iter().find(|c| c.node == node).map(|c| c.segment(t)),
        }
    }

    /// Local transforms of every node at time `t`: rest transforms with the clip's channels
    /// applied. `out` is resized to the node count.
    pub fn sample_locals(&self, skeleton: &Skeleton, t: f32, out: &mut Vec<Trs>) {
        out.clear();
        out.extend(skeleton.nodes.iter().map(|n| n.rest));
        for c in &self.translations {
            out[c.node as usize].translation = c.sample(t);
        }
        for c in &self.rotations {
            out[c.node as usize].rotation = c.sample(t);
        }
        for c in &self.scales {
            out[c.node as usize].scale = c.sample(t);
        }
    }

    /// True when the clip animates `node` (any property).
    pub fn animates(&self, node: u32) -> bool {
        self.translations.iter().any(|c| c.node == node)
            || self.rotations.iter().any(|c| c.node == node)
            || self.scales.iter().any(|c| c.node == node)
    }
}

/// Segments of one node's local TRS around a time; `None` means "rest value, constant".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalSegments {
    pub translation: Option<Segment<Vec3>>,
    pub rotation: Option<Segment<Quat>>,
    pub scale: Option<Segment<Vec3>>,
}

fn sort_dedup(t: &mut Vec<f32>) {
    t.sort_by(f32::total_cmp);
    t.dedup();
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    fn ch<T>(interpolation: Interpolation, times: Vec<f32>, values: Vec<T>) -> Channel<T> {
        Channel { node: 0, interpolation, times, values }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    /// Same rotation (q and -q are the same rotation).
    fn same_rotation(a: Quat, b: Quat, tol: f32) -> bool {
        a.dot(b).abs() > 1.0 - tol
    }

    #[test]
    fn step_holds_value_until_next_key() {
        let c = ch(Interpolation::Step, vec![0.0, 1.0, 2.0], vec![Vec3::X, Vec3::Y, Vec3::Z]);
        assert_eq!(c.sample(-1.0), Vec3::X);
        assert_eq!(c.sample(0.5), Vec3::X);
        assert_eq!(c.sample(1.0), Vec3::Y);
        assert_eq!(c.sample(1.999), Vec3::Y);
        assert_eq!(c.sample(2.0), Vec3::Z);
        assert_eq!(c.sample(9.0), Vec3::Z);
    }

    #[test]
    fn linear_translation_hand_computed() {
        let c = ch(Interpolation::Linear, vec![1.0, 3.0], vec![Vec3::ZERO, Vec3::new(2.0, 4.0, 6.0)]);
        assert!(close(c.sample(1.5), Vec3::new(0.5, 1.0, 1.5)));
        assert!(close(c.sample(2.0), Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(c.sample(0.0), Vec3::ZERO);
        assert_eq!(c.sample(4.0), Vec3::new(2.0, 4.0, 6.0));
    }

    #[test]
    fn linear_rotation_is_slerp_at_constant_speed() {
        let q1 = Quat::from_rotation_z(FRAC_PI_2);
        let c = ch(Interpolation::Linear, vec![0.0, 1.0], vec![Quat::IDENTITY, q1]);
        // Halfway: 45° about Z = (0, 0, sin 22.5°, cos 22.5°).
        let h = (PI / 8.0).sin_cos();
        assert!(same_rotation(c.sample(0.5), Quat::from_xyzw(0.0, 0.0, h.0, h.1), 1e-7));
        // A quarter of the way: 22.5°, not what nlerp would give.
        let x = c.sample(0.25) * Vec3::X;
        assert!(close(x, Vec3::new((PI / 8.0).cos(), (PI / 8.0).sin(), 0.0)));
    }

    #[test]
    fn linear_rotation_takes_the_shorter_arc() {
        // Key 1 is +270° about Z, the same as -90°: slerp must go through -45°.
        let c = ch(Interpolation::Linear, vec![0.0, 1.0], vec![Quat::IDENTITY, Quat::from_rotation_z(1.5 * PI)]);
        let x = c.sample(0.5) * Vec3::X;
        assert!(close(x, Vec3::new(FRAC_PI_4.cos(), -FRAC_PI_4.sin(), 0.0)), "{x}");
        // 179°: still the direct arc, through +89.5°.
        let a = 179f32.to_radians();
        let c = ch(Interpolation::Linear, vec![0.0, 1.0], vec![Quat::IDENTITY, Quat::from_rotation_y(a)]);
        assert!(same_rotation(c.sample(0.5), Quat::from_rotation_y(a / 2.0), 1e-6));
    }

    #[test]
    fn cubic_spline_hand_computed() {
        // [in, value, out] per key. At s = 1/2 the Hermite weights are 1/2, 1/8, 1/2, -1/8
        // and tangents are scaled by the interval (2 s): p = v0/2 + out0/4 + v1/2 - in1/4.
        let values = vec![
            Vec3::splat(9.0),
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::ONE,
            Vec3::splat(9.0),
        ];
        let c = ch(Interpolation::CubicSpline, vec![0.0, 2.0], values);
        assert!(close(c.sample(1.0), Vec3::new(0.75, 0.0, 0.5)), "{}", c.sample(1.0));
        assert_eq!(c.sample(0.0), Vec3::ZERO);
        assert_eq!(c.sample(2.0), Vec3::ONE);
        assert_eq!(c.sample(-3.0), Vec3::ZERO);
    }

    #[test]
    fn cubic_spline_rotation_is_normalized() {
        let q = Quat::from_rotation_x(1.0);
        let t = Quat::from_xyzw(0.3, 0.1, 0.0, 0.2);
        let c = ch(Interpolation::CubicSpline, vec![0.0, 1.0], vec![t, Quat::IDENTITY, t, t, q, t]);
        let s = c.sample(0.37);
        assert!((s.length() - 1.0).abs() < 1e-6);
        // Hand-computed: h = (2s³-3s²+1, s³-2s²+s, -2s³+3s², s³-s²) at s = 0.37.
        let s_ = 0.37f32;
        let h = [
            2.0 * s_.powi(3) - 3.0 * s_ * s_ + 1.0,
            s_.powi(3) - 2.0 * s_ * s_ + s_,
            -2.0 * s_.powi(3) + 3.0 * s_ * s_,
            s_.powi(3) - s_ * s_,
        ];
        let v =
            glam::Vec4::from(Quat::IDENTITY) * h[0] + glam::Vec4::from(t) * (h[1] + h[3]) + glam::Vec4::from(q) * h[2];
        assert!(same_rotation(s, Quat::from_vec4(v.normalize()), 1e-7));
    }

    #[test]
    fn key_times_affecting_includes_ancestors() {
        use crate::model::{Node, Skeleton, Trs};
        let node = |parent| Node { name: String::new(), parent, rest: Trs::IDENTITY, matrix: None };
        let sk = Skeleton::new(vec![node(None), node(Some(0)), node(Some(1)), node(Some(0))]).unwrap();
        let clip = Clip {
            rotations: vec![Channel {
                node: 0,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 2.0],
                values: vec![Quat::IDENTITY; 2],
            }],
            translations: vec![
                Channel {
                    node: 2,
                    interpolation: Interpolation::Step,
                    times: vec![0.5, 1.0],
                    values: vec![Vec3::ZERO; 2],
                },
                Channel { node: 3, interpolation: Interpolation::Step, times: vec![0.7], values: vec![Vec3::ZERO] },
            ],
            ..Clip::default()
        };
        assert_eq!(clip.key_times_affecting(&sk, 2), vec![0.0, 0.5, 1.0, 2.0]);
        assert_eq!(clip.key_times_affecting(&sk, 1), vec![0.0, 2.0]);
        assert_eq!(clip.key_times_affecting(&sk, 3), vec![0.0, 0.7, 2.0]);
        assert!(clip.local_segments(1, 0.3).rotation.is_none());
        let seg = clip.local_segments(2, 0.7).translation.unwrap();
        assert_eq!((seg.t0, seg.t1), (0.5, 1.0));
    }

    fn unit_quat() -> impl Strategy<Value = Quat> {
        (-1f32..1.0, -1f32..1.0, -1f32..1.0, -1f32..1.0)
            .prop_filter("non-zero", |(x, y, z, w)| x * x + y * y + z * z + w * w > 0.01)
            .prop_map(|(x, y, z, w)| Quat::from_xyzw(x, y, z, w).normalize())
    }

    proptest! {
        /// LINEAR rotation sampling equals slerp of the two keys, computed independently as
        /// `a · (a⁻¹ b)^s` through axis-angle with the shorter arc, in double precision.
        #[test]
        fn linear_rotation_equals_slerp(a in unit_quat(), b in unit_quat(), s in 0f32..=1.0, t0 in -5f32..5.0, dt in 0.01f32..3.0) {
            let c = ch(Interpolation::Linear, vec![t0, t0 + dt], vec![a, b]);
            let (t, t1) = (t0 + s * dt, t0 + dt);
            // The interpolation parameter as the stored key times define it.
            let s_eff = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0) as f64;
            let (da, mut db) = (a.as_dquat().normalize(), b.as_dquat().normalize());
            if da.dot(db) < 0.0 { db = -db; }
            let (axis, angle) = (da.inverse() * db).normalize().to_axis_angle();
            let expected = da * glam::DQuat::from_axis_angle(axis, angle * s_eff);
            let got = c.sample(t).as_dquat().normalize();
            prop_assert!(got.dot(expected).abs() > 1.0 - 1e-12, "got {got:?} expected {expected:?}");
        }

        /// At every key time the sampled value is the key value, bit for bit.
        #[test]
        fn key_times_are_exact(keys in proptest::collection::vec((0.001f32..1.0, unit_quat(), -10f32..10.0), 1..12), mode in 0..3usize) {
            let mut t = 0.0;
            let times: Vec<f32> = keys.iter().map(|k| { t += k.0; t }).collect();
            let interpolation = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline][mode];
            let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
            let rot: Vec<Quat> = keys.iter().flat_map(|k| std::iter::repeat_n(k.1, per_key)).collect();
            let pos: Vec<Vec3> = keys.iter().flat_map(|k| std::iter::repeat_n(Vec3::splat(k.2), per_key)).collect();
            let cr = ch(interpolation, times.clone(), rot);
            let cp = ch(interpolation, times.clone(), pos);
            for (k, &tk) in times.iter().enumerate() {
                prop_assert_eq!(cr.sample(tk), keys[k].1);
                prop_assert_eq!(cp.sample(tk), Vec3::splat(keys[k].2));
            }
        }
    }
}
