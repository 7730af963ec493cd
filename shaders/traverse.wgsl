// Inner sphere tree traversal on the GPU: one invocation per cloud point, every link's tree
// descended depth first with the shared bounds kept in storage atomics (the seed's atomicMin).
//
// Mirrors src/query/traverse.rs step for step, over the same flat arrays (`IstNode`,
// `InnerSphere`) and the same posed links, so that CPU and GPU agree by construction:
//   * `seed` pass: every 61st point (stride in `Params`), nothing counted, tightens the bounds;
//   * `main` pass: every point: validity, region of interest (distance to the robot's box in
//     its root frame), self-filter (a sphere within the padding), then each link's descent
//     pruned by the link's threshold; minima by atomicMin on non-negative f32 bits, which
//     order like the floats; exact-mode candidates appended to a list;
//   * `argmin` pass: with the final minima known, each point re-descends with the link's minimum
//     as bound and, where it attains it bit for bit, atomicMin's its index: the smallest index
//     among ties, as the CPU's packed 64-bit minimum gives (WGSL has no 64-bit atomics).
// Stage counts go through workgroup atomics, one global add per workgroup and stage.
//
// Host mirrors (src/query/gpu/mod.rs): Node = IstNode, Sphere = InnerSphere, Link = GpuLink,
// Params = GpuParams, State = GpuState, Candidate = GpuCandidate. Sizes are asserted there
// and checked against this file by a naga test.

struct Node {
    center: vec3<f32>,
    radius: f32,
    first_child: u32,
    child_count: u32,
    children_are_spheres: u32,
    pad: u32,
}

struct Sphere {
    center: vec3<f32>,
    radius: f32,
}

// link_from_sensor as three rows (xyz rotation, w translation); the surface gap h; where the
// link's nodes and spheres start in the concatenated arrays.
struct Link {
    row0: vec4<f32>,
    row1: vec4<f32>,
    row2: vec4<f32>,
    gap: f32,
    node_base: u32,
    sphere_base: u32,
    pad: u32,
}

struct Params {
    // root_from_sensor rows (w: translation), for the region of interest.
    box_row0: vec4<f32>,
    box_row1: vec4<f32>,
    box_row2: vec4<f32>,
    // The robot's box in its root frame; lo.w = max_distance, hi.w = self-filter padding (< 0: off).
    box_lo: vec4<f32>,
    box_hi: vec4<f32>,
    n_points: u32,
    n_links: u32,
    // 0 fast, 1 certified, 2 exact.
    mode: u32,
    per_link: u32,
    // Points processed: index = offset + k * stride for k < n_work.
    stride: u32,
    offset: u32,
    n_work: u32,
    // 0 seed, 1 main (counts), 2 argmin.
    pass_kind: u32,
    capacity: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct State {
    global: atomic<u32>,
    global_lower: atomic<u32>,
    candidate_count: atomic<u32>,
    pad: u32,
    // invalid, outside_roi, self_filtered, pruned, evaluated, inside
    counts: array<atomic<u32>, 6>,
    pad1: u32,
    pad2: u32,
}

struct Candidate {
    lower_bits: u32,
    link: u32,
    point: u32,
    pad: u32,
}

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;
@group(0) @binding(2) var<storage, read> links: array<Link>;
@group(0) @binding(3) var<storage, read> points: array<f32>;
@group(0) @binding(4) var<uniform> params: Params;
@group(0) @binding(5) var<storage, read_write> state: State;
// [0, n_links): each link's minimum (f32 bits); [n_links, 2 n_links): its arg-min point.
@group(0) @binding(6) var<storage, read_write> minima: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> candidates: array<Candidate>;

const STACK: u32 = 64u;
const INF_BITS: u32 = 0x7f800000u;
const BIG: f32 = 3.0e38;
const STAGE_NONE: u32 = 6u;
const INVALID: u32 = 0u;
const OUTSIDE: u32 = 1u;
const SELF: u32 = 2u;
const PRUNED: u32 = 3u;
const EVALUATED: u32 = 4u;

var<workgroup> wg_counts: array<atomic<u32>, 6>;

struct Hit {
    d: f32,
    found: bool,
}

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & INF_BITS) != INF_BITS;
}

// A cloud point that carries a measurement: finite and not (0, 0, 0).
fn valid(p: vec3<f32>) -> bool {
    return finite(p.x) && finite(p.y) && finite(p.z) && any(p != vec3<f32>(0.0));
}

fn as_f32(bits: u32) -> f32 {
    if bits == INF_BITS {
        return BIG;
    }
    return bitcast<f32>(bits);
}

fn in_link(l: u32, p: vec3<f32>) -> vec3<f32> {
    let k = links[l];
    let h = vec4<f32>(p, 1.0);
    return vec3<f32>(dot(k.row0, h), dot(k.row1, h), dot(k.row2, h));
}

fn box_distance(p: vec3<f32>) -> f32 {
    let h = vec4<f32>(p, 1.0);
    let q = vec3<f32>(dot(params.box_row0, h), dot(params.box_row1, h), dot(params.box_row2, h));
    let d = max(max(params.box_lo.xyz - q, q - params.box_hi.xyz), vec3<f32>(0.0));
    return length(d);
}

