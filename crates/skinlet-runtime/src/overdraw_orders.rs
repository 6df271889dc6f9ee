//! The run-time half of animated overdraw orders (Han & Sander 2016, section 3.3): a bake
//! stores a few index buffers, each ordered for low overdraw over a cluster of (keyframe,
//! viewpoint) nodes, and a table that names the buffer for each keyframe and view direction;
//! [`Orders::select`] picks the one to draw. The baker (`skinlet::overdraw`) clusters the
//! nodes and orders the buffers.

use crate::Result;
use crate::bake_view::{BakedPartRecord, Cursor};
use glam::{Mat4, Vec3};

/// Where viewpoints sit: on the sphere of `3 × radius` around `center`, looking at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Framing {
    pub center: Vec3,
    pub radius: f32,
}

impl Framing {
    /// The bounding sphere (box center, farthest point) of every keyframe's positions.
    pub fn of(keyframes: &[Vec<Vec3>]) -> Framing {
        let all = keyframes.iter().flatten();
        let (lo, hi) = all.clone().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
        let center = if lo.x <= hi.x { (lo + hi) / 2.0 } else { Vec3::ZERO };
        let radius = all.map(|p| p.distance(center)).fold(0.0f32, f32::max).max(1e-6);
        Framing { center, radius }
    }

    /// The eye for a unit direction `dir` at `distance` radii.
    pub fn eye(&self, dir: Vec3, distance: f32) -> Vec3 {
        self.center + dir * self.radius * distance
    }

    /// A perspective view-projection from `eye` that frames the bounding sphere.
    pub fn view_proj(&self, eye: Vec3) -> Mat4 {
        let d = eye.distance(self.center).max(self.radius * 1.01);
        let fov = 2.0 * (self.radius / d).clamp(-1.0, 1.0).asin() * 1.05;
        let up = if (eye - self.center).normalize_or_zero().y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        Mat4::perspective_rh(fov, 1.0, (d - self.radius) * 0.5, d + self.radius * 2.0)
            * Mat4::look_at_rh(eye, self.center, up)
    }
}

/// The run-time table (section 3.3): for each keyframe and each (polar, azimuth) cell, the
/// buffer of the nearest stored viewpoint.
#[derive(Clone, Debug, PartialEq)]
pub struct Lookup {
    pub keyframes: usize,
    pub polar: usize,
    pub azimuth: usize,
    pub table: Vec<u8>,
}

impl Lookup {
    /// The buffer for keyframe `f` seen from unit direction `dir` (model space, from the
    /// model's center toward the eye), both rounded to the nearest stored value.
    pub fn get(&self, f: usize, dir: Vec3) -> u8 {
        let dir = dir.normalize_or(Vec3::Z);
        let theta = dir.z.clamp(-1.0, 1.0).acos();
        let phi = dir.y.atan2(dir.x).rem_euclid(std::f32::consts::TAU);
        let i = (theta / std::f32::consts::PI * self.polar.saturating_sub(1).max(1) as f32).round() as usize;
        let j = (phi / std::f32::consts::TAU * self.azimuth as f32).round() as usize % self.azimuth.max(1);
        let f = f.min(self.keyframes.saturating_sub(1));
        // An empty table (no keyframes) selects buffer 0.
        let cell = (f * self.polar + i.min(self.polar.saturating_sub(1))) * self.azimuth + j;
        self.table.get(cell).copied().unwrap_or(0)
    }
}

/// How the triangles were cut into the patches an order moves whole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Patches {
    /// Sander et al. 2007's fast linear clustering of the Tipsify order at threshold λ
    /// (the paper's; larger λ: smaller patches, worse vertex-cache use).
    Linear { lambda: f32 },
    /// Compact patches of at most `size` vertices and triangles (meshoptimizer meshlets,
    /// each in Tipsify order; skinlet's default, size 32).
    Compact { size: u32 },
}

impl Default for Patches {
    fn default() -> Self {
        Patches::Compact { size: 32 }
    }
}

impl Patches {
    /// The one `f32` a bake stores (`docs/FORMAT.md`): λ (> 0) or −size.
    pub fn to_f32(self) -> f32 {
        match self {
            Patches::Linear { lambda } => lambda,
            Patches::Compact { size } => -(size as f32),
        }
    }

    /// The inverse of [`Patches::to_f32`]; `None` for a value neither can store (zero, not
    /// finite, or a negative non-integer).
    pub fn from_f32(x: f32) -> Option<Patches> {
        if x.is_finite() && x > 0.0 {
            Some(Patches::Linear { lambda: x })
        } else if x.is_finite() && x <= -1.0 && x.fract() == 0.0 && x >= -(u32::MAX as f32) {
            Some(Patches::Compact { size: -x as u32 })
        } else {
            None
        }
    }
}

impl std::fmt::Display for Patches {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Patches::Linear { lambda } => write!(f, "linear λ={lambda}"),
            Patches::Compact { size } => write!(f, "compact {size}"),
        }
    }
}

/// What a bake stores for run-time selection: the buffers, the keyframes they were
/// clustered for, the framing the viewpoints were placed with, and the lookup table.
#[derive(Clone, Debug, PartialEq)]
pub struct Orders {
    pub patches: Patches,
    /// (clip index among the baked clips, time) of each keyframe.
    pub keyframes: Vec<(u32, f32)>,
    pub framing: Framing,
    pub buffers: Vec<Vec<[u32; 3]>>,
    pub lookup: Lookup,
}

impl Orders {
    /// Lookup cells per keyframe the baker stores: 37 polar × 72 azimuth (5°).
    pub const CELLS: (usize, usize) = (37, 72);

