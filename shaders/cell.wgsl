// The unseen space's cells judged on the GPU (src/query/gpu/cell.rs; the CPU's are
// src/unseen/cell.rs and src/unseen/footprint.rs, whose rule this is): in the depth query's
// submission, after `unproject` has written the image's points, one invocation per lattice cell
// says whether this view rules out the cell's base ball, or else which of its eight sub-balls.
//
// A ball of radius r at camera-frame p is ruled out when one pixel ray whose whole pixel lies in
// its silhouette (angle to p at most asin(r/l) - kappa, kappa the pixel's half diagonal) returned
// beyond the ray's entry into it: its free distance g = (z - noise)|d~| - rounding (no return:
// -1) is at least proj = d.p, or (proj - g)^2 < r^2 - perp^2. The pixel nearest the centre's
// projection first, then the footprint's window row by row over the columns its cone meets.
//
// Output, per cell: bit 0, the base ball ruled out; else bit 1 + k, sub-ball k ruled out (bit a
// of k: +h/4 along axis a, else -h/4). Constants (WORKGROUP) are prepended by the host.

// Mirrored by src/query/layout.rs `CellParams`.
struct CellParams {
    width: u32,
    height: u32,
    n0: u32,
    n1: u32,
    n2: u32,
    cells: u32,
    pad0: u32,
    pad1: u32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    min_range: f32,
    max_range: f32,
    noise: f32,
    rounding: f32,
    cos_k: f32,
    sin_k: f32,
    ball: f32,
    sub_ball: f32,
    origin: vec4<f32>,
    step0: vec4<f32>,
    step1: vec4<f32>,
    step2: vec4<f32>,
}

// The query's points: x y z (f32 bits) per pixel, NaN where no return or out of range.
@group(0) @binding(0) var<storage, read> points: array<u32>;
@group(0) @binding(1) var<storage, read_write> verdicts: array<u32>;
@group(0) @binding(2) var<uniform> cp: CellParams;

// Pixel q's unit ray through its centre.
fn ray(q: u32) -> vec3<f32> {
    let a = (f32(q % cp.width) - cp.cx) / cp.fx;
    let b = (f32(q / cp.width) - cp.cy) / cp.fy;
    let n = sqrt(a * a + b * b + 1.0);
    return vec3<f32>(a / n, b / n, 1.0 / n);
}

// Pixel q's free distance along its unit ray d (m; -1: no return).
fn free(q: u32, d: vec3<f32>) -> f32 {
    let z = bitcast<f32>(points[3u * q + 2u]);
    if (!(z > 0.0) || z != z) {
        return -1.0;
    }
    return max((z - cp.noise) / d.z - cp.rounding, 0.0);
}

// The ball (p, its |p|^2, the least projection in its footprint, r^2): whether pixel q rules it
// out.
fn rules(p: vec3<f32>, l2: f32, min_proj: f32, r2: f32, q: u32) -> bool {
    let d = ray(q);
    let proj = d.x * p.x + d.y * p.y + d.z * p.z;
    if (proj < min_proj) {
        return false;
    }
    let s2 = r2 - max(l2 - proj * proj, 0.0);
    if (s2 <= 0.0) {
        return false;
    }
    let g = free(q, d);
    if (g >= proj) {
        return true;
    }
    let diff = proj - g;
    return diff * diff < s2;
}

