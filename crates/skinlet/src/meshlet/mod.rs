//! Meshlets: small clusters of triangles (at most `max_vertices` vertices and
//! `max_triangles` triangles) with a local vertex list and local u8 triangle indices, the
//! unit of mesh-shader rendering and of skinlet's culling.
//!
//! Seven builders share one layout ([`Meshlets`]) and one entry point ([`build`]):
//! [`scan`] (thesis listing 4.1), [`common_influences`] (thesis listing 4.2 / A.2),
//! [`greedy`] (meshoptimizer's three: greedy, flex, spatial), [`skin_aware`] and
//! [`cone_split`] (ours: skin-aware meshlets cut by face normal where that saves skinning).
//! Every builder works on a [`prepare()`]d mesh (welded, vertex-cache ordered). Every meshlet whose vertices all have
//! the same set of influencing joints carries that set once ([`Meshlet::joint_count`] > 0),
//! so those vertices can use a slim format without joint IDs (thesis section 3.1.1).
//!
//! Guarantee (checked by [`Meshlets::validate`] and the tests): every triangle of the
//! prepared mesh is in exactly one meshlet, with its winding, and no limit is exceeded.

pub mod common_influences;
pub mod cone_split;
pub mod flat;
pub mod greedy;
pub mod lod;
pub mod prepare;
pub mod scan;
pub mod skin_aware;
pub mod sources;
pub mod stats;

pub use prepare::{PartRange, PreparedMesh, prepare, prepare_parts};

use crate::model::Influences;
use crate::{Error, Result};

/// Size limits of one meshlet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshletLimits {
    pub max_vertices: usize,
    pub max_triangles: usize,
}

impl MeshletLimits {
    /// NVIDIA's recommendation (64 vertices, 126 triangles) as meshoptimizer uses it: 124
    /// triangles, a multiple of 4. (126 works too: the meshoptimizer-backed builders then
    /// fill meshlets to 124, see [`greedy`].)
    pub const NVIDIA: MeshletLimits = MeshletLimits { max_vertices: 64, max_triangles: 124 };
    /// Common on AMD RDNA and in UE5 Nanite-style renderers.
    pub const LARGE: MeshletLimits = MeshletLimits { max_vertices: 128, max_triangles: 256 };
    /// Small square meshlets (e.g. Apple / mobile mesh shading).
    pub const SMALL: MeshletLimits = MeshletLimits { max_vertices: 64, max_triangles: 64 };

    pub fn check(&self) -> Result<()> {
        if !(3..=256).contains(&self.max_vertices) || !(1..=512).contains(&self.max_triangles) {
            return Err(Error::invalid(
                "meshlet limits",
                format!(
                    "{} vertices / {} triangles: need 3..=256 vertices and 1..=512 triangles",
                    self.max_vertices, self.max_triangles
                ),
            ));
        }
        Ok(())
    }
}

impl Default for MeshletLimits {
    fn default() -> Self {
        MeshletLimits::NVIDIA
    }
}

/// One meshlet: ranges into [`Meshlets::vertices`], [`Meshlets::triangles`] (3 bytes per
/// triangle) and [`Meshlets::joints`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Meshlet {
    pub vertex_offset: u32,
    pub triangle_offset: u32,
    pub joint_offset: u32,
    pub vertex_count: u16,
    pub triangle_count: u16,
    /// Number of joints shared by every vertex of the meshlet; 0 when they differ.
    pub joint_count: u16,
}

impl Meshlet {
    /// True when all vertices have the same joint set (the thesis' "optimal" meshlet).
    pub fn single_joint_set(&self) -> bool {
        self.joint_count > 0
    }
}

/// A mesh split into meshlets.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Meshlets {
    pub meshlets: Vec<Meshlet>,
    /// Mesh vertex index of each meshlet-local vertex.
    pub vertices: Vec<u32>,
    /// Local vertex indices, three per triangle.
    pub triangles: Vec<u8>,
    /// Shared joint sets (ascending joint numbers) of single-joint-set meshlets.
    pub joints: Vec<u16>,
}

