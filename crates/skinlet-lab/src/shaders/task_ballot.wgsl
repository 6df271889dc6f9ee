// Task-shader culling with survivors compacted by subgroup operations (after task_cull.wgsl;
// only where the device has subgroups): each subgroup counts its survivors, one lane reserves
// their places with a single atomic, and each survivor writes at the subgroup's base plus its
// rank among the subgroup's survivors (instead of one atomic per survivor).

@task
@payload(payload)
@workgroup_size(32)
fn task_ballot(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(subgroup_invocation_id) lane: u32,
) -> @builtin(mesh_task_size) vec3<u32> {
    if lid == 0u {
        atomicStore(&survivors, 0u);
    }
    workgroupBarrier();
    let slot = task_range.first + wg.x * 32u + lid;
    var visible = 0u;
    var id = 0u;
    if slot < task_range.first + task_range.count {
        let s = slots[slot];
        visible = select(0u, 1u, meshlet_flag(s, task_range.instance) == 0u);
        id = s.id;
    }
    let rank = subgroupExclusiveAdd(visible);
    let count = subgroupAdd(visible);
    // Every lane is active here: lane 0 reserves for the subgroup.
    var base = 0u;
    if lane == 0u {
        base = atomicAdd(&survivors, count);
    }
    base = subgroupBroadcast(base, 0u);
    if visible == 1u {
        payload.ids[base + rank] = id;
    }
    return launch(lid);
}
