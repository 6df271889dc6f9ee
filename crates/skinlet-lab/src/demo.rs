//! The built-in demo character: a deterministic, procedurally built four-legged creature
//! (33 joints: hips, spine, belly, neck, head, jaw, ears, a six-joint tail and four legs of
//! four joints) skinned by one capsule per bone with soft 1-to-4-influence weights, and three
//! clips that together use every interpolation mode and the awkward cases of glTF animation:
//! a near-180° turn between two keys, a spin past a full turn, non-uniform scale, STEP jumps
//! and cubic-spline tangents. It is the test and benchmark input when no file is at hand:
//! the same [`DemoParams`] always give the same [`Asset`], the body at the triangle count
//! asked for.
//!
//! It is a whole character, as real files are: besides the body (mesh 0, skin 0) it has a
//! collar around the neck (mesh 1, a second skin listing its joints in another order), a
//! rigid anklet under the waving front foot's ankle joint (mesh 2), a propeller on the head,
//! a non-joint node every clip spins (mesh 3), and one eye mesh drawn by two nodes (mesh 4).
//! Its face is morph targets on the body, as in most exported characters: "cheeks" puffs the
//! head out along its normals, "mouth" drops and opens the jaw (with normal deltas); default
//! weights 0.25 and 0, and every clip animates both in its own interpolation mode.

use glam::{DMat4, Mat4, Quat, Vec3, Vec4};
use skinlet::clip::{Channel, Clip, Interpolation, WeightChannel};
use skinlet::model::{
    Asset, Influences, Instance, Mesh, MorphTarget, Node, Primitive, Skeleton, Skin, SkinnedMesh, Trs,
};
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// What to build: `seed` varies the proportions, `triangles` is the mesh size (±10%).
#[derive(Clone, Copy, Debug)]
pub struct DemoParams {
    pub seed: u64,
    pub triangles: usize,
}

impl Default for DemoParams {
    fn default() -> Self {
        DemoParams { seed: 7, triangles: 20_000 }
    }
}

/// Fraction of a bone's length, at each end, over which its vertices blend with neighbours.
const BLEND: f32 = 0.3;
/// Share of a blend each joint of a chain passes on to the next (parent to grandparent, ...).
const FALLOFF: f32 = 0.35;
/// Weights below this are dropped before normalizing.
const MIN_WEIGHT: f32 = 1e-4;
/// Time step of the finite differences that give cubic-spline tangents.
const SLOPE_DT: f32 = 1e-3;

/// The non-joint nodes after the joints: (name, parent joint, offset in the parent's space).
const EXTRA_NODES: [(&str, &str, Vec3); 6] = [
    ("body", "root", Vec3::ZERO),
    ("collar", "root", Vec3::ZERO),
    ("anklet", "front_r_ankle", Vec3::new(0.0, 0.05, 0.0)),
    ("propeller", "head", Vec3::new(0.0, 0.2, 0.05)),
    ("eye_l", "head", Vec3::new(0.07, 0.08, 0.25)),
    ("eye_r", "head", Vec3::new(-0.07, 0.08, 0.25)),
];

/// Builds the demo character: skeleton, two skins, five meshes drawn by six nodes, and three
/// clips.
pub fn demo_character(params: &DemoParams) -> Asset {
    let rig = Rig::build(params.seed);
    let mut nodes = rig.nodes();
    let joints = nodes.len() as u32;
    for (name, parent, offset) in EXTRA_NODES {
        let parent = rig.id(parent) as u32;
        let rest = Trs { translation: offset, ..Trs::IDENTITY };
        nodes.push(Node { name: name.into(), parent: Some(parent), rest, matrix: None });
    }
    let node = |name: &str| joints + EXTRA_NODES.iter().position(|e| e.0 == name).expect("a demo node") as u32;
    let skeleton = Skeleton::new(nodes).expect("the demo hierarchy is a tree");
    let rest: Vec<Trs> = skeleton.nodes.iter().map(|n| n.rest).collect();
    let mut globals = Vec::new();
    skinlet::pose::global_transforms(&skeleton, &rest, &mut globals);
    let inverse_bind = |j: u32| globals[j as usize].inverse().as_mat4();
    let skin = Skin {
        name: "demo_skin".into(),
        joints: (0..joints).collect(),
        inverse_bind: (0..joints).map(inverse_bind).collect(),
    };
    let body = build_mesh(&rig, &globals, params.triangles);
    let segments = ((params.triangles as f64 / (2 * rig.bones.len()) as f64).sqrt().round() as usize).clamp(6, 48);
    let (collar, collar_joints) = collar(&rig, &globals, segments);
    let collar_skin = Skin {
        name: "collar_skin".into(),
        inverse_bind: collar_joints.iter().map(|&j| inverse_bind(j)).collect(),
        joints: collar_joints,
    };
    let one = |name: &str, geometry| Mesh {
        name: name.into(),
        primitives: vec![Primitive { index: 0, geometry, targets: Vec::new() }],
        weights: Vec::new(),
    };
    let face = face_targets(&rig, &body);
    let meshes = vec![
        Mesh {
            name: "demo_creature".into(),
            primitives: vec![Primitive { index: 0, geometry: body, targets: face }],
            weights: vec![0.25, 0.0],
        },
        one("collar", collar),
        one("anklet", rigid_box(Vec3::new(0.075, 0.03, 0.075))),
        one("propeller", rigid_box(Vec3::new(0.22, 0.01, 0.03))),
        one("eye", rigid_box(Vec3::splat(0.025))),
    ];
    let instances = vec![
        Instance { node: node("body"), mesh: 0, skin: Some(0) },
        Instance { node: node("collar"), mesh: 1, skin: Some(1) },
        Instance { node: node("anklet"), mesh: 2, skin: None },
        Instance { node: node("propeller"), mesh: 3, skin: None },
        Instance { node: node("eye_l"), mesh: 4, skin: None },
        Instance { node: node("eye_r"), mesh: 4, skin: None },
    ];
    let mut clips = vec![walk(&rig), twitch(&rig), wave(&rig)];
    // The propeller spins and the face moves in every clip, in each clip's interpolation mode.
    for c in &mut clips {
        let k = keys(c.interpolations()[0], 9, c.duration() / 8.0);
        c.rotations.push(channel(node("propeller") as usize, &k, |t| Quat::from_rotation_y(3.0 * t)));
        let d = c.duration();
        let cheeks = channel(node("body") as usize, &k, |t| 0.5 - 0.5 * (TAU * t / d).cos());
        let mouth = channel(node("body") as usize, &k, |t| (PI * t / d).sin().powi(2));
        c.weights.extend([WeightChannel { target: 0, channel: cheeks }, WeightChannel { target: 1, channel: mouth }]);
    }
    Asset { skeleton, skins: vec![skin, collar_skin], meshes, instances, clips, ..Asset::default() }
}

