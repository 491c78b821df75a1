"""I/O floor for bench_analyze: read each frame's vertex block and write datasets of the
same shapes, dtypes and chunking as clothtool analyze (the nine face fields and the
per-frame positions /frame_vertices), with no analysis at all.

    python floor_io.py FOLDER OUT.h5
"""

import os
import re
import sys

import h5py
import numpy as np

SHAPES = {"F": (2, 2), "C": (2, 2), "U": (2, 2), "R": (2, 2), "strain": (2, 2), "stretch": (2,),
          "directions": (2, 3), "area_ratio": (), "flags": ()}


def vertex_block(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    n = int(re.search(rb"element vertex (\d+)", data[:end]).group(1))
    faces = int(re.search(rb"element face (\d+)", data[:end]).group(1))
    return np.frombuffer(data, "<f4", 3 * n, end).reshape(n, 3).astype(np.float64), faces


def main(folder, out):
    paths = sorted((os.path.join(folder, f) for f in os.listdir(folder)),
                   key=lambda p: int(re.findall(r"\d+", os.path.basename(p))[-1]))
    x, m = vertex_block(paths[0])
    with h5py.File(out, "w") as f:
        sets = {}
        for name, shape in SHAPES.items():
            dt = np.uint8 if name == "flags" else np.float32
            sets[name] = f.create_dataset(f"face/{name}", (len(paths) - 1, m, *shape), dt,
                                          chunks=(1, m, *shape))
        positions = f.create_dataset("frame_vertices", (len(paths), len(x), 3), np.float32,
                                     chunks=(1, len(x), 3))
        positions[0] = x
        for p, path in enumerate(paths[1:]):
            x, _ = vertex_block(path)
            positions[p + 1] = x
            for name, shape in SHAPES.items():
                sets[name][p] = np.full((m, *shape), x[0, 0], sets[name].dtype)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
