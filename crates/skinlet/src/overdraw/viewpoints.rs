//! Viewing directions around a model: the vertices of a subdivided icosahedron (Nehab,
//! Barczak & Sander 2006; Han & Sander 2016, fig. 2: twice subdivided, 162 directions).
//! Each subdivision splits every triangle in four at its edge midpoints, pushed onto the
//! unit sphere: 12, 42, 162, 642 ... directions, spread almost uniformly. Deterministic.

use glam::Vec3;
use std::collections::HashMap;

/// Unit directions of an icosahedron subdivided `levels` times.
pub fn icosphere(levels: u32) -> Vec<Vec3> {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut points: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, points: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push(((points[a as usize] + points[b as usize]) / 2.0).normalize());
                points.len() as u32 - 1
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) =
                    (midpoint(a, b, &mut points), midpoint(b, c, &mut points), midpoint(c, a, &mut points));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_spread() {
        assert_eq!([0, 1, 2, 3].map(|l| icosphere(l).len()), [12, 42, 162, 642]);
        let p = icosphere(2);
        assert!(p.iter().all(|d| (d.length() - 1.0).abs() < 1e-6));
        // Nearly uniform: every direction's nearest neighbour lies between 13° and 19° away.
        for (i, a) in p.iter().enumerate() {
            let nearest = p
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, b)| a.angle_between(*b))
                .fold(f32::INFINITY, f32::min);
            assert!((13f32.to_radians()..19f32.to_radians()).contains(&nearest), "{}", nearest.to_degrees());
        }
        assert_eq!(icosphere(2), icosphere(2));
    }
}
