// The survivors of skinlet's crowd culling, drawn with one draw_indirect of their header: one
// instance per survivor, as many corners as the largest meshlet has. Reads the survivor list
// (DrawIndexedIndirectArgs, 5 words each) as `survivor_draws`, declared by the includer.

struct SurvivorCorner {
    // The crowd instance the survivor belongs to.
    instance: u32,
    // Where this corner's vertex index is in the caller's index buffer.
    index: u32,
    // false for corners past the meshlet's own (whole triangles: they are all dead or alive).
    live: bool,
}

fn survivor_corner(survivor: u32, corner: u32) -> SurvivorCorner {
    let c = 5u * survivor;
    var out: SurvivorCorner;
    out.instance = survivor_draws[c + 4u];
    out.live = corner < survivor_draws[c];
    out.index = survivor_draws[c + 2u] + select(0u, corner, out.live);
    return out;
}
