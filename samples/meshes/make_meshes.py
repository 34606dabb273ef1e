#!/usr/bin/env python3
"""Writes the sample meshes of this folder (standard library only):

- u_channel.obj: a U channel, 10 x 8 x 6 cm, a 4 cm slot (concave).
- plus_prism.obj: a plus-shaped prism, 12 x 12 cm, arms 4 cm wide, 5 cm tall (concave).
- hex_nut.stl (binary): a hexagonal ring, 9 cm across corners, a 4 cm hole, 3.5 cm tall (concave).
- wedge.stl (ASCII): a triangular prism (door wedge), 12 cm long, 6 cm wide, 4 cm tall.

Units are metres, z up. Run from anywhere: python3 samples/meshes/make_meshes.py
"""
import math
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent


def extrude(outline, height, convex_pieces):
    """A prism over a counter-clockwise outline (x, y); caps from convex pieces (index lists)."""
    n = len(outline)
    vertices = [(x, y, 0.0) for x, y in outline] + [(x, y, height) for x, y in outline]
    faces = []
    for piece in convex_pieces:
        faces.append(list(reversed(piece)))  # bottom, facing down
        faces.append([i + n for i in piece])  # top, facing up
    for i in range(n):
        j = (i + 1) % n
        faces.append([i, j, j + n, i + n])
    return vertices, faces


def ring(r_out, r_in, sides_out, sides_in_per_side, height):
    """A prism with a polygonal outer wall and a round hole, as quads."""
    vertices, faces = [], []
    segments = sides_out * sides_in_per_side
    for k in range(segments):
        a = 2 * math.pi * k / segments
        # The outer polygon, sampled at the same angles as the hole.
        side = 2 * math.pi / sides_out
        local = (a % side) - side / 2
        r = r_out * math.cos(side / 2) / math.cos(local)
        for z in (0.0, height):
            vertices.append((r * math.cos(a), r * math.sin(a), z))
            vertices.append((r_in * math.cos(a), r_in * math.sin(a), z))
    # Vertex (k, z, outer/inner) -> 4k + 2z + inner.
    idx = lambda k, z, inner: 4 * (k % segments) + 2 * z + inner
    for k in range(segments):
        faces.append([idx(k, 0, 0), idx(k + 1, 0, 0), idx(k + 1, 1, 0), idx(k, 1, 0)])  # outer wall
        faces.append([idx(k, 0, 1), idx(k, 1, 1), idx(k + 1, 1, 1), idx(k + 1, 0, 1)])  # hole wall
        faces.append([idx(k, 1, 0), idx(k + 1, 1, 0), idx(k + 1, 1, 1), idx(k, 1, 1)])  # top
        faces.append([idx(k, 0, 0), idx(k, 0, 1), idx(k + 1, 0, 1), idx(k + 1, 0, 0)])  # bottom
    return vertices, faces


def triangles(vertices, faces):
    for f in faces:
        for k in range(1, len(f) - 1):
            yield vertices[f[0]], vertices[f[k]], vertices[f[k + 1]]


def write_obj(path, vertices, faces, title):
    lines = [f"# {title}"] + [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")


def write_stl_binary(path, vertices, faces, title):
    tris = list(triangles(vertices, faces))
    out = bytearray(title.encode()[:80].ljust(80, b" "))
    out += struct.pack("<I", len(tris))
    for t in tris:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for p in t:
            out += struct.pack("<3f", *p)
        out += b"\0\0"
    path.write_bytes(bytes(out))


def write_stl_ascii(path, vertices, faces, title):
    lines = [f"solid {title}"]
    for t in triangles(vertices, faces):
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.6f} {y:.6f} {z:.6f}" for x, y, z in t]
        lines += ["    endloop", "  endfacet"]
    path.write_text("\n".join(lines + [f"endsolid {title}"]) + "\n")


def main():
    # U channel: outline in x-z extruded along y, so build it in x-y and swap y, z.
    u = [(-0.05, 0.0), (0.05, 0.0), (0.05, 0.06), (0.02, 0.06), (0.02, 0.02), (-0.02, 0.02), (-0.02, 0.06), (-0.05, 0.06)]
    v, f = extrude(u, 0.08, [[0, 1, 4, 5], [0, 5, 6, 7], [1, 2, 3, 4]])
    v = [(x, z - 0.04, y) for x, y, z in v]
    f = [list(reversed(face)) for face in f]  # the swap mirrors: keep faces outward
    write_obj(HERE / "u_channel.obj", v, f, "U channel, metres, z up")

    a, b = 0.06, 0.02
    plus = [(b, -a), (b, -b), (a, -b), (a, b), (b, b), (b, a), (-b, a), (-b, b), (-a, b), (-a, -b), (-b, -b), (-b, -a)]
    v, f = extrude(plus, 0.05, [[0, 1, 10, 11], [1, 4, 7, 10], [1, 2, 3, 4], [4, 5, 6, 7], [7, 8, 9, 10]])
    write_obj(HERE / "plus_prism.obj", v, f, "plus-shaped prism, metres, z up")

    v, f = ring(0.045, 0.02, 6, 4, 0.035)
    write_stl_binary(HERE / "hex_nut.stl", v, f, "hexagonal ring, metres, z up")

    # A triangular prism: the cross-section in x-z (0 to 4 cm high along x), extruded along y.
    tri = [(-0.06, 0.0), (0.06, 0.0), (-0.06, 0.04)]
    v, f = extrude(tri, 0.06, [[0, 1, 2]])
    v = [(x, z - 0.03, y) for x, y, z in v]
    f = [list(reversed(face)) for face in f]
    write_stl_ascii(HERE / "wedge.stl", v, f, "wedge")
    for p in sorted(HERE.glob("*.obj")) + sorted(HERE.glob("*.stl")):
        print(f"wrote {p.name}: {p.stat().st_size} bytes")


if __name__ == "__main__":
    main()
