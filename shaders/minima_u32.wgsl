// Each link's minimum as f32 bits in a 32-bit atomic, for adapters without 64-bit atomics
// (minima_u64.wgsl otherwise). [0, n_links): the minima; [n_links, 2 n_links): each one's
// arg-min point, found by the `argmin` pass below once the minima are final.

@group(0) @binding(6) var<storage, read_write> minima: array<atomic<u32>>;

// Whether the arg-min pass's item is for a measured link (one value for the workgroup).
var<workgroup> wg_flag: u32;

// The link's minimum so far (BIG while none).
fn link_best(l: u32) -> f32 {
    return as_f32(atomicLoad(&minima[l]));
}

fn record_minimum(l: u32, point: u32, d: f32) {
    atomicMin(&minima[l], bitcast<u32>(d));
}

// The seeds' scan keeps each link's nearest sample's squared distance (f32 bits) in
// state.seed_key; `seed_pick` then finds its point.
fn seed_key(l: u32) -> u32 {
    return atomicLoad(&state.seed_key[l]);
}

fn offer_seed(l: u32, key: u32, point: u32) {
    atomicMin(&state.seed_key[l], key);
}

fn seed_of(l: u32) -> u32 {
    return atomicLoad(&state.seed_point[l]);
}

// With the keys final: each link's seed is the smallest sample index that attains its key and
// is not the robot.
@compute @workgroup_size(WORKGROUP)
fn seed_pick(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = sample(gid.x);
    if i == NO_POINT {
        return;
    }
    let p = point_at(i);
    var checked = false;
    var robot = false;
    for (var l = 0u; l < params.n_links && !robot; l++) {
        if root_key(l, p) == atomicLoad(&state.seed_key[l]) {
            if !checked {
                robot = self_link(p, true) != NO_LINK;
                checked = true;
            }
            if !robot {
                atomicMin(&state.seed_point[l], i);
            }
        }
    }
}

// With the minima final, over the measure pass's work items again: each point of an item
// re-descends the item's link with the link's minimum as the bound (`widened` by a few ulps:
// the rounding of a node's lower bound must not prune the sphere that attains it, a knife edge
// at this bound) and, where it attains the
// minimum bit for bit, atomicMin's its index: the smallest index among ties, as the CPU's packed
// 64-bit minimum gives. A link's minimum within its final threshold was recorded by a point of
// one of its items (the blocks pass kept every block and link within the threshold, and the
// measure pass descended their points exactly); the host reports the others as farther than it.
@compute @workgroup_size(BLOCK)
fn argmin(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    clear_counts(lane);
    let n = item_count(lane);
    for (var k = wid.x; k < n; k += nwg.x) {
        let s = items[k] >> 7u;
        let l = items[k] & 127u;
        let m = atomicLoad(&minima[l]);
        let d = bitcast<f32>(m);
        // The same for every invocation (the minima are final in this pass), made uniform.
        if lane == 0u {
            wg_flag = select(0u, 1u, m != INF_BITS && d <= threshold(l));
        }
        if workgroupUniformLoad(&wg_flag) != 0u {
            frontier(l, in_link(l, kept[s].center), kept[s].radius, lane, true);
            if (kept[s].todo & (1u << lane)) != 0u {
                let i = block_point(kept[s].block, lane);
                let hit = descend_from_frontier(l, in_link(l, point_at(i)), widened(d));
                if hit.found && bitcast<u32>(hit.d) == m {
                    atomicMin(&minima[params.n_links + l], i);
                }
            }
            workgroupBarrier();
        }
    }
    flush_counts(lane, false);
}
