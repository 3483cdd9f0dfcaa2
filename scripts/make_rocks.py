#!/usr/bin/env python3
"""Writes assets/props/rocks.glb: 40 rocks exported the way modelling tools write LOD
levels, for the gltf_props example and the glTF ladder test.

Each rock is a node `RockN` with three children `RockN_LOD0`, `RockN_LOD1`, `RockN_LOD2`
(9 000, 1 000 and 130 triangles: a displaced UV sphere at three resolutions, shared by
every rock), one PBR material. The rocks lie on a 8 x 5 grid, 6 m apart, each scaled
1.5-3 m, on the plane y = 0. Deterministic: the same file every run.

    python3 scripts/make_rocks.py [OUT.glb]
"""
import json
import math
import struct
import sys

LEVELS = [(75, 61), (25, 21), (13, 6)]  # (segments, rings): 2 * segments * (rings - 1) triangles


def height(theta, phi):
    """A rock's radius in a direction: lumps that do not depend on the resolution."""
    x, y, z = math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi)
    return 1.0 + 0.12 * math.sin(3.1 * x + 1.3) * math.cos(2.3 * z) + 0.08 * math.sin(5.0 * y + 0.7)


def sphere(segments, rings):
    positions, normals, indices = [], [], []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2 * math.pi * s / segments
            h = height(theta, phi)
            n = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            positions.append((n[0] * h, n[1] * h * 0.7, n[2] * h))
            normals.append(n)
    row = segments + 1
    for r in range(rings):
        for s in range(segments):
            a, b = r * row + s, r * row + s + 1
            c, d = a + row, b + row
            if r != 0:
                indices += [a, b, c]
            if r != rings - 1:
                indices += [b, d, c]
    return positions, normals, indices


def main(out):
    blob = bytearray()
    views, accessors, meshes = [], [], []

    def add_view(data, target):
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        return len(views) - 1

    for segments, rings in LEVELS:
        positions, normals, indices = sphere(segments, rings)
        pos = b"".join(struct.pack("<3f", *p) for p in positions)
        nor = b"".join(struct.pack("<3f", *n) for n in normals)
        idx = b"".join(struct.pack("<I", i) for i in indices)
        lo = [min(p[k] for p in positions) for k in range(3)]
        hi = [max(p[k] for p in positions) for k in range(3)]
        accessors.append({"bufferView": add_view(pos, 34962), "componentType": 5126,
                          "count": len(positions), "type": "VEC3", "min": lo, "max": hi})
        accessors.append({"bufferView": add_view(nor, 34962), "componentType": 5126,
                          "count": len(normals), "type": "VEC3"})
        accessors.append({"bufferView": add_view(idx, 34963), "componentType": 5125,
                          "count": len(indices), "type": "SCALAR"})
        a = len(accessors) - 3
        meshes.append({"name": f"rock_{len(indices) // 3}",
                       "primitives": [{"attributes": {"POSITION": a, "NORMAL": a + 1},
                                       "indices": a + 2, "material": 0}]})
    nodes, roots = [], []
    for i in range(40):
        children = []
        for level in range(len(LEVELS)):
            nodes.append({"name": f"Rock{i}_LOD{level}", "mesh": level})
            children.append(len(nodes) - 1)
        scale = 1.5 + 1.5 * ((i * 7919) % 40) / 40.0
        nodes.append({"name": f"Rock{i}", "children": children,
                      "translation": [6.0 * (i % 8), 0.0, 6.0 * (i // 8)],
                      "rotation": [0.0, math.sin(i * 0.7), 0.0, math.cos(i * 0.7)],
                      "scale": [scale, scale, scale]})
        roots.append(len(nodes) - 1)
    while len(blob) % 4:
        blob.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": "bevy_sherwood scripts/make_rocks.py"},
        "scene": 0,
        "scenes": [{"name": "Rocks", "nodes": roots}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [{"name": "rock", "pbrMetallicRoughness": {
            "baseColorFactor": [0.45, 0.43, 0.40, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    with open(out, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(blob)))
        f.write(struct.pack("<I4s", len(text), b"JSON") + text)
        f.write(struct.pack("<I4s", len(blob), b"BIN\0") + bytes(blob))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "assets/props/rocks.glb")