// Whether the view rules out the ball of radius r at camera-frame p.
fn ruled_out(p: vec3<f32>, r: f32) -> bool {
    let l2 = p.x * p.x + p.y * p.y + p.z * p.z;
    let l = sqrt(l2);
    if (!(p.z > r) || l - r < cp.min_range || l - r > cp.max_range) {
        return false;
    }
    // The footprint's half angle asin(r/l) - kappa, by its sine and cosine.
    let s = min(r / l, 1.0);
    let c = sqrt(max(1.0 - s * s, 0.0));
    let sin_a = s * cp.cos_k - c * cp.sin_k;
    if (!(sin_a > 0.0)) {
        return false;
    }
    let cos_a = c * cp.cos_k + s * cp.sin_k;
    let u = cp.fx * p.x / p.z + cp.cx;
    let v = cp.fy * p.y / p.z + cp.cy;
    let uc = floor(u + 0.5);
    let vc = floor(v + 0.5);
    let w = f32(cp.width);
    let h = f32(cp.height);
    if (!(uc >= 0.0 && vc >= 0.0 && uc < w && vc < h)) {
        return false;
    }
    let min_proj = l * cos_a;
    let r2 = r * r;
    if (rules(p, l2, min_proj, r2, u32(vc) * cp.width + u32(uc))) {
        return true;
    }
    // The window.
    let cos_phi = clamp(p.z / l, -1.0, 1.0);
    let sin_phi = sqrt(1.0 - cos_phi * cos_phi);
    let cc = cos_phi * cos_a - sin_phi * sin_a;
    var lo = vec2<f32>(0.0, 0.0);
    var hi = vec2<f32>(w, h);
    if (cc > 0.05) {
        let half = (sin_a / cos_a) / (cc * cc);
        let hu = cp.fx * half + 1.0;
        let hv = cp.fy * half + 1.0;
        lo = vec2<f32>(u - hu, v - hv);
        hi = vec2<f32>(u + hu, v + hv);
    }
    let u0 = max(ceil(lo.x), 0.0);
    let u1 = min(floor(hi.x), w - 1.0);
    let v0 = max(ceil(lo.y), 0.0);
    let v1 = min(floor(hi.y), h - 1.0);
    if (!(u0 <= u1 && v0 <= v1)) {
        return false;
    }
    // Each row over the columns the footprint's cone meets (the roots of a quadratic in x).
    let k = min_proj * min_proj;
    let qa = p.x * p.x - k;
    for (var row = u32(v0); row <= u32(v1); row++) {
        var a = u0;
        var z = u1;
        if (qa < 0.0) {
            let y = (f32(row) - cp.cy) / cp.fy;
            let b = y * p.y + p.z;
            let qb = 2.0 * p.x * b;
            let qc = b * b - k * (y * y + 1.0);
            let disc = qb * qb - 4.0 * qa * qc;
            if (!(disc >= 0.0)) {
                continue;
            }
            let sq = sqrt(disc);
            let x1 = (-qb + sq) / (2.0 * qa);
            let x2 = (-qb - sq) / (2.0 * qa);
            a = max(floor(cp.fx * x1 + cp.cx - 1.0), u0);
            z = min(ceil(cp.fx * x2 + cp.cx + 1.0), u1);
        }
        if (!(a <= z)) {
            continue;
        }
        for (var col = u32(a); col <= u32(z); col++) {
            if (rules(p, l2, min_proj, r2, row * cp.width + col)) {
                return true;
            }
        }
    }
    return false;
}

@compute @workgroup_size(WORKGROUP)
fn judge_cells(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let stride = groups.x * WORKGROUP;
    for (var cell = gid.x; cell < cp.cells; cell += stride) {
        let i = f32(cell % cp.n0);
        let j = f32((cell / cp.n0) % cp.n1);
        let kk = f32(cell / (cp.n0 * cp.n1));
        let centre = cp.origin.xyz + i * cp.step0.xyz + j * cp.step1.xyz + kk * cp.step2.xyz;
        var bits = 0u;
        if (ruled_out(centre, cp.ball)) {
            bits = 1u;
        } else {
            for (var sub = 0u; sub < 8u; sub++) {
                var p = centre;
                p += select(-0.25, 0.25, (sub & 1u) != 0u) * cp.step0.xyz;
                p += select(-0.25, 0.25, (sub & 2u) != 0u) * cp.step1.xyz;
                p += select(-0.25, 0.25, (sub & 4u) != 0u) * cp.step2.xyz;
                if (ruled_out(p, cp.sub_ball)) {
                    bits |= 2u << sub;
                }
            }
        }
        verdicts[cell] = bits;
    }
}