impl Meshlets {
    pub fn len(&self) -> usize {
        self.meshlets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.meshlets.is_empty()
    }

    pub fn vertices_of(&self, m: &Meshlet) -> &[u32] {
        &self.vertices[m.vertex_offset as usize..m.vertex_offset as usize + m.vertex_count as usize]
    }

    pub fn triangles_of(&self, m: &Meshlet) -> &[u8] {
        &self.triangles[m.triangle_offset as usize..m.triangle_offset as usize + 3 * m.triangle_count as usize]
    }

    pub fn joints_of(&self, m: &Meshlet) -> &[u16] {
        &self.joints[m.joint_offset as usize..m.joint_offset as usize + m.joint_count as usize]
    }

    /// The meshlet's triangles as mesh vertex indices.
    pub fn mesh_triangles<'a>(&'a self, m: &'a Meshlet) -> impl Iterator<Item = [u32; 3]> + 'a {
        let v = self.vertices_of(m);
        self.triangles_of(m).chunks_exact(3).map(move |t| [v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]])
    }

    /// Appends a meshlet given its local vertices and local triangles.
    pub fn push(&mut self, vertices: &[u32], triangles: &[u8]) {
        self.meshlets.push(Meshlet {
            vertex_offset: self.vertices.len() as u32,
            triangle_offset: self.triangles.len() as u32,
            joint_offset: self.joints.len() as u32,
            vertex_count: vertices.len() as u16,
            triangle_count: (triangles.len() / 3) as u16,
            joint_count: 0,
        });
        self.vertices.extend_from_slice(vertices);
        self.triangles.extend_from_slice(triangles);
    }

    /// Appends a meshlet given its triangles as mesh vertex indices (three per triangle):
    /// its vertices in order of first use. The caller keeps within the limits.
    pub fn push_triangles(&mut self, triangles: &[u32]) {
        let mut vertices: Vec<u32> = Vec::new();
        let local: Vec<u8> = (triangles.iter())
            .map(|&v| match vertices.iter().position(|&x| x == v) {
                Some(i) => i as u8,
                None => {
                    vertices.push(v);
                    (vertices.len() - 1) as u8
                }
            })
            .collect();
        self.push(&vertices, &local);
    }

    /// The meshlets of `range`, in order (joint sets not copied).
    pub fn subset(&self, range: std::ops::Range<usize>) -> Meshlets {
        let mut out = Meshlets::default();
        for m in &self.meshlets[range] {
            out.push(self.vertices_of(m), self.triangles_of(m));
        }
        out
    }

    /// Appends `other`'s meshlets, whose vertex numbers start at `vertex_base` in this mesh
    /// (joint sets are not copied: [`annotate_joint_sets`] recomputes them).
    pub fn append(&mut self, other: &Meshlets, vertex_base: u32) {
        for m in &other.meshlets {
            let v: Vec<u32> = other.vertices_of(m).iter().map(|&i| i + vertex_base).collect();
            self.push(&v, other.triangles_of(m));
        }
    }

    /// Checks the guarantee: limits kept, local indices in range, and the meshlets' triangles
    /// are exactly `triangles` (each once, same winding up to rotation).
    pub fn validate(&self, triangles: &[[u32; 3]], limits: MeshletLimits) -> Result<()> {
        let fail = |i: usize, msg: String| Err(Error::invalid(format!("meshlet {i}"), msg));
        let mut got: Vec<[u32; 3]> = Vec::with_capacity(triangles.len());
        for (i, m) in self.meshlets.iter().enumerate() {
            if m.vertex_count as usize > limits.max_vertices || m.triangle_count as usize > limits.max_triangles {
                return fail(
                    i,
                    format!("{} vertices / {} triangles exceed the limits", m.vertex_count, m.triangle_count),
                );
            }
            if m.triangle_count == 0 {
                return fail(i, "is empty".into());
            }
            if self.triangles_of(m).iter().any(|&t| t as u16 >= m.vertex_count) {
                return fail(i, "local index out of range".into());
            }
            got.extend(self.mesh_triangles(m).map(canonical));
        }
        let mut want: Vec<[u32; 3]> = triangles.iter().copied().map(canonical).collect();
        got.sort_unstable();
        want.sort_unstable();
        if got != want {
            return Err(Error::invalid("meshlets", "the meshlets' triangles differ from the mesh's"));
        }
        Ok(())
    }
}