// The nearest inner sphere of link `l` to `q` (link frame) within `bound`: depth first,
// nearest child on top, nodes pruned by |q − c| − r > best.
fn descend(l: u32, q: vec3<f32>, bound: f32) -> Hit {
    let link = links[l];
    var stack_lb: array<f32, STACK>;
    var stack_node: array<u32, STACK>;
    var best = bound;
    var found = false;
    let root = nodes[link.node_base];
    let root_lb = length(q - root.center) - root.radius;
    if root_lb > best {
        return Hit(best, false);
    }
    stack_lb[0] = root_lb;
    stack_node[0] = link.node_base;
    var sp = 1u;
    loop {
        if sp == 0u {
            break;
        }
        sp -= 1u;
        if stack_lb[sp] > best {
            continue;
        }
        let node = nodes[stack_node[sp]];
        if node.children_are_spheres != 0u {
            for (var k = 0u; k < node.child_count; k++) {
                let s = spheres[link.sphere_base + node.first_child + k];
                let d = length(q - s.center) - s.radius;
                if d <= best {
                    best = d;
                    found = true;
                }
            }
        } else {
            var top = STACK;
            var top_lb = BIG;
            for (var k = 0u; k < node.child_count; k++) {
                let index = link.node_base + node.first_child + k;
                let c = nodes[index];
                let lb = length(q - c.center) - c.radius;
                if lb <= best && sp < STACK {
                    stack_lb[sp] = lb;
                    stack_node[sp] = index;
                    if lb < top_lb {
                        top_lb = lb;
                        top = sp;
                    }
                    sp += 1u;
                }
            }
            if top != STACK {
                let last = sp - 1u;
                let lb = stack_lb[top];
                let n = stack_node[top];
                stack_lb[top] = stack_lb[last];
                stack_node[top] = stack_node[last];
                stack_lb[last] = lb;
                stack_node[last] = n;
            }
        }
    }
    return Hit(max(best, 0.0), found);
}

// The largest inner-sphere distance of link `l` that can still change the result.
fn threshold(l: u32) -> f32 {
    let g = as_f32(atomicLoad(&state.global));
    var t = g;
    if params.per_link != 0u {
        t = as_f32(atomicLoad(&minima[l]));
    }
    if params.mode == 1u && params.per_link == 0u {
        t = max(t, as_f32(atomicLoad(&state.global_lower)) + links[l].gap);
    }
    if params.mode == 2u {
        t = max(t, g + links[l].gap);
    }
    return t;
}

fn record(l: u32, point: u32, d: f32) {
    atomicMin(&minima[l], bitcast<u32>(d));
    atomicMin(&state.global, bitcast<u32>(d));
    let lower = max(d - links[l].gap, 0.0);
    if params.mode == 1u {
        atomicMin(&state.global_lower, bitcast<u32>(lower));
    }
    if params.mode == 2u && lower <= as_f32(atomicLoad(&state.global)) {
        let slot = atomicAdd(&state.candidate_count, 1u);
        if slot < params.capacity {
            candidates[slot] = Candidate(bitcast<u32>(lower), l, point, 0u);
        }
    }
}

fn is_self(p: vec3<f32>) -> bool {
    let padding = params.box_hi.w;
    if padding < 0.0 {
        return false;
    }
    for (var l = 0u; l < params.n_links; l++) {
        if descend(l, in_link(l, p), padding).found {
            return true;
        }
    }
    return false;
}

fn point_at(i: u32) -> vec3<f32> {
    return vec3<f32>(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
}

// One point of the seed or main pass; returns its stage.
fn process(i: u32) -> u32 {
    let p = point_at(i);
    if !valid(p) {
        return INVALID;
    }
    if box_distance(p) > params.box_lo.w {
        return OUTSIDE;
    }
    if is_self(p) {
        return SELF;
    }
    var evaluated = false;
    var inside = false;
    for (var l = 0u; l < params.n_links; l++) {
        let hit = descend(l, in_link(l, p), threshold(l));
        if hit.found {
            record(l, i, hit.d);
            evaluated = true;
            inside = inside || hit.d == 0.0;
        }
    }
    if !evaluated {
        return PRUNED;
    }
    if inside {
        return EVALUATED + 16u;
    }
    return EVALUATED;
}

// One point of the argmin pass.
fn argmin(i: u32) {
    let p = point_at(i);
    if !valid(p) || box_distance(p) > params.box_lo.w {
        return;
    }
    var checked = false;
    for (var l = 0u; l < params.n_links; l++) {
        let b = atomicLoad(&minima[l]);
        if b == INF_BITS {
            continue;
        }
        let hit = descend(l, in_link(l, p), bitcast<f32>(b));
        if hit.found && bitcast<u32>(hit.d) == b {
            if !checked {
                if is_self(p) {
                    return;
                }
                checked = true;
            }
            atomicMin(&minima[params.n_links + l], i);
        }
    }
}

@compute @workgroup_size(256)
fn traverse(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if li < 6u {
        atomicStore(&wg_counts[li], 0u);
    }
    workgroupBarrier();
    var stage = STAGE_NONE;
    if gid.x < params.n_work {
        let i = params.offset + gid.x * params.stride;
        if i < params.n_points {
            if params.pass_kind == 2u {
                argmin(i);
            } else {
                stage = process(i);
            }
        }
    }
    if params.pass_kind == 1u && stage != STAGE_NONE {
        atomicAdd(&wg_counts[stage & 15u], 1u);
        if stage >= 16u {
            atomicAdd(&wg_counts[5], 1u);
        }
    }
    workgroupBarrier();
    if params.pass_kind == 1u && li < 6u {
        let c = atomicLoad(&wg_counts[li]);
        if c != 0u {
            atomicAdd(&state.counts[li], c);
        }
    }
}
