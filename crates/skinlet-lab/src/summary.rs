//! The facts `skinlet inspect` reports about an asset: counts as stored (each glTF mesh
//! once, however many nodes draw it), skins and their depth, the influence histogram,
//! what the importer changed, and per clip its time range, keys, channels and modes.

use skinlet::clip::Interpolation;
use skinlet::model::Asset;

#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub meshes: Vec<MeshSummary>,
    pub skins: Vec<SkinSummary>,
    /// Distinct joint nodes over all skins.
    pub joints: usize,
    pub vertices: usize,
    /// Vertices left after welding equal position + skin data (see [`skinlet::weld`]).
    pub welded_vertices: usize,
    pub triangles: usize,
    /// `influence_histogram[k - 1]`: skinned vertices with `k` non-zero weights (k = 1..8).
    pub influence_histogram: [usize; 8],
    pub instances: usize,
    pub clips: Vec<ClipSummary>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MeshSummary {
    pub name: String,
    pub primitives: Vec<PrimitiveSummary>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimitiveSummary {
    /// Index of the primitive in the glTF mesh.
    pub index: usize,
    pub vertices: usize,
    pub welded_vertices: usize,
    pub triangles: usize,
    pub skinned: bool,
    pub morph_targets: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SkinSummary {
    pub name: String,
    pub joints: usize,
    /// Parent links from the deepest joint up to its root.
    pub depth: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ClipSummary {
    pub name: String,
    pub start: f32,
    pub end: f32,
    pub duration: f32,
    /// Distinct key times over all channels.
    pub keys: usize,
    pub max_channel_keys: usize,
    /// Channel counts: translation, rotation, scale, morph weights.
    pub channels: [usize; 4],
    pub animated_nodes: usize,
    pub interpolation: Vec<Interpolation>,
}

pub fn summarize(asset: &Asset) -> Summary {
    let mut histogram = [0usize; 8];
    let mut vertices = 0;
    let mut welded_vertices = 0;
    let mut triangles = 0;
    let meshes = asset
        .meshes
        .iter()
        .map(|m| MeshSummary {
            name: m.name.clone(),
            primitives: m
                .primitives
                .iter()
                .map(|p| {
                    let g = &p.geometry;
                    vertices += g.positions.len();
                    triangles += g.triangles.len();
                    if let Some(inf) = &g.influences {
                        for v in 0..inf.vertex_count() {
                            let k = inf.count(v);
                            if k > 0 {
                                histogram[k - 1] += 1;
                            }
                        }
                    }
                    let welded = skinlet::weld::weld(g).2.output_vertices;
                    welded_vertices += welded;
                    PrimitiveSummary {
                        index: p.index,
                        vertices: g.positions.len(),
                        welded_vertices: welded,
                        triangles: g.triangles.len(),
                        skinned: g.influences.is_some(),
                        morph_targets: p.targets.len(),
                    }
                })
                .collect(),
        })
        .collect();
    let skins = asset
        .skins
        .iter()
        .map(|s| SkinSummary {
            name: s.name.clone(),
            joints: s.joints.len(),
            depth: s.joints.iter().map(|&j| asset.skeleton.depth(j)).max().unwrap_or(0),
        })
        .collect();
    let mut joint_nodes: Vec<u32> = asset.skins.iter().flat_map(|s| s.joints.iter().copied()).collect();
    joint_nodes.sort_unstable();
    joint_nodes.dedup();
    let clips = asset
        .clips
        .iter()
        .map(|c| {
            let mut nodes: Vec<u32> = c
                .translations
                .iter()
                .map(|x| x.node)
                .chain(c.rotations.iter().map(|x| x.node))
                .chain(c.scales.iter().map(|x| x.node))
                .collect();
            nodes.sort_unstable();
            nodes.dedup();
            ClipSummary {
                name: c.name.clone(),
                start: c.start,
                end: c.end,
                duration: c.duration(),
                keys: c.key_times().len(),
                max_channel_keys: c.max_channel_keys(),
                channels: [c.translations.len(), c.rotations.len(), c.scales.len(), c.weights.len()],
                animated_nodes: nodes.len(),
                interpolation: c.interpolations(),
            }
        })
        .collect();
    Summary {
        meshes,
        skins,
        joints: joint_nodes.len(),
        vertices,
        welded_vertices,
        triangles,
        influence_histogram: histogram,
        instances: asset.instances.len(),
        clips,
    }
}
