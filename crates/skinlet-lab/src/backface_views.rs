//! What backface culling of meshlets saves, view by view: random views around the
//! character (directions even over the sphere, at three times its radius, looking at it)
//! at random times of random clips, each culled by the backface test alone with the baked
//! bounds (conservative-bounds paper, section 6) and compared with per-triangle backface
//! culling of the skinned mesh, the limit of any backface culling (thesis 5.1.3; about half
//! the triangles of a closed mesh). Deterministic for a seed.

use crate::crowd::Rng;
use glam::Vec3;
use skinlet::Result;
use skinlet::bounds::sphere_cone::{Class, MeshletBounds};
use skinlet::clip::Clip;
use skinlet::cull::Camera;
use skinlet::cull::triangle::cull_triangles;
use skinlet::meshlet::Meshlets;
use skinlet::model::{Skeleton, Skin, SkinnedMesh};
use skinlet::pose::{Poser, joint_globals, skinning_matrices};
use skinlet::skinning::skin_mesh;
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};

/// Shares over all views (percent).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BackfaceSavings {
    pub views: usize,
    /// Meshlets culled by the backface test alone.
    pub meshlets_pct: f64,
    /// Triangles and vertex references (skinning) in those meshlets.
    pub triangles_pct: f64,
    pub skinning_pct: f64,
    /// Meshlet vertex references left to skin per view: absolute, to compare builders (more,
    /// narrower meshlets share fewer vertices).
    pub vertex_refs_skinned: f64,
    /// Triangles back-facing or edge-on one by one after skinning.
    pub backfacing_triangles_pct: f64,
}

