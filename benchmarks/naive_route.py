"""The naive route for bench_analyze: trimesh to load, numpy for tangent frames and F,
np.linalg.svd for the polar split and stretches, h5py to write, frame pairs (i, i+1).

    python naive_route.py FOLDER OUT.h5
"""

import os
import re
import sys

import h5py
import numpy as np
import trimesh


def edge_matrices(x, faces):
    e1 = x[faces[:, 1]] - x[faces[:, 0]]
    e2 = x[faces[:, 2]] - x[faces[:, 0]]
    t1 = e1 / np.linalg.norm(e1, axis=1)[:, None]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1)[:, None]
    T = np.stack([t1, np.cross(n, t1)], 1)
    return T, T @ np.stack([e1, e2], 2)


def main(folder, out):
    paths = sorted((os.path.join(folder, f) for f in os.listdir(folder)),
                   key=lambda p: int(re.findall(r"\d+", os.path.basename(p))[-1]))
    load = lambda p: trimesh.load(p, process=False)  # noqa: E731
    prev = load(paths[0])
    faces = np.asarray(prev.faces)
    with h5py.File(out, "w") as f:
        for p, path in enumerate(paths[1:]):
            cur = load(path)
            T0, D0 = edge_matrices(np.asarray(prev.vertices, np.float64), faces)
            _, D1 = edge_matrices(np.asarray(cur.vertices, np.float64), faces)
            F = D1 @ np.linalg.inv(D0)
            W, S, Vt = np.linalg.svd(F)
            C = np.transpose(F, (0, 2, 1)) @ F
            fields = {"F": F, "C": C, "U": np.transpose(Vt, (0, 2, 1)) @ (S[:, :, None] * Vt),
                      "R": W @ Vt, "strain": 0.5 * (C - np.eye(2)), "stretch": S,
                      "directions": np.einsum("mkj,mjc->mkc", Vt, T0), "area_ratio": S[:, 0] * S[:, 1]}
            for name, value in fields.items():
                if p == 0:
                    f.create_dataset(f"face/{name}", (len(paths) - 1, *value.shape), np.float32,
                                     chunks=(1, *value.shape))
                f[f"face/{name}"][p] = value
            prev = cur


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
