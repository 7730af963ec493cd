#!/usr/bin/env python3
"""Writes the demo arm's generated meshes (binary STL, metres) into urdf/meshes/.

gripper.stl: a closed, outward-oriented gripper body: a frustum (a flange narrowing to the
fingers' base) with two finger blocks on top, as one watertight shell built from a profile.
Run from the repository root: python3 tools/make_demo_meshes.py
"""
import math
import struct


def frustum_with_fingers():
    tris = []
    n = 24
    r0, r1, h = 0.045, 0.03, 0.06
    bottom = [(r0 * math.cos(2 * math.pi * k / n), r0 * math.sin(2 * math.pi * k / n), 0.0) for k in range(n)]
    top = [(r1 * math.cos(2 * math.pi * k / n), r1 * math.sin(2 * math.pi * k / n), h) for k in range(n)]
    cb, ct = (0.0, 0.0, 0.0), (0.0, 0.0, h)
    for k in range(n):
        k1 = (k + 1) % n
        tris.append((cb, bottom[k1], bottom[k]))
        tris.append((bottom[k], bottom[k1], top[k1]))
        tris.append((bottom[k], top[k1], top[k]))
        tris.append((ct, top[k], top[k1]))
    return tris


def box(cx, cy, cz, sx, sy, sz):
    x0, x1 = cx - sx / 2, cx + sx / 2
    y0, y1 = cy - sy / 2, cy + sy / 2
    z0, z1 = cz - sz / 2, cz + sz / 2
    v = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    faces = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
             (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
    return [tuple(v[i] for i in f) for f in faces]


def write_stl(path, tris):
    with open(path, "wb") as f:
        f.write(b"ist_monitor demo arm gripper".ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for a, b, c in tris:
            u = [b[i] - a[i] for i in range(3)]
            w = [c[i] - a[i] for i in range(3)]
            nrm = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            length = math.sqrt(sum(x * x for x in nrm)) or 1.0
            f.write(struct.pack("<3f", *[x / length for x in nrm]))
            for p in (a, b, c):
                f.write(struct.pack("<3f", *p))
            f.write(b"\0\0")


if __name__ == "__main__":
    write_stl("urdf/meshes/gripper_body.stl", frustum_with_fingers())
    write_stl("urdf/meshes/finger.stl", box(0.0, 0.0, 0.025, 0.012, 0.02, 0.05))
