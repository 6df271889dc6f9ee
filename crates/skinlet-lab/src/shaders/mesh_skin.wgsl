// Mesh-shader skinning (after common.wgsl and draw.wgsl; the module starts with
// `enable wgpu_mesh_shader;`): one workgroup per meshlet skins the meshlet's vertices and
// emits its triangles (thesis chapter 4). Workgroup memory is written before it is read
// (lavapipe does not zero it in mesh shaders).

struct Meshlet {
    vertex_offset: u32,
    vertex_count: u32,
    triangle_offset: u32,
    triangle_count: u32,
    // Slim meshlets (slim_skin.wgsl): their joint list; count 0 otherwise.
    joint_offset: u32,
    joint_count: u32,
    pad0: u32,
    pad1: u32,
}

@group(2) @binding(0) var<storage, read> meshlets: array<Meshlet>;
@group(2) @binding(1) var<storage, read> meshlet_vertices: array<u32>;
// Three local vertex indices per triangle, packed in the low three bytes.
@group(2) @binding(2) var<storage, read> meshlet_triangles: array<u32>;

struct Primitive {
    @builtin(triangle_indices) indices: vec3<u32>,
    // Per-triangle culling (task_cull.wgsl); false elsewhere.
    @builtin(cull_primitive) cull: bool,
    // Multiplies the shading (white: plain drawing; a meshlet's color in the colored views).
    @per_primitive @location(1) color: vec4<f32>,
}

struct PrimitiveIn {
    @per_primitive @location(1) color: vec4<f32>,
}

@fragment
fn shade_colored(in: VertexOut, primitive: PrimitiveIn) -> @location(0) vec4<f32> {
    return lit(in) * primitive.color;
}

struct MeshOutput {
    @builtin(vertices) vertices: array<VertexOut, 128>,
    @builtin(primitives) primitives: array<Primitive, 256>,
    @builtin(vertex_count) vertex_count: u32,
    @builtin(primitive_count) primitive_count: u32,
}

var<workgroup> mesh_out: MeshOutput;

// Meshlets are numbered across a 2D grid of mesh workgroups, 1024 per row.
const ROW: u32 = 1024u;

// Skins meshlet `id`'s vertices into the mesh outputs and emits its triangles in `color`.
fn emit_meshlet(id: u32, lid: u32, color: vec4<f32>) {
    if id >= arrayLength(&meshlets) {
        mesh_out.vertex_count = 0u;
        mesh_out.primitive_count = 0u;
        return;
    }
    let m = meshlets[id];
    for (var i = lid; i < m.vertex_count; i += 32u) {
        mesh_out.vertices[i] = to_screen(skin_vertex(meshlet_vertices[m.vertex_offset + i]).position);
    }
    emit_triangles(m, lid, color);
}

// Sets the output counts and emits meshlet `m`'s triangles in `color`.
fn emit_triangles(m: Meshlet, lid: u32, color: vec4<f32>) {
    mesh_out.vertex_count = m.vertex_count;
    mesh_out.primitive_count = m.triangle_count;
    for (var i = lid; i < m.triangle_count; i += 32u) {
        let t = meshlet_triangles[m.triangle_offset + i];
        mesh_out.primitives[i].indices = vec3<u32>(t & 255u, (t >> 8u) & 255u, (t >> 16u) & 255u);
        mesh_out.primitives[i].color = color;
        mesh_out.primitives[i].cull = false;
    }
}

@mesh(mesh_out)
@workgroup_size(32)
fn mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    emit_meshlet(wg.y * ROW + wg.x, lid, vec4<f32>(1.0));
}

// Per meshlet an RGBA8 color (the colored views).
@group(3) @binding(3) var<storage, read> meshlet_colors: array<u32>;

@mesh(mesh_out)
@workgroup_size(32)
fn colored_mesh(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let id = wg.y * ROW + wg.x;
    emit_meshlet(id, lid, unpack4x8unorm(meshlet_colors[min(id, arrayLength(&meshlet_colors) - 1u)]));
}
