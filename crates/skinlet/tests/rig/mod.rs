//! Random rigs shared by the guarantee tests: branching hierarchies (up to depth 12+,
//! constant matrix nodes with shear), clips in all three interpolation modes (turns up to
//! 180° between keys, full spins over several keys, non-uniform and negative scale), random
//! soft weights and bind matrices.

#![allow(dead_code)]

use glam::{Mat4, Quat, Vec3};
use skinlet::clip::{Channel, Clip, Interpolation};
use skinlet::model::{Influences, Node, Skeleton, Skin, Trs};
use skinlet::pose::Poser;

/// Vertices of each random character's mesh.
pub const VERTICES: usize = 12;

pub struct Rng(pub u64);
impl Rng {
    pub fn u(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.u()
    }
    pub fn below(&mut self, n: usize) -> usize {
        ((self.u() * n as f32) as usize).min(n - 1)
    }
    pub fn v3(&mut self, a: f32) -> Vec3 {
        Vec3::new(self.range(-a, a), self.range(-a, a), self.range(-a, a))
    }
    pub fn axis(&mut self) -> Vec3 {
        loop {
            let v = self.v3(1.0);
            if v.length() > 0.1 {
                return v.normalize();
            }
        }
    }
    pub fn scale(&mut self) -> Vec3 {
        let mut s = Vec3::new(self.range(0.5, 1.6), self.range(0.5, 1.6), self.range(0.5, 1.6));
        if self.u() < 0.15 {
            s.x = -s.x;
        }
        s
    }
}

pub fn random_character(seed: u64) -> (Skeleton, Skin, Clip, Vec<Vec3>, Influences) {
    let mut r = Rng(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1);
    let n = 2 + r.below(18);
    let chain = r.u() < 0.3; // deep chains reach depth 12+
    let nodes: Vec<Node> = (0..n)
        .map(|i| {
            let parent = if i == 0 || (i > 3 && r.u() < 0.05) {
                None
            } else if chain {
                Some((i - 1) as u32)
            } else {
                Some(r.below(i) as u32)
            };
            let rest = Trs {
                translation: r.v3(1.0),
                rotation: Quat::from_axis_angle(r.axis(), r.range(-3.1, 3.1)),
                scale: r.scale(),
            };
            let matrix = (r.u() < 0.1).then(|| {
                let mut m = rest.to_mat4();
                m.x_axis.y += r.range(-0.5, 0.5); // shear
                m
            });
            Node { name: format!("n{i}"), parent, rest, matrix }
        })
        .collect();
    let skeleton = Skeleton::new(nodes).unwrap();
    let mut clip = Clip { name: "random".into(), ..Clip::default() };
    let modes = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline];
    for i in 0..n as u32 {
        if skeleton.nodes[i as usize].matrix.is_some() {
            continue;
        }
        let keys = 2 + r.below(5);
        let mut t = 0.0;
        let times: Vec<f32> = (0..keys)
            .map(|k| {
                if k > 0 {
                    t += r.range(0.05, 0.8);
                }
                t
            })
            .collect();
        let per = |m: Interpolation| if m == Interpolation::CubicSpline { 3 } else { 1 };
        if r.u() < 0.7 {
            let m = modes[r.below(3)];
            let spin = r.u() < 0.3;
            let (axis, step) = (r.axis(), r.range(0.5, 2.2));
            let mut q = Quat::from_axis_angle(r.axis(), r.range(-3.0, 3.0));
            let mut values = Vec::new();
            for k in 0..keys {
                if k > 0 {
                    // Spins: equal steps about one axis, full turns over several keys.
                    // Otherwise: random turns up to 180° per key.
                    let d = if spin {
                        Quat::from_axis_angle(axis, step)
                    } else {
                        Quat::from_axis_angle(r.axis(), r.range(0.0, std::f32::consts::PI))
                    };
                    q = (d * q).normalize();
                }
                for c in 0..per(m) {
                    values.push(if per(m) == 3 && c != 1 {
                        Quat::from_xyzw(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0))
                    } else {
                        q
                    });
                }
            }
            clip.rotations.push(Channel { node: i, interpolation: m, times: times.clone(), values });
        }
        for is_scale in [false, true] {
            if r.u() < 0.4 {
                let m = modes[r.below(3)];
                let values = (0..keys * per(m))
                    .map(|k| {
                        let tangent = per(m) == 3 && k % 3 != 1;
                        if tangent {
                            r.v3(1.0)
                        } else if is_scale {
                            r.scale()
                        } else {
                            r.v3(1.0)
                        }
                    })
                    .collect();
                let ch = Channel { node: i, interpolation: m, times: times.clone(), values };
                if is_scale { clip.scales.push(ch) } else { clip.translations.push(ch) }
            }
        }
    }
    clip.start = 0.0;
    clip.end = clip.key_times().last().copied().unwrap_or(0.0);
    // Skin: a random subset of nodes as joints, bound at the rest pose or at random matrices.
    let joints: Vec<u32> = (0..n as u32).filter(|_| r.u() < 0.8).collect();
    let joints = if joints.is_empty() { vec![0] } else { joints };
    let mut poser = Poser::default();
    let rest = poser.globals(&skeleton, None, 0.0).to_vec();
    let inverse_bind = joints
        .iter()
        .map(|&j| {
            if r.u() < 0.8 {
                rest[j as usize].inverse().as_mat4()
            } else {
                Mat4::from_scale_rotation_translation(r.scale(), Quat::from_axis_angle(r.axis(), 1.0), r.v3(1.0))
            }
        })
        .collect();
    let skin = Skin { name: "s".into(), joints: joints.clone(), inverse_bind };
    let verts = VERTICES;
    let positions: Vec<Vec3> = (0..verts).map(|_| r.v3(2.0)).collect();
    let mut inf = Influences { stride: 4, joints: vec![0; 4 * verts], weights: vec![0.0; 4 * verts] };
    for v in 0..verts {
        let k = 1 + r.below(4.min(joints.len()));
        let mut used = Vec::new();
        let raw: Vec<f32> = (0..k).map(|_| r.range(0.05, 1.0)).collect();
        let sum: f32 = raw.iter().sum();
        let mut ws: Vec<(u16, f32)> = Vec::new();
        for w in raw {
            let mut j = r.below(joints.len()) as u16;
            while used.contains(&j) {
                j = (j + 1) % joints.len() as u16;
            }
            used.push(j);
            ws.push((j, w / sum));
        }
        ws.sort_by(|a, b| b.1.total_cmp(&a.1));
        for (s, (j, w)) in ws.into_iter().enumerate() {
            inf.joints[4 * v + s] = j;
            inf.weights[4 * v + s] = w;
        }
    }
    (skeleton, skin, clip, positions, inf)
}

