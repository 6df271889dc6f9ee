//! A frame of CPU culling allocates nothing once its buffers have grown: preparing and
//! culling instances with the bounds, with the bounds and the any-pose boxes, with the boxes
//! alone and with nothing, the pose guard, and the per-joint box update, counted by a
//! counting global allocator over many frames of moving joints; and a frame of contour
//! extraction with skinned patches (equal to brute force on every frame).

use glam::{Affine3A, DMat4, DVec3, Quat, Vec3};
use skinlet_runtime::Trs;
use skinlet_runtime::any_pose::AnyPoseBoxes;
use skinlet_runtime::camera::{Camera, Projection};
use skinlet_runtime::contour_edges::{Edges, brute_force};
use skinlet_runtime::contour_patches::{ClipWindows, PatchBounds, Patches, SkinnedPatches};
use skinlet_runtime::joint_boxes::{Box3, JointBoxes, JointSpace};
use skinlet_runtime::meshlet_bounds::{Class, MeshletBounds};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
use skinlet_runtime::pose_guard::{NodeRange, PoseGuard};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    /// Allocations made by this thread (tests run on threads of their own, in parallel).
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    ALLOCATIONS.with(|c| c.set(c.get() + 1));
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator, counting calls that allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's promises hold for System too.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `alloc` above, that is from System.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: as for `alloc` and `dealloc`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const JOINTS: usize = 12;

/// A character of `JOINTS` joints along x, four meshlets per joint, two boxes per meshlet.
fn character() -> (MeshletCuller, JointBoxes) {
    let mut bounds = Vec::new();
    let mut classes = Vec::new();
    let mut boxes = AnyPoseBoxes { offsets: vec![0], ..AnyPoseBoxes::default() };
    for j in 0..JOINTS {
        for k in 0..4 {
            let axis = [Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y][k];
            bounds.push(MeshletBounds {
                joint: j as u16,
                center: axis * 0.3,
                radius: 0.4,
                rest_radius: 0.35,
                cone_axis: axis,
                cone_angle: 0.6,
                rest_cone_angle: 0.5,
            });
            classes.push([Class::Both, Class::FrustumOnly, Class::Both, Class::None][k]);
            for joint in [j, (j + 1) % JOINTS] {
                boxes.joints.push(joint as u16);
                boxes.center.push(axis * 0.3);
                boxes.half.push(Vec3::splat(0.4));
            }
            boxes.offsets.push(boxes.joints.len() as u32);
        }
    }
    let culler = MeshletCuller::new(&bounds, &classes, JOINTS).unwrap().with_any_pose(&boxes).unwrap();
    let extents: Vec<_> = (0..JOINTS)
        .map(|j| (Vec3::new(j as f32 - 0.5, -0.5, -0.5).as_dvec3(), Vec3::new(j as f32 + 0.5, 0.5, 0.5).as_dvec3()))
        .collect();
    (culler, JointBoxes::from_boxes(JointSpace::Joint, &extents).unwrap())
}

#[test]
fn a_frame_of_cpu_culling_allocates_nothing() {
    let (culler, joint_boxes) = character();
    let ranges: Vec<NodeRange> = (0..JOINTS as u32)
        .map(|node| NodeRange {
            node,
            centre: Quat::IDENTITY,
            angle: 0.5,
            translation: (Vec3::splat(-0.1), Vec3::splat(1.1)),
            scale: (Vec3::splat(0.9), Vec3::splat(1.1)),
        })
        .collect();
    let guard = PoseGuard::new(&ranges, &[]).unwrap();
    let camera =
        Camera::perspective(Vec3::new(4.0, 3.0, 12.0), Vec3::new(5.0, 0.0, 0.0), Vec3::Y, 1.0, 1.5, 0.1, 100.0)
            .unwrap();
    let (mut frame, mut flags, mut visible) = (JointFrame::default(), Vec::new(), Vec::new());
    let (mut locals, mut world, mut boxes_out) = (Vec::new(), Vec::new(), vec![Box3::EMPTY; 1]);
    let mut frame_of = |f: usize, culled: &mut usize, counted: bool| {
        let before = allocations();
        for instance in 0..16 {
            // Each instance's pose: joints in a row, turning more with the frame; every
            // fourth instance turns past the guard's cap.
            let turn = (f as f32 * 0.05 + instance as f32 * 0.1).sin() * if instance % 4 == 0 { 2.0 } else { 0.3 };
            locals.clear();
            locals.extend((0..JOINTS).map(|_| Trs { rotation: Quat::from_rotation_z(turn), ..Trs::IDENTITY }));
            world.clear();
            let model = Affine3A::from_translation(Vec3::new(instance as f32 * 0.7 - 5.0, 0.0, -(instance as f32)));
            let mut g = model;
            for l in &locals {
                g *= Affine3A::from_rotation_translation(l.rotation, Vec3::X);
                world.push(g);
            }
            match (guard.admits(&locals, &[]), f % 3) {
                (true, 0) => culler.prepare(&world, &camera, Tests::Both, &mut frame),
                (true, _) => culler.prepare_with_boxes(&world, &camera, Tests::Both, &mut frame),
                (false, 1) => frame.set_keep_all(JOINTS),
                (false, _) => culler.prepare_boxes_only(&world, &camera, Tests::Both, &mut frame),
            }
            visible.clear();
            let counts = culler.cull(&frame, &mut flags, &mut visible);
            *culled += counts.meshlets - counts.visible;
            joint_boxes.update_all(&world, JOINTS, &mut boxes_out).unwrap();
        }
        let after = allocations();
        if counted {
            assert_eq!(after - before, 0, "frame {f} allocated {} times", after - before);
        }
    };
    let mut culled = 0;
    // The first frames grow the buffers; none after may allocate.
    for f in 0..3 {
        frame_of(f, &mut culled, false);
    }
    for f in 3..200 {
        frame_of(f, &mut culled, true);
    }
    assert!(culled > 0, "nothing was culled: the frames would not exercise the culling");
}

