#!/usr/bin/env python3
"""Writes assets/models/character.glb: a small skinned character with a walk loop, a cape and a
skirt, for the scene-level cloth (`ClothHierarchy`) and the `gltf_character` example.

    python3 scripts/make_character.py            # writes assets/models/character.glb

Plain Python 3, no packages: the glTF 2.0 binary is written by hand, so the same script gives
the same bytes on any machine. What it holds:

- a skeleton of named joints: Hips (the root), Spine, Chest, Neck, Head, UpperArm.L/R,
  LowerArm.L/R, UpperLeg.L/R, LowerLeg.L/R;
- "Body": one skinned mesh of boxes, each box bound to one joint with weight 1;
- "Cape": a 12 x 16 sheet behind the back, 0.5 m wide and 0.6 m long, sloping 0.13 m back from
  top to bottom so that it starts clear of the skirt, skinned to Chest, its top
  row's outer vertices blended with the upper arm on their side (up to half, at the corners) as
  a cape sewn over the shoulders is; its top row is painted 1 in the red channel of COLOR_0 (the
  pin weight), the rest 0, and it is blue in green and blue;
- "Skirt": an open cone around the hips, 24 around by 8 down, skinned to Hips, its top ring
  painted 1 in red, green in green and blue;
- "Walk": a 1 s loop of the hips' bob and the legs' and arms' swing.

The model is 1.7 m tall, +Y up, facing +Z, in metres, as glTF and Bevy expect.
"""

import json
import math
import struct
from pathlib import Path

# Joints: name, parent, head position in the model (bind pose, no rotation).
JOINTS = [
    ("Hips", None, (0.0, 0.95, 0.0)),
    ("Spine", "Hips", (0.0, 1.10, 0.0)),
    ("Chest", "Spine", (0.0, 1.30, 0.0)),
    ("Neck", "Chest", (0.0, 1.50, 0.0)),
    ("Head", "Neck", (0.0, 1.57, 0.0)),
    ("UpperArm.L", "Chest", (0.22, 1.45, 0.0)),
    ("LowerArm.L", "UpperArm.L", (0.22, 1.17, 0.0)),
    ("UpperArm.R", "Chest", (-0.22, 1.45, 0.0)),
    ("LowerArm.R", "UpperArm.R", (-0.22, 1.17, 0.0)),
    ("UpperLeg.L", "Hips", (0.10, 0.92, 0.0)),
    ("LowerLeg.L", "UpperLeg.L", (0.10, 0.50, 0.0)),
    ("UpperLeg.R", "Hips", (-0.10, 0.92, 0.0)),
    ("LowerLeg.R", "UpperLeg.R", (-0.10, 0.50, 0.0)),
]
JOINT = {name: i for i, (name, _, _) in enumerate(JOINTS)}

# The garments' colours in COLOR_0's green and blue channels (red holds the pin weight), which
# Bevy multiplies into the material's white: a blue cape and a green skirt.
CAPE = (0.25, 0.75)
SKIRT = (0.6, 0.25)

# The body's boxes: joint, centre, half extents (metres, model space).
BOXES = [
    ("Hips", (0.0, 0.98, 0.0), (0.16, 0.08, 0.10)),
    ("Spine", (0.0, 1.20, 0.0), (0.15, 0.10, 0.09)),
    ("Chest", (0.0, 1.40, 0.0), (0.18, 0.10, 0.10)),
    ("Neck", (0.0, 1.53, 0.0), (0.04, 0.04, 0.04)),
    ("Head", (0.0, 1.66, 0.0), (0.09, 0.10, 0.10)),
    ("UpperArm.L", (0.22, 1.31, 0.0), (0.04, 0.14, 0.04)),
    ("LowerArm.L", (0.22, 1.04, 0.0), (0.035, 0.13, 0.035)),
    ("UpperArm.R", (-0.22, 1.31, 0.0), (0.04, 0.14, 0.04)),
    ("LowerArm.R", (-0.22, 1.04, 0.0), (0.035, 0.13, 0.035)),
    ("UpperLeg.L", (0.10, 0.71, 0.0), (0.06, 0.21, 0.06)),
    ("LowerLeg.L", (0.10, 0.27, 0.0), (0.05, 0.25, 0.05)),
    ("UpperLeg.R", (-0.10, 0.71, 0.0), (0.06, 0.21, 0.06)),
    ("LowerLeg.R", (-0.10, 0.27, 0.0), (0.05, 0.25, 0.05)),
]


