//! The runtime's promise to a caller: every public entry point takes any lengths and any
//! values (NaN and infinities included) and answers with an `Err` or a conservative result
//! (a box or sphere that holds everything, a meshlet kept), never a panic. One property per
//! entry point, fed random lengths and values; where an answer can be checked for being
//! conservative without a reference, it is.

use glam::{Affine3A, DMat4, DVec3, Mat4, Quat, Vec3};
use proptest::prelude::*;
use skinlet_runtime::Trs;
use skinlet_runtime::any_pose::AnyPoseBoxes;
use skinlet_runtime::bake_view::BakeView;
use skinlet_runtime::camera::{Camera, Projection, planes};
use skinlet_runtime::contour_edges::{Edges, Viewer, brute_force, extract_uncullable, quad_is_contour};
use skinlet_runtime::contour_patches::{BakedContours, ClipWindows, skinned_edges};
use skinlet_runtime::joint_boxes::{Box3, JointBoxes, JointSpace};
use skinlet_runtime::meshlet_bounds::{Class, MeshletBounds};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
use skinlet_runtime::overdraw_orders::{Lookup, Orders};
use skinlet_runtime::part_bounds::{PartBounds, PoseBounds};
use skinlet_runtime::pose_guard::{NodeRange, PoseGuard};
use skinlet_runtime::source_corners::{PartSource, source_corners};

/// Any f32, weighted toward the awkward ones.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -10.0f32..10.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(0.0f32),
        1 => any::<f32>(),
    ]
}

fn any_vec3() -> impl Strategy<Value = Vec3> {
    (any_f32(), any_f32(), any_f32()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Mostly finite, well-formed matrices (so that culling really runs), some with any numbers.
fn any_affine() -> impl Strategy<Value = Affine3A> {
    prop_oneof![
        4 => (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0, 0.1f32..3.0, -3.0f32..3.0).prop_map(|(x, y, z, s, a)| {
            Affine3A::from_scale_rotation_translation(Vec3::splat(s), Quat::from_rotation_y(a), Vec3::new(x, y, z))
        }),
        1 => proptest::array::uniform12(any_f32()).prop_map(|a| Affine3A::from_cols_array(&a)),
    ]
}

fn affines(max: usize) -> impl Strategy<Value = Vec<Affine3A>> {
    proptest::collection::vec(any_affine(), 0..max)
}

/// Mostly bounds a culler accepts (so that culling really runs), some with any numbers.
fn any_bounds(joints: u16) -> impl Strategy<Value = MeshletBounds> {
    let valid = (0..joints + 2, any_unit(), 0.0f32..3.0, 0.0f32..std::f32::consts::PI, -3.0f32..3.0).prop_map(
        |(joint, axis, radius, angle, x)| MeshletBounds {
            joint,
            center: Vec3::new(x, -x, 0.5 * x),
            radius,
            rest_radius: radius,
            cone_axis: axis,
            cone_angle: angle,
            rest_cone_angle: angle,
        },
    );
    let any = (0..joints + 2, any_vec3(), any_f32(), any_vec3(), any_f32(), any_f32(), any_f32()).prop_map(
        |(joint, center, radius, cone_axis, cone_angle, rest_radius, rest_cone_angle)| MeshletBounds {
            joint,
            center,
            radius,
            rest_radius,
            cone_axis,
            cone_angle,
            rest_cone_angle,
        },
    );
    prop_oneof![4 => valid, 1 => any]
}

fn any_unit() -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z).normalize_or(Vec3::Z))
}

fn any_class() -> impl Strategy<Value = Class> {
    prop_oneof![Just(Class::Both), Just(Class::FrustumOnly), Just(Class::None)]
}

fn any_tests() -> impl Strategy<Value = Tests> {
    prop_oneof![Just(Tests::Both), Just(Tests::Frustum), Just(Tests::Backface)]
}

/// A valid camera looking at the origin from a random place (perspective or orthographic).
fn camera() -> impl Strategy<Value = Camera> {
    (-8.0f32..8.0, -8.0f32..8.0, 2.0f32..8.0, any::<bool>()).prop_map(|(x, y, z, ortho)| {
        let eye = Vec3::new(x, y, z);
        if ortho {
            Camera::orthographic(eye, Vec3::ZERO, Vec3::Y, 3.0, 3.0, 0.1, 50.0).unwrap()
        } else {
            Camera::perspective(eye, Vec3::ZERO, Vec3::Y, 1.0, 1.5, 0.1, 50.0).unwrap()
        }
    })
}

