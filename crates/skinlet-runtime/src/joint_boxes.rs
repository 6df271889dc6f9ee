//! Whole-mesh bounds of a skinned mesh from per-joint boxes (the approach of Bevy's
//! "per-joint skinned bounds" pull request, `per-joint-skinned-bounds-bevy-pr.txt`).
//!
//! Each joint has the box of the bind-pose vertices with a nonzero weight on it, in mesh
//! space or in the joint's own space ([`JointSpace`]). Every frame, each box is moved by its
//! joint's matrix with Arvo's method (center by the matrix, half extents by its absolute
//! values) and the union taken. Guarantee: a skinned vertex `Σ wⱼ Mⱼ pⱼ` (weights ≥ 0,
//! summing to 1) is a convex combination of points of the moved boxes, so it lies in their
//! union's box: whatever the joint matrices (shear, negative or zero scale).
//!
//! The baker makes the boxes (`skinlet::cull::joint_aabb`: from a mesh, or with leaf joints
//! folded into ancestors over the baked clips); [`JointBoxes::sphere`] gives a whole-mesh
//! sphere, and [`Policy`] lists the choices users asked for in the PR's discussion.

use crate::{Error, Result};
use glam::{Affine3A, DVec3, Vec3, Vec3A};

/// Relative margin by which boxes stored in f32 are grown beyond their f64 extent, far above
/// f32 rounding (also the baker's margin for the rounding of skinning).
pub const INFLATE: f64 = 2e-6;

/// The space the per-joint boxes are stored in, and so which matrices move them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointSpace {
    /// Bind-pose mesh space: moved by skinning matrices `global × inverse_bind` (Bevy's
    /// choice: needs only the mesh).
    Mesh,
    /// Each joint's bind space: moved by the joints' global matrices (bevy_mod_skinned_aabb's
    /// choice). Tighter only where joint frames follow the limbs; on most shared assets mesh
    /// space was as tight or tighter (docs/CULLING.md), and folding needs this space.
    Joint,
}

/// What an engine does with a skinned mesh's box (the choices asked for in the PR).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Policy {
    /// Per-joint boxes updated every frame (the default).
    Dynamic,
    /// The bind-pose box, never updated (wrong as soon as the mesh moves away from it).
    BindPose,
    /// A box given by the artist, in entity space.
    Fixed { min: Vec3, max: Vec3 },
    /// A box given by the artist in a joint's space (Unity's root-bone bounds, any joint).
    FixedJointRelative { joint: u16, min: Vec3, max: Vec3 },
    /// Never culled.
    NoCulling,
}

impl Policy {
    /// The entity-space box for one frame, `None` for [`Policy::NoCulling`]. `dynamic` are
    /// the mesh's joint boxes, moved by `skinning` (skinning matrices) or `joint_globals`
    /// (joint global matrices) as their space requires; `bind_pose` is the bind-pose box.
    pub fn entity_box(
        &self,
        dynamic: &JointBoxes,
        skinning: &[Affine3A],
        joint_globals: &[Affine3A],
        bind_pose: Box3,
    ) -> Option<Box3> {
        match *self {
            Policy::Dynamic => Some(match dynamic.space {
                JointSpace::Mesh => dynamic.update(skinning),
                JointSpace::Joint => dynamic.update(joint_globals),
            }),
            Policy::BindPose => Some(bind_pose),
            Policy::Fixed { min, max } => Some(Box3 { min, max }),
            Policy::FixedJointRelative { joint, min, max } => {
                let m = joint_globals.get(joint as usize)?;
                Some(Box3 { min, max }.transformed(m))
            }
            Policy::NoCulling => None,
        }
    }
}

/// An axis-aligned box in f32 (min, max).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box3 {
    pub min: Vec3,
    pub max: Vec3,
}

