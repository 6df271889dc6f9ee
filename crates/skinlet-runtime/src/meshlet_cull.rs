//! Per-meshlet frustum and backface culling of skinned instances with the baked
//! conservative bounds (Unterguggenberger et al. 2021, section 6: one test per meshlet, the
//! sphere and cone moved by the meshlet's principal joint).
//!
//! Both tests run in the joint's bind space, where the bounds live, so nothing per meshlet is
//! transformed and no bound is widened. With the joint's world matrix `G = [A | t]`:
//! - Frustum: the world image of the sphere `B(c, r)` is an ellipsoid, and its signed
//!   distance to a plane `(n, w)` is `n·(G c) + w − r·|Aᵀn|`. With the plane moved into joint
//!   space, `n_j = Aᵀn`, `w_j = n·t + w`, the meshlet is outside when
//!   `n_j·c + w_j + r·|n_j| < 0`: exact for any `A` (the paper scales the radius by the
//!   largest singular value, which is looser under non-uniform scale).
//! - Backface: face normals move by `cof(A)`, and `(A x)·(cof(A) n) = det(A)·(x·n)` for every
//!   `A`, so a world triangle faces away from the eye `e` exactly when its bind-space normal
//!   faces away from `e_j = G⁻¹ e` (sides swapped when `det A < 0`). The paper's cone test
//!   (every point of the sphere sees the cone from behind: `(c − e)·a ≥ |c − e|·sin α +
//!   r·(1 + sin α)`) in joint space is therefore exact, also under shear, non-uniform and
//!   negative scale; orthographic cameras use the direction `A⁻¹ d`.
//!   Singular joints (a zero scale) are never backface-culled.
//!
//! Per instance and frame, [`MeshletCuller::prepare`] first moves the box around every
//! joint's meshlet group by the joint matrices ([`JointBoxes`]): an instance wholly outside
//! one plane is culled at once, one wholly inside skips every frustum test. Otherwise it tests
//! the sphere around each joint's meshlets in world space (four joints per SIMD lane): groups
//! wholly inside skip the per-meshlet frustum test, groups wholly outside are culled at once,
//! and only straddling groups get joint-space planes. The per-meshlet tests then run in f32 over meshlets grouped by joint (structure
//! of arrays, branch-free, vectorized by the compiler). Every f32 step carries a margin of
//! 1e-5 of the magnitudes involved (1e-6 × the condition number more for the eye moved by
//! `A⁻¹`), far above f32 rounding, so a meshlet culled here is culled in exact arithmetic
//! too; the crowd scene checks this triangle by triangle against reference skinning.
//!
//! A culler may also hold the any-pose boxes of [`crate::any_pose`] (one box per meshlet and
//! influencing joint, in that joint's bind space): [`MeshletCuller::prepare_with_boxes`]
//! adds their test to the bounds', [`MeshletCuller::prepare_boxes_only`] runs it alone for a
//! pose no stored bound covers. A box moved by `G` lies beyond a plane `(n, w)` exactly when
//! `n_j·c + w_j + |n_j|·h < 0` with the plane in joint space (`|n_j|` componentwise), so the
//! test needs no per-box transform, only each joint's six planes per instance; the GPU passes
//! read the same planes and run it operation for operation.

use crate::any_pose::AnyPoseBoxes;
use crate::camera::{Camera, Projection};
use crate::joint_boxes::{JointBoxes, JointSpace};
use crate::meshlet_bounds::{Class, MeshletBounds};
use glam::{Affine3A, DVec3, Mat4, Vec3, Vec3A, Vec4};

/// Which tests run (the paper's three culling pipelines).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Tests {
    Frustum,
    Backface,
    #[default]
    Both,
}

/// Baked bounds laid out for culling: meshlets grouped by principal joint.
#[derive(Clone, Debug, Default)]
pub struct MeshletCuller {
    /// Original meshlet index of each slot.
    ids: Vec<u32>,
    /// Slots of joint `j`: `groups[j]..groups[j + 1]`.
    groups: Vec<u32>,
    cx: Vec<f32>,
    cy: Vec<f32>,
    cz: Vec<f32>,
    r: Vec<f32>,
    ax: Vec<f32>,
    ay: Vec<f32>,
    az: Vec<f32>,
    /// sin α of the cone; 2 when the meshlet may not be backface-culled (no cone or class).
    sin: Vec<f32>,
    /// 1 when the meshlet may be frustum-culled (class is not "none"), else 0.
    frustum_ok: Vec<u8>,
    /// Per joint: largest `|c| + r` of its meshlets (scales the rounding margins).
    extent: Vec<f32>,
    /// Per joint: a sphere around its frustum-cullable meshlets' spheres (joint space), tested
    /// first: a group wholly inside the frustum skips the per-meshlet frustum test, a group
    /// wholly outside one plane is culled at once.
    group_center: Vec<Vec3>,
    group_radius: Vec<f32>,
    /// Per joint: whether any of its meshlets may be backface-culled.
    group_cones: Vec<bool>,
    /// Per joint, padded with zeros to a multiple of four (one SIMD lane per joint): group
    /// sphere center and radius, and `extent`.
    lane_cx: Vec<f32>,
    lane_cy: Vec<f32>,
    lane_cz: Vec<f32>,
    lane_radius: Vec<f32>,
    lane_extent: Vec<f32>,
    /// Per joint, the box around its group sphere (joint space): moved by the joint matrices
    /// ([`JointBoxes::update`]), their union bounds the whole instance's cullable meshlets.
    instance: JointBoxes,
    /// Any-pose boxes of meshlet `m` (original index): `box_offsets[m]..box_offsets[m + 1]`
    /// (empty without boxes).
    box_offsets: Vec<u32>,
    boxes: Vec<PoseBox>,
}

/// One any-pose box as the culling loop reads it (8 words, also the GPU layout): its joint,
/// center and half extents in the joint's bind space, and `magnitude` = Σ (|cᵢ| + hᵢ),
/// which scales the rounding margin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct PoseBox {
    pub joint: u32,
    pub center: [f32; 3],
    pub half: [f32; 3],
    pub magnitude: f32,
}

/// Joint world matrices from what a renderer usually holds: the instance's model matrix and
/// skinning matrices `S_j = global_j × inverse_bind_j` (mesh space to model space), with the
/// bind matrices `bind_j = inverse_bind_j⁻¹` precomputed once per skin: `model × S_j × bind_j`.
pub fn joints_from_skinning(model: &Affine3A, skinning: &[Affine3A], bind: &[Affine3A], out: &mut Vec<Affine3A>) {
    out.clear();
    out.extend(skinning.iter().zip(bind).map(|(s, b)| *model * *s * *b));
}

