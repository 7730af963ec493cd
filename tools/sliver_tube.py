#!/usr/bin/env python3
"""A closed tube of sliver triangles, as CAD exports a long cylinder: one ring of long, thin
side triangles and a fan on each end (issue 56: large links whose validation took minutes).

    python3 tools/sliver_tube.py DIR [--length 0.3] [--radius 0.04] [--segments 1500]

writes DIR/tube.stl (binary, 4 x segments triangles) and DIR/robot.urdf (one link, `tube`), for
`ist_monitor build --no-cache --urdf DIR/robot.urdf --json`. The ring's last vertices are
computed again from the angle 2 pi, so they differ from the first by rounding, as CAD noise
does: the intake welds them and the validation measures h on the file's own triangles too.
"""

import argparse
import math
import pathlib
import struct


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", type=pathlib.Path)
    parser.add_argument("--length", type=float, default=0.3, help="m")
    parser.add_argument("--radius", type=float, default=0.04, help="m")
    parser.add_argument("--segments", type=int, default=1500)
    args = parser.parse_args()
    n, r, length = args.segments, args.radius, args.length
    if n < 3 or not (r > 0 and length > 0):
        parser.error("--segments >= 3, --radius and --length > 0")
    triangles = []
    for i in range(n):
        a0, a1 = 2 * math.pi * i / n, 2 * math.pi * (i + 1) / n
        p0 = (r * math.cos(a0), r * math.sin(a0))
        p1 = (r * math.cos(a1), r * math.sin(a1))
        b0, b1 = (*p0, 0.0), (*p1, 0.0)
        t0, t1 = (*p0, length), (*p1, length)
        triangles += [(b0, b1, t1), (b0, t1, t0), ((0.0, 0.0, 0.0), b1, b0), ((0.0, 0.0, length), t0, t1)]
    args.dir.mkdir(parents=True, exist_ok=True)
    with open(args.dir / "tube.stl", "wb") as f:
        f.write(b"\0" * 80 + struct.pack("<I", len(triangles)))
        for t in triangles:
            f.write(struct.pack("<3f", 0.0, 0.0, 0.0))
            for v in t:
                f.write(struct.pack("<3f", *v))
            f.write(b"\0\0")
    (args.dir / "robot.urdf").write_text(
        '<?xml version="1.0"?>\n<robot name="sliver_tube"><link name="tube"><collision><geometry>'
        '<mesh filename="tube.stl"/></geometry></collision></link></robot>\n'
    )
    print(f"{args.dir / 'tube.stl'}: {len(triangles)} triangles, {length} m long, radius {r} m")


if __name__ == "__main__":
    main()
