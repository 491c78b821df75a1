"""The panels of an OBJ file: which triangles each ``g`` group and ``usemtl`` material holds.

A ``g`` statement sets the current groups (``g a b``: both) and ``usemtl`` the current material
for the faces after it, until the next such statement (Wavefront's OBJ specification, "Grouping"
and "Display/render attributes"). Triangles keep their polygon's names (``face_source``,
``source_lines`` of :func:`clothtool.io.obj.read_obj`).
"""

import numpy as np

from clothtool.errors import InputError

_KEYS = (b"g", b"usemtl")


def face_groups(path, mesh):
    """{name: (K,) int64 sorted triangle indices} of the ``g`` and ``usemtl`` names of the OBJ
    file ``path`` read as ``mesh``; a name both a group and a material holds both's triangles."""
    try:
        with open(path, "rb") as fh:
            lines = fh.read().split(b"\n")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
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