/// Three coordinates of four joints (structure of arrays: lane `i` is joint `i`).
#[derive(Clone, Copy)]
struct V4 {
    x: Vec4,
    y: Vec4,
    z: Vec4,
}

impl V4 {
    /// Four vectors, one per lane.
    fn columns(v: [Vec3A; 4]) -> V4 {
        let m = Mat4::from_cols(v[0].extend(0.0), v[1].extend(0.0), v[2].extend(0.0), v[3].extend(0.0)).transpose();
        V4 { x: m.x_axis, y: m.y_axis, z: m.z_axis }
    }

    fn splat(v: Vec3) -> V4 {
        V4 { x: Vec4::splat(v.x), y: Vec4::splat(v.y), z: Vec4::splat(v.z) }
    }

    fn dot(self, o: V4) -> Vec4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Each lane's vector dotted with the same `v`.
    fn dot_splat(self, v: Vec3) -> Vec4 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }

    fn cross(self, o: V4) -> V4 {
        V4 { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
}

impl std::ops::Add for V4 {
    type Output = V4;
    fn add(self, o: V4) -> V4 {
        V4 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}

impl std::ops::Sub for V4 {
    type Output = V4;
    fn sub(self, o: V4) -> V4 {
        V4 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

impl std::ops::Mul<Vec4> for V4 {
    type Output = V4;
    fn mul(self, s: Vec4) -> V4 {
        V4 { x: self.x * s, y: self.y * s, z: self.z * s }
    }
}

/// Where a joint's meshlet group lies relative to the frustum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Group {
    #[default]
    Inside,
    Outside,
    Straddles,
}

/// Per-joint values of one instance at one frame; reuse it across frames (no allocation
/// once grown).
#[derive(Clone, Debug, Default)]
pub struct JointFrame {
    /// Per joint, 6 planes in joint space: `(n_j, w_j)`, and `|n_j|` in `len`.
    planes: Vec<[[f32; 4]; 6]>,
    len: Vec<[f32; 6]>,
    /// Frustum rounding margin per joint.
    margin: Vec<f32>,
    /// Eye (perspective) or unit direction (orthographic) in joint space, times sign(det A)
    /// in `sign`; `sign` is 0 for a singular joint.
    view: Vec<Vec3>,
    sign: Vec<f32>,
    backface_margin: Vec<f32>,
    group: Vec<Group>,
    /// With `any_pose`: per joint, the any-pose box margin `scale · magnitude + offset` as
    /// `[scale, offset]`, and planes set for every joint (not only straddling ones).
    box_margin: Vec<[f32; 2]>,
    any_pose: bool,
    orthographic: bool,
    tests: Tests,
}

/// One meshlet as the culling loop reads it (for GPU culling passes): bounds in its joint's
/// space, the cone's `sin α` (2: never backface-culled), whether the frustum test may cull
/// it, its joint and its original index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CullSlot {
    pub center: Vec3,
    pub radius: f32,
    pub axis: Vec3,
    pub sin: f32,
    pub frustum_ok: bool,
    pub joint: u32,
    pub id: u32,
}

impl JointFrame {
    /// A frame that culls nothing (every group inside the frustum, no backface test, no
    /// boxes): for an instance whose pose nothing the culler holds covers (morph weights out
    /// of the boxes' ranges), so that GPU culling passes draw it whole.
    pub fn keep_all(joints: usize) -> JointFrame {
        let mut frame = JointFrame::default();
        frame.set_keep_all(joints);
        frame
    }

    /// This frame made one that culls nothing ([`JointFrame::keep_all`]), reusing its buffers.
    pub fn set_keep_all(&mut self, joints: usize) {
        self.reset(joints, false, Tests::Both);
    }

    /// Sizes the frame for `joints` joints with every group inside and no backface test;
    /// planes, lengths, margins, views and backface margins keep stale values, which nothing
    /// reads until they are set.
    fn reset(&mut self, joints: usize, orthographic: bool, tests: Tests) {
        self.planes.resize(joints, [[0.0; 4]; 6]);
        self.len.resize(joints, [0.0; 6]);
        self.margin.resize(joints, 0.0);
        self.view.resize(joints, Vec3::ZERO);
        self.backface_margin.resize(joints, 0.0);
        self.box_margin.resize(joints, [0.0; 2]);
        self.sign.clear();
        self.sign.resize(joints, 0.0);
        self.group.clear();
        self.group.resize(joints, Group::Inside);
        self.any_pose = false;
        self.orthographic = orthographic;
        self.tests = tests;
    }

    /// Whether the any-pose boxes are tested.
    pub fn any_pose(&self) -> bool {
        self.any_pose
    }

    /// Joints prepared.
    pub fn joints(&self) -> usize {
        self.group.len()
    }
}

/// Meshlets culled by one call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CullCounts {
    pub meshlets: usize,
    pub visible: usize,
    /// Culled by the frustum test (with [`Tests::Both`]: those outside, whatever their facing).
    pub frustum: usize,
    /// Culled by the backface test and not by the frustum test.
    pub backface: usize,
}

impl CullCounts {
    pub fn add(&mut self, o: &CullCounts) {
        self.meshlets += o.meshlets;
        self.visible += o.visible;
        self.frustum += o.frustum;
        self.backface += o.backface;
    }
}

impl MeshletCuller {
    /// Lays out bounds and their classes (`joints`: the skin's joint count). Errors when the
    /// counts of bounds and classes differ or a meshlet's principal joint is not below `joints`.
    pub fn new(bounds: &[MeshletBounds], classes: &[Class], joints: usize) -> crate::Result<MeshletCuller> {
        if bounds.len() != classes.len() {
            return Err(crate::Error::invalid(
                "meshlet culler",
                format!("{} bounds but {} classes", bounds.len(), classes.len()),
            ));
        }
        if let Some((i, b)) = bounds.iter().enumerate().find(|(_, b)| b.joint as usize >= joints) {
            return Err(crate::Error::invalid(
                "meshlet culler",
                format!("meshlet {i}'s principal joint {} is not one of {joints} joints", b.joint),
            ));
        }
        let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
        order.sort_by_key(|&i| bounds[i as usize].joint);
        let mut c = MeshletCuller { extent: vec![0.0; joints], ..MeshletCuller::default() };
        c.groups = vec![0; joints + 1];
        for &i in &order {
            let (b, class) = (&bounds[i as usize], classes[i as usize]);
            let j = b.joint as usize;
            c.groups[j + 1] += 1;
            c.ids.push(i);
            c.cx.push(b.center.x);
            c.cy.push(b.center.y);
            c.cz.push(b.center.z);
            c.r.push(b.radius);
            // A meshlet without a cone stores a zero axis with its "no cone" sine, so no axis
            // the file holds for it (any length past π/2) can make it look back-facing.
            let cone = b.cone_angle < std::f32::consts::FRAC_PI_2 && class == Class::Both;
            let axis = if cone { b.cone_axis } else { Vec3::ZERO };
            c.ax.push(axis.x);
            c.ay.push(axis.y);
            c.az.push(axis.z);
            c.sin.push(if cone { b.cone_angle.sin() } else { 2.0 });
            c.frustum_ok.push((class != Class::None) as u8);
            c.extent[j] = c.extent[j].max(b.center.length() + b.radius);
        }
        for j in 0..joints {
            c.groups[j + 1] += c.groups[j];
        }
        // Group spheres: centered on the box of the cullable meshlets' centers.
        for j in 0..joints {
            let slots = c.groups[j] as usize..c.groups[j + 1] as usize;
            let cullable: Vec<usize> = slots.filter(|&i| c.frustum_ok[i] == 1).collect();
            let at = |i: usize| Vec3::new(c.cx[i], c.cy[i], c.cz[i]);
            let (lo, hi) =
                cullable.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &i| (l.min(at(i)), h.max(at(i))));
            let center = if cullable.is_empty() { Vec3::ZERO } else { (lo + hi) / 2.0 };
            let radius = cullable.iter().map(|&i| at(i).distance(center) + c.r[i]).fold(0.0f32, f32::max);
            c.group_center.push(center);
            c.group_radius.push(radius * (1.0 + 1e-5));
            c.group_cones.push((c.groups[j] as usize..c.groups[j + 1] as usize).any(|i| c.sin[i] <= 1.0));
        }
        let padded = joints.div_ceil(4) * 4;
        let lanes = |v: Vec<f32>| {
            let mut v = v;
            v.resize(padded, 0.0);
            v
        };
        c.lane_cx = lanes(c.group_center.iter().map(|p| p.x).collect());
        c.lane_cy = lanes(c.group_center.iter().map(|p| p.y).collect());
        c.lane_cz = lanes(c.group_center.iter().map(|p| p.z).collect());
        c.lane_radius = lanes(c.group_radius.clone());
        c.lane_extent = lanes(c.extent.clone());
        let group_boxes: Vec<(DVec3, DVec3)> = (0..joints)
            .map(|j| {
                let cullable = (c.groups[j]..c.groups[j + 1]).any(|i| c.frustum_ok[i as usize] == 1);
                let (center, r) = (c.group_center[j].as_dvec3(), c.group_radius[j] as f64);
                if cullable { (center - r, center + r) } else { (DVec3::INFINITY, DVec3::NEG_INFINITY) }
            })
            .collect();
        c.instance = JointBoxes::from_boxes(JointSpace::Joint, &group_boxes)?;
        Ok(c)
    }

    pub fn len(&self) -> usize {
        self.ids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    pub fn joints(&self) -> usize {
        self.extent.len()
    }

    /// Per joint, the largest `|c| + r` of its meshlets' spheres (joint space): what the
    /// rounding margins of [`MeshletCuller::prepare`] scale with (GPU preparation passes
    /// use the same).
    pub fn joint_extents(&self) -> &[f32] {
        &self.extent
    }

    /// Per-joint values for `joint_to_world` (one matrix per joint: the joint's world
    /// transform, i.e. model matrix × the joint's global transform) and the tests to run.
    /// Each joint's meshlet group is first tested as one sphere in world space (radius scaled
    /// by a Gershgorin bound of the largest singular value); only groups that straddle a
    /// plane get joint-space planes, and only groups that may be drawn get the eye. Four
    /// joints are prepared at once, one per SIMD lane.
    pub fn prepare(&self, joint_to_world: &[Affine3A], camera: &Camera, tests: Tests, frame: &mut JointFrame) {
        let n = joint_to_world.len().min(self.joints());
        frame.reset(n, matches!(camera.projection, Projection::Orthographic { .. }), tests);
        let (do_frustum, do_back) = (tests != Tests::Backface, tests != Tests::Frustum);
        // The whole instance first: when the box around every group sphere is outside a plane
        // or inside all six, no group needs its own frustum test (and outside, no eye).
        let whole = if do_frustum { self.instance_side(&joint_to_world[..n], camera) } else { Group::Inside };
        frame.group.fill(whole);
        if whole == Group::Outside {
            return;
        }
        for base in (0..n).step_by(4) {
            let lanes = (n - base).min(4);
            let active: [bool; 4] =
                std::array::from_fn(|i| i < lanes && self.groups[base + i] < self.groups[base + i + 1]);
            let cones = |i: usize| active[i] && self.group_cones[base + i];
            if !(active.contains(&true) && (whole == Group::Straddles || do_back && (0..4).any(cones))) {
                continue;
            }
            let g: [Affine3A; 4] =
                std::array::from_fn(|i| if i < lanes { joint_to_world[base + i] } else { Affine3A::IDENTITY });
            let (x, y, z, t) = (
                V4::columns(g.map(|m| m.matrix3.x_axis)),
                V4::columns(g.map(|m| m.matrix3.y_axis)),
                V4::columns(g.map(|m| m.matrix3.z_axis)),
                V4::columns(g.map(|m| m.translation)),
            );
            let at = |v: &[f32]| Vec4::from_slice(&v[base..base + 4]);
            let ext = at(&self.lane_extent);
            // Shared by both tests: the Gram matrix AᵀA (squared column norms and their dot
            // products) and the cofactor columns (y×z, z×x, x×y).
            let (xx, yy, zz) = (x.dot(x), y.dot(y), z.dot(z));
            let mut group = [whole; 4];
            if whole == Group::Straddles {
                // Largest singular value: Gershgorin on AᵀA (exact for rotation × scale).
                let (xy, xz, yz) = (x.dot(y).abs(), x.dot(z).abs(), y.dot(z).abs());
                let smax = (xx + xy + xz).max(yy + xy + yz).max(zz + xz + yz).map(f32::sqrt) * (1.0 + 1e-6);
                let gc = V4 { x: at(&self.lane_cx), y: at(&self.lane_cy), z: at(&self.lane_cz) };
                let c = x * gc.x + y * gc.y + z * gc.z + t;
                let r = at(&self.lane_radius) * smax * (1.0 + 1e-5) + 1e-5 * (c.x.abs() + c.y.abs() + c.z.abs() + ext);
                // Lane masks (bits, so that glam's `scalar-math` mask type works alike).
                let (mut outside, mut inside) = (0u32, 0b1111u32);
                for p in &camera.planes {
                    let d = c.x * p.x + c.y * p.y + c.z * p.z + p.w;
                    outside |= d.cmplt(-r).bitmask();
                    inside &= d.cmpgt(r).bitmask();
                }
                group = std::array::from_fn(|i| {
                    if outside & (1 << i) != 0 {
                        Group::Outside
                    } else if inside & (1 << i) != 0 {
                        Group::Inside
                    } else {
                        Group::Straddles
                    }
                });
            }
            let straddles: [bool; 4] = std::array::from_fn(|i| active[i] && group[i] == Group::Straddles);
            if straddles.contains(&true) {
                let t_len = t.dot(t).map(f32::sqrt);
                let mut margin = Vec4::ZERO;
                for (k, p) in camera.planes.iter().enumerate() {
                    let nj =
                        V4 { x: x.dot_splat(p.truncate()), y: y.dot_splat(p.truncate()), z: z.dot_splat(p.truncate()) };
                    let wj = t.dot_splat(p.truncate()) + p.w;
                    let len = nj.dot(nj).map(f32::sqrt);
                    margin = margin.max(1e-5 * (wj.abs() + len * ext + t_len + p.w.abs()));
                    for i in (0..4).filter(|&i| straddles[i]) {
                        frame.planes[base + i][k] = [nj.x[i], nj.y[i], nj.z[i], wj[i]];
                        frame.len[base + i][k] = len[i];
                    }
                }
                for i in (0..4).filter(|&i| straddles[i]) {
                    frame.margin[base + i] = margin[i];
                }
            }
            let backface: [bool; 4] = std::array::from_fn(|i| {
                do_back && active[i] && self.group_cones[base + i] && group[i] != Group::Outside
            });
            if backface.contains(&true) {
                // The eye moves into joint space through A⁻¹ = cof(A)ᵀ / det(A). Its f32
                // error grows with the condition number, bounded by |A|·|A⁻¹| (Frobenius),
                // which the margin covers.
                let (c0, c1, c2) = (y.cross(z), z.cross(x), x.cross(y));
                let det = x.dot(c0);
                let scale2 = xx.max(yy).max(zz);
                let regular =
                    (det * det).cmpgt(1e-18 * scale2 * scale2 * scale2).bitmask() & det.is_finite_mask().bitmask();
                let inv_frob2 = (c0.dot(c0) + c1.dot(c1) + c2.dot(c2)) / (det * det);
                let cond = ((xx + yy + zz) * inv_frob2).map(f32::sqrt);
                let solve = |v: V4| V4 { x: v.dot(c0) / det, y: v.dot(c1) / det, z: v.dot(c2) / det };
                let (view, bmargin) = match camera.projection {
                    Projection::Perspective { eye } => {
                        // |e|₁ ≥ |e|: a margin without a square root.
                        let ej = solve(V4::splat(eye) - t);
                        (ej, (1e-5 + 1e-6 * cond) * (ej.x.abs() + ej.y.abs() + ej.z.abs() + ext))
                    }
                    Projection::Orthographic { dir } => (solve(V4::splat(dir)), 1e-5 + 1e-6 * cond),
                };
                for i in (0..4).filter(|&i| backface[i] && regular & (1 << i) != 0) {
                    let v = Vec3::new(view.x[i], view.y[i], view.z[i]);
                    frame.view[base + i] = if frame.orthographic { v.normalize_or_zero() } else { v };
                    frame.sign[base + i] = det[i].signum();
                    frame.backface_margin[base + i] = bmargin[i];
                }
            }
            frame.group[base..base + lanes].copy_from_slice(&group[..lanes]);
        }
    }

    /// [`MeshletCuller::prepare`], and the any-pose boxes tested too (in [`MeshletCuller::cull`],
    /// on the meshlets the bounds keep): for a pose the bounds hold for, with morph weights
    /// inside the ranges the boxes were built for. Without boxes, the same as `prepare`.
    pub fn prepare_with_boxes(
        &self,
        joint_to_world: &[Affine3A],
        camera: &Camera,
        tests: Tests,
        frame: &mut JointFrame,
    ) {
        self.prepare(joint_to_world, camera, tests, frame);
        self.box_planes(joint_to_world, camera, frame);
    }

    /// Only the any-pose boxes (frustum test): for a pose the bounds do not hold for (the pose
    /// guard refused it), with morph weights inside the boxes' ranges. Without boxes, or with
    /// [`Tests::Backface`], the frame culls nothing.
    pub fn prepare_boxes_only(
        &self,
        joint_to_world: &[Affine3A],
        camera: &Camera,
        tests: Tests,
        frame: &mut JointFrame,
    ) {
        let n = joint_to_world.len().min(self.joints());
        frame.reset(n, matches!(camera.projection, Projection::Orthographic { .. }), tests);
        self.box_planes(joint_to_world, camera, frame);
    }

    /// Joint-space planes of every joint and the box margins, for the any-pose boxes:
    /// `n_j = Aᵀn` (one matrix-vector product per plane), `w_j = n·t + w`. Margin, with
    /// `ν` the largest `|nₖ|` component and `ω` the largest `|w|` over the planes: `n_j`'s
    /// components carry f32 errors below 3 ulps of `s = ν·max |aᵢ|₁` (and are at most `s`),
    /// `w_j`'s below 4 ulps of `u = ν·|t|₁ + ω`, the box test's own sum below 8 ulps of
    /// `s·Σ(|cᵢ| + hᵢ) + u`; 1e-5 of that covers all of them many times. A joint matrix that
    /// is not finite gets NaN planes, which cull nothing. After `prepare`, this also rewrites
    /// the straddling joints' planes with the same products rounded in another order: both
    /// lie within the same f32 rounding bound of the exact plane, which is what the sphere
    /// test's margin covers.
    fn box_planes(&self, joint_to_world: &[Affine3A], camera: &Camera, frame: &mut JointFrame) {
        if self.boxes.is_empty() {
            return;
        }
        let nu = camera.planes.iter().map(|p| p.truncate().abs().max_element()).fold(0.0f32, f32::max);
        let omega = camera.planes.iter().map(|p| p.w.abs()).fold(0.0f32, f32::max);
        let n = frame.joints();
        for (j, g) in joint_to_world[..n].iter().enumerate() {
            let (a, t) = (g.matrix3.transpose(), g.translation);
            for (plane, p) in frame.planes[j].iter_mut().zip(&camera.planes) {
                let nj = a * Vec3A::from(p.truncate());
                *plane = [nj.x, nj.y, nj.z, t.x * p.x + t.y * p.y + t.z * p.z + p.w];
            }
            if !g.is_finite() {
                frame.planes[j] = [[f32::NAN; 4]; 6];
            }
            let m = &g.matrix3;
            let s =
                nu * m.x_axis.abs().element_sum().max(m.y_axis.abs().element_sum()).max(m.z_axis.abs().element_sum());
            let u = nu * t.abs().element_sum() + omega;
            frame.box_margin[j] = [1e-5 * s, 1e-5 * u];
        }
        frame.any_pose = true;
    }

    /// Whether every any-pose box of meshlet `id`, moved by its joint, is beyond one and the
    /// same plane of `frame`. A meshlet without boxes, or with a box of a joint the frame
    /// lacks, is kept.
    fn boxes_outside(&self, frame: &JointFrame, id: usize) -> bool {
        let (Some(&lo), Some(&hi)) = (self.box_offsets.get(id), self.box_offsets.get(id + 1)) else { return false };
        let mut out = 0b11_1111u32;
        for b in &self.boxes[lo as usize..hi as usize] {
            let j = b.joint as usize;
            let (Some(p), Some(&[scale, offset])) = (frame.planes.get(j), frame.box_margin.get(j)) else {
                return false;
            };
            let ([cx, cy, cz], [hx, hy, hz]) = (b.center, b.half);
            let margin = scale * b.magnitude + offset;
            for (k, p) in p.iter().enumerate() {
                let d =
                    p[0] * cx + p[1] * cy + p[2] * cz + p[3] + (p[0].abs() * hx + p[1].abs() * hy + p[2].abs() * hz);
                out &= !(((d + margin < 0.0) as u32 ^ 1) << k);
            }
            if out == 0 {
                return false;
            }
        }
        lo < hi && out != 0
    }

    /// The any-pose boxes as the culling loop reads them: per meshlet (original index) the
    /// range of its boxes, `offsets[m]..offsets[m + 1]`, and the boxes (both empty without
    /// boxes).
    pub fn any_pose_boxes(&self) -> (&[u32], &[PoseBox]) {
        (&self.box_offsets, &self.boxes)
    }

    /// A culler with the any-pose boxes alone (its meshlets get bounds that never cull, class
    /// "none"): for [`MeshletCuller::prepare_boxes_only`] where no other bounds exist.
    pub fn from_any_pose(boxes: &AnyPoseBoxes, joints: usize) -> crate::Result<MeshletCuller> {
        let none = MeshletBounds {
            joint: 0,
            center: Vec3::ZERO,
            radius: 0.0,
            rest_radius: 0.0,
            cone_axis: Vec3::Z,
            cone_angle: std::f32::consts::PI,
            rest_cone_angle: std::f32::consts::PI,
        };
        let n = boxes.len();
        MeshletCuller::new(&vec![none; n], &vec![Class::None; n], joints.max(1))?.with_any_pose(boxes)
    }

    /// The culler with `boxes` (built for the same meshlets and joints) tested by frames
    /// prepared with [`MeshletCuller::prepare_with_boxes`] or
    /// [`MeshletCuller::prepare_boxes_only`]. Errors when [`AnyPoseBoxes::check`] refuses
    /// them for this culler's meshlets and joints.
    pub fn with_any_pose(mut self, boxes: &AnyPoseBoxes) -> crate::Result<MeshletCuller> {
        boxes.check(self.len(), self.joints())?;
        self.box_offsets = boxes.offsets.clone();
        self.boxes = (boxes.joints.iter().zip(&boxes.center).zip(&boxes.half))
            .map(|((&joint, &c), &h)| PoseBox {
                joint: joint as u32,
                center: c.to_array(),
                half: h.to_array(),
                magnitude: (c.abs() + h).element_sum() * (1.0 + 1e-6),
            })
            .collect();
        Ok(self)
    }

    /// Where the box around all group spheres, moved by the joint matrices, lies relative to
    /// the frustum (with a rounding margin of 1e-5 of the magnitudes involved).
    fn instance_side(&self, joint_to_world: &[Affine3A], camera: &Camera) -> Group {
        let b = self.instance.update(joint_to_world);
        let (c, h) = ((b.min + b.max) / 2.0, (b.max - b.min) / 2.0);
        if !(c.is_finite() && h.is_finite()) || self.instance.joints.is_empty() {
            return Group::Straddles;
        }
        let mut inside = true;
        for p in &camera.planes {
            let n = p.truncate();
            let (d, e) = (n.dot(c) + p.w, n.abs().dot(h));
            let margin = 1e-5 * (n.abs().dot(c.abs()) + e + p.w.abs());
            if d + e + margin < 0.0 {
                return Group::Outside;
            }
            inside &= d - e - margin > 0.0;
        }
        if inside { Group::Inside } else { Group::Straddles }
    }

    /// Every meshlet as [`MeshletCuller::cull`] reads it, in its slot order (grouped by joint).
    pub fn slots(&self) -> Vec<CullSlot> {
        let mut joint_of = vec![0u32; self.len()];
        for j in 0..self.joints() {
            joint_of[self.groups[j] as usize..self.groups[j + 1] as usize].fill(j as u32);
        }
        (0..self.len())
            .map(|i| CullSlot {
                center: Vec3::new(self.cx[i], self.cy[i], self.cz[i]),
                radius: self.r[i],
                axis: Vec3::new(self.ax[i], self.ay[i], self.az[i]),
                sin: self.sin[i],
                frustum_ok: self.frustum_ok[i] == 1,
                joint: joint_of[i],
                id: self.ids[i],
            })
            .collect()
    }

    /// Culls every meshlet of one instance: appends the original indices of the visible ones
    /// to `visible` and returns the counts (meshlets the any-pose boxes cull count as
    /// frustum-culled). `frame` comes from one of the `prepare` methods. `flags` is scratch
    /// space (one byte per meshlet), reused across calls.
    pub fn cull(&self, frame: &JointFrame, flags: &mut Vec<u8>, visible: &mut Vec<u32>) -> CullCounts {
        flags.clear();
        flags.resize(self.len(), 0);
        let (do_frustum, do_back) = (frame.tests != Tests::Backface, frame.tests != Tests::Frustum);
        // A frame of another joint count (another culler's): the joints both have are tested,
        // the meshlets of the others kept.
        for j in 0..frame.planes.len().min(self.joints()) {
            let (lo, hi) = (self.groups[j] as usize, self.groups[j + 1] as usize);
            if lo < hi {
                let back = do_back && frame.sign[j] != 0.0;
                let f = &mut flags[lo..hi];
                match (do_frustum, frame.group[j]) {
                    (true, Group::Outside) => {
                        f.iter_mut().zip(&self.frustum_ok[lo..hi]).for_each(|(f, &ok)| *f = ok);
                        if back {
                            self.backface(frame, j, lo, f);
                        }
                    }
                    (true, Group::Straddles) => self.frustum_and_backface(frame, j, lo, f, back),
                    _ if back => self.backface(frame, j, lo, f),
                    _ => {}
                }
            }
        }
        if frame.any_pose && do_frustum && !self.boxes.is_empty() {
            for (f, &id) in flags.iter_mut().zip(&self.ids) {
                if *f == 0 && self.boxes_outside(frame, id as usize) {
                    *f = 1;
                }
            }
        }
        let mut counts = CullCounts { meshlets: self.len(), ..CullCounts::default() };
        // Branch-free compaction: every id is written, the end moves past the visible ones
        // (a branch per meshlet mispredicts on the mixed flags of a typical frame).
        let start = visible.len();
        visible.resize(start + flags.len(), 0);
        let mut end = start;
        for (&fl, &id) in flags.iter().zip(&self.ids) {
            visible[end] = id;
            end += (fl == 0) as usize;
            counts.frustum += (fl & 1) as usize;
            counts.backface += (fl == 2) as usize;
        }
        visible.truncate(end);
        counts.visible = counts.meshlets - counts.frustum - counts.backface;
        counts
    }

    /// Flags of one joint's meshlets: bit 0 when the sphere is outside a plane, bit 1 (with
    /// `back`) when every point of the sphere sees every normal of the cone from behind. One
    /// branch-free pass (the compiler vectorizes it over meshlets).
    fn frustum_and_backface(&self, frame: &JointFrame, j: usize, lo: usize, flags: &mut [u8], back: bool) {
        let n = flags.len();
        let (cx, cy, cz, r) = (&self.cx[lo..lo + n], &self.cy[lo..lo + n], &self.cz[lo..lo + n], &self.r[lo..lo + n]);
        let ok = &self.frustum_ok[lo..lo + n];
        let (p, l, m) = (&frame.planes[j], &frame.len[j], frame.margin[j]);
        for i in 0..n {
            let (x, y, z, ri) = (cx[i], cy[i], cz[i], r[i]);
            let mut dmin = f32::INFINITY;
            for k in 0..6 {
                dmin = dmin.min(p[k][0] * x + p[k][1] * y + p[k][2] * z + p[k][3] + ri * l[k]);
            }
            flags[i] = ((dmin + m < 0.0) as u8) & ok[i];
        }
        if back {
            self.backface(frame, j, lo, flags);
        }
    }

    /// Sets bit 1 of each flag when every point of the meshlet's sphere sees every normal of
    /// its cone from behind (joint space, eye or direction moved there by `prepare`).
    fn backface(&self, frame: &JointFrame, j: usize, lo: usize, flags: &mut [u8]) {
        let n = flags.len();
        let (cx, cy, cz, r) = (&self.cx[lo..lo + n], &self.cy[lo..lo + n], &self.cz[lo..lo + n], &self.r[lo..lo + n]);
        let (ax, ay, az, sin) =
            (&self.ax[lo..lo + n], &self.ay[lo..lo + n], &self.az[lo..lo + n], &self.sin[lo..lo + n]);
        let (v, sign, bm) = (frame.view[j], frame.sign[j], frame.backface_margin[j]);
        if frame.orthographic {
            for i in 0..n {
                let away = sign * (v.x * ax[i] + v.y * ay[i] + v.z * az[i]) >= sin[i] + bm;
                flags[i] |= (away as u8) << 1;
            }
        } else {
            for i in 0..n {
                let (dx, dy, dz, s) = (cx[i] - v.x, cy[i] - v.y, cz[i] - v.z, sin[i]);
                // along ≥ |d|·sin + r·(1 + sin) + margin, squared when the left side is positive.
                let lhs = sign * (dx * ax[i] + dy * ay[i] + dz * az[i]) - r[i] * (1.0 + s) - bm;
                let away = (lhs >= 0.0) & (lhs * lhs >= (dx * dx + dy * dy + dz * dz) * s * s);
                flags[i] |= (away as u8) << 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DMat4, DQuat, DVec3, DVec4};
    use proptest::prelude::*;

    /// The cofactor matrix `det(A)·A⁻ᵀ` (columns `b×c, c×a, a×b`): face normals move by it.
    fn cofactor(a: &DMat3) -> DMat3 {
        DMat3::from_cols(a.y_axis.cross(a.z_axis), a.z_axis.cross(a.x_axis), a.x_axis.cross(a.y_axis))
    }

    fn unit(v: [f64; 3]) -> DVec3 {
        let v = DVec3::from(v);
        if v.length() < 1e-3 { DVec3::X } else { v.normalize() }
    }

    /// A random joint matrix: rotation, non-uniform (possibly negative, possibly tiny)
    /// scale, shear, translation.
    fn joint(r: [f64; 3], angle: f64, scale: [f64; 3], shear: f64, t: [f64; 3]) -> Affine3A {
        let mut a = DMat3::from_quat(DQuat::from_axis_angle(unit(r), angle)) * DMat3::from_diagonal(DVec3::from(scale));
        a.x_axis.y += shear;
        Affine3A::from_mat3_translation(a.as_mat3(), DVec3::from(t).as_vec3())
    }

    fn culled(b: MeshletBounds, g: Affine3A, cam: &Camera) -> u8 {
        let c = MeshletCuller::new(&[b], &[Class::Both], 1).unwrap();
        let mut frame = JointFrame::default();
        c.prepare(&[g], cam, Tests::Both, &mut frame);
        let (mut flags, mut visible) = (Vec::new(), Vec::new());
        c.cull(&frame, &mut flags, &mut visible);
        flags[0]
    }

    #[test]
    fn a_frame_of_another_joint_count_never_panics_nor_culls_wrongly() {
        // A meshlet behind the camera on joint 0 of a one-joint culler, culled with frames
        // prepared for three joints and for none.
        let b = MeshletBounds {
            joint: 0,
            center: Vec3::new(0.0, 0.0, 10.0),
            radius: 1.0,
            rest_radius: 1.0,
            cone_axis: Vec3::Z,
            cone_angle: 0.1,
            rest_cone_angle: 0.1,
        };
        let one = MeshletCuller::new(&[b], &[Class::Both], 1).unwrap();
        let three = MeshletCuller::new(&[b, b, b], &[Class::Both; 3], 3).unwrap();
        let cam = Camera::perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 1.0, 1.0, 0.1, 100.0).unwrap();
        let (mut flags, mut visible) = (Vec::new(), Vec::new());
        let mut frame = JointFrame::default();
        three.prepare(&[Affine3A::IDENTITY; 3], &cam, Tests::Both, &mut frame);
        one.cull(&frame, &mut flags, &mut visible);
        assert_eq!(flags, [1], "the same joint 0: culled");
        one.prepare(&[], &cam, Tests::Both, &mut frame);
        one.cull(&frame, &mut flags, &mut visible);
        assert_eq!((flags.as_slice(), visible.as_slice()), (&[0][..], &[0][..]), "nothing known: kept");
    }

    /// A camera of one of glam's projections (`kind`, see `camera::glam_camera`) at `eye`
    /// looking at `target`; `None` where no view exists (eye at the target or looking along
    /// the up axis).
    fn camera(kind: usize, eye: [f64; 3], target: [f64; 3]) -> Option<crate::camera::GlamCamera> {
        crate::camera::glam_camera(kind, DVec3::from(eye).as_vec3(), DVec3::from(target).as_vec3())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

        /// Whatever the joint matrix and camera (every projection glam builds, also far from
        /// the origin): when the frustum test culls, every sampled point of the moved sphere
        /// (random surface points and each plane's extreme point) is outside one plane, and
        /// outside the clip volume of the matrix glam built; when the backface test culls, every
        /// sampled point sees every sampled normal of the moved cone (moved by cof(A)) from
        /// behind.
        #[test]
        fn culls_only_what_brute_force_confirms(
            c in prop::array::uniform3(-2.0f64..2.0), radius in 0.0f64..1.5,
            a in prop::array::uniform3(-1.0f64..1.0), angle in 0.0f64..1.5,
            r in prop::array::uniform3(-1.0f64..1.0), rot in -3.1f64..3.1,
            scale in prop::array::uniform3(prop_oneof![0.3f64..3.0, -3.0f64..-0.3, -0.01f64..0.01]),
            shear in -1.0f64..1.0, t in prop::array::uniform3(-6.0f64..6.0),
            kind in 0..crate::camera::GLAM_KINDS, eye in prop::array::uniform3(-12.0f64..12.0),
            target in prop::array::uniform3(-3.0f64..3.0),
            samples in prop::collection::vec((prop::array::uniform3(-1.0f64..1.0), 0.0f64..1.0, 0.0f64..6.3), 48),
            far in prop_oneof![Just([0.0; 3]), prop::array::uniform3(-1e5f64..1e5)],
        ) {
            // Game worlds: the joint and the camera may both be far from the origin.
            let (t, eye, target) = ([0, 1, 2].map(|i| t[i] + far[i]), [0, 1, 2].map(|i| eye[i] + far[i]),
                [0, 1, 2].map(|i| target[i] + far[i]));
            let axis = unit(a);
            let b = MeshletBounds {
                joint: 0, center: DVec3::from(c).as_vec3(), radius: radius as f32, rest_radius: radius as f32,
                cone_axis: axis.as_vec3(), cone_angle: angle as f32, rest_cone_angle: angle as f32,
            };
            let g = joint(r, rot, scale, shear, t);
            let Some(glam) = camera(kind, eye, target) else { return Ok(()) };
            let cam = glam.camera;
            let flags = culled(b, g, &cam);
            let gd = dmat(&g);
            let a3 = DMat3::from_mat4(gd);
            let center = DVec3::from(c);
            let mut points: Vec<DVec3> = samples.iter().map(|(d, _, _)| center + unit(*d) * radius).collect();
            for p in &cam.planes {
                let n = a3.transpose() * p.truncate().as_dvec3();
                points.push(center - n.normalize_or_zero() * radius);
            }
            let world: Vec<DVec3> = points.iter().map(|&p| gd.transform_point3(p)).collect();
            if flags & 1 != 0 {
                let out = cam.planes.iter().any(|p| {
                    world.iter().all(|q| p.truncate().as_dvec3().dot(*q) + p.w as f64 <= 1e-9)
                });
                prop_assert!(out, "frustum-culled, but a point of the sphere is inside");
                let depth = world.iter().map(|&q| glam.clip_depth(q)).fold(f64::NEG_INFINITY, f64::max);
                prop_assert!(depth <= 1e-6, "{}: frustum-culled, but a point is {depth} inside the clip volume", glam.name);
            }
            if flags & 2 != 0 {
                let m = cofactor(&a3);
                let perp = axis.any_orthonormal_vector();
                for (i, (_, phi, turn)) in samples.iter().enumerate() {
                    let n = DQuat::from_axis_angle(axis, *turn) * (DQuat::from_axis_angle(perp, phi * angle) * axis);
                    let nw = m * n;
                    let facing = match cam.projection {
                        Projection::Perspective { eye } => (world[i] - eye.as_dvec3()).dot(nw),
                        Projection::Orthographic { dir } => dir.as_dvec3().dot(nw),
                    };
                    prop_assert!(facing >= -1e-9 * nw.length(), "backface-culled, but a normal faces the eye");
                }
            }
        }
    }

    /// The f32 joint matrix in f64.
    fn dmat(g: &Affine3A) -> DMat4 {
        DMat4::from_cols(
            DVec4::from((Vec3::from(g.matrix3.x_axis).as_dvec3(), 0.0)),
            DVec4::from((Vec3::from(g.matrix3.y_axis).as_dvec3(), 0.0)),
            DVec4::from((Vec3::from(g.matrix3.z_axis).as_dvec3(), 0.0)),
            DVec4::from((Vec3::from(g.translation).as_dvec3(), 1.0)),
        )
    }

    /// One meshlet with one any-pose box (and bounds that never cull) for joint `g`.
    fn box_culled(c: Vec3, h: Vec3, g: Affine3A, cam: &Camera) -> bool {
        let boxes = AnyPoseBoxes { offsets: vec![0, 1], joints: vec![0], center: vec![c], half: vec![h] };
        let culler = MeshletCuller::from_any_pose(&boxes, 1).unwrap();
        let mut frame = JointFrame::default();
        culler.prepare_boxes_only(&[g], cam, Tests::Both, &mut frame);
        let mut visible = Vec::new();
        culler.cull(&frame, &mut Vec::new(), &mut visible);
        visible.is_empty()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

        /// Whatever the joint matrix and camera: a box the any-pose test culls has its eight
        /// moved corners (f64) outside one plane; and a box whose moved corners are all well
        /// outside one plane (1e-3 of the magnitudes) is culled: the test is exact up to its
        /// rounding margin, not Arvo's looser world box.
        #[test]
        fn any_pose_box_test_is_exact(
            c in prop::array::uniform3(-2.0f64..2.0), h in prop::array::uniform3(0.0f64..1.0),
            r in prop::array::uniform3(-1.0f64..1.0), rot in -3.1f64..3.1,
            scale in prop::array::uniform3(prop_oneof![0.3f64..3.0, -3.0f64..-0.3, -0.01f64..0.01]),
            shear in -1.0f64..1.0, t in prop::array::uniform3(-6.0f64..6.0),
            kind in 0..crate::camera::GLAM_KINDS, eye in prop::array::uniform3(-12.0f64..12.0),
            target in prop::array::uniform3(-3.0f64..3.0),
        ) {
            let g = joint(r, rot, scale, shear, t);
            let Some(cam) = camera(kind, eye, target).map(|g| g.camera) else { return Ok(()) };
            let (c, h) = (DVec3::from(c).as_vec3(), DVec3::from(h).as_vec3());
            let gd = dmat(&g);
            let corners: Vec<DVec3> = (0..8)
                .map(|i| {
                    let s = DVec3::new([-1.0, 1.0][i & 1], [-1.0, 1.0][(i >> 1) & 1], [-1.0, 1.0][i >> 2]);
                    gd.transform_point3(c.as_dvec3() + s * h.as_dvec3())
                })
                .collect();
            let scale = corners.iter().map(|p| p.abs().max_element()).fold(1.0, f64::max);
            let beyond = |by: f64| cam.planes.iter().any(|p| {
                corners.iter().all(|q| p.truncate().as_dvec3().dot(*q) + p.w as f64 <= by)
            });
            let culled = box_culled(c, h, g, &cam);
            prop_assert!(!culled || beyond(1e-9 * scale), "culled, but a corner of the moved box is inside");
            prop_assert!(culled || !beyond(-1e-3 * scale), "kept, but every corner is well outside one plane");
        }
    }

    #[test]
    fn joints_from_skinning_undo_the_inverse_bind() {
        let g = [joint([0.3, 1.0, 0.2], 0.7, [1.0, 2.0, -1.0], 0.3, [1.0, 2.0, 3.0]), Affine3A::IDENTITY];
        let ibm = [
            joint([1.0, 0.0, 0.0], 1.1, [0.5, 0.5, 0.5], 0.0, [0.0, -1.0, 0.0]),
            joint([0.0, 1.0, 0.0], 0.2, [1.0; 3], 0.0, [2.0; 3]),
        ];
        let model = Affine3A::from_translation(Vec3::new(5.0, 0.0, -2.0));
        let skinning: Vec<Affine3A> = g.iter().zip(&ibm).map(|(g, i)| *g * *i).collect();
        let bind: Vec<Affine3A> = ibm.iter().map(|m| m.inverse()).collect();
        let mut out = Vec::new();
        joints_from_skinning(&model, &skinning, &bind, &mut out);
        for (o, g) in out.iter().zip(&g) {
            let want = model * *g;
            assert!(
                o.to_cols_array().iter().zip(want.to_cols_array()).all(|(a, b)| (a - b).abs() < 1e-5),
                "{o:?} {want:?}"
            );
        }
    }

    #[test]
    fn culls_often_enough_to_matter() {
        // Facing away from a camera in front: culled by the backface test; behind it: by the
        // frustum; facing it: kept. Also through a mirroring joint matrix.
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 1.0, 0.1, 100.0).unwrap();
        let b = |axis: Vec3, center: Vec3| MeshletBounds {
            joint: 0,
            center,
            radius: 0.5,
            rest_radius: 0.5,
            cone_axis: axis,
            cone_angle: 0.3,
            rest_cone_angle: 0.3,
        };
        assert_eq!(culled(b(-Vec3::Z, Vec3::ZERO), Affine3A::IDENTITY, &cam), 2);
        assert_eq!(culled(b(Vec3::Z, Vec3::ZERO), Affine3A::IDENTITY, &cam), 0);
        assert_eq!(culled(b(-Vec3::Z, Vec3::new(0.0, 0.0, 20.0)), Affine3A::IDENTITY, &cam), 1);
        // Mirrored in x, a triangle in the xy plane keeps its place but reverses its winding:
        // its face normal flips from -z to +z (facing the eye): kept.
        let mirror = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        assert_eq!(culled(b(-Vec3::Z, Vec3::ZERO), mirror, &cam), 0);
        assert_eq!(culled(b(Vec3::Z, Vec3::ZERO), mirror, &cam), 2);
        // A zero scale: no backface culling (the frustum test still works).
        let flat = Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(culled(b(-Vec3::Z, Vec3::ZERO), flat, &cam), 0);
    }

    #[test]
    fn backface_test_culls_most_of_the_region_it_may() {
        // Eyes all around a meshlet at distance 10, looking at it: culled from behind only.
        // The exact region is the cap within 90° − α − asin(r/d) of −axis; the test's is a
        // bit smaller but not much.
        let b = MeshletBounds {
            joint: 0,
            center: Vec3::ZERO,
            radius: 0.5,
            rest_radius: 0.5,
            cone_axis: Vec3::Z,
            cone_angle: 0.3,
            rest_cone_angle: 0.3,
        };
        let dirs = 2000;
        let culled = (0..dirs)
            .filter(|&i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / dirs as f32;
                let phi = i as f32 * 2.399963;
                let e = Vec3::new((1.0 - z * z).sqrt() * phi.cos(), (1.0 - z * z).sqrt() * phi.sin(), z) * 10.0;
                let up = if z.abs() > 0.9 { Vec3::X } else { Vec3::Z };
                let cam = Camera::perspective(e, Vec3::ZERO, up, 1.0, 1.0, 0.1, 100.0).unwrap();
                culled(b, Affine3A::IDENTITY, &cam) == 2
            })
            .count();
        let exact_cap = (1.0 - (std::f64::consts::FRAC_PI_2 - 0.3 - 0.05f64.asin()).cos()) / 2.0;
        let share = culled as f64 / dirs as f64;
        assert!(share > 0.8 * exact_cap && share <= exact_cap + 0.01, "culled {share}, exact {exact_cap}");
    }
}