/// Random morph targets for a mesh of `vertices` vertices drawn by `node`: three weights
/// (default weights in [-1, 1]), two animated by `clip` in random interpolation modes, and
/// deltas on about half the vertices.
pub fn random_morphs(seed: u64, vertices: usize, node: u32, clip: &mut Clip) -> skinlet::model::Morphs {
    use skinlet::clip::WeightChannel;
    use skinlet::model::{MorphDelta, MorphWeight, Morphs};
    let mut r = Rng(seed.wrapping_mul(0x2545F4914F6CDD1D) | 1);
    let weights: Vec<MorphWeight> =
        (0..3).map(|target| MorphWeight { node, target, default: r.range(-1.0, 1.0) }).collect();
    let end = clip.end.max(0.5);
    for target in 0..2 {
        let mode = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline][r.below(3)];
        let keys = 2 + r.below(4);
        let times: Vec<f32> = (0..keys).map(|k| end * k as f32 / (keys - 1) as f32).collect();
        let per = if mode == Interpolation::CubicSpline { 3 } else { 1 };
        let values = (0..per * keys).map(|_| r.range(-1.0, 1.5)).collect();
        clip.weights.push(WeightChannel { target, channel: Channel { node, interpolation: mode, times, values } });
    }
    clip.end = end;
    let mut morphs = Morphs { weights, offsets: vec![0], deltas: Vec::new() };
    for _ in 0..vertices {
        if r.u() < 0.5 {
            for weight in 0..3 {
                if r.u() < 0.7 {
                    morphs.deltas.push(MorphDelta { weight, position: r.v3(0.6), normal: r.v3(0.3) });
                }
            }
        }
        morphs.offsets.push(morphs.deltas.len() as u32);
    }
    morphs
}

/// Triangles over a random character's vertices: for even seeds a gently bent 4×3 grid patch
/// (positions and weights rewritten: mostly one joint, up to 5% on another, so that normal
/// cones survive and normal checks have teeth), for odd seeds 20 random triangles.
pub fn random_triangles(seed: u64, joints: usize, positions: &mut [Vec3], inf: &mut Influences) -> Vec<[u32; 3]> {
    let mut r = Rng(seed ^ 0x5EED);
    if seed.is_multiple_of(2) {
        let (w, h) = (4, 3);
        let main = r.below(joints) as u16;
        for (i, p) in positions.iter_mut().enumerate() {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            *p = Vec3::new(x * 0.3, y * 0.3, 0.05 * x * x) + r.v3(0.02);
            inf.joints[4 * i..4 * i + 4].copy_from_slice(&[main, (main + 1) % joints as u16, 0, 0]);
            let second = if joints > 1 && r.u() < 0.3 { r.range(0.0, 0.05) } else { 0.0 };
            inf.weights[4 * i..4 * i + 4].copy_from_slice(&[1.0 - second, second, 0.0, 0.0]);
        }
        (0..h - 1)
            .flat_map(|y| (0..w - 1).map(move |x| (x, y)))
            .flat_map(|(x, y)| {
                let i = (y * w + x) as u32;
                [[i, i + 1, i + w as u32 + 1], [i, i + w as u32 + 1, i + w as u32]]
            })
            .collect()
    } else {
        (0..20)
            .map(|_| [r.below(VERTICES) as u32, r.below(VERTICES) as u32, r.below(VERTICES) as u32])
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect()
    }
}