/// A triangle rotated so its smallest index comes first (winding kept).
pub use skinlet_runtime::overdraw_orders::canonical;

/// Which meshlet builder to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Builder {
    Scan,
    CommonInfluences,
    Meshopt,
    SkinAware,
    ConeSplit,
    MeshoptFlex,
    MeshoptSpatial,
}

impl Builder {
    pub const ALL: [Builder; 7] = [
        Builder::Scan,
        Builder::CommonInfluences,
        Builder::Meshopt,
        Builder::SkinAware,
        Builder::ConeSplit,
        Builder::MeshoptFlex,
        Builder::MeshoptSpatial,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Builder::Scan => "scan",
            Builder::CommonInfluences => "common-influences",
            Builder::Meshopt => "meshopt",
            Builder::SkinAware => "skin-aware",
            Builder::ConeSplit => "cone-split",
            Builder::MeshoptFlex => "meshopt-flex",
            Builder::MeshoptSpatial => "meshopt-spatial",
        }
    }

    pub fn from_name(name: &str) -> Option<Builder> {
        Builder::ALL.into_iter().find(|b| b.name() == name)
    }
}

/// Splits a prepared mesh into meshlets with the chosen builder, part by part (no meshlet
/// holds triangles of two parts; the meshlets follow the parts' order), and records shared
/// joint sets.
pub fn build(prepared: &PreparedMesh, builder: Builder, limits: MeshletLimits) -> Result<Meshlets> {
    build_moving(prepared, builder, limits, None)
}

/// [`build`], with the poses the bounds will cover sampled for the builders that read them
/// (cone-split: cones over the poses, not the rest pose alone).
pub fn build_moving(
    prepared: &PreparedMesh,
    builder: Builder,
    limits: MeshletLimits,
    motion: Option<&cone_split::Motion>,
) -> Result<Meshlets> {
    limits.check()?;
    let mesh = &prepared.mesh;
    let one = |mesh: &crate::model::SkinnedMesh| build_one(mesh, builder, limits, motion);
    let mut meshlets = if prepared.parts.len() <= 1 {
        one(mesh)
    } else if builder == Builder::ConeSplit {
        cone_split::build_parts(mesh, &prepared.parts, limits, &cone_split::Params::default(), motion)
    } else {
        let mut all = Meshlets::default();
        for p in &prepared.parts {
            all.append(&one(&mesh.slice(p.vertices.clone(), p.triangles.clone())), p.vertices.start);
        }
        all
    };
    if let Some(inf) = &mesh.influences {
        annotate_joint_sets(&mut meshlets, inf);
    }
    Ok(meshlets)
}

/// The meshlets of a mesh that is one part, by `builder` (defaults for its parameters).
pub(crate) fn build_one(
    mesh: &crate::model::SkinnedMesh,
    builder: Builder,
    limits: MeshletLimits,
    motion: Option<&cone_split::Motion>,
) -> Meshlets {
    match builder {
        Builder::Scan => scan::build(&mesh.triangles, mesh.positions.len(), limits),
        Builder::CommonInfluences => common_influences::build(mesh, limits),
        Builder::Meshopt => greedy::build(&mesh.triangles, &mesh.positions, limits, greedy::CONE_WEIGHT),
        Builder::SkinAware => skin_aware::build(mesh, limits, &skin_aware::Params::default()),
        // One part; several go through `build_parts` (one budget over all of them).
        Builder::ConeSplit => cone_split::build(mesh, limits, &cone_split::Params::default(), motion),
        Builder::MeshoptFlex => greedy::build_with(&mesh.triangles, &mesh.positions, limits, greedy::FLEX),
        Builder::MeshoptSpatial => greedy::build_with(&mesh.triangles, &mesh.positions, limits, greedy::SPATIAL),
    }
}

