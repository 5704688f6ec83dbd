#!/usr/bin/python3
"""Writes blob.ply beside this script: a bumpy closed blob of 81920 flat-shaded triangles (an
icosphere subdivided 6 times, displaced), standing in for a scanned mesh in scan_pose.json.
The same surface as fineBlobScene() in tests/core/diff/shape_gradient_test.cc."""
import os
import struct
import sys

import numpy as np


def icosphere(subdivisions):
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
             (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    verts = [np.array(v, float) / np.linalg.norm(v) for v in verts]
    for _ in range(subdivisions):
        middle = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                middle[key] = len(verts) - 1
            return middle[key]

        finer = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            finer += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = finer
    return np.array(verts), np.array(faces)


def main():
    p, f = icosphere(6)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    r = (1 + 0.12 * np.sin(5 * x + 1) * np.cos(4 * y) + 0.08 * np.sin(9 * z + 2 * x) + 0.05 * np.cos(13 * y + 7 * z)
         + 0.3 * np.maximum(0, z) ** 2)
    p = p * r[:, None] * np.array([0.5, 0.38, 0.42])
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "blob.ply")
    with open(out, "wb") as fh:
        fh.write(b"ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
                 b"property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n" % (len(p), len(f)))
        fh.write(p.astype("<f4").tobytes())
        for a, b, c in f:
            fh.write(struct.pack("<Biii", 3, a, b, c))
    print("wrote", out, len(p), "vertices,", len(f), "triangles")


if __name__ == "__main__":
    main()