/// Culls `views` random views of `mesh` (its `meshlets` with `bounds` and `classes`, over
/// the joints of `skin`) posed by `clips` (the rest pose without clips).
#[allow(clippy::too_many_arguments)]
pub fn backface_savings(
    skeleton: &Skeleton,
    skin: &Skin,
    clips: &[&Clip],
    mesh: &SkinnedMesh,
    meshlets: &Meshlets,
    bounds: &[MeshletBounds],
    classes: &[Class],
    views: usize,
    seed: u64,
) -> Result<BackfaceSavings> {
    let culler = MeshletCuller::new(bounds, classes, skin.joints.len())?;
    let tris: Vec<usize> = meshlets.meshlets.iter().map(|m| m.triangle_count as usize).collect();
    let refs: Vec<usize> = meshlets.meshlets.iter().map(|m| m.vertex_count as usize).collect();
    let (all_tris, all_refs): (usize, usize) = (tris.iter().sum(), refs.iter().sum());
    let every: Vec<u32> = (0..meshlets.len() as u32).collect();
    let mut rng = Rng(seed);
    let (mut poser, mut frame) = (Poser::default(), JointFrame::default());
    let (mut flags, mut visible, mut joints, mut matrices, mut weights) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut posed = vec![Vec3::ZERO; mesh.positions.len()];
    let (mut culled, mut culled_tris, mut culled_refs, mut backfacing) = (0, 0, 0, 0);
    for _ in 0..views {
        let clip = (!clips.is_empty()).then(|| clips[(rng.next() * clips.len() as f64) as usize % clips.len()]);
        let t = clip.map_or(0.0, |c| c.start + rng.next() as f32 * c.duration());
        // One pose: the joints' globals move the bounds, the skinning matrices the vertices.
        let globals = poser.globals(skeleton, clip, t);
        joint_globals(skin, globals, &mut joints);
        skinning_matrices(skin, globals, &mut matrices);
        mesh.morphs.weights_at(clip, t, &mut weights);
        skin_mesh(mesh, &weights, &matrices, &mut posed, &mut [])?;
        let (lo, hi) = posed.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
        let (center, radius) = ((lo + hi) / 2.0, ((hi - lo).length() / 2.0).max(1e-6));
        // A direction even over the sphere.
        let (z, phi) = (2.0 * rng.next() as f32 - 1.0, std::f32::consts::TAU * rng.next() as f32);
        let dir = Vec3::new((1.0 - z * z).max(0.0).sqrt() * phi.cos(), z, (1.0 - z * z).max(0.0).sqrt() * phi.sin());
        let up = if dir.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        let camera = Camera::perspective(center + 3.0 * radius * dir, center, up, 1.0, 1.0, radius, 5.0 * radius)?;
        culler.prepare(&joints, &camera, Tests::Backface, &mut frame);
        visible.clear();
        let counts = culler.cull(&frame, &mut flags, &mut visible);
        culled += counts.backface;
        let kept = visible.iter().fold((0, 0), |(t, r), &m| (t + tris[m as usize], r + refs[m as usize]));
        culled_tris += all_tris - kept.0;
        culled_refs += all_refs - kept.1;
        let one_by_one = cull_triangles(meshlets, &every, &posed, camera.projection, None);
        backfacing += one_by_one.backfacing + one_by_one.degenerate;
    }
    let pct = |n: usize, of: usize| 100.0 * n as f64 / (of * views).max(1) as f64;
    Ok(BackfaceSavings {
        views,
        meshlets_pct: pct(culled, meshlets.len()),
        triangles_pct: pct(culled_tris, all_tris),
        skinning_pct: pct(culled_refs, all_refs),
        vertex_refs_skinned: (all_refs * views - culled_refs) as f64 / views.max(1) as f64,
        backfacing_triangles_pct: pct(backfacing, all_tris),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::{DemoParams, demo_character};
    use skinlet::bounds::sphere_cone::{classify, meshlet_bounds};
    use skinlet::meshlet::{MeshletLimits, cone_split, skin_aware};

    #[test]
    fn culled_meshlets_hold_only_back_faces_and_cone_split_skins_less() {
        let asset = demo_character(&DemoParams { triangles: 6000, ..DemoParams::default() });
        let character = asset.character().unwrap();
        let prepared = skinlet::bake::prepare_character(&character).unwrap();
        let (skeleton, skin, mesh) = (&asset.skeleton, &character.palette, &prepared.mesh);
        let limits = MeshletLimits::NVIDIA;
        let savings = |meshlets: &Meshlets, clips: &[&Clip]| {
            let bounds = meshlet_bounds(skeleton, skin, clips, mesh, meshlets).unwrap();
            let classes: Vec<Class> = bounds.iter().map(|b| classify(b, 3.0, 20f32.to_radians())).collect();
            let s = backface_savings(skeleton, skin, clips, mesh, meshlets, &bounds, &classes, 48, 3).unwrap();
            assert_eq!(s, backface_savings(skeleton, skin, clips, mesh, meshlets, &bounds, &classes, 48, 3).unwrap());
            // Every triangle of a culled meshlet faces away: never more than one by one
            // (up to the f32 rounding of near edge-on triangles).
            assert!(s.triangles_pct <= s.backfacing_triangles_pct + 0.1, "{s:?}");
            assert!((40.0..60.0).contains(&s.backfacing_triangles_pct), "a closed body: {s:?}");
            s
        };
        let base = skin_aware::build(mesh, limits, &Default::default());
        let split = cone_split::build(mesh, limits, &cone_split::Params { budget: 2.0, ..Default::default() }, None);
        // Over the clips (the invariants above), and in the rest pose (every cone under 90°
        // usable), the pose cone-split's objective saw here, where it must skin less (by culling
        // more, or, where another builder's meshlets leave less to skin, by taking those).
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        savings(&split, &clips);
        let (rest_base, rest_split) = (savings(&base, &[]), savings(&split, &[]));
        assert!(rest_base.meshlets_pct > 0.0, "{rest_base:?}");
        assert!(rest_split.vertex_refs_skinned < rest_base.vertex_refs_skinned, "{rest_split:?} vs {rest_base:?}");
    }
}