/// The face's morph targets on the body: "cheeks" moves the vertices that follow the head
/// most 4 cm out along their normals; "mouth" moves those that follow the jaw most 5 cm down
/// and 2 cm forward in the jaw's bind frame and tilts their normals forward.
fn face_targets(rig: &Rig, body: &SkinnedMesh) -> Vec<MorphTarget> {
    let inf = body.influences.as_ref().expect("the body is skinned");
    let (head, jaw) = (rig.id("head") as u16, rig.id("jaw") as u16);
    let follows = |v: usize, j: u16| inf.strongest(v).is_some_and(|(strongest, _)| strongest == j);
    let n = body.positions.len();
    let normal = |v: usize| body.normals.get(v).copied().unwrap_or(Vec3::ZERO);
    let cheeks = (0..n).map(|v| if follows(v, head) { 0.04 * normal(v) } else { Vec3::ZERO }).collect();
    let mouth = (0..n).map(|v| if follows(v, jaw) { Vec3::new(0.0, -0.05, 0.02) } else { Vec3::ZERO }).collect();
    let tilt = (0..n).map(|v| if follows(v, jaw) { Vec3::new(0.0, 0.0, 0.3) } else { Vec3::ZERO }).collect();
    vec![MorphTarget { positions: cheeks, normals: Vec::new() }, MorphTarget { positions: mouth, normals: tilt }]
}

/// A collar: a capsule around the neck bone, 1.35 times its radius, skinned like the body there
/// but by its own skin, whose joints are the ones it uses in descending node order. Returns the
/// mesh (joint numbers index that skin) and the skin's joints.
fn collar(rig: &Rig, globals: &[DMat4], segments: usize) -> (SkinnedMesh, Vec<u32>) {
    let neck = rig.id("neck");
    let mut mesh =
        SkinnedMesh { influences: Some(Influences { stride: 4, ..Default::default() }), ..Default::default() };
    add_capsule(&mut mesh, rig, neck, 1.35, segments / 2 + 2, segments, globals[neck].as_mat4());
    let inf = mesh.influences.as_mut().expect("skinned");
    let mut used: Vec<u32> =
        (0..inf.vertex_count()).flat_map(|v| inf.of(v).map(|(j, _)| j as u32).collect::<Vec<_>>()).collect();
    used.sort_unstable_by(|a, b| b.cmp(a));
    used.dedup();
    for (k, j) in inf.joints.iter_mut().enumerate() {
        if inf.weights[k] != 0.0 {
            *j = used.iter().position(|u| *u == *j as u32).expect("a used joint") as u16;
        }
    }
    (mesh, used)
}

/// An axis-aligned box of half extents `half` around its node's origin, flat-shaded
/// (24 vertices, 12 triangles wound counter-clockwise outside), not skinned.
fn rigid_box(half: Vec3) -> SkinnedMesh {
    let mut mesh = SkinnedMesh::default();
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let n = Vec3::from_array(std::array::from_fn(|i| if i == axis { sign } else { 0.0 }));
            let (u, v) = (n.any_orthonormal_pair().0, n.any_orthonormal_pair().1);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push((n + u * a + v * b) * half);
                mesh.normals.push(n);
            }
            // u × v = n for glam's orthonormal pair, so (0, 1, 2) winds counter-clockwise about n.
            mesh.triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        }
    }
    mesh
}