impl Box3 {
    pub const EMPTY: Box3 = Box3 { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };
    /// The infinite box, which no frustum misses: what a box that cannot be bounded gives.
    pub const ALL: Box3 = Box3 { min: Vec3::NEG_INFINITY, max: Vec3::INFINITY };

    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).max(Vec3::ZERO).length()
    }

    /// Arvo's transform of the box (center and half extents) by `m`.
    pub fn transformed(&self, m: &Affine3A) -> Box3 {
        let (c, h) = (Vec3A::from((self.min + self.max) / 2.0), Vec3A::from((self.max - self.min) / 2.0));
        let (c, h) = arvo(m, c, h);
        Box3 { min: (c - h).into(), max: (c + h).into() }
    }
}

#[inline]
fn arvo(m: &Affine3A, c: Vec3A, h: Vec3A) -> (Vec3A, Vec3A) {
    let a = &m.matrix3;
    let center = a.x_axis * c.x + a.y_axis * c.y + a.z_axis * c.z + m.translation;
    let half = a.x_axis.abs() * h.x + a.y_axis.abs() * h.y + a.z_axis.abs() * h.z;
    (center, half)
}

/// Per-joint boxes of one skinned mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct JointBoxes {
    pub space: JointSpace,
    /// Skin joint of each box (joints without vertices have none).
    pub joints: Vec<u16>,
    pub center: Vec<Vec3A>,
    pub half: Vec<Vec3A>,
    /// The same boxes two by two, centers and half extents splatted for [`wide::update`].
    pairs: Vec<wide::Pair>,
    /// One more than the largest joint index: the matrices `update` needs.
    needs: usize,
}

impl Default for JointBoxes {
    /// No boxes (joint space).
    fn default() -> JointBoxes {
        JointBoxes::empty(JointSpace::Joint)
    }
}

impl JointBoxes {
    /// No boxes, in `space`.
    fn empty(space: JointSpace) -> JointBoxes {
        JointBoxes { space, joints: Vec::new(), center: Vec::new(), half: Vec::new(), pairs: Vec::new(), needs: 0 }
    }

    /// Boxes from their f64 extents, one `(min, max)` per skin joint (a joint without
    /// vertices has an empty box, `min > max` on some axis): stored in f32, grown by
    /// [`INFLATE`] and rounded outwards. Errors on more than 65,536 joints (stored in 16 bits)
    /// and on a box with a NaN or an infinite bound that is not empty.
    pub fn from_boxes(space: JointSpace, boxes: &[(DVec3, DVec3)]) -> Result<JointBoxes> {
        if boxes.len() > 1 << 16 {
            return Err(Error::invalid("joint boxes", format!("{} joints (at most 65,536)", boxes.len())));
        }
        let bad = |&(min, max): &(DVec3, DVec3)| {
            min.is_nan() || max.is_nan() || (min.cmple(max).all() && !(min.is_finite() && max.is_finite()))
        };
        if let Some(j) = boxes.iter().position(bad) {
            return Err(Error::invalid("joint boxes", format!("joint {j}: box {:?} is not finite", boxes[j])));
        }
        let mut out = JointBoxes::empty(space);
        for (j, &(min, max)) in boxes.iter().enumerate() {
            if min.cmple(max).all() {
                // Stored in f32: round outward by a relative margin far above f32 rounding.
                // Grown by INFLATE of the largest coordinate magnitude (at least of 1).
                let grow = DVec3::splat(INFLATE * min.abs().max(max.abs()).max_element().max(1.0));
                let (min, max) = (min - grow, max + grow);
                out.joints.push(j as u16);
                out.center.push(((min + max) / 2.0).as_vec3a());
                out.half.push(((max - min) / 2.0 * (1.0 + 1e-6)).as_vec3a());
            }
        }
        out.needs = out.joints.iter().map(|&j| j as usize + 1).max().unwrap_or(0);
        out.pairs = wide::pairs(&out.joints, &out.center, &out.half);
        Ok(out)
    }

