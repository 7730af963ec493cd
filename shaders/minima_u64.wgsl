// Each link's minimum with the point that attains it, packed (distance bits << 32 | point) in
// one 64-bit storage atomic: one atomicMin keeps both, and the smallest index among ties, as the
// CPU's packed minimum does (bounds.rs pack_minimum). No arg-min pass. Compiled where the
// adapter has SHADER_INT64 and SHADER_INT64_ATOMIC_MIN_MAX (wgpu's Vulkan backend: the
// shaderBufferInt64Atomics of VK_KHR_shader_atomic_int64); minima_u32.wgsl otherwise.

// [0, n_links): the minima; [n_links, 2 n_links): the seeds' scan, each link's nearest sample to
// its root centre packed as (squared distance bits << 32 | point), found in one pass.
@group(0) @binding(6) var<storage, read_write> minima: array<atomic<u64>>;

const EMPTY_MINIMUM: u64 = 0xfffffffffffffffflu;

// The link's minimum so far (BIG while none).
fn link_best(l: u32) -> f32 {
    let v = atomicLoad(&minima[l]);
    if v == EMPTY_MINIMUM {
        return BIG;
    }
    return bitcast<f32>(u32(v >> 32u));
}

fn record_minimum(l: u32, point: u32, d: f32) {
    atomicMin(&minima[l], (u64(bitcast<u32>(d)) << 32u) | u64(point));
}

// The squared distance bits of link l's seed so far.
fn seed_key(l: u32) -> u32 {
    return u32(atomicLoad(&minima[params.n_links + l]) >> 32u);
}

fn offer_seed(l: u32, key: u32, point: u32) {
    atomicMin(&minima[params.n_links + l], (u64(key) << 32u) | u64(point));
}

// Link l's seed point (NO_POINT: none).
fn seed_of(l: u32) -> u32 {
    let v = atomicLoad(&minima[params.n_links + l]);
    if v == EMPTY_MINIMUM {
        return NO_POINT;
    }
    return u32(v);
}
