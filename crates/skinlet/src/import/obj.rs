//! Wavefront OBJ import for static meshes: `v` and `f` lines (polygons are fan-triangulated,
//! negative indices count from the end, `v/vt/vn` forms accepted); everything else is
//! ignored. Errors give the line number.

use crate::model::Asset;
use crate::{Error, Result};
use glam::Vec3;

pub fn load_obj_str(text: &str, name: &str) -> Result<Asset> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face: Vec<u32> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let loc = || format!("{name} line {}", ln + 1);
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0f32; 3];
                for x in &mut c {
                    let tok = it.next().ok_or_else(|| Error::invalid(loc(), "vertex needs 3 coordinates"))?;
                    *x = tok.parse().map_err(|_| Error::invalid(loc(), format!("bad coordinate {tok:?}")))?;
                    if !x.is_finite() {
                        return Err(Error::invalid(loc(), "coordinate is NaN or infinite"));
                    }
                }
                positions.push(Vec3::from(c));
            }
            Some("f") => {
                face.clear();
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| Error::invalid(loc(), format!("bad face index {tok:?}")))?;
                    let n = positions.len() as i64;
                    let idx = if i > 0 { i - 1 } else { n + i };
                    if i == 0 || idx < 0 || idx >= n {
                        return Err(Error::invalid(
                            loc(),
                            format!("face index {i} is out of range (only {n} vertices so far)"),
                        ));
                    }
                    face.push(idx as u32);
                }
                if face.len() < 3 {
                    return Err(Error::invalid(loc(), format!("face has {} vertices (needs 3 or more)", face.len())));
                }
                triangles.extend((1..face.len() - 1).map(|k| [face[0], face[k], face[k + 1]]));
            }
            _ => {}
        }
    }
    if triangles.is_empty() {
        return Err(Error::invalid(name, "no faces found (is this an OBJ file?)"));
    }
    Asset::from_static(name, positions, triangles)
}
