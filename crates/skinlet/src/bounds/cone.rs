//! The narrowest cone around a set of directions: the smallest spherical cap containing
//! unit vectors, by Welzl's incremental algorithm on the sphere (a cap is fixed by at most
//! three of its directions: one, the midpoint of two, or the circle through three).
//!
//! The paper (section 4) takes the mean rest normal as a meshlet's reference axis; a
//! meshlet whose normals spread unevenly then gets a wider cone than it needs, often past
//! 90°, where backface culling is impossible. The smallest cap is exact when the directions
//! fit in an open hemisphere; otherwise (or when rounding misleads it) the caller still
//! measures the real angle around the returned axis, so the result is never wrong, only
//! possibly wider than optimal. [`reference_axis`] keeps whichever of the mean and the cap
//! axis is narrower.

use glam::DVec3;

/// Axis and cosine of the smallest cap containing the unit vectors `dirs` (an empty set
/// gives `+Z` and cosine 1). The order of `dirs` decides which ties win: deterministic.
pub fn smallest_cap(dirs: &[DVec3]) -> (DVec3, f64) {
    let Some(&first) = dirs.first() else { return (DVec3::Z, 1.0) };
    let inside = |(axis, cos): (DVec3, f64), p: DVec3| axis.dot(p) >= cos - 1e-12;
    let mut cap = (first, 1.0);
    for i in 1..dirs.len() {
        if inside(cap, dirs[i]) {
            continue;
        }
        cap = (dirs[i], 1.0);
        for j in 0..i {
            if inside(cap, dirs[j]) {
                continue;
            }
            cap = cap2(dirs[i], dirs[j]);
            for k in 0..j {
                if !inside(cap, dirs[k]) {
                    cap = cap3(dirs[i], dirs[j], dirs[k]);
                }
            }
        }
    }
    cap
}

fn cap2(a: DVec3, b: DVec3) -> (DVec3, f64) {
    let axis = (a + b).normalize_or(a.any_orthonormal_vector());
    (axis, axis.dot(a).min(axis.dot(b)))
}

fn cap3(a: DVec3, b: DVec3, c: DVec3) -> (DVec3, f64) {
    let n = (b - a).cross(c - a);
    let Some(mut axis) = n.try_normalize() else { return cap2(a, b) };
    if axis.dot(a) < 0.0 {
        axis = -axis;
    }
    (axis, axis.dot(a).min(axis.dot(b)).min(axis.dot(c)))
}

/// Smallest cosine between `axis` and the nonzero vectors of `normals` (1 when there are none).
pub fn min_cos(axis: DVec3, normals: &[DVec3]) -> f64 {
    normals.iter().filter(|n| n.length() > 0.0).map(|n| n.dot(axis) / n.length()).fold(1.0, f64::min)
}

/// The reference axis of a meshlet's cone from its (unnormalized) rest face normals: the
/// smallest cap's axis or the normalized sum, whichever leaves the smaller angle. Returns the
/// axis and the smallest cosine of a normal around it.
pub fn reference_axis(normals: &[DVec3]) -> (DVec3, f64) {
    let mean = normals.iter().sum::<DVec3>().normalize_or_zero();
    let dirs: Vec<DVec3> = normals.iter().filter_map(|n| n.try_normalize()).collect();
    let (cap, _) = smallest_cap(&dirs);
    let (by_mean, by_cap) = (min_cos(mean, normals), min_cos(cap, normals));
    if mean != DVec3::ZERO && by_mean >= by_cap { (mean, by_mean) } else { (cap, by_cap) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;
    use proptest::prelude::*;

    fn dir(polar: f64, azimuth: f64) -> DVec3 {
        DVec3::new(polar.sin() * azimuth.cos(), polar.sin() * azimuth.sin(), polar.cos())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

        /// The cap contains every direction, and no cap around a direction of a dense grid
        /// is narrower (brute force over axes), when the directions fit in a cone below 80°.
        #[test]
        fn cap_contains_all_and_is_smallest(
            pts in prop::collection::vec((0.0f64..1.35, 0.0f64..6.3), 1..40),
            turn in prop::array::uniform3(-1.0f64..1.0), angle in 0.0f64..3.0,
        ) {
            let q = DQuat::from_axis_angle(DVec3::from(turn).normalize_or(DVec3::X), angle);
            let dirs: Vec<DVec3> = pts.iter().map(|&(p, a)| q * dir(p / 2.0, a)).collect();
            let (axis, cos) = smallest_cap(&dirs);
            prop_assert!((axis.length() - 1.0).abs() < 1e-9);
            for d in &dirs {
                prop_assert!(axis.dot(*d) >= cos - 1e-9);
            }
            let best = min_cos(axis, &dirs);
            for i in 0..2000 {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
                let a = DVec3::new((1.0 - z * z).sqrt() * (i as f64 * 2.4).cos(), (1.0 - z * z).sqrt() * (i as f64 * 2.4).sin(), z);
                prop_assert!(min_cos(a, &dirs) <= best + 1e-9, "axis {a} beats the cap");
            }
        }
    }

    #[test]
    fn uneven_spread_gets_a_narrower_cone_than_the_mean() {
        // Many normals near +Z and one at 80°: the mean leans to +Z and leaves ~80°; the
        // cap is centered between them, at 40°.
        let mut normals = vec![DVec3::Z; 20];
        normals.push(dir(80f64.to_radians(), 0.0));
        let (axis, cos) = reference_axis(&normals);
        assert!((cos.acos().to_degrees() - 40.0).abs() < 1e-6, "{}", cos.acos().to_degrees());
        assert!((axis.dot(DVec3::Z).acos().to_degrees() - 40.0).abs() < 1e-6);
        assert!(min_cos(normals.iter().sum::<DVec3>().normalize(), &normals) < cos);
    }
}