/// splitmix64: tiny and well mixed, plenty for jittering proportions.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let z = (self.0 ^ (self.0 >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        let z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub(crate) fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A factor uniform in [1 - amount, 1 + amount].
    fn jitter(&mut self, amount: f32) -> f32 {
        1.0 + amount * (2.0 * self.unit() - 1.0)
    }
}

/// One joint in the rest pose, in model space. Its bone runs along the joint's local +Y.
struct Bone {
    name: String,
    parent: Option<usize>,
    /// The first child that starts at this bone's tip: the chain continues through it.
    next: Option<usize>,
    pos: Vec3,
    rot: Quat,
    length: f32,
    radius: f32,
}

struct Rig {
    bones: Vec<Bone>,
    rng: Rng,
}

impl Rig {
    fn build(seed: u64) -> Rig {
        let mut rig = Rig { bones: Vec::new(), rng: Rng(seed) };
        let v = Vec3::new;
        let root = rig.add("root", None, Some(Vec3::ZERO), Vec3::Y, 0.0, 0.0);
        let hips = rig.add("hips", Some(root), Some(v(0.0, 1.0, -0.45)), v(0.0, 0.05, 1.0), 0.3, 0.26);
        let spine0 = rig.add("spine0", Some(hips), None, v(0.0, 0.05, 1.0), 0.3, 0.28);
        let spine1 = rig.add("spine1", Some(spine0), None, v(0.0, 0.05, 1.0), 0.3, 0.3);
        let chest = rig.add("chest", Some(spine1), None, v(0.0, 0.15, 1.0), 0.28, 0.29);
        let neck = rig.add("neck", Some(chest), None, v(0.0, 0.9, 0.6), 0.32, 0.13);
        let head = rig.add("head", Some(neck), None, v(0.0, 0.15, 1.0), 0.32, 0.16);
        rig.add("jaw", Some(head), Some(v(0.0, -0.09, 0.06)), v(0.0, -0.35, 1.0), 0.28, 0.07);
        rig.add("ear_l", Some(head), Some(v(0.09, 0.12, 0.08)), v(0.5, 1.0, -0.3), 0.16, 0.04);
        rig.add("ear_r", Some(head), Some(v(-0.09, 0.12, 0.08)), v(-0.5, 1.0, -0.3), 0.16, 0.04);
        rig.add("belly", Some(spine1), Some(v(0.0, -0.12, -0.1)), v(0.0, -0.1, 1.0), 0.25, 0.22);
        let mut tail = rig.add("tail0", Some(hips), Some(v(0.0, 0.08, -0.2)), v(0.0, 0.5, -1.0), 0.16, 0.09);
        for i in 1..6 {
            let dir = v(0.0, 0.5 - 0.2 * i as f32, -1.0);
            tail = rig.add(&format!("tail{i}"), Some(tail), None, dir, 0.16, 0.09 - 0.011 * i as f32);
        }
        const LEG: [(&str, Vec3, f32, f32); 4] = [
            ("upper", Vec3::new(0.08, -1.0, 0.25), 0.36, 0.1),
            ("lower", Vec3::new(0.0, -1.0, -0.3), 0.32, 0.075),
            ("ankle", Vec3::new(0.0, -1.0, 0.1), 0.16, 0.055),
            ("foot", Vec3::new(0.0, -0.25, 1.0), 0.15, 0.05),
        ];
        for (side, x) in [("l", 1.0), ("r", -1.0)] {
            for (end, hip) in [("front", chest), ("back", hips)] {
                let mut parent = hip;
                for (i, &(part, dir, length, radius)) in LEG.iter().enumerate() {
                    let start = (i == 0).then_some(v(0.2 * x, -0.12, 0.1));
                    let name = format!("{end}_{side}_{part}");
                    parent = rig.add(&name, Some(parent), start, dir * v(x, 1.0, 1.0), length, radius);
                }
            }
        }
        rig
    }

    /// Adds a joint at `start` (offset from the parent joint, in model space) or, when `None`,
    /// at the parent's tip. The seed jitters its length and radius by up to 8%.
    fn add(&mut self, name: &str, parent: Option<usize>, start: Option<Vec3>, dir: Vec3, len: f32, r: f32) -> usize {
        let id = self.bones.len();
        let pos = match (parent, start) {
            (Some(p), None) => {
                self.bones[p].next.get_or_insert(id);
                self.bones[p].pos + self.bones[p].rot * Vec3::Y * self.bones[p].length
            }
            (p, offset) => p.map_or(Vec3::ZERO, |p| self.bones[p].pos) + offset.unwrap_or_default(),
        };
        let (length, radius) = (len * self.rng.jitter(0.08), r * self.rng.jitter(0.08));
        let rot = Quat::from_rotation_arc(Vec3::Y, dir.normalize());
        self.bones.push(Bone { name: name.into(), parent, next: None, pos, rot, length, radius });
        id
    }

