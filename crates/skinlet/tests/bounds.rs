//! The conservative-bounds guarantee, checked against dense sampling of reference skinning:
//! random hierarchies (branching, up to depth 12, constant matrix nodes with shear), random
//! clips in all three interpolation modes (rotations up to 180° between keys, full turns
//! over several keys, non-uniform and negative scale), random soft weights and targets.

use glam::{DVec3, Mat4, Quat, Vec3};
use proptest::prelude::*;
use skinlet::bounds::vertex::{IntervalMotions, vertex_box};
use skinlet::clip::{Channel, Clip, Interpolation};
use skinlet::model::{Influences, Node, Skeleton, Skin, Trs};
use skinlet::pose::Poser;

/// Vertices of each random character's mesh.
const VERTICES: usize = 12;

struct Rng(u64);
impl Rng {
    fn u(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.u()
    }
    fn below(&mut self, n: usize) -> usize {
        ((self.u() * n as f32) as usize).min(n - 1)
    }
    fn v3(&mut self, a: f32) -> Vec3 {
        Vec3::new(self.range(-a, a), self.range(-a, a), self.range(-a, a))
    }
    fn axis(&mut self) -> Vec3 {
        loop {
            let v = self.v3(1.0);
            if v.length() > 0.1 {
                return v.normalize();
            }
        }
    }
    fn scale(&mut self) -> Vec3 {
        let mut s = Vec3::new(self.range(0.5, 1.6), self.range(0.5, 1.6), self.range(0.5, 1.6));
        if self.u() < 0.15 {
            s.x = -s.x;
        }
        s
    }
}

fn random_character(seed: u64) -> (Skeleton, Skin, Clip, Vec<Vec3>, Influences) {
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

/// `global(to)⁻¹ · global(from)` from the local transforms below the common ancestor.
fn relative(skeleton: &Skeleton, locals: &[Trs], from: u32, to: u32) -> glam::DMat4 {
    let local = |n: u32| match skeleton.nodes[n as usize].matrix {
        Some(m) => m.as_dmat4(),
        None => locals[n as usize].to_dmat4(),
    };
    let up: Vec<u32> = skeleton.ancestry(from).collect();
    let down: Vec<u32> = skeleton.ancestry(to).collect();
    let lca = up.iter().copied().find(|n| down.contains(n));
    let chain =
        |path: &[u32]| path.iter().take_while(|&&n| Some(n) != lca).fold(glam::DMat4::IDENTITY, |m, &n| local(n) * m);
    chain(&down).inverse() * chain(&up)
}

/// Checks every vertex against every target joint over every key interval and a random
/// sub-interval of each, at 40 sample times per interval (ends included).
fn check_character(seed: u64) -> Result<usize, String> {
    let (skeleton, skin, clip, positions, inf) = random_character(seed);
    let mut keys = clip.key_times();
    if keys.len() == 1 {
        keys.push(keys[0]);
    }
    let mut r = Rng(seed ^ 0xABCDEF);
    let mut locals = Vec::new();
    let mut checks = 0;
    for w in keys.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (u1, u2) = (r.u(), r.u());
        let sub = (a + (b - a) * u1.min(u2), a + (b - a) * u1.max(u2));
        for (t1, t2) in [(a, b), sub] {
            let motions = IntervalMotions::new(&skeleton, Some(&clip), t1, t2).map_err(|e| e.to_string())?;
            for target in 0..skin.joints.len() as u16 {
                let boxes: Vec<_> = (0..positions.len())
                    .map(|v| vertex_box(&skeleton, &skin, &motions, &inf, v, positions[v], target))
                    .collect();
                for k in 0..40 {
                    let t = t1 + (t2 - t1) * k as f32 / 39.0;
                    let t = t.min(t2);
                    // Reference in f64: each influence's `global(target)⁻¹ · global(joint)` as the
                    // product of sampled local matrices below their lowest common ancestor (the
                    // common part cancels exactly, so a scale passing through zero above it does
                    // not turn rounding into false alarms), times the inverse bind matrix.
                    clip.sample_locals(&skeleton, t, &mut locals);
                    let to = skin.joints[target as usize];
                    for v in 0..positions.len() {
                        let q: DVec3 = inf
                            .of(v)
                            .map(|(j, w)| {
                                let rel = relative(&skeleton, &locals, skin.joints[j as usize], to);
                                let bind = skin.inverse_bind[j as usize].as_dmat4();
                                (rel * bind).transform_point3(positions[v].as_dvec3()) * w as f64
                            })
                            .sum();
                        let p = q;
                        let bx = &boxes[v];
                        // f32 sampling of key values and times, relative to the size of the numbers.
                        let tol = 1e-5 * p.abs().max_element().max(q.abs().max_element()).max(1.0);
                        let inside =
                            q.cmpge(bx.min - DVec3::splat(tol)).all() && q.cmple(bx.max + DVec3::splat(tol)).all();
                        if !inside && q.is_finite() {
                            return Err(format!(
                                "seed {seed}: vertex {v} target {target} interval [{t1}, {t2}] t {t}: {q} outside {bx:?}"
                            ));
                        }
                        checks += 1;
                    }
                }
            }
        }
    }
    Ok(checks)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]
    #[test]
    fn vertex_boxes_contain_every_sampled_position(seed in any::<u64>()) {
        check_character(seed).map_err(TestCaseError::fail)?;
    }
}