/// The poses [`build_moving`] reads for `builder` over `clips` (about 48 in all, 2 to 8 per
/// clip, fewer on meshes of over 87k vertices: at most 4M skinned positions, 48 MB, unless
/// that leaves fewer than 2 per clip); `None` for builders that read none, or without clips.
pub fn motion_for(
    builder: Builder,
    skeleton: &crate::model::Skeleton,
    skin: &crate::model::Skin,
    mesh: &crate::model::SkinnedMesh,
    clips: &[&crate::clip::Clip],
) -> Result<Option<cone_split::Motion>> {
    if builder != Builder::ConeSplit || clips.is_empty() || mesh.influences.is_none() {
        return Ok(None);
    }
    let poses = 48.min((1 << 22) / mesh.positions.len().max(1));
    let per_clip = (poses / clips.len()).clamp(2, 8);
    cone_split::Motion::sample(skeleton, skin, mesh, clips, per_clip).map(Some)
}

/// Sorted non-zero joints of vertex `v`.
pub fn joint_set(inf: &Influences, v: usize) -> Vec<u16> {
    let mut s: Vec<u16> = inf.of(v).map(|(j, _)| j).collect();
    s.sort_unstable();
    s
}

/// Sets `joint_count`/`joint_offset` of every meshlet whose vertices share one joint set.
pub fn annotate_joint_sets(meshlets: &mut Meshlets, inf: &Influences) {
    meshlets.joints.clear();
    for i in 0..meshlets.meshlets.len() {
        let m = meshlets.meshlets[i];
        let verts = meshlets.vertices_of(&m);
        let first = joint_set(inf, verts[0] as usize);
        let shared = verts.iter().all(|&v| joint_set(inf, v as usize) == first);
        let m = &mut meshlets.meshlets[i];
        m.joint_offset = meshlets.joints.len() as u32;
        m.joint_count = if shared { first.len() as u16 } else { 0 };
        if shared {
            meshlets.joints.extend_from_slice(&first);
        }
    }
}

/// Local packing shared by the scan-style builders: adds triangles in order, closing the
/// current meshlet when the next triangle would exceed a limit.
pub(crate) struct Packer {
    limits: MeshletLimits,
    local: Vec<u16>,
    verts: Vec<u32>,
    tris: Vec<u8>,
}

impl Packer {
    const NONE: u16 = u16::MAX;

    pub(crate) fn new(vertex_count: usize, limits: MeshletLimits) -> Packer {
        Packer { limits, local: vec![Self::NONE; vertex_count], verts: Vec::new(), tris: Vec::new() }
    }

    pub(crate) fn add(&mut self, t: [u32; 3], out: &mut Meshlets) {
        let new = t
            .iter()
            .enumerate()
            .filter(|&(k, &v)| self.local[v as usize] == Self::NONE && !t[..k].contains(&v))
            .count();
        if self.verts.len() + new > self.limits.max_vertices || self.tris.len() / 3 >= self.limits.max_triangles {
            self.flush(out);
        }
        for v in t {
            if self.local[v as usize] == Self::NONE {
                self.local[v as usize] = self.verts.len() as u16;
                self.verts.push(v);
            }
            self.tris.push(self.local[v as usize] as u8);
        }
    }

