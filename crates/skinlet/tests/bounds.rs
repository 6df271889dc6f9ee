//! The conservative-bounds guarantee, checked against dense sampling of reference skinning:
//! random hierarchies (branching, up to depth 12, constant matrix nodes with shear), random
//! clips in all three interpolation modes (rotations up to 180° between keys, full turns
//! over several keys, non-uniform and negative scale), random soft weights and targets, and
//! morph targets whose weights are animated in all three modes.

use glam::{DVec3, Quat};
use proptest::prelude::*;
use skinlet::bounds::vertex::{IntervalMotions, vertex_box};
use skinlet::clip::{Channel, Clip, Interpolation};
use skinlet::model::{Node, Skeleton, Trs};

mod rig;
use rig::{Rng, random_character};

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
    let (skeleton, skin, mut clip, positions, inf) = random_character(seed);
    // Half the characters morph before skinning (weights animated in all three modes).
    let morphs = if seed.is_multiple_of(2) {
        rig::random_morphs(seed, positions.len(), 0, &mut clip)
    } else {
        skinlet::model::Morphs::default()
    };
    let mesh = skinlet::SkinnedMesh { positions, influences: Some(inf), morphs, ..Default::default() };
    let (positions, inf) = (&mesh.positions, mesh.influences.as_ref().unwrap());
    let mut weights = Vec::new();
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
            let motions =
                IntervalMotions::new(&skeleton, &mesh.morphs, Some(&clip), t1, t2).map_err(|e| e.to_string())?;
            for target in 0..skin.joints.len() as u16 {
                let boxes: Vec<_> =
                    (0..positions.len()).map(|v| vertex_box(&skeleton, &skin, &motions, &mesh, v, target)).collect();
                for k in 0..40 {
                    let t = t1 + (t2 - t1) * k as f32 / 39.0;
                    let t = t.min(t2);
                    // Reference in f64: each influence's `global(target)⁻¹ · global(joint)` as the
                    // product of sampled local matrices below their lowest common ancestor (the
                    // common part cancels exactly, so a scale passing through zero above it does
                    // not turn rounding into false alarms), times the inverse bind matrix.
                    clip.sample_locals(&skeleton, t, &mut locals);
                    mesh.morphs.weights_at(Some(&clip), t, &mut weights);
                    let to = skin.joints[target as usize];
                    for v in 0..positions.len() {
                        // The morphed rest point, in f64 from the sampled weights.
                        let morphed = (mesh.morphs.of(v).iter())
                            .map(|d| d.position.as_dvec3() * weights[d.weight as usize] as f64)
                            .fold(positions[v].as_dvec3(), |p, d| p + d);
                        let q: DVec3 = inf
                            .of(v)
                            .map(|(j, w)| {
                                let rel = relative(&skeleton, &locals, skin.joints[j as usize], to);
                                let bind = skin.inverse_bind[j as usize].as_dmat4();
                                (rel * bind).transform_point3(morphed) * w as f64
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
    let motions = IntervalMotions::new(&skeleton, &Default::default(), Some(&clip), 0.0, 1.0).unwrap();
    // A point on node 1's X axis seen from its unrotated sibling: both half circles.
    let b = motions.carry(&skeleton, 1, 2, skinlet::bounds::Aabb::point(DVec3::X));
    assert!(b.contains(DVec3::Y * 0.999) && b.contains(-DVec3::Y * 0.999), "{b:?}");
}

/// The whole pipeline on random characters: a random triangle mesh over the character's
/// vertices, skin-aware meshlets, spheres and cones over the clip (refined for a few rounds),
/// and the dense check of every vertex and face normal in each meshlet's joint space.
/// Returns whether some meshlet had a useful normal cone (so normals were really checked).
fn check_meshlet_bounds(seed: u64) -> Result<Option<bool>, String> {
    use skinlet::bounds::refine::{Refinement, refine};
    use skinlet::bounds::verify::verify_bounds;
    use skinlet::meshlet::{Builder, MeshletLimits, build, prepare};
    let (skeleton, skin, clip, mut positions, mut inf) = random_character(seed);
    let triangles = rig::random_triangles(seed, skin.joints.len(), &mut positions, &mut inf);
    if triangles.is_empty() {
        return Ok(None);
    }
    let mesh = skinlet::SkinnedMesh { positions, triangles, influences: Some(inf), ..Default::default() };
    let prepared = prepare(&mesh).unwrap();
    let limits = MeshletLimits { max_vertices: 8, max_triangles: 8 };
    let meshlets = build(&prepared, Builder::SkinAware, limits).map_err(|e| e.to_string())?;
    // Refined bounds, with thresholds that keep every meshlet refining: each key interval's
    // evaluation and every halving are checked.
    let how = Refinement { s_r: 1.0, alpha_t: 0.0, budget: None, max_rounds: 6 };
    let refined = refine(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets, &how).map_err(|e| e.to_string())?;
    let bounds = refined.bounds;
    let report = verify_bounds(&skeleton, &skin, &[&clip], &prepared.mesh, &meshlets, &bounds, 60).unwrap();
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
