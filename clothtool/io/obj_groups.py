"""The panels of an OBJ file: which triangles each ``g`` group and ``usemtl`` material holds,
and the edges of the ``l`` polylines each ``g`` group holds.

A ``g`` statement sets the current groups (``g a b``: both) and ``usemtl`` the current material
for the faces after it, until the next such statement (Wavefront's OBJ specification, "Grouping"
and "Display/render attributes"). Triangles keep their polygon's names (``face_source``,
``source_lines`` of :func:`clothtool.io.obj.read_obj`).
"""

import numpy as np

from clothtool.errors import InputError
from clothtool.io.files import read_bytes

_KEYS = (b"g", b"usemtl")


def face_groups(path, mesh):
    """{name: (K,) int64 sorted triangle indices} of the ``g`` and ``usemtl`` names of the OBJ
    file ``path`` read as ``mesh``; a name both a group and a material holds both's triangles."""
    lines = read_bytes(path, "an OBJ file").split(b"\n")
    statements = {key: ([], []) for key in _KEYS}  # line numbers, names
    for number, raw in enumerate(lines, start=1):
        words = raw.split(b"#", 1)[0].split()
        if words and words[0] in _KEYS:
            at, names = statements[words[0]]
            at.append(number)
            names.append([w.decode("utf-8", "replace") for w in words[1:]])
    tri_line = np.asarray(mesh.source_lines, np.int64)[mesh.face_source]
    out = {}
    for at, names in statements.values():
        if not at:
            continue
        current = np.searchsorted(np.asarray(at), tri_line, side="right") - 1  # −1: before any
        for j, group in enumerate(names):
            hit = np.flatnonzero(current == j)
            for name in group:
                out[name] = np.union1d(out.get(name, np.zeros(0, np.int64)), hit).astype(np.int64)
    return out


def line_groups(path):
    """{name: (K, 2) int64 vertex pairs} of the ``l`` polylines under each ``g`` group of the
    OBJ file ``path``: each polyline ``l v1 v2 … vn`` gives its n − 1 segments, vertices
    0-based (1-based or negative in the file, as in ``f``)."""
    lines = read_bytes(path, "an OBJ file").split(b"\n")
    out, current, vertices = {}, [], 0
    for number, raw in enumerate(lines, start=1):
        words = raw.split(b"#", 1)[0].split()
        if not words:
            continue
        if words[0] == b"v":
            vertices += 1
        elif words[0] == b"g":
            current = [w.decode("utf-8", "replace") for w in words[1:]]
        elif words[0] == b"l":
            try:
                ids = [int(w.split(b"/")[0]) for w in words[1:]]
            except ValueError:
                raise InputError(f"{path}:{number}: an l statement takes vertex indices") from None
            ids = [i - 1 if i > 0 else vertices + i for i in ids]
            if len(ids) < 2 or not all(0 <= i < vertices for i in ids):
                raise InputError(f"{path}:{number}: an l statement needs 2 or more vertices "
                                 "defined before it")
            segments = np.stack([ids[:-1], ids[1:]], axis=1).astype(np.int64)
            for name in current:
                out[name] = np.concatenate([out.get(name, np.zeros((0, 2), np.int64)), segments])
    return out