def box(centre, half):
    """A box's 24 vertices (4 a face, so each face has its own normal) and 36 indices."""
    positions, normals, indices = [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = [0.0, 0.0, 0.0]
            n[axis] = sign
            u, v = [(axis + 1) % 3, (axis + 2) % 3]
            start = len(positions)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = list(centre)
                p[axis] += sign * half[axis]
                p[u] += a * half[u]
                p[v] += b * half[v]
                positions.append(tuple(p))
                normals.append(tuple(n))
            quad = [0, 1, 2, 0, 2, 3] if sign > 0 else [0, 2, 1, 0, 3, 2]
            indices += [start + q for q in quad]
    return positions, normals, indices


def body():
    positions, normals, indices, joints = [], [], [], []
    for joint, centre, half in BOXES:
        p, n, i = box(centre, half)
        base = len(positions)
        positions += p
        normals += n
        indices += [base + k for k in i]
        joints += [one(joint)] * len(p)
    return positions, normals, indices, joints, None


def one(joint):
    """A vertex bound to one joint with weight 1: (joints, weights)."""
    return (JOINT[joint], 0, 0, 0), (1.0, 0.0, 0.0, 0.0)


def cape(cols=12, rows=16, width=0.5, length=0.6):
    """A sheet behind the back from the shoulders, facing -Z, sloping back as it goes down so
    that it starts clear of the skirt (it swings down onto it once simulated)."""
    positions, normals, colours, indices, skin = [], [], [], [], []
    for r in range(rows):
        for c in range(cols):
            x = width * (c / (cols - 1) - 0.5)
            y = 1.48 - length * r / (rows - 1)
            positions.append((x, y, -0.13 - 0.13 * r / (rows - 1)))
            normals.append((0.0, 0.2121, -0.9772))
            colours.append((1.0 if r == 0 else 0.0, *CAPE, 1.0))
            # Over the shoulders the seam follows the arm: from none at 0.1 m out to half at
            # the corner (weights rounded to 1/8, exact in binary).
            arm = round(8 * min(0.5, max(0.0, (abs(x) - 0.1) / 0.3))) / 8 if r == 0 else 0.0
            side = "UpperArm.L" if x > 0 else "UpperArm.R"
            if arm > 0:
                skin.append(((JOINT["Chest"], JOINT[side], 0, 0), (1.0 - arm, arm, 0.0, 0.0)))
            else:
                skin.append(one("Chest"))
    for r in range(rows - 1):
        for c in range(cols - 1):
            i = r * cols + c
            indices += [i, i + 1, i + cols, i + 1, i + cols + 1, i + cols]
    return positions, normals, indices, skin, colours


def skirt(around=24, down=8, top=0.19, bottom=0.30, length=0.40):
    """An open cone around the hips, from the waist down."""
    positions, normals, colours, indices = [], [], [], []
    slope = (bottom - top) / length
    for r in range(down):
        t = r / (down - 1)
        radius = top + (bottom - top) * t
        y = 1.00 - length * t
        for a in range(around):
            angle = 2.0 * math.pi * a / around
            s, c = math.sin(angle), math.cos(angle)
            positions.append((radius * s, y, radius * c))
            k = 1.0 / math.sqrt(1.0 + slope * slope)
            normals.append((s * k, slope * k, c * k))
            colours.append((1.0 if r == 0 else 0.0, *SKIRT, 1.0))
    for r in range(down - 1):
        for a in range(around):
            i, j = r * around + a, r * around + (a + 1) % around
            indices += [i, i + around, j, j, i + around, j + around]
    return positions, normals, indices, [one("Hips")] * len(positions), colours


def quat_x(angle):
    return (math.sin(angle / 2.0), 0.0, 0.0, math.cos(angle / 2.0))


def walk(frames=25, seconds=1.0):
    """Keyframes of the walk loop: times, the hips' translation, and each swinging joint's
    rotation about X."""
    times = [seconds * k / (frames - 1) for k in range(frames)]
    phase = [2.0 * math.pi * t / seconds for t in times]
    hips = [(0.0, JOINTS[0][2][1] + 0.03 * math.cos(2.0 * p), 0.0) for p in phase]
    swing = {
        "UpperLeg.L": [quat_x(0.45 * math.sin(p)) for p in phase],
        "UpperLeg.R": [quat_x(-0.45 * math.sin(p)) for p in phase],
        "LowerLeg.L": [quat_x(0.5 * max(0.0, -math.sin(p))) for p in phase],
        "LowerLeg.R": [quat_x(0.5 * max(0.0, math.sin(p))) for p in phase],
        "UpperArm.L": [quat_x(-0.35 * math.sin(p)) for p in phase],
        "UpperArm.R": [quat_x(0.35 * math.sin(p)) for p in phase],
        "Spine": [(0.0, math.sin(0.08 * math.sin(p) / 2.0), 0.0, math.cos(0.08 * math.sin(p) / 2.0)) for p in phase],
    }
    return times, hips, swing


class Writer:
    """Buffer views and accessors over one binary buffer."""

    def __init__(self):
        self.bin = bytearray()
        self.views, self.accessors = [], []

    def _view(self, data, target=None):
        while len(self.bin) % 4:
            self.bin.append(0)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            view["target"] = target
        self.bin += data
        self.views.append(view)
        return len(self.views) - 1

    def floats(self, rows, kind, target=34962, bounds=False):
        width = len(rows[0])
        data = b"".join(struct.pack(f"<{width}f", *row) for row in rows)
        accessor = {"bufferView": self._view(data, target), "componentType": 5126, "count": len(rows), "type": kind}
        if bounds:
            accessor["min"] = [min(r[k] for r in rows) for k in range(width)]
            accessor["max"] = [max(r[k] for r in rows) for k in range(width)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def joints(self, rows):
        data = b"".join(struct.pack("<4H", *row) for row in rows)
        self.accessors.append(
            {"bufferView": self._view(data, 34962), "componentType": 5123, "count": len(rows), "type": "VEC4"}
        )
        return len(self.accessors) - 1

    def indices(self, values):
        data = struct.pack(f"<{len(values)}I", *values)
        self.accessors.append(
            {"bufferView": self._view(data, 34963), "componentType": 5125, "count": len(values), "type": "SCALAR"}
        )
        return len(self.accessors) - 1

    def matrices(self, mats):
        data = b"".join(struct.pack("<16f", *m) for m in mats)
        self.accessors.append(
            {"bufferView": self._view(data), "componentType": 5126, "count": len(mats), "type": "MAT4"}
        )
        return len(self.accessors) - 1

    def times(self, values):
        rows = [(t,) for t in values]
        return self.floats(rows, "SCALAR", target=None, bounds=True)


def build():
    w = Writer()
    # Skinned meshes: each vertex with its joints and weights.
    meshes = []
    for name, (positions, normals, indices, skin, colours) in (
        ("Body", body()),
        ("Cape", cape()),
        ("Skirt", skirt()),
    ):
        attributes = {
            "POSITION": w.floats(positions, "VEC3", bounds=True),
            "NORMAL": w.floats(normals, "VEC3"),
            "JOINTS_0": w.joints([joints for joints, _ in skin]),
            "WEIGHTS_0": w.floats([weights for _, weights in skin], "VEC4"),
        }
        if colours:
            attributes["COLOR_0"] = w.floats(colours, "VEC4")
        meshes.append({"name": name, "primitives": [{"attributes": attributes, "indices": w.indices(indices), "material": 0}]})

    # Nodes: the joints (translation relative to the parent's head), then the three meshes.
    nodes = []
    for name, parent, head in JOINTS:
        base = JOINTS[JOINT[parent]][2] if parent else (0.0, 0.0, 0.0)
        nodes.append({"name": name, "translation": [head[k] - base[k] for k in range(3)]})
    for name, parent, _ in JOINTS:
        if parent:
            nodes[JOINT[parent]].setdefault("children", []).append(JOINT[name])
    inverse = [
        (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -head[0], -head[1], -head[2], 1) for _, _, head in JOINTS
    ]
    skin = {"name": "Skeleton", "joints": list(range(len(JOINTS))), "skeleton": 0, "inverseBindMatrices": w.matrices(inverse)}
    mesh_nodes = []
    for k, mesh in enumerate(meshes):
        nodes.append({"name": mesh["name"], "mesh": k, "skin": 0})
        mesh_nodes.append(len(nodes) - 1)

    times, hips, swing = walk()
    time = w.times(times)
    samplers = [{"input": time, "output": w.floats(hips, "VEC3", target=None), "interpolation": "LINEAR"}]
    channels = [{"sampler": 0, "target": {"node": JOINT["Hips"], "path": "translation"}}]
    for joint, rotations in swing.items():
        samplers.append({"input": time, "output": w.floats(rotations, "VEC4", target=None), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": JOINT[joint], "path": "rotation"}})

    while len(w.bin) % 4:
        w.bin.append(0)
    gltf = {
        "asset": {"version": "2.0", "generator": "bevy_bvh_cloth scripts/make_character.py"},
        "scene": 0,
        # The skeleton and the skinned meshes are the scene's roots, as glTF asks of a skinned
        # mesh (its node's own transform is not used).
        "scenes": [{"name": "Character", "nodes": [JOINT["Hips"]] + mesh_nodes}],
        "nodes": nodes,
        "meshes": meshes,
        "skins": [skin],
        "materials": [{"name": "Cloth", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0}, "doubleSided": True}],
        "animations": [{"name": "Walk", "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": len(w.bin)}],
        "bufferViews": w.views,
        "accessors": w.accessors,
    }
    text = json.dumps(gltf, separators=(",", ":"), sort_keys=True).encode()
    text += b" " * (-len(text) % 4)
    out = bytearray(b"glTF" + struct.pack("<II", 2, 12 + 8 + len(text) + 8 + len(w.bin)))
    out += struct.pack("<I", len(text)) + b"JSON" + text
    out += struct.pack("<I", len(w.bin)) + b"BIN\x00" + bytes(w.bin)
    return bytes(out)


if __name__ == "__main__":
    path = Path(__file__).resolve().parent.parent / "assets" / "models" / "character.glb"
    path.write_bytes(build())
    print(f"wrote {path} ({path.stat().st_size} bytes)")
