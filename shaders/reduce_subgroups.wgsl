// The workgroup reductions of the traversal with subgroup operations (the fast path, where the
// adapter has them: wgpu's SUBGROUP feature): each subgroup reduces its values first, and one of
// its invocations offers the result to the workgroup atomic, so that a workgroup of 32 makes
// 32 / (subgroup size) atomic operations instead of 32. Nothing here assumes a subgroup size.
// Every function is called in uniform control flow (all of the workgroup's invocations), with
// a neutral value from the invocations that have nothing to offer; `lane` is the invocation's
// local index, and the subgroup's first invocation (subgroupBroadcastFirst) offers. The same
// values as reduce_shared.wgsl.

fn offer_seed_key(l: u32, key: u32, lane: u32) {
    let m = subgroupMin(key);
    if subgroupBroadcastFirst(lane) == lane && m != 0xffffffffu {
        atomicMin(&wg_seed[l], m);
    }
}

fn offer_item(hit: Hit, bit: u32, lane: u32) {
    let d = subgroupMin(select(0xffffffffu, bitcast<u32>(hit.d), hit.found));
    let measured = subgroupOr(select(0u, bit, hit.found));
    let inside = subgroupOr(select(0u, bit, hit.found && hit.d == 0.0));
    if subgroupBroadcastFirst(lane) == lane && measured != 0u {
        atomicMin(&wg_min, d);
        atomicOr(&wg_measured, measured);
        if inside != 0u {
            atomicOr(&wg_inside, inside);
        }
    }
}

fn offer_item_point(i: u32, lane: u32) {
    let m = subgroupMin(i);
    if subgroupBroadcastFirst(lane) == lane && m != NO_POINT {
        atomicMin(&wg_arg, m);
    }
}