    fn id(&self, name: &str) -> usize {
        self.bones.iter().position(|b| b.name == name).expect("a demo joint")
    }

    /// Rest transform of joint `b` relative to its parent.
    fn local(&self, b: usize) -> Trs {
        let bone = &self.bones[b];
        let (pos, rot) = bone.parent.map_or((Vec3::ZERO, Quat::IDENTITY), |p| (self.bones[p].pos, self.bones[p].rot));
        let inv = rot.inverse();
        Trs { translation: inv * (bone.pos - pos), rotation: (inv * bone.rot).normalize(), scale: Vec3::ONE }
    }

    fn nodes(&self) -> Vec<Node> {
        let node = |(b, bone): (usize, &Bone)| Node {
            name: bone.name.clone(),
            parent: bone.parent.map(|p| p as u32),
            rest: self.local(b),
            matrix: None,
        };
        self.bones.iter().enumerate().map(node).collect()
    }

    /// A rotation channel of joint `b`: its rest rotation turned by `angle(t)` radians about
    /// `axis`, an axis in model space (as the rest pose orients it).
    fn turn(&self, b: usize, keys: &Keys, axis: Vec3, angle: impl Fn(f32) -> f32) -> Channel<Quat> {
        let (rest, axis) = (self.local(b).rotation, self.bones[b].rot.inverse() * axis);
        channel(b, keys, |t| rest * Quat::from_axis_angle(axis, angle(t)))
    }
}

/// One capsule per bone in model space. `segments` around every capsule and rings shared out
/// in proportion to profile length: a capsule of `r` rings has `2 * segments * r` triangles.
fn build_mesh(rig: &Rig, globals: &[DMat4], triangles: usize) -> SkinnedMesh {
    let tubes: Vec<usize> = (0..rig.bones.len()).filter(|&b| rig.bones[b].length > 0.0).collect();
    let segments = ((triangles as f64 / (2 * tubes.len()) as f64).sqrt().round() as usize).max(3);
    let total_rings = (triangles as f64 / (2 * segments) as f64).round();
    let profile = |b: usize| f64::from(PI * rig.bones[b].radius + rig.bones[b].length);
    let sum: f64 = tubes.iter().map(|&b| profile(b)).sum();
    let mut mesh =
        SkinnedMesh { influences: Some(Influences { stride: 4, ..Default::default() }), ..Default::default() };
    let (mut covered, mut done) = (0.0, 0);
    for &b in &tubes {
        covered += profile(b);
        let rings = ((total_rings * covered / sum).round() as usize).saturating_sub(done).max(1);
        done += rings;
        add_capsule(&mut mesh, rig, b, 1.0, rings, segments, globals[b].as_mat4());
    }
    mesh
}

/// Appends bone `b`'s capsule (its radius times `widen`): a pole, `rings` rings evenly spaced
/// along the profile (quarter circle, straight side, quarter circle) and the other pole,
/// wound counter-clockwise outside.
fn add_capsule(mesh: &mut SkinnedMesh, rig: &Rig, b: usize, widen: f32, rings: usize, segments: usize, to_model: Mat4) {
    let inf = mesh.influences.as_mut().expect("the demo mesh is skinned");
    let (length, radius) = (rig.bones[b].length, rig.bones[b].radius * widen);
    let first = mesh.positions.len() as u32;
    let full = PI * radius + length;
    for i in 0..rings + 2 {
        let (y, phi) = profile_point(radius, length, full * i as f32 / (rings + 1) as f32);
        let (joints, weights) = ring_influences(rig, b, y / length);
        let count = if i == 0 || i == rings + 1 { 1 } else { segments };
        for k in 0..count {
            let around = TAU * k as f32 / segments as f32;
            let radial = Vec3::new(around.sin(), 0.0, around.cos());
            let local = radial * (radius * phi.cos()) + Vec3::Y * y;
            mesh.positions.push(to_model.transform_point3(local));
            mesh.normals.push(to_model.transform_vector3(radial * phi.cos() + Vec3::Y * phi.sin()).normalize());
            inf.joints.extend(joints);
            inf.weights.extend(weights);
        }
    }
    let ring = |i: usize, k: usize| first + 1 + (i * segments + k % segments) as u32;
    let top = first + 1 + (rings * segments) as u32;
    for k in 0..segments {
        mesh.triangles.push([first, ring(0, k + 1), ring(0, k)]);
        for i in 0..rings - 1 {
            let (a, b, c, d) = (ring(i, k), ring(i, k + 1), ring(i + 1, k + 1), ring(i + 1, k));
            mesh.triangles.extend([[a, b, c], [a, c, d]]);
        }
        mesh.triangles.push([ring(rings - 1, k), ring(rings - 1, k + 1), top]);
    }
}

/// Height and latitude of the capsule profile point at arc length `s` from the bottom pole.
fn profile_point(radius: f32, length: f32, s: f32) -> (f32, f32) {
    let quarter = FRAC_PI_2 * radius;
    if s < quarter {
        let phi = s / radius - FRAC_PI_2;
        (radius * phi.sin(), phi)
    } else if s <= quarter + length {
        (s - quarter, 0.0)
    } else {
        let phi = (s - quarter - length) / radius;
        (length + radius * phi.sin(), phi)
    }
}