/// The bytes of a small valid bake: one driver (node 0), a tetrahedron of four vertices on it
/// with normals, one meshlet with its bounds, one part, each triangle's source (the same
/// triangle of a primitive indexed as `TRIS`). Each section 16-byte aligned.
fn tetrahedron_bake() -> Vec<u8> {
    let w = |v: &[u32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let f = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let p = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0f32]];
    let n: Vec<f32> = p.iter().flat_map(|v| Vec3::from(*v).normalize().to_array()).collect();
    let tris = [[0u32, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    let mut vert = w(&[4, 4, 1]);
    vert.extend(f(p.as_flattened()));
    vert.extend(f(&n));
    vert.extend([0u8; 32]); // 16 joint numbers, all driver 0
    vert.extend(f(&[1.0, 0.0, 0.0, 0.0].repeat(4)));
    let mut tri = w(&[4]);
    tri.extend(w(tris.as_flattened()));
    let packed = 4 | 4 << 9 | 1 << 19 | 1 << 31;
    let mut mlet = w(&[1, 4, 12, 1, 0, 0, 0, packed, 0, 1, 2, 3]);
    mlet.extend(tris.as_flattened().iter().map(|&i| i as u8));
    mlet.extend([0u8; 4]); // joint set [0], padded
    let mut bnds = w(&[1, 0, 0, 0]);
    bnds.extend(f(&[0.0, 0.0, 0.0, 1.8, 0.0, 0.0, 1.0, 2.0, 1.8, 3.0]));
    bnds.extend(w(&[0, 2]));
    let mut skin = w(&[1]);
    skin.extend(f(Mat4::IDENTITY.as_ref()));
    skin.extend(w(&[0, 0]));
    let info = [w(&[2, 64, 124]), f(&[0.0, 0.0]), w(&[0, 0, 0])].concat();
    let part = w(&[1, 0, 0, 0, 0, 0, 4, 0, 4, 0, 1]);
    let sources = w(&[4, 0, 1, 2, 3]);
    let sections: [(&[u8; 4], Vec<u8>); 8] = [
        (b"INFO", info),
        (b"SKIN", skin),
        (b"VERT", vert),
        (b"TRIS", tri),
        (b"MLET", mlet),
        (b"BNDS", bnds),
        (b"PART", part),
        (b"SRCT", sources),
    ];
    let mut b = [&b"SKINLET\0"[..], &w(&[3, sections.len() as u32])].concat();
    b.resize(16 + 24 * sections.len(), 0);
    for (k, (tag, body)) in sections.iter().enumerate() {
        b.resize(b.len().next_multiple_of(16), 0);
        let e = 16 + 24 * k;
        let offset = b.len() as u64;
        b[e..e + 4].copy_from_slice(*tag);
        b[e + 8..e + 16].copy_from_slice(&offset.to_le_bytes());
        b[e + 16..e + 24].copy_from_slice(&(body.len() as u64).to_le_bytes());
        b.extend_from_slice(body);
    }
    b
}

/// Bytes in 4-byte aligned storage, as `BakeView::new` needs them.
fn aligned(bytes: &[u8]) -> Vec<u32> {
    let mut words = vec![0u32; bytes.len().div_ceil(4)];
    bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
    words
}

#[test]
fn the_tetrahedron_bake_is_valid() {
    let bytes = tetrahedron_bake();
    let words = aligned(&bytes);
    let view = BakeView::new(&bytemuck::cast_slice(&words)[..bytes.len()]).unwrap();
    assert_eq!((view.joint_count(), view.meshlet_count(), view.parts().len()), (1, 1, 1));
    let (indices, positions) = tetrahedron_source();
    let source = PartSource { indices: Some(&indices), vertices: 4, positions: Some(&positions) };
    let corners = source_corners(&view, &[source]).unwrap();
    let vertices: Vec<u32> = corners.iter().map(|c| c.vertex).collect();
    assert_eq!(vertices, indices);
    assert!(corners.iter().zip(&indices).all(|(c, &i)| c.source == i && c.part == 0));
}

/// The tetrahedron's primitive as an engine loads it: indices and positions.
fn tetrahedron_source() -> (Vec<u32>, Vec<[f32; 3]>) {
    let indices = vec![0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2];
    (indices, vec![[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// `BakeView::new` on a valid bake with bytes overwritten (or cut): an error, or a view
    /// whose culler, part boxes and mesh data run on any frame.
    #[test]
    fn bake_view_takes_any_bytes(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..3),
        cut in any::<prop::sample::Index>(),
        truncate in proptest::bool::weighted(0.1),
        joints in affines(3),
        weights in proptest::collection::vec(any_f32(), 0..3),
        cam in camera(),
        indices in proptest::option::of(proptest::collection::vec(0u32..8, 0..16)),
        vertices in 0u32..8,
        moved in any::<bool>(),
    ) {
        let mut bytes = tetrahedron_bake();
        for (at, x) in &edits {
            let i = at.index(bytes.len());
            bytes[i] = *x;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        let words = aligned(&bytes);
        if let Ok(view) = BakeView::new(&bytemuck::cast_slice(&words)[..bytes.len()]) {
            let _ = view.meshlets().index_buffer();
            let (_, mut positions) = tetrahedron_source();
            positions.resize(vertices as usize, [0.0; 3]);
            positions.iter_mut().for_each(|p| p[0] += moved as u8 as f32);
            let positions = (vertices > 0).then_some(&positions[..]);
            let _ = source_corners(&view, &[PartSource { indices: indices.as_deref(), vertices, positions }]);
            if let Ok(culler) = view.culler() {
                let mut frame = JointFrame::default();
                culler.prepare(&joints, &cam, Tests::Both, &mut frame);
                culler.cull(&frame, &mut Vec::new(), &mut Vec::new());
            }
            let parts = PartBounds::new(&view);
            if let Ok(parts) = parts {
                for pose in [PoseBounds::Any, PoseBounds::Clips, PoseBounds::Envelope, PoseBounds::ClipAt { clip: 0, time: 0.5 }] {
                    for i in 0..parts.parts().len() + 1 {
                        parts.part_box(i, &Affine3A::IDENTITY, &joints, &weights, pose);
                    }
                }
            }
        }
    }

    /// `MeshletCuller`: any bounds are an error or a culler; any matrices (too few, too many,
    /// not finite), cameras and frames from another culler cull without a panic, and a
    /// meshlet whose principal joint the frame does not reach is kept.
    #[test]
    fn culler_takes_any_bounds_and_frames(
        records in proptest::collection::vec((any_bounds(4), any_class()), 0..12),
        short in 0usize..8,
        joints in prop_oneof![4 => 4usize..7, 1 => 0usize..4],
        other in 0usize..7,
        matrices in affines(8),
        box_data in proptest::collection::vec((0u16..6, any_vec3(), any_vec3()), 12),
        cam in camera(),
        tests in any_tests(),
    ) {
        let (bounds, mut classes): (Vec<MeshletBounds>, Vec<Class>) = records.into_iter().unzip();
        // Now and then a class short.
        classes.truncate(classes.len().saturating_sub((short == 0) as usize));
        // One box per meshlet.
        let n = bounds.len();
        let boxes = AnyPoseBoxes {
            offsets: (0..=n as u32).collect(),
            joints: box_data[..n].iter().map(|b| b.0).collect(),
            center: box_data[..n].iter().map(|b| b.1).collect(),
            half: box_data[..n].iter().map(|b| b.2.abs()).collect(),
        };
        let Ok(culler) = MeshletCuller::new(&bounds, &classes, joints) else { return Ok(()) };
        let culler = culler.clone().with_any_pose(&boxes).unwrap_or(culler);
        let others = MeshletCuller::new(&[], &[], other).unwrap();
        let (mut frame, mut flags, mut visible) = (JointFrame::default(), Vec::new(), Vec::new());
        for prepare in 0..3 {
            for source in [&culler, &others] {
                match prepare {
                    0 => source.prepare(&matrices, &cam, tests, &mut frame),
                    1 => source.prepare_with_boxes(&matrices, &cam, tests, &mut frame),
                    _ => source.prepare_boxes_only(&matrices, &cam, tests, &mut frame),
                }
                visible.clear();
                let counts = culler.cull(&frame, &mut flags, &mut visible);
                prop_assert_eq!(counts.meshlets, culler.len());
                let reached = frame.joints();
                for (i, b) in bounds.iter().enumerate() {
                    // The any-pose boxes may cull any meshlet; the bounds only those whose
                    // joint the frame reaches.
                    if (b.joint as usize) >= reached && !frame.any_pose() {
                        prop_assert!(visible.contains(&(i as u32)), "meshlet {} of joint {} culled by a frame of {} joints", i, b.joint, reached);
                    }
                }
            }
        }
        let keep = JointFrame::keep_all(joints);
        visible.clear();
        culler.cull(&keep, &mut flags, &mut visible);
        prop_assert_eq!(visible.len(), culler.len(), "a keep-all frame culled");
    }

    /// `JointBoxes`: any boxes are an error or boxes; any matrices give a box (the infinite
    /// one when too few) and a sphere; `update_all` with any stride and lengths is an error or
    /// the boxes `update` gives.
    #[test]
    fn joint_boxes_take_any_matrices(
        boxes in proptest::collection::vec((any_vec3(), any_vec3()), 0..6),
        mesh in any::<bool>(),
        matrices in affines(8),
        stride in 0usize..8,
        instances in 0usize..3,
    ) {
        let space = if mesh { JointSpace::Mesh } else { JointSpace::Joint };
        let boxes: Vec<(DVec3, DVec3)> = boxes.iter().map(|(a, b)| (a.as_dvec3(), b.as_dvec3())).collect();
        let Ok(jb) = JointBoxes::from_boxes(space, &boxes) else { return Ok(()) };
        jb.update(&matrices);
        jb.sphere(&matrices);
        let mut out = vec![Box3::EMPTY; instances];
        let palette: Vec<Affine3A> = matrices.iter().cycle().take(stride * instances).copied().collect();
        if jb.update_all(&palette, stride, &mut out).is_ok() {
            // Each instance's box is the one `update` gives for its matrices.
            for (i, o) in out.iter().enumerate() {
                let one = jb.update(&palette[i * stride..(i + 1) * stride]);
                let same = |a: Vec3, b: Vec3| a.to_array().iter().zip(b.to_array()).all(|(x, y)| x == &y || x.is_nan() && y.is_nan());
                prop_assert!(same(o.min, one.min) && same(o.max, one.max), "{:?} against {:?}", o, one);
            }
            // A palette one instance short of `out` is an error.
            let mut more = vec![Box3::EMPTY; instances + 1];
            prop_assert!(stride == 0 || jb.update_all(&palette, stride, &mut more).is_err());
        }
    }

    /// `PoseGuard`: any ranges are an error or a guard; any pose (too few or too many nodes
    /// and weights, any numbers) is admitted or not, never a panic, and a pose with a NaN is
    /// never admitted.
    #[test]
    fn pose_guard_takes_any_pose(
        ranges in proptest::collection::vec((0u32..5, prop_oneof![4 => 0.1f32..3.1, 1 => any_f32()], any_vec3(), any_vec3()), 0..4),
        weight_ranges in proptest::collection::vec((any_f32(), any_f32()), 0..3),
        locals in proptest::collection::vec((any_vec3(), any_f32(), any_vec3()), 0..7),
        weights in proptest::collection::vec(any_f32(), 0..4),
    ) {
        let nodes: Vec<NodeRange> = ranges
            .iter()
            .map(|&(node, angle, lo, hi)| NodeRange {
                node,
                centre: Quat::IDENTITY,
                angle,
                translation: (lo.min(hi), lo.max(hi)),
                scale: (Vec3::splat(0.5), Vec3::splat(2.0)),
            })
            .collect();
        let weight_ranges: Vec<(f32, f32)> = weight_ranges.iter().map(|&(a, b)| (a.min(b), a.max(b))).collect();
        let Ok(guard) = PoseGuard::new(&nodes, &weight_ranges) else { return Ok(()) };
        let locals: Vec<Trs> = locals
            .iter()
            .map(|&(translation, a, scale)| Trs { translation, rotation: Quat::from_rotation_x(a), scale })
            .collect();
        let admitted = guard.admits(&locals, &weights);
        if weights.iter().take(weight_ranges.len()).any(|w| w.is_nan()) {
            prop_assert!(!admitted, "a NaN morph weight was admitted");
        }
        guard.admits_weights(&weights);
    }

    /// Contour entry points: any positions and triangles are an error or edges; the tests
    /// with positions shorter than the mesh (a vertex missing) never panic.
    #[test]
    fn contours_take_any_mesh(
        positions in proptest::collection::vec(any_vec3(), 0..8),
        triangles in proptest::collection::vec([0u32..10, 0u32..10, 0u32..10], 0..8),
        shorter in 0usize..8,
        eye in any_vec3(),
        quad in [0u32..10, 0u32..10, 0u32..10, 0u32..10],
    ) {
        let projection = Projection::Perspective { eye };
        if let Ok(edges) = Edges::build(&positions, &triangles) {
            let p = &positions[..shorter.min(positions.len())];
            brute_force(p, &edges, projection, &mut Vec::new());
            extract_uncullable(p, &edges, &Viewer::new(projection), &mut Vec::new());
        }
        let _ = skinned_edges(&positions, &triangles, None);
        quad_is_contour(&positions, quad, &Viewer::new(projection));
        // A CONT section of any bytes: an error or patches that extract on any frame.
        let bytes: Vec<u8> = positions.iter().flat_map(|p| p.to_array()).flat_map(|x| x.to_le_bytes()).collect();
        if let Ok(edges) = Edges::build(&positions, &triangles)
            && let Ok(c) = BakedContours::read(&bytes, &edges, 2)
        {
            c.patches.extract(&positions, &edges, &[DMat4::IDENTITY], None, projection, &mut Vec::new());
        }
    }

    /// Clip windows and the overdraw lookup: any counts, times and directions give an index
    /// in range (or the fallback), never a panic.
    #[test]
    fn windows_and_lookups_take_any_values(
        start in any_f32(), end in any_f32(), count in 0u32..5, first in any::<u32>(), t in any_f32(),
        keyframes in 0usize..4, polar in 0usize..5, azimuth in 0usize..5, table in 0usize..40, f in 0usize..6,
        dir in any_vec3(),
    ) {
        let w = ClipWindows { start, end, count, first };
        let k = w.at(t);
        prop_assert!(k >= first && (count == 0 || k - first < count));
        w.range(count.saturating_sub(1));
        let lookup = Lookup { keyframes, polar, azimuth, table: vec![1; table] };
        let x = lookup.get(f, dir);
        prop_assert!(x <= 1);
        let _ = Orders::read(&[0u8; 16], &[], &[], 1);
    }

    /// Cameras: any numbers are an error or a camera whose planes are finite.
    #[test]
    fn cameras_take_any_numbers(
        eye in any_vec3(), target in any_vec3(), up in any_vec3(),
        a in any_f32(), b in any_f32(), near in any_f32(), far in any_f32(),
        m in proptest::array::uniform16(any_f32()),
    ) {
        for cam in [
            Camera::perspective(eye, target, up, a, b, near, far),
            Camera::orthographic(eye, target, up, a, b, near, far),
            Camera::from_view_proj(Mat4::from_cols_array(&m), Projection::Perspective { eye }),
            Camera::from_view_proj(Mat4::from_cols_array(&m), Projection::Orthographic { dir: eye }),
        ]
        .into_iter()
        .flatten()
        {
            prop_assert!(cam.planes.iter().all(|q| q.is_finite()), "an accepted camera without finite planes");
            prop_assert!(planes(&cam.view_proj).is_some());
        }
    }

    /// LOD thresholds: any numbers give a finite threshold ≥ 0.
    #[test]
    fn lod_thresholds_take_any_numbers(
        pixels in any_f32(), fov in any_f32(), aspect in any_f32(), eye in any_vec3(), forward in any_vec3(),
        center in any_vec3(), radius in any_f32(), scale in any_f32(), height in any::<u32>(),
    ) {
        let cam = skinlet_runtime::lod_select::LodCamera::perspective(eye, forward, fov, aspect, height);
        let t = cam.threshold(pixels, center, radius, scale);
        prop_assert!(t.is_finite() && t >= 0.0, "{t}");
        let t = cam.threshold_box(pixels, center.min(forward), center.max(forward), scale);
        prop_assert!(t.is_finite() && t >= 0.0, "{t}");
    }
}
