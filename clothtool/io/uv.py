"""The uv rest state of a mesh (``--reference uv``): per-corner texture coordinates when the file
has them (PLY face ``texcoord``, OBJ ``vt``), else per-vertex ones (PLY ``s t`` / ``u v``).

With per-corner uv each triangle takes its own corners' uv, so both sides of a uv seam (one
vertex, two texture positions) are measured against their own panel. The uv kernel gathers
``points[faces]``: per-corner uv (M, 3, 2) is passed as ``points`` = uv.reshape(-1, 2) with
``faces`` = arange(3M).reshape(M, 3).
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError


@dataclass
class RestUV:
    """``points[faces]`` is each triangle's (3, 2) uv; ``name``/``data``: the /mesh dataset
    (``uv`` (N, 2) per vertex, or ``corner_uv`` (M, 3, 2))."""

    points: np.ndarray
    faces: np.ndarray
    name: str
    data: np.ndarray
    mesh_faces: np.ndarray
    n_vertices: int
    path: str
    where: object = None  # triangle k → 'line L' / 'face F', for messages

    def vertex_uv(self):
        """(N, 2) uv per vertex (the 3D variant needs one); fails on a uv seam."""
        if self.name == "uv":
            return self.data
        corner = self.data.reshape(-1, 2)
        ids = self.mesh_faces.reshape(-1)
        out = np.full((self.n_vertices, 2), np.nan)
        out[ids[::-1]] = corner[::-1]  # each vertex takes its first corner's uv
        differ = (out[ids] != corner).any(axis=1)
        if differ.any():
            k = int(np.argmax(differ))
            raise InputError(f"{self.path}: {self.where(k // 3)}: vertex {int(ids[k])} has two "
                             "texture positions (a uv seam); --kabsch with --reference uv needs "
                             "one uv per vertex")
        return out


def rest_uv(mesh, path):
    """The :class:`RestUV` of ``mesh`` (read from ``path``); per-corner uv wins over
    per-vertex uv. Raises InputError when there is none, or when some corners have none."""
    m = len(mesh.faces)

    def where(k):
        source = int(mesh.face_source[k])
        if mesh.source_lines is not None:
            return f"line {int(mesh.source_lines[source])}"
        return f"face {source}"

    if mesh.corner_uv is not None:
        missing = mesh.corner_uv_missing
        if missing is not None and missing.any():
            k = int(np.argmax(missing))
            raise InputError(f"{path}: {where(k)}: face without texture coordinates on some "
                             "corners; --reference uv needs uv on every corner")
        corner = np.ascontiguousarray(mesh.corner_uv, dtype=np.float64)
        return RestUV(corner.reshape(-1, 2), np.arange(3 * m, dtype=np.int64).reshape(m, 3),
                      "corner_uv", corner, mesh.faces, len(mesh.vertices), path, where)
    uv = mesh.uv
    if uv is None:
        raise InputError(f"{path}: --reference uv needs texture coordinates (PLY vertex "
                         "properties 's t' or 'u v', a PLY face 'texcoord' list or OBJ 'vt'), "
                         "and the file has none")
    return RestUV(uv, mesh.faces, "uv", uv, mesh.faces, len(mesh.vertices), path, where)