#[test]
fn half_turn_between_keys_is_covered_both_ways() {
    // Exactly 180° between two LINEAR keys: the slerp direction is decided by rounding.
    let q1 = Quat::from_xyzw(0.0, 0.0, 1.0, 0.0);
    let node = Node { name: "j".into(), parent: None, rest: Trs::IDENTITY, matrix: None };
    let child = Node { parent: Some(0), ..node.clone() };
    let skeleton = Skeleton::new(vec![node, child.clone(), child]).unwrap();
    let clip = Clip {
        rotations: vec![Channel {
            node: 1,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![Quat::IDENTITY, q1],
        }],
        end: 1.0,
        ..Clip::default()
    };
    let motions = IntervalMotions::new(&skeleton, Some(&clip), 0.0, 1.0).unwrap();
    // A point on node 1's X axis seen from its unrotated sibling: both half circles.
    let b = motions.carry(&skeleton, 1, 2, skinlet::bounds::Aabb::point(DVec3::X));
    assert!(b.contains(DVec3::Y * 0.999) && b.contains(-DVec3::Y * 0.999), "{b:?}");
}

/// The whole pipeline on random characters: a random triangle mesh over the character's
/// vertices, skin-aware meshlets, spheres and cones over the clip (refined for a few rounds),
/// and the dense world-space check of every vertex and face normal.
/// Returns whether some meshlet had a useful normal cone (so normals were really checked).
fn check_meshlet_bounds(seed: u64) -> Result<Option<bool>, String> {
    use skinlet::bounds::refine::{Refinement, refine};
    use skinlet::bounds::verify::verify_bounds;
    use skinlet::meshlet::{Builder, MeshletLimits, build, prepare};
    let (skeleton, skin, clip, mut positions, mut inf) = random_character(seed);
    let mut r = Rng(seed ^ 0x5EED);
    let triangles: Vec<[u32; 3]> = if seed.is_multiple_of(2) {
        // A gently bent 4×3 grid patch: narrow rest cones, so normal checks have teeth.
        let (w, h) = (4, 3);
        let main = r.below(skin.joints.len()) as u16;
        for (i, p) in positions.iter_mut().enumerate() {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            *p = Vec3::new(x * 0.3, y * 0.3, 0.05 * x * x) + r.v3(0.02);
            // Mostly one joint, some vertices with up to 5% on another: cones survive.
            inf.joints[4 * i..4 * i + 4].copy_from_slice(&[main, (main + 1) % skin.joints.len() as u16, 0, 0]);
            let second = if skin.joints.len() > 1 && r.u() < 0.3 { r.range(0.0, 0.05) } else { 0.0 };
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
    };
    if triangles.is_empty() {
        return Ok(None);
    }
    let mesh = skinlet::SkinnedMesh { positions, normals: Vec::new(), triangles, influences: Some(inf) };
    let prepared = prepare(&mesh);
    let limits = MeshletLimits { max_vertices: 8, max_triangles: 8 };
    let meshlets = build(&prepared, Builder::SkinAware, limits).map_err(|e| e.to_string())?;
    // Refined bounds, with thresholds that keep every meshlet refining: each key interval's
    // evaluation and every halving are checked.
    let how = Refinement { s_r: 1.0, alpha_t: 0.0, budget: None, max_rounds: 6 };
    let refined = refine(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets, &how).map_err(|e| e.to_string())?;
    let bounds = refined.bounds;
    let report = verify_bounds(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets, &bounds, 60);
    if report.violations() > 0 {
        return Err(format!("seed {seed}: {} rounds, {report:?}", refined.rounds));
    }
    Ok(Some(bounds.iter().any(|b| b.cone_angle < std::f32::consts::FRAC_PI_2)))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]
    #[test]
    fn meshlet_bounds_hold_on_random_characters(seed in any::<u64>()) {
        check_meshlet_bounds(seed).map_err(TestCaseError::fail)?;
    }
}

#[test]
fn random_patches_have_cones_to_check() {
    let with_cones = (0..200u64).filter(|s| check_meshlet_bounds(2 * s).unwrap() == Some(true)).count();
    assert!(with_cones > 50, "only {with_cones} of 200 patches had a normal cone");
}

/// Seeds that once failed (rounding through near-singular scales, unbounded boxes, tiny
/// cones); kept so that a fix cannot silently regress.
#[test]
fn seeds_that_once_failed() {
    for seed in [48850896777888519, 4279649241624201730, 8120701573591387314, 3165077517545815709, 14844516871249792886]
    {
        check_character(seed).unwrap();
    }
    for seed in [4835460085934742770, 12520672679534881996, 12738666605761301130] {
        check_meshlet_bounds(seed).unwrap();
    }
}