    /// The entity-space box for this frame. `matrices[j]`, per skin joint: the skinning
    /// matrix (space [`JointSpace::Mesh`]) or the joint's global matrix ([`JointSpace::Joint`]),
    /// both relative to the entity. Returns [`Box3::EMPTY`] when there are no boxes, and the
    /// infinite box (never culled) when `matrices` has fewer entries than the skin's joints.
    pub fn update(&self, matrices: &[Affine3A]) -> Box3 {
        let mut out = [Box3::EMPTY];
        match self.update_all(matrices, matrices.len(), &mut out) {
            Ok(()) => out[0],
            Err(_) => Box3::ALL,
        }
    }

    /// [`JointBoxes::update`] for many instances of the mesh at once: instance `i`'s matrices
    /// are `palette[i * stride..(i + 1) * stride]` (an engine's joint matrix palette), its box
    /// goes to `out[i]`. Errors when `stride` does not reach every joint with a box or the
    /// palette does not hold `out.len()` instances.
    ///
    /// Where the CPU has AVX2 and FMA (checked at run time) two boxes are moved per 256-bit
    /// register; elsewhere one per 128-bit register. Both round to nearest in f32, so their
    /// results differ by an ulp or so, far inside the boxes' outward rounding margin.
    pub fn update_all(&self, palette: &[Affine3A], stride: usize, out: &mut [Box3]) -> Result<()> {
        if stride < self.needs || palette.len() != stride * out.len() {
            return Err(Error::invalid(
                "joint boxes",
                format!(
                    "{} matrices for {} instances of stride {stride} (the boxes use {} joints)",
                    palette.len(),
                    out.len(),
                    self.needs
                ),
            ));
        }
        if self.joints.is_empty() {
            out.fill(Box3::EMPTY);
            return Ok(());
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            // SAFETY: the features are present, and every joint in `pairs` is below `needs`,
            // so below `stride`: each instance's slice holds it.
            unsafe { wide::update_all(&self.pairs, palette, stride, out) };
            return Ok(());
        }
        for (m, b) in palette.chunks_exact(stride).zip(out) {
            *b = self.update_narrow(m);
        }
        Ok(())
    }

    /// One instance's box, one joint box at a time (also the reference for the wide path).
    fn update_narrow(&self, matrices: &[Affine3A]) -> Box3 {
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for ((&j, &c), &h) in self.joints.iter().zip(&self.center).zip(&self.half) {
            let (c, h) = arvo(&matrices[j as usize], c, h);
            lo = lo.min(c - h);
            hi = hi.max(c + h);
        }
        Box3 { min: lo.into(), max: hi.into() }
    }

    /// A whole-mesh sphere (center, radius) enclosing every moved joint box: each box's
    /// bounding sphere, moved with its radius scaled by the largest column norm times √3
    /// (a bound on the matrix's largest singular value), then one sphere around them all.
    /// Fewer matrices than the skin's joints give the infinite sphere (never culled).
    pub fn sphere(&self, matrices: &[Affine3A]) -> (Vec3, f32) {
        if matrices.len() < self.needs {
            return (Vec3::ZERO, f32::INFINITY);
        }
        let mut spheres = self.joints.iter().zip(&self.center).zip(&self.half).map(|((&j, &c), &h)| {
            let m = &matrices[j as usize];
            let a = &m.matrix3;
            let scale = a.x_axis.length().max(a.y_axis.length()).max(a.z_axis.length()) * 3f32.sqrt();
            (m.transform_point3a(c), h.length() * scale * (1.0 + 1e-5))
        });
        let Some(first) = spheres.next() else { return (Vec3::ZERO, 0.0) };
        // Ritter-style growth: enlarge the sphere just enough for each next one.
        let (mut c, mut r) = first;
        for (sc, sr) in spheres {
            let d = (sc - c).length();
            if d + r <= sr {
                (c, r) = (sc, sr);
            } else if d + sr > r {
                let nr = (r + d + sr) / 2.0;
                if d > 0.0 {
                    c += (sc - c) * ((nr - r) / d);
                }
                r = nr;
            }
        }
        (c.into(), r * (1.0 + 1e-6))
    }
}

/// Arvo's update two boxes per AVX register (x86-64 with AVX2 and FMA).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
mod wide {
    use super::Box3;
    use glam::{Affine3A, Vec3A};

