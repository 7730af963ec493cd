// The workgroup reductions of the traversal through workgroup memory: each invocation offers
// its value to a workgroup atomic. The portable way, used where the adapter has no subgroup
// operations; reduce_subgroups.wgsl is the fast path. Both give the same values (minima and
// unions of bits are taken in any order).

// The seeds' scan: `key` (u32::MAX: none) offered as the workgroup's nearest to link l. (`lane`,
// the invocation's local index, is what reduce_subgroups.wgsl elects by.)
fn offer_seed_key(l: u32, key: u32, _lane: u32) {
    if key != 0xffffffffu {
        atomicMin(&wg_seed[l], key);
    }
}

// The measure pass: an invocation's result for the item (its lane's bit), offered to the
// item's minimum and its sets of measured and inside points.
fn offer_item(hit: Hit, bit: u32, _lane: u32) {
    if hit.found {
        atomicMin(&wg_min, bitcast<u32>(hit.d));
        atomicOr(&wg_measured, bit);
        if hit.d == 0.0 {
            atomicOr(&wg_inside, bit);
        }
    }
}

// The measure pass: a point attaining the item's minimum (NO_POINT: none), offered as its
// smallest.
fn offer_item_point(i: u32, _lane: u32) {
    if i != NO_POINT {
        atomicMin(&wg_arg, i);
    }
}
