"""Wavefront OBJ frames: positions per frame, the pattern's texture coordinates per corner.

Lines in this order: ``v x y z`` (every vertex, in the given order, each number with 17
significant digits, which read back as the same double), ``vt u v`` (the distinct corner
texture positions in order of first use, each number the shortest text that reads back as
the same double), optional ``g NAME`` before each run of faces of one group, and
``f a/ta b/tb c/tc`` (1-based). A uv seam (a vertex with two texture positions) is kept, and
a mesh without texture coordinates gets ``f a b c``. What does not change between frames
(the ``vt`` and ``f`` lines) is formatted once; the faces are the file's last lines, so
:func:`clothtool.io.obj.read_obj` reads a later frame without parsing them again.
Every file is written under a temporary name and renamed.
"""

import os

import numpy as np

from clothtool.io.atomic import atomic_path


class ObjWriter:
    """Writes one mesh's frames as OBJ. ``faces`` (M, 3) int; ``corner_uv`` (M, 3, 2)
    finite texture coordinates of each triangle's corners, or None; ``groups``: None, or
    (names, (M,) index into names of each face's group)."""

    def __init__(self, faces, corner_uv=None, groups=None):
        faces = np.asarray(faces, np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must be (M, 3), got {faces.shape}")
        m = len(faces)
        if corner_uv is None:
            texture_lines, corners = b"", faces + 1
            form = "f %d %d %d\n"
        else:
            corner_uv = np.asarray(corner_uv, np.float64)
            if corner_uv.shape != (m, 3, 2):
                raise ValueError(f"corner_uv must be ({m}, 3, 2), got {corner_uv.shape}")
            flat = corner_uv.reshape(-1, 2)
            _, first, inverse = np.unique(flat, axis=0, return_index=True, return_inverse=True)
            order = np.argsort(first)  # the distinct positions in order of first use
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order))
            table = flat[first[order]]
            texture_lines = _lines("vt %r %r\n", table)
            texture = rank[inverse.ravel()].reshape(m, 3) + 1
            corners = np.stack([faces + 1, texture], axis=2)  # (M, 3, 2): v/vt per corner
            form = "f %d/%d %d/%d %d/%d\n"
        if groups is None:
            face_lines = _lines(form, corners.reshape(m, -1))
        else:
            names, which = groups
            which = np.asarray(which, np.int64)
            starts = np.flatnonzero(np.diff(which, prepend=-1))
            ends = np.append(starts[1:], m)
            face_lines = b"".join(f"g {names[which[a]]}\n".encode("utf-8")
                                  + _lines(form, corners[a:b].reshape(b - a, -1))
                                  for a, b in zip(starts, ends))
        self.tail = texture_lines + face_lines

    def write(self, path, vertices):
        """Write the frame with positions ``vertices`` (N, 3) to ``path``."""
        body = _lines("v %.17g %.17g %.17g\n", np.asarray(vertices, np.float64)) + self.tail
        with atomic_path(os.fspath(path)) as tmp, open(tmp, "wb") as fh:
            fh.write(body)


def write_obj(path, vertices, faces, *, corner_uv=None, groups=None):
    """Write one OBJ mesh (see :class:`ObjWriter`); atomic."""
    ObjWriter(faces, corner_uv, groups).write(path, vertices)


def _lines(form, rows):
    """``form`` applied to each row of ``rows``, as ASCII bytes, in one formatting call (a
    float as ``%r`` is its shortest round-trip text; ``%.17g`` round-trips too, and is
    formatted 1.6× faster)."""
    if len(rows) == 0:
        return b""
    values = rows.tolist()
    return ((form * len(values)) % tuple(v for row in values for v in row)).encode("ascii")