    pub(crate) fn flush(&mut self, out: &mut Meshlets) {
        if self.tris.is_empty() {
            return;
        }
        out.push(&self.verts, &self.tris);
        for &v in &self.verts {
            self.local[v as usize] = Self::NONE;
        }
        self.verts.clear();
        self.tris.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SkinnedMesh;
    use glam::Vec3;
    use proptest::prelude::*;

    #[test]
    fn a_triangle_past_the_vertices_is_an_error_not_a_panic() {
        let mesh = SkinnedMesh { positions: vec![Vec3::ZERO; 3], triangles: vec![[0, 1, 5]], ..SkinnedMesh::default() };
        let e = prepare(&mesh).unwrap_err().to_string();
        assert!(e.contains("vertex 5"), "{e}");
    }

    /// A random skinned triangle soup: arbitrary connectivity (also non-manifold and
    /// repeated triangles), 1–4 influences per vertex over `joints` joints.
    fn random_mesh(seed: u64, vertices: usize, triangles: usize, joints: u16) -> SkinnedMesh {
        let mut s = seed | 1;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let positions: Vec<Vec3> =
            (0..vertices).map(|_| Vec3::new(next() as f32, next() as f32, next() as f32) / u64::MAX as f32).collect();
        let tris = (0..triangles)
            .map(|_| {
                let a = (next() % vertices as u64) as u32;
                // Mostly local triangles, like real meshes, plus some long ones.
                let near = |x: u64| ((a as u64 + x % 16) % vertices as u64) as u32;
                let (b, c) = if next() % 8 == 0 {
                    ((next() % vertices as u64) as u32, (next() % vertices as u64) as u32)
                } else {
                    (near(1 + next()), near(1 + next()))
                };
                [a, b, c]
            })
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        let mut inf = Influences { stride: 4, joints: vec![0; 4 * vertices], weights: vec![0.0; 4 * vertices] };
        for v in 0..vertices {
            let k = (1 + (next() % 4) as usize).min(joints as usize);
            let base = (v * joints as usize / vertices) as u16;
            let sum: f32 = (0..k).map(|i| 1.0 / (i + 1) as f32).sum();
            let mut seen: Vec<u16> = Vec::new();
            for i in 0..k {
                // Distinct joints near the vertex's "bone", weights decreasing.
                let mut j = (base + i as u16 * (1 + (next() % 2) as u16)) % joints;
                while seen.contains(&j) {
                    j = (j + 1) % joints;
                }
                seen.push(j);
                inf.joints[4 * v + i] = j;
                inf.weights[4 * v + i] = 1.0 / (i + 1) as f32 / sum;
            }
        }
        SkinnedMesh { positions, triangles: tris, influences: Some(inf), ..SkinnedMesh::default() }
    }

    fn check_all_builders(mesh: &SkinnedMesh, limits: MeshletLimits) {
        let prepared = prepare(mesh).unwrap();
        for b in Builder::ALL {
            let m = build(&prepared, b, limits).unwrap();
            m.validate(&prepared.mesh.triangles, limits).unwrap_or_else(|e| panic!("{}: {e}", b.name()));
            let inf = prepared.mesh.influences.as_ref().unwrap();
            for h in &m.meshlets {
                if h.single_joint_set() {
                    assert!(m.vertices_of(h).iter().all(|&v| joint_set(inf, v as usize) == m.joints_of(h)));
                }
            }
            assert_eq!(flat::from_bytes(&flat::to_bytes(&m)).unwrap(), m, "{}: flat layout round trip", b.name());
            assert_eq!(flat::to_bytes(&m).len(), flat::byte_len(&m));
        }
        // cone-split (one part here): deterministic; its cuts stay within 1.3× meshopt's count
        // (or skin-aware's where that is more), and it keeps them or another builder's meshlets
        // where those leave less expected skinning, whatever their count.
        let built = |b| build(&prepared, b, limits).unwrap();
        let split = built(Builder::ConeSplit);
        assert_eq!(split, built(Builder::ConeSplit));
        assert_eq!(prepared.parts.len(), 1);
        let (meshopt, skin_aware) = (built(Builder::Meshopt).len(), built(Builder::SkinAware).len());
        let budget = ((1.3 * meshopt as f32) as usize).max(skin_aware);
        let others: Vec<Meshlets> = Builder::ALL.into_iter().filter(|&b| b != Builder::ConeSplit).map(built).collect();
        assert!(
            split.len() <= budget || others.contains(&split),
            "{} meshlets: over the budget of {budget} and not another builder's",
            split.len()
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
        #[test]
        fn every_builder_is_valid_on_random_meshes(
            seed in any::<u64>(),
            vertices in 3usize..3000,
            tri_factor in 1usize..4,
            joints in 1u16..40,
            limits in prop_oneof![
                Just(MeshletLimits::NVIDIA), Just(MeshletLimits::LARGE), Just(MeshletLimits::SMALL),
                (3usize..=256, 1usize..=512).prop_map(|(v, t)| MeshletLimits { max_vertices: v, max_triangles: t }),
            ],
        ) {
            check_all_builders(&random_mesh(seed, vertices, vertices * tri_factor, joints), limits);
        }
    }

    #[test]
    fn cone_split_over_its_budget_is_another_builders_meshlets() {
        // Found by the property above: tiny limits, one joint; a builder with more meshlets
        // than the budget leaves less expected skinning, and cone-split takes its meshlets.
        let limits = MeshletLimits { max_vertices: 5, max_triangles: 4 };
        check_all_builders(&random_mesh(0, 412, 412, 1), limits);
    }

    #[test]
    fn welding_and_degenerate_triangles_are_handled() {
        // Two triangles sharing an edge through duplicated vertices, plus a degenerate one.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X, Vec3::Y, Vec3::ONE];
        let inf = Influences { stride: 4, joints: vec![0; 24], weights: [1.0, 0.0, 0.0, 0.0].repeat(6) };
        let mesh = SkinnedMesh {
            positions: p.to_vec(),
            triangles: vec![[0, 1, 2], [3, 5, 4], [0, 0, 1]],
            influences: Some(inf),
            ..SkinnedMesh::default()
        };
        let prepared = prepare(&mesh).unwrap();
        assert_eq!(prepared.weld.output_vertices, 4);
        assert_eq!(prepared.dropped_triangles, 1);
        for b in Builder::ALL {
            let m = build(&prepared, b, MeshletLimits::NVIDIA).unwrap();
            assert_eq!(m.len(), 1);
            assert!(m.meshlets[0].single_joint_set());
            assert_eq!(m.joints, vec![0]);
        }
    }

    #[test]
    fn bad_limits_and_corrupt_flat_buffers_are_errors() {
        let prepared = prepare(&random_mesh(3, 100, 200, 4)).unwrap();
        for limits in [
            MeshletLimits { max_vertices: 300, max_triangles: 124 },
            MeshletLimits { max_vertices: 2, max_triangles: 124 },
            MeshletLimits { max_vertices: 64, max_triangles: 0 },
        ] {
            assert!(build(&prepared, Builder::Scan, limits).is_err());
        }
        let bytes = flat::to_bytes(&build(&prepared, Builder::Meshopt, MeshletLimits::NVIDIA).unwrap());
        for cut in [0, 3, 16, bytes.len() - 1] {
            assert!(flat::from_bytes(&bytes[..cut]).is_err());
        }
        let mut bad = bytes.clone();
        bad[16..20].copy_from_slice(&u32::MAX.to_le_bytes()); // first meshlet's vertex offset
        assert!(flat::from_bytes(&bad).unwrap_err().to_string().contains("meshlet 0"));
        // A triangle offset inside a triangle (in range, not a multiple of 3).
        let mut bad = bytes.clone();
        bad[20..24].copy_from_slice(&1u32.to_le_bytes()); // first meshlet's triangle offset
        assert!(flat::from_bytes(&bad).unwrap_err().to_string().contains("triangle offset"));
    }
}
