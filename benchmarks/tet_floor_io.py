"""I/O floor for bench_tet: read each legacy binary VTK frame's vertex block and write datasets
of the same shapes, dtypes and chunking as ``clothtool analyze`` of a tetrahedral sequence (the
nine /tet fields and /frame_vertices, by clothtool's own row writer), with no analysis at all.

    python tet_floor_io.py FOLDER OUT.h5
"""

import os
import re
import sys

import h5py
import numpy as np

from clothtool.fields import FIELDS_TET
from clothtool.io.h5 import create_pair_dataset, write_row


def vertex_block(path):
    """(N, 3) float64 points of a binary legacy VTK file, and its number of cells."""
    data = open(path, "rb").read()
    head = re.search(rb"POINTS (\d+) (\w+)\n", data)
    n, kind = int(head.group(1)), head.group(2)
    dtype = ">f8" if kind == b"double" else ">f4"
    x = np.frombuffer(data, dtype, 3 * n, head.end()).reshape(n, 3).astype(np.float64)
    return x, int(re.search(rb"CELLS (\d+)", data).group(1))


def main(folder, out):
    paths = sorted((os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".vtk")),
                   key=lambda p: int(re.findall(r"\d+", os.path.basename(p))[-1]))
    x, m = vertex_block(paths[0])
    with h5py.File(out, "w") as f:
        group = f.create_group("tet")
        sets = {f.name: create_pair_dataset(group, f.name, len(paths) - 1, (m, *f.shape),
                                            np.uint8 if f.integer else np.float32, {})
                for f in FIELDS_TET}
        positions = create_pair_dataset(f, "frame_vertices", len(paths), (len(x), 3), np.float32,
                                        {}, fillvalue=np.nan)
        write_row(positions, 0, x.astype(np.float32))
        for p, path in enumerate(paths[1:]):
            x, _ = vertex_block(path)
            write_row(positions, p + 1, x.astype(np.float32))
            for name, ds in sets.items():
                write_row(ds, p, np.full(ds.shape[1:], x[0, 0], ds.dtype))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