    /// The buffer to draw for `clip` at `time` seen from `eye` (model space): the nearest
    /// stored keyframe of that clip (the first keyframe when the clip has none), then the
    /// lookup by the direction from the model's center to the eye.
    pub fn select(&self, clip: u32, time: f32, eye: Vec3) -> usize {
        let f = (0..self.keyframes.len())
            .filter(|&f| self.keyframes[f].0 == clip)
            .min_by(|&a, &b| (self.keyframes[a].1 - time).abs().total_cmp(&(self.keyframes[b].1 - time).abs()))
            .unwrap_or(0);
        self.lookup.get(f, (eye - self.framing.center).normalize_or(Vec3::Z)) as usize
    }
}

impl Orders {
    /// Reads and checks a bake's `OVDR` bytes (`docs/FORMAT.md`) for a mesh of `triangles`
    /// in `parts`, baked over `clips` clips: every buffer a reordering of exactly the
    /// triangles (windings kept), each part's triangles inside the part's triangle range,
    /// keyframes naming baked clips, lookup cells naming stored buffers.
    pub fn read(section: &[u8], triangles: &[[u32; 3]], parts: &[BakedPartRecord], clips: usize) -> Result<Orders> {
        let mut s = Cursor::new("OVDR", section);
        let (k, f, polar, azimuth) = (s.u32()? as usize, s.u32()? as usize, s.u32()? as usize, s.u32()? as usize);
        if k == 0 || k > 255 || polar == 0 || azimuth == 0 || f == 0 {
            return Err(s.err(format!("{k} buffers, {f} keyframes, {polar} × {azimuth} cells")));
        }
        let rule = s.f32()?;
        let patches = Patches::from_f32(rule).ok_or_else(|| s.err(format!("patch rule {rule} (λ > 0 or −size)")))?;
        let framing = Framing { center: s.vec3()?, radius: s.f32()? };
        if f.saturating_mul(8) > s.remaining() {
            return Err(s.err(format!("{f} keyframes do not fit in the section")));
        }
        let mut keyframes = Vec::with_capacity(f);
        for i in 0..f {
            let (clip, t) = (s.u32()?, s.f32()?);
            if clip as usize >= clips {
                return Err(s.err(format!("keyframe {i} names clip {clip} of {clips}")));
            }
            keyframes.push((clip, t));
        }
        let mut want: Vec<[u32; 3]> = triangles.iter().map(|t| canonical(*t)).collect();
        want.sort_unstable();
        let mut buffers = Vec::with_capacity(k);
        for b in 0..k {
            let n = s.u32()? as usize;
            if n.saturating_mul(12) > s.remaining() {
                return Err(s.err(format!("{n} triangles do not fit in the section")));
            }
            let buf = (0..n).map(|_| Ok([s.u32()?, s.u32()?, s.u32()?])).collect::<Result<Vec<[u32; 3]>>>()?;
            let mut got: Vec<[u32; 3]> = buf.iter().map(|t| canonical(*t)).collect();
            got.sort_unstable();
            if got != want {
                return Err(s.err(format!("buffer {b} is not a reordering of the mesh's triangles")));
            }
            let outside = |p: &BakedPartRecord| {
                let own = p.vertices[0]..p.vertices[1];
                let range = buf.get(p.triangles[0] as usize..p.triangles[1] as usize);
                range.is_none_or(|r| r.iter().flatten().any(|v| !own.contains(v)))
            };
            if let Some(p) = parts.iter().position(outside) {
                return Err(s.err(format!("buffer {b} moves a triangle out of part {p}'s range")));
            }
            buffers.push(buf);
        }
        let cells =
            f.checked_mul(polar).and_then(|x| x.checked_mul(azimuth)).ok_or_else(|| s.err("lookup table too large"))?;
        let table = s.bytes(cells)?.to_vec();
        if let Some(bad) = table.iter().position(|&b| b as usize >= k) {
            return Err(s.err(format!("lookup cell {bad} names buffer {} of {k}", table[bad])));
        }
        s.align(4)?;
        s.end()?;
        Ok(Orders { patches, keyframes, framing, buffers, lookup: Lookup { keyframes: f, polar, azimuth, table } })
    }
}

/// A triangle rotated so its smallest index comes first (winding kept).
pub fn canonical(t: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

/// The unit direction at polar angle `theta` from +z and azimuth `phi` from +x toward +y.
pub fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// Fragments that passed the depth test and pixels covered by one render: what an overdraw
/// order is measured by (the baker's rasterizer and skinlet-gpu's overdraw view both fill it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Overdraw {
    pub shaded: u64,
    pub covered: u64,
}

impl Overdraw {
    /// OVR: shaded fragments per visible pixel (1 = no overdraw; 0 when nothing is visible).
    pub fn ratio(&self) -> f64 {
        if self.covered == 0 { 0.0 } else { self.shaded as f64 / self.covered as f64 }
    }

    pub fn add(&mut self, o: Overdraw) {
        self.shaded += o.shaded;
        self.covered += o.covered;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lookup_without_cells_selects_buffer_0() {
        for (polar, azimuth) in [(0, 0), (0, 4), (3, 0)] {
            let l = Lookup { keyframes: 2, polar, azimuth, table: Vec::new() };
            assert_eq!(l.get(1, Vec3::Y), 0);
        }
    }

    #[test]
    fn patch_rules_round_trip_through_their_stored_number() {
        for p in [Patches::Linear { lambda: 0.85 }, Patches::Linear { lambda: 3.0 }, Patches::Compact { size: 32 }] {
            assert_eq!(Patches::from_f32(p.to_f32()), Some(p));
        }
        for bad in [0.0, -0.5, -2.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(Patches::from_f32(bad), None, "{bad}");
        }
    }
}
