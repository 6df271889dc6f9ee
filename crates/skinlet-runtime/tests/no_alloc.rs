//! A frame of CPU culling allocates nothing once its buffers have grown: preparing and
//! culling instances with the bounds, with the bounds and the any-pose boxes, with the boxes
//! alone and with nothing, the pose guard, and the per-joint box update, counted by a
//! counting global allocator over many frames of moving joints.

use glam::{Affine3A, Quat, Vec3};
use skinlet_runtime::Trs;
use skinlet_runtime::any_pose::AnyPoseBoxes;
use skinlet_runtime::camera::Camera;
use skinlet_runtime::joint_boxes::{Box3, JointBoxes, JointSpace};
use skinlet_runtime::meshlet_bounds::{Class, MeshletBounds};
use skinlet_runtime::meshlet_cull::{JointFrame, MeshletCuller, Tests};
use skinlet_runtime::pose_guard::{NodeRange, PoseGuard};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, counting calls that allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's promises hold for System too.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `alloc` above, that is from System.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
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
    (culler, JointBoxes::from_boxes(JointSpace::Joint, &extents))
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
        let before = ALLOCATIONS.load(Ordering::Relaxed);
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
        let after = ALLOCATIONS.load(Ordering::Relaxed);
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