    /// Two boxes: their joints, then per box axis the center coordinate and the half extent,
    /// each repeated over the box's four lanes (first box in lanes 0–3, second in 4–7).
    #[derive(Clone, Debug, PartialEq)]
    #[repr(C, align(32))]
    pub(super) struct Pair {
        center: [[f32; 8]; 3],
        half: [[f32; 8]; 3],
        joints: [u32; 2],
    }

    /// Boxes paired in order; an odd last box is paired with itself.
    pub(super) fn pairs(joints: &[u16], center: &[Vec3A], half: &[Vec3A]) -> Vec<Pair> {
        (0..joints.len().div_ceil(2))
            .map(|p| {
                let (a, b) = (2 * p, (2 * p + 1).min(joints.len() - 1));
                let splat = |v: [Vec3A; 2], axis: usize| {
                    let mut out = [v[0][axis]; 8];
                    out[4..].fill(v[1][axis]);
                    out
                };
                Pair {
                    center: [0, 1, 2].map(|k| splat([center[a], center[b]], k)),
                    half: [0, 1, 2].map(|k| splat([half[a], half[b]], k)),
                    joints: [joints[a] as u32, joints[b] as u32],
                }
            })
            .collect()
    }

    /// The union box of the moved boxes of each instance (see `JointBoxes::update_all`).
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA, every joint in `pairs` must be below `stride`, and
    /// `palette` must hold `out.len()` instances of `stride` matrices.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn update_all(pairs: &[Pair], palette: &[Affine3A], stride: usize, out: &mut [Box3]) {
        use std::arch::x86_64::*;
        let abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        for (i, b) in out.iter_mut().enumerate() {
            let (mut lo, mut hi) = (_mm256_set1_ps(f32::INFINITY), _mm256_set1_ps(f32::NEG_INFINITY));
            // SAFETY: instance i's matrices are in `palette` and every joint is below `stride`
            // (the caller's promise); an Affine3A is 64 bytes: three columns then the
            // translation, each three f32 and a lane of padding, which the masked loads leave
            // unread (it is uninitialized under glam's `scalar-math`).
            unsafe {
                let m = palette.as_ptr().add(i * stride).cast::<f32>();
                let three = _mm_setr_epi32(-1, -1, -1, 0);
                for p in pairs {
                    let (a, b) = (m.add(16 * p.joints[0] as usize), m.add(16 * p.joints[1] as usize));
                    let column = |k: usize| {
                        _mm256_set_m128(_mm_maskload_ps(b.add(4 * k), three), _mm_maskload_ps(a.add(4 * k), three))
                    };
                    let (x, y, z, t) = (column(0), column(1), column(2), column(3));
                    let c = |k: usize| _mm256_load_ps(p.center[k].as_ptr());
                    let h = |k: usize| _mm256_load_ps(p.half[k].as_ptr());
                    let center = _mm256_fmadd_ps(z, c(2), _mm256_fmadd_ps(y, c(1), _mm256_fmadd_ps(x, c(0), t)));
                    let half = _mm256_fmadd_ps(
                        _mm256_and_ps(z, abs),
                        h(2),
                        _mm256_fmadd_ps(_mm256_and_ps(y, abs), h(1), _mm256_mul_ps(_mm256_and_ps(x, abs), h(0))),
                    );
                    lo = _mm256_min_ps(lo, _mm256_sub_ps(center, half));
                    hi = _mm256_max_ps(hi, _mm256_add_ps(center, half));
                }
            }
            let lo = _mm_min_ps(_mm256_castps256_ps128(lo), _mm256_extractf128_ps::<1>(lo));
            let hi = _mm_max_ps(_mm256_castps256_ps128(hi), _mm256_extractf128_ps::<1>(hi));
            // Through arrays: `Vec3A` holds no `__m128` under glam's `scalar-math`.
            let (mut min, mut max) = ([0f32; 4], [0f32; 4]);
            // SAFETY: each store writes four f32 into a four-f32 array.
            unsafe { (_mm_storeu_ps(min.as_mut_ptr(), lo), _mm_storeu_ps(max.as_mut_ptr(), hi)) };
            *b = Box3 { min: glam::Vec3::from_slice(&min[..3]), max: glam::Vec3::from_slice(&max[..3]) };
        }
    }
}