/// Weights at height `u` (in bone lengths) along bone `b`: the bone alone mid-way, blending
/// smoothly into its ancestors towards the base and into the chain continuing from its tip
/// towards the tip. Normalized, sorted by decreasing weight (ties by joint), padded to four.
fn ring_influences(rig: &Rig, b: usize, u: f32) -> ([u16; 4], [f32; 4]) {
    let bone = &rig.bones[b];
    let up = if bone.parent.is_some() { smoothstep((BLEND - u) / (2.0 * BLEND)) } else { 0.0 };
    let down = if bone.next.is_some() { smoothstep((u - 1.0 + BLEND) / (2.0 * BLEND)) } else { 0.0 };
    let mut list = vec![(b, 1.0 - up - down)];
    spread(&mut list, std::iter::successors(bone.parent, |&j| rig.bones[j].parent).take(3), up);
    spread(&mut list, std::iter::successors(bone.next, |&j| rig.bones[j].next).take(2), down);
    list.retain(|&(_, w)| w > MIN_WEIGHT);
    let sum: f32 = list.iter().map(|&(_, w)| w).sum();
    list.iter_mut().for_each(|(_, w)| *w /= sum);
    list.sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.cmp(&y.0)));
    debug_assert!(list.len() <= 4, "with BLEND <= 0.5 the base and tip blends never overlap");
    let (mut joints, mut weights) = ([0u16; 4], [0f32; 4]);
    for (slot, &(j, w)) in list.iter().enumerate() {
        (joints[slot], weights[slot]) = (j as u16, w);
    }
    (joints, weights)
}

/// Hands `share` down a chain of joints, each keeping all but `FALLOFF` of what reaches it.
fn spread(list: &mut Vec<(usize, f32)>, chain: impl Iterator<Item = usize>, share: f32) {
    let mut left = share;
    for j in chain {
        list.push((j, left * (1.0 - FALLOFF)));
        left *= FALLOFF;
    }
}

fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Values that can be keyed with a cubic-spline tangent (a time derivative).
trait Tangent: Copy {
    fn slope(before: Self, after: Self, dt: f32) -> Self;
}

impl Tangent for Vec3 {
    fn slope(before: Self, after: Self, dt: f32) -> Self {
        (after - before) / dt
    }
}

impl Tangent for f32 {
    fn slope(before: Self, after: Self, dt: f32) -> Self {
        (after - before) / dt
    }
}

impl Tangent for Quat {
    fn slope(before: Self, after: Self, dt: f32) -> Self {
        Quat::from_vec4((Vec4::from(after) - Vec4::from(before)) / dt)
    }
}

/// The key times and interpolation of a channel.
struct Keys {
    mode: Interpolation,
    times: Vec<f32>,
}

/// `count` keys `dt` apart, starting at 0.
fn keys(mode: Interpolation, count: usize, dt: f32) -> Keys {
    Keys { mode, times: (0..count).map(|k| k as f32 * dt).collect() }
}

/// A channel keyed from `f`; CUBICSPLINE stores [in-tangent, value, out-tangent] per key,
/// both tangents the time derivative of `f`.
fn channel<T: Tangent>(node: usize, keys: &Keys, f: impl Fn(f32) -> T) -> Channel<T> {
    let mut values = Vec::new();
    for &t in &keys.times {
        if keys.mode == Interpolation::CubicSpline {
            let d = T::slope(f(t - SLOPE_DT), f(t + SLOPE_DT), 2.0 * SLOPE_DT);
            values.extend([d, f(t), d]);
        } else {
            values.push(f(t));
        }
    }
    Channel { node: node as u32, interpolation: keys.mode, times: keys.times.clone(), values }
}

/// A clip of the given channels, `start` and `end` taken from their key times.
fn clip(name: &str, moves: Vec<Channel<Vec3>>, turns: Vec<Channel<Quat>>, scales: Vec<Channel<Vec3>>) -> Clip {
    let times = moves.iter().chain(&scales).map(|c| &c.times).chain(turns.iter().map(|c| &c.times));
    let (start, end) = times.fold((f32::INFINITY, f32::NEG_INFINITY), |(s, e), t| (s.min(t[0]), e.max(t[t.len() - 1])));
    Clip { name: name.into(), translations: moves, rotations: turns, scales, weights: Vec::new(), start, end }
}