/// A closed UV sphere of `rings × segments` quads split into triangles.
fn sphere(rings: u32, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = vec![Vec3::Z];
    for r in 1..rings {
        let (s, c) = (std::f32::consts::PI * r as f32 / rings as f32).sin_cos();
        p.extend((0..segments).map(|k| {
            let (y, x) = (std::f32::consts::TAU * k as f32 / segments as f32).sin_cos();
            Vec3::new(s * x, s * y, c)
        }));
    }
    p.push(-Vec3::Z);
    let at = |r: u32, k: u32| 1 + (r - 1) * segments + k % segments;
    let mut t = Vec::new();
    for k in 0..segments {
        t.push([0, at(1, k), at(1, k + 1)]);
        t.push([p.len() as u32 - 1, at(rings - 1, k + 1), at(rings - 1, k)]);
        for r in 1..rings - 1 {
            t.push([at(r, k), at(r + 1, k), at(r + 1, k + 1)]);
            t.push([at(r, k), at(r + 1, k + 1), at(r, k + 1)]);
        }
    }
    (p, t)
}

/// Patches of 16 consecutive quads with a sphere around their vertices and a cone around
/// their faces' normals (exact, in f64, widened a little): valid bounds built by hand.
fn patches(p: &[Vec3], edges: &Edges) -> SkinnedPatches {
    let mut patches = Patches::default();
    let ids: Vec<u32> = (0..edges.quads.len() as u32).collect();
    for chunk in ids.chunks(16) {
        let points: Vec<DVec3> =
            chunk.iter().flat_map(|&q| edges.quads[q as usize]).map(|v| p[v as usize].as_dvec3()).collect();
        let center = points.iter().sum::<DVec3>() / points.len() as f64;
        let radius = points.iter().map(|x| x.distance(center)).fold(0.0, f64::max);
        let normals: Vec<DVec3> = chunk
            .iter()
            .flat_map(|&q| {
                let [a, b, c, d] = edges.quads[q as usize].map(|v| p[v as usize].as_dvec3());
                [(b - a).cross(c - a).normalize(), (d - a).cross(b - a).normalize()]
            })
            .collect();
        let axis = normals.iter().sum::<DVec3>().normalize();
        let angle = normals.iter().map(|n| n.dot(axis).clamp(-1.0, 1.0).acos()).fold(0.0, f64::max);
        patches.ranges.push([patches.order.len() as u32, chunk.len() as u32]);
        patches.bounds.push(PatchBounds::new(center, radius, axis, angle + 1e-6));
        patches.order.extend_from_slice(chunk);
    }
    patches.always_from = patches.order.len();
    patches.quads = patches.order.iter().map(|&q| edges.quads[q as usize]).collect();
    let n = patches.bounds.len();
    SkinnedPatches {
        joints: vec![0; n],
        rigid_quads: patches.order.len(),
        animated_quads: 0,
        clips: vec![ClipWindows { start: 0.0, end: 1.0, count: 1, first: 0 }],
        window_bounds: patches.bounds.clone(),
        patches,
    }
}

#[test]
fn a_frame_of_contour_extraction_allocates_nothing_and_equals_brute_force() {
    let (rest, triangles) = sphere(24, 48);
    let edges = Edges::build(&rest, &triangles).unwrap();
    let patches = patches(&rest, &edges);
    // Reserved once: a frame's contour is at most every edge.
    let (mut posed, mut got, mut want) = (Vec::new(), Vec::with_capacity(edges.len()), Vec::new());
    let mut culled = 0;
    for f in 0..100 {
        // One joint carries the whole sphere: turned, stretched and moved with the frame.
        let g = DMat4::from_scale_rotation_translation(
            DVec3::new(1.0, 1.5, 0.8),
            glam::DQuat::from_rotation_y(f as f64 * 0.07),
            DVec3::new(0.3, -0.2, f as f64 * 0.01),
        );
        posed.clear();
        posed.extend(rest.iter().map(|x| g.transform_point3(x.as_dvec3()).as_vec3()));
        let eye = Vec3::new((f as f32 * 0.1).sin() * 6.0, 2.0, 5.0);
        let projection = if f % 2 == 0 {
            Projection::Perspective { eye }
        } else {
            Projection::Orthographic { dir: -eye.normalize() }
        };
        let before = allocations();
        let tested = patches.extract(&posed, &edges, &[g], Some((0, 0.5)), projection, &mut got);
        let after = allocations();
        assert_eq!(after - before, 0, "frame {f} allocated {} times", after - before);
        brute_force(&posed, &edges, projection, &mut want);
        got.sort_unstable();
        assert_eq!(got, want, "frame {f}");
        culled += edges.quads.len() - tested.edges;
    }
    assert!(culled > 0, "no patch was culled: the frames would not exercise the cone test");
}