/// The exact box of points (for measuring how loose a bound is).
pub fn points_box(points: &[Vec3]) -> Box3 {
    points.iter().fold(Box3::EMPTY, |b, &p| Box3 { min: b.min.min(p), max: b.max.max(p) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sphere_from_too_few_matrices_holds_everything() {
        let b = JointBoxes::from_boxes(JointSpace::Joint, &[(DVec3::ZERO, DVec3::ONE); 3]).unwrap();
        let (_, r) = b.sphere(&[Affine3A::IDENTITY; 2]);
        assert_eq!(r, f32::INFINITY);
        assert!(b.sphere(&[Affine3A::IDENTITY; 3]).1.is_finite());
    }

    #[test]
    fn boxes_past_16_bits_or_not_finite_are_errors() {
        let empty = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let e = JointBoxes::from_boxes(JointSpace::Joint, &vec![empty; 65_537]).unwrap_err().to_string();
        assert!(e.contains("65537 joints"), "{e}");
        assert!(JointBoxes::from_boxes(JointSpace::Joint, &vec![empty; 65_536]).is_ok());
        for bad in [(DVec3::NAN, DVec3::ONE), (DVec3::ZERO, DVec3::new(1.0, f64::INFINITY, 1.0))] {
            let e = JointBoxes::from_boxes(JointSpace::Joint, &[empty, bad]).unwrap_err().to_string();
            assert!(e.contains("joint 1"), "{e}");
        }
    }

    /// A small xorshift generator for test data.
    struct Rng(u64);
    impl Rng {
        fn f(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        }
        fn v(&mut self) -> Vec3 {
            Vec3::new(self.f(), self.f(), self.f())
        }
    }

    #[test]
    fn wide_and_narrow_updates_agree() {
        let mut r = Rng(0x5EED);
        // Odd and even box counts (the wide path pairs an odd last box with itself).
        for count in [1, 2, 7, 30] {
            let joints = count + 3;
            let boxes: Vec<(DVec3, DVec3)> = (0..joints)
                .map(|j| {
                    let (c, h) = (r.v() * 2.0, r.v().abs());
                    if j % 5 == 4 { (DVec3::ONE, DVec3::ZERO) } else { ((c - h).as_dvec3(), (c + h).as_dvec3()) }
                })
                .collect();
            let b = JointBoxes::from_boxes(JointSpace::Joint, &boxes).unwrap();
            for _ in 0..8 {
                let m: Vec<Affine3A> = (0..joints)
                    .map(|_| {
                        let a = glam::Mat3::from_cols(r.v(), r.v(), r.v()) * 2.0;
                        Affine3A::from_mat3_translation(a, r.v() * 5.0)
                    })
                    .collect();
                let (fast, slow) = (b.update(&m), b.update_narrow(&m));
                let tol = 1e-5 * (slow.max - slow.min).abs().max_element().max(1.0);
                assert!(
                    (fast.min - slow.min).abs().max_element() <= tol
                        && (fast.max - slow.max).abs().max_element() <= tol
                );
            }
            assert_eq!(b.update(&[]).max, Vec3::INFINITY, "too few matrices: never culled");
        }
    }

    #[test]
    fn boxes_hold_their_f64_extent() {
        let (min, max) = (DVec3::new(-1.0, 0.1, 3.0), DVec3::new(1.0 / 3.0, 0.2, 1e3));
        let b = JointBoxes::from_boxes(JointSpace::Mesh, &[(min, max), (DVec3::ONE, DVec3::ZERO)]).unwrap();
        assert_eq!(b.joints, [0], "the empty box is dropped");
        let (lo, hi) = ((b.center[0] - b.half[0]).as_dvec3(), (b.center[0] + b.half[0]).as_dvec3());
        assert!(lo.cmple(min).all() && hi.cmpge(max).all(), "{lo} {hi}");
    }
}