/// LINEAR, 2 s: a trotting stride, tail wag, bobbing forward root, breathing belly, a 175°
/// head turn between two keys and a tail tip spinning 480° in 120° steps.
fn walk(rig: &Rig) -> Clip {
    let (times, halves) = (keys(Interpolation::Linear, 9, 0.25), keys(Interpolation::Linear, 5, 0.5));
    let phase = |t: f32| TAU * t / 2.0;
    let mut rotations = Vec::new();
    for (leg, offset) in [("front_l", 0.0), ("back_r", 0.0), ("front_r", PI), ("back_l", PI)] {
        let (upper, lower) = (rig.id(&format!("{leg}_upper")), rig.id(&format!("{leg}_lower")));
        rotations.push(rig.turn(upper, &times, Vec3::X, |t| 0.45 * (phase(t) + offset).sin()));
        rotations.push(rig.turn(lower, &times, Vec3::X, |t| 0.3 * (1.0 - (phase(t) + offset).cos())));
    }
    for i in 0..4 {
        let lag = 0.7 * i as f32;
        rotations.push(rig.turn(rig.id(&format!("tail{i}")), &times, Vec3::Y, |t| 0.3 * (phase(t) - lag).sin()));
    }
    let head_degrees = [0.0f32, 0.0, 175.0, 175.0, 0.0];
    let head_turn = |t: f32| head_degrees[(t * 2.0).round() as usize].to_radians();
    rotations.push(rig.turn(rig.id("head"), &halves, Vec3::Y, head_turn));
    let tip = rig.id("tail5");
    let spin = |t: f32| rig.local(tip).rotation * Quat::from_axis_angle(Vec3::Y, (240.0 * t).to_radians());
    rotations.push(channel(tip, &halves, spin));
    let root = channel(0, &times, |t| Vec3::new(0.0, 0.04 * (2.0 * phase(t)).sin(), 0.9 * t));
    let breath = |t: f32| if (t * 2.0).round() as usize % 2 == 1 { Vec3::new(1.15, 0.9, 1.0) } else { Vec3::ONE };
    let belly = channel(rig.id("belly"), &halves, breath);
    clip("walk", vec![root], rotations, vec![belly])
}

/// STEP, 1.2 s: ears, jaw and a front foot jump between poses, the head hops (translation)
/// and the tail base puffs up (scale).
fn twitch(rig: &Rig) -> Clip {
    let times = keys(Interpolation::Step, 5, 0.3);
    let key = |t: f32| (t / 0.3).round() as usize;
    let pose = |name: &str, axis: Vec3, angles: [f32; 5]| rig.turn(rig.id(name), &times, axis, move |t| angles[key(t)]);
    let rotations = vec![
        pose("ear_l", Vec3::Z, [0.0, 0.7, -0.3, 0.7, 0.0]),
        pose("ear_r", Vec3::Z, [0.0, -0.7, 0.3, -0.7, 0.0]),
        pose("jaw", Vec3::X, [0.0, 0.5, 0.0, 0.5, 0.0]),
        pose("front_l_foot", Vec3::X, [0.0, 0.0, -0.6, 0.0, 0.0]),
    ];
    let head = rig.id("head");
    let hop = channel(head, &times, |t| rig.local(head).translation + Vec3::new(0.0, 0.04, 0.03) * (key(t) % 2) as f32);
    let puff = channel(rig.id("tail0"), &times, |t| Vec3::splat(if (1..=2).contains(&key(t)) { 1.3 } else { 1.0 }));
    clip("twitch", vec![hop], rotations, vec![puff])
}

/// CUBICSPLINE, 2.4 s: the right front leg lifts and waves, the hips sway (translation), the
/// head pulses (scale) and the tail sways; tangents are the motion's non-zero derivatives.
fn wave(rig: &Rig) -> Clip {
    let times = keys(Interpolation::CubicSpline, 5, 0.6);
    let w = TAU / 2.4;
    let rotations = vec![
        rig.turn(rig.id("front_r_upper"), &times, Vec3::X, |t| -0.7 - 0.4 * (w * t + 0.5).sin()),
        rig.turn(rig.id("front_r_lower"), &times, Vec3::Z, |t| 0.6 * (2.0 * w * t + 0.4).sin()),
        rig.turn(rig.id("tail0"), &times, Vec3::Y, |t| 0.5 * (w * t + 0.2).sin()),
    ];
    let hips = rig.id("hips");
    let offset = |t: f32| Vec3::new(0.06 * (w * t + 0.3).sin(), 0.03 * (2.0 * w * t + 0.3).sin(), 0.0);
    let sway = channel(hips, &times, |t| rig.local(hips).translation + offset(t));
    let pulse = channel(rig.id("head"), &times, |t| Vec3::splat(1.0 + 0.1 * (w * t + 0.7).sin()));
    clip("wave", vec![sway], rotations, vec![pulse])
}

