// Contour extraction (Tsiapkolis & Bénard 2024, section 4.3) in three compute passes:
// `cull_patches` tests every patch's spatialized normal cone and appends the accepted ones;
// `test_edges` (dispatched indirectly, one workgroup per accepted patch) tests their quads;
// `test_uncullable` tests the irregular edges and appends the boundary edges. Contour edge ids
// go to `contours`, counted by the vertex count of the indirect line draw (two per edge).
//
// Both tests are skinlet's CPU tests with the same operations in the same order: the cone
// test in f32 (`PatchBounds::accepts_eye` / `accepts_dir`), the edge test in f64 on the f32
// positions (`quad_is_contour`, `irregular_is_contour`).

struct Frame {
    // The eye (w = 0), or the unit vector toward the viewer, −dir (w = 1).
    viewer: vec4<f32>,
    groups: u32,
    // First bound of this frame's bound set.
    bound_base: u32,
    irregular: u32,
    boundary: u32,
    // Edge id of the first irregular edge (the quad count); boundary edges follow them.
    first_irregular: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct Bound {
    center: vec3<f32>,
    radius: f32,
    axis: vec3<f32>,
    sin_angle: f32,
    cos_angle: f32,
}

struct State {
    accepted: atomic<u32>,
    tested: atomic<u32>,
    // DrawIndirectArgs of the line draw: two vertices per contour edge.
    vertex_count: atomic<u32>,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

const NONE: u32 = 0xffffffffu;
const MARGIN: f32 = 1e-5;

@group(0) @binding(0) var<uniform> frame: Frame;
// Per group of quads: first index into `quads`, count, joint (NONE: no view), bound (NONE:
// always accepted).
@group(0) @binding(1) var<storage, read> groups: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> bounds: array<Bound>;
// Per joint: the viewer in the joint's space, xyz and w: 0 eye, 1 direction, 2 none (accept).
@group(0) @binding(3) var<storage, read> views: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> accepted: array<u32>;
@group(0) @binding(5) var<storage, read_write> state: State;
@group(0) @binding(6) var<storage, read_write> dispatch: array<atomic<u32>, 3>;
@group(0) @binding(7) var<storage, read> positions: array<f32>;
@group(0) @binding(8) var<storage, read> quads: array<vec4<u32>>;
@group(0) @binding(9) var<storage, read> ids: array<u32>;
// Per irregular edge: first face, face count, its first vertex.
@group(0) @binding(10) var<storage, read> irregular: array<vec4<u32>>;
@group(0) @binding(11) var<storage, read> faces: array<u32>;
@group(0) @binding(12) var<storage, read_write> contours: array<u32>;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// PatchBounds::accepts_eye.
fn accepts_eye(b: Bound, eye: vec3<f32>) -> bool {
    let d = b.center - eye;
    let dist2 = dot3(d, d);
    let r = b.radius;
    let inv = 1.0 / sqrt(dist2);
    let sin_b = min(r * inv, 1.0);
    let cos_b = sqrt(max(1.0 - sin_b * sin_b, 0.0));
    let cos_sum = b.cos_angle * cos_b - b.sin_angle * sin_b;
    let sin_sum = b.sin_angle * cos_b + b.cos_angle * sin_b;
    let inside = dist2 <= r * r * (1.0 + 1e-4);
    return inside || cos_sum <= MARGIN || abs(dot3(b.axis, d) * inv) <= sin_sum + MARGIN;
}

// PatchBounds::accepts_dir.
fn accepts_dir(b: Bound, dir: vec3<f32>) -> bool {
    return b.cos_angle <= MARGIN || abs(dot3(b.axis, dir)) <= b.sin_angle + MARGIN;
}

@compute @workgroup_size(64)
fn cull_patches(@builtin(global_invocation_id) id: vec3<u32>) {
    let g = id.x;
    if g >= frame.groups {
        return;
    }
    let group = groups[g];
    var accept = group.z == NONE || group.w == NONE;
    if !accept {
        let view = views[group.z];
        let b = bounds[frame.bound_base + group.w];
        if view.w == 0.0 {
            accept = accepts_eye(b, view.xyz);
        } else if view.w == 1.0 {
            accept = accepts_dir(b, view.xyz);
        } else {
            accept = true;
        }
    }
    if accept {
        let slot = atomicAdd(&state.accepted, 1u);
        accepted[slot] = g;
        atomicMax(&dispatch[0], min(slot + 1u, 65535u));
    }
}

fn position(i: u32) -> vec3<f64> {
    return vec3<f64>(f64(positions[3u * i]), f64(positions[3u * i + 1u]), f64(positions[3u * i + 2u]));
}

// glam's DVec3::cross and dot, in their order.
fn cross64(a: vec3<f64>, b: vec3<f64>) -> vec3<f64> {
    return vec3<f64>(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}

fn dot64(a: vec3<f64>, b: vec3<f64>) -> f64 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// Viewer::toward: from point a toward the viewer.
fn toward(a: vec3<f64>) -> vec3<f64> {
    let v = vec3<f64>(frame.viewer.xyz);
    if frame.viewer.w == 1.0 {
        return v;
    }
    return v - a;
}

// quad_is_contour: faces (a, b, c) and (b, a, d) differ in facing.
fn quad_is_contour(q: vec4<u32>) -> bool {
    let a = position(q.x);
    let ab = position(q.y) - a;
    let n1 = cross64(ab, position(q.z) - a);
    let n2 = cross64(position(q.w) - a, ab);
    let v = toward(a);
    return (dot64(n1, v) > 0.0lf) != (dot64(n2, v) > 0.0lf);
}

fn append(edge: u32) {
    let slot = atomicAdd(&state.vertex_count, 2u) / 2u;
    contours[slot] = edge;
}

@compute @workgroup_size(64)
fn test_edges(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) workgroups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let count = atomicLoad(&state.accepted);
    for (var k = wg.x; k < count; k += workgroups.x) {
        let group = groups[accepted[k]];
        for (var i = lane; i < group.y; i += 64u) {
            if quad_is_contour(quads[group.x + i]) {
                append(ids[group.x + i]);
            }
        }
        if lane == 0u {
            atomicAdd(&state.tested, group.y);
        }
    }
}

fn facing(f: u32, v: vec3<f64>) -> bool {
    let x = position(faces[3u * f]);
    return dot64(cross64(position(faces[3u * f + 1u]) - x, position(faces[3u * f + 2u]) - x), v) > 0.0lf;
}

@compute @workgroup_size(64)
fn test_uncullable(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i == 0u {
        atomicAdd(&state.tested, frame.irregular);
    }
    if i < frame.irregular {
        // irregular_is_contour: the faces do not all face the same way.
        let e = irregular[i];
        let v = toward(position(e.z));
        let first = facing(e.x, v);
        var contour = false;
        for (var f = e.x + 1u; f < e.x + e.y; f++) {
            contour = contour || facing(f, v) != first;
        }
        if contour {
            append(frame.first_irregular + i);
        }
    } else if i < frame.irregular + frame.boundary {
        append(frame.first_irregular + i);
    }
}