/// A UV sphere of unit radius (`rings` ≥ 2 latitude bands, `segments` ≥ 3), closed with
/// pole vertices; for tests and examples.
pub fn uv_sphere(rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = vec![Vec3::Z, Vec3::NEG_Z];
    for r in 1..rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let ph = std::f32::consts::TAU * s as f32 / segments as f32;
            p.push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    let v = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
    let mut t = Vec::new();
    for s in 0..segments {
        t.push([0, v(1, s), v(1, s + 1)]);
        t.push([1, v(rings - 1, s + 1), v(rings - 1, s)]);
        for r in 1..rings - 1 {
            t.push([v(r, s), v(r + 1, s), v(r + 1, s + 1)]);
            t.push([v(r, s), v(r + 1, s + 1), v(r, s + 1)]);
        }
    }
    (p, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skinlet::pose::Poser;

    fn demo(seed: u64, triangles: usize) -> Asset {
        demo_character(&DemoParams { seed, triangles })
    }

    fn geometry(asset: &Asset) -> &SkinnedMesh {
        &asset.meshes[0].primitives[0].geometry
    }

    fn same(a: &Asset, b: &Asset) -> bool {
        (&a.skeleton, &a.skins, &a.meshes, &a.instances, &a.clips)
            == (&b.skeleton, &b.skins, &b.meshes, &b.instances, &b.clips)
    }

    /// Angle in degrees of the shorter arc between two rotations.
    fn degrees(a: Quat, b: Quat) -> f64 {
        2.0 * a.as_dquat().dot(b.as_dquat()).abs().min(1.0).acos().to_degrees()
    }

    #[test]
    fn skeleton_is_a_body_skin_of_thirty_plus_joints_and_extra_nodes() {
        let a = demo(7, 1_000);
        let nodes = &a.skeleton.nodes;
        let joints = nodes.len() - EXTRA_NODES.len();
        assert!(joints >= 30, "{joints} joints");
        assert_eq!(a.skins[0].joints, (0..joints as u32).collect::<Vec<_>>());
        assert!(nodes[0].parent.is_none());
        assert!(nodes.iter().enumerate().skip(1).all(|(i, n)| n.parent.is_some_and(|p| (p as usize) < i)));
        assert_eq!(a.instances[0], Instance { node: joints as u32, mesh: 0, skin: Some(0) });
        assert_eq!(a.meshes[0].name, "demo_creature");
        // The collar's skin lists its joints in another order than the body's.
        let collar = &a.skins[1].joints;
        assert!(collar.len() >= 3 && collar.windows(2).all(|w| w[0] > w[1]), "{collar:?}");
    }

    #[test]
    fn the_whole_character_has_every_kind_of_part() {
        use skinlet::character::PartKind;
        let a = demo(7, 2_000);
        let c = a.character().unwrap();
        let kinds: Vec<(u32, PartKind)> = c.parts.iter().map(|p| (p.mesh, p.kind)).collect();
        assert_eq!(
            kinds,
            [
                (0, PartKind::Skinned { skin: 0 }),
                (1, PartKind::Skinned { skin: 1 }),
                (2, PartKind::Rigid),
                (3, PartKind::Rigid),
                (4, PartKind::Rigid),
                (4, PartKind::Rigid)
            ]
        );
        // The body skin's joints come first, unchanged; each rigid node adds one driver.
        assert_eq!(c.palette.joints[..a.skins[0].joints.len()], a.skins[0].joints[..]);
        assert_eq!(c.palette.joints.len(), a.skins[0].joints.len() + 4);
        let drawn: usize =
            a.instances.iter().map(|i| a.meshes[i.mesh as usize].primitives[0].geometry.triangles.len()).sum();
        assert_eq!(c.triangle_count(), drawn);
        // Only the propeller's node is animated among the rigid ones, and in every clip.
        let propeller = c.parts[3].node;
        assert!(a.clips.iter().all(|clip| clip.rotations.iter().any(|ch| ch.node == propeller)));
    }

    #[test]
    fn every_mesh_faces_outwards() {
        let a = demo(7, 1_000);
        for m in &a.meshes {
            let g = &m.primitives[0].geometry;
            for t in &g.triangles {
                let [p0, p1, p2] = t.map(|i| g.positions[i as usize]);
                let normal: Vec3 = t.iter().map(|&i| g.normals[i as usize]).sum();
                assert!((p1 - p0).cross(p2 - p0).dot(normal) > 0.0, "{}: triangle {t:?}", m.name);
            }
        }
    }

    #[test]
    fn triangle_count_follows_the_request() {
        for want in [1_000, 20_000, 200_000] {
            let got = geometry(&demo(3, want)).triangles.len();
            assert!((got as f64 - want as f64).abs() <= 0.1 * want as f64, "asked {want}, got {got}");
        }
    }

    #[test]
    fn triangles_have_area_and_face_outwards() {
        for triangles in [1_000, 200_000] {
            let a = demo(7, triangles);
            let g = geometry(&a);
            for t in &g.triangles {
                let [p0, p1, p2] = t.map(|i| g.positions[i as usize]);
                let cross = (p1 - p0).cross(p2 - p0);
                let normal: Vec3 = t.iter().map(|&i| g.normals[i as usize]).sum();
                assert!(cross.length() > 1e-9 && cross.dot(normal) > 0.0, "triangle {t:?}");
            }
        }
    }

    #[test]
    fn influences_are_normalized_sorted_and_span_one_to_four() {
        let a = demo(7, 20_000);
        let inf = geometry(&a).influences.as_ref().expect("skinned");
        let mut histogram = [0usize; 5];
        for v in 0..inf.vertex_count() {
            let n = inf.count(v);
            histogram[n] += 1;
            let (joints, weights) = (&inf.joints[v * 4..v * 4 + 4], &inf.weights[v * 4..v * 4 + 4]);
            assert!((weights.iter().sum::<f32>() - 1.0).abs() <= 1e-6, "vertex {v}: {weights:?}");
            assert!(joints.iter().all(|&j| (j as usize) < a.skins[0].joints.len()));
            assert!((1..n).all(|i| (weights[i - 1], joints[i]) > (weights[i], joints[i - 1])), "vertex {v}: order");
            assert!(weights[n..].iter().all(|&w| w == 0.0) && joints[n..].iter().all(|&j| j == 0));
        }
        assert_eq!(histogram[0], 0);
        assert!(histogram[1..].iter().all(|&c| c > 0), "histogram {histogram:?}");
    }

    #[test]
    fn rest_pose_skinning_reproduces_the_mesh() {
        let a = demo(7, 20_000);
        let g = geometry(&a);
        let mut matrices = Vec::new();
        Poser::default().skinning_matrices(&a.skeleton, &a.skins[0], None, 0.0, &mut matrices);
        let (mut positions, mut normals) = (vec![Vec3::ZERO; g.positions.len()], vec![Vec3::ZERO; g.normals.len()]);
        let inf = g.influences.as_ref().expect("skinned");
        skinlet::skinning::skin(inf, &g.positions, &g.normals, &matrices, &mut positions, &mut normals).unwrap();
        let (lo, hi) = g.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let tolerance = 1e-5 * (hi - lo).length();
        for (v, (p, q)) in g.positions.iter().zip(&positions).enumerate() {
            assert!(p.distance(*q) <= tolerance, "vertex {v}: {p} became {q}");
            assert!(g.normals[v].distance(normals[v]) <= 1e-4, "normal {v}");
        }
    }

    #[test]
    fn clips_cover_every_interpolation_with_valid_keys() {
        fn check<T>(c: &Channel<T>, clip: &Clip) {
            let per_key = if c.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
            assert_eq!(c.values.len(), per_key * c.times.len(), "{}", clip.name);
            assert!(c.times[0] == 0.0 && c.times.windows(2).all(|w| w[0] < w[1]), "{}", clip.name);
        }
        let a = demo(7, 1_000);
        assert!(a.clips.len() >= 3);
        for mode in [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline] {
            assert!(a.clips.iter().any(|c| c.interpolations() == [mode]), "no {} clip", mode.name());
        }
        for c in &a.clips {
            assert!(c.start == 0.0 && (1.0..=3.0).contains(&c.duration()), "{}", c.name);
            // The face: both morph weights of the body, in the clip's own mode.
            assert_eq!(c.weights.iter().map(|w| w.target).collect::<Vec<_>>(), [0, 1], "{}", c.name);
            c.weights.iter().for_each(|w| check(&w.channel, c));
            assert!(!c.translations.is_empty() && !c.rotations.is_empty() && !c.scales.is_empty(), "{}", c.name);
            c.translations.iter().chain(&c.scales).for_each(|ch| check(ch, c));
            c.rotations.iter().for_each(|ch| check(ch, c));
        }
        let wave = a.clips.iter().find(|c| c.name == "wave").expect("wave clip");
        let out_tangents = |c: &Channel<Vec3>| c.values.iter().skip(2).step_by(3).all(|v| v.length() > 1e-3);
        assert!(wave.translations.iter().chain(&wave.scales).all(out_tangents));
        assert!(
            wave.rotations.iter().all(|c| c.values.iter().skip(2).step_by(3).all(|&q| Vec4::from(q).length() > 1e-3))
        );
    }

    #[test]
    fn walk_has_a_near_half_turn_and_a_full_spin() {
        let a = demo(7, 1_000);
        let walk = a.clips.iter().find(|c| c.name == "walk").expect("walk clip");
        let steps = |c: &Channel<Quat>| c.values.windows(2).map(|w| degrees(w[0], w[1])).collect::<Vec<_>>();
        assert!(walk.rotations.iter().any(|c| steps(c).iter().any(|&d| d >= 170.0)));
        assert!(walk.rotations.iter().any(|c| steps(c).iter().sum::<f64>() >= 360.0));
        assert!(walk.scales.iter().flat_map(|c| &c.values).any(|s| s.x != s.y));
    }

    #[test]
    fn same_seed_same_asset_other_seed_other_asset() {
        let p = DemoParams::default();
        assert!(same(&demo_character(&p), &demo_character(&p)));
        let (a, b) = (demo(1, 5_000), demo(2, 5_000));
        assert!(a.skeleton != b.skeleton && a.meshes != b.meshes);
    }

    #[test]
    #[ignore = "timing: cargo test --release -p skinlet-lab --lib demo -- --ignored --nocapture"]
    fn time_one_million_triangles() {
        let start = std::time::Instant::now();
        let a = demo(7, 1_000_000);
        let elapsed = start.elapsed();
        let g = geometry(&a);
        eprintln!("1M request: {} triangles, {} vertices in {elapsed:?}", g.triangles.len(), g.positions.len());
    }
}
