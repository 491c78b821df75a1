"""The rest mesh: a grid or a PLY file, with the rest coordinates of each vertex.

The rest shape of Baraff–Witkin cloth is its flat pattern: per-vertex (u, v) in
metres. A grid's (u, v) are its own in-plane coordinates; a PLY's are its ``s t``
/ ``u v`` texture coordinates times ``uv_scale``; a PLY without them is its own
rest state (``uv`` is None and each triangle is measured in its tangent frame).
"""

from dataclasses import dataclass

import numpy as np

from clothtool.errors import InputError
from clothtool.geometry import DEGENERATE_TOL, grid_triangles, grid_uv, tangent_edge_matrices

PLANE_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


@dataclass(frozen=True)
class RestMesh:
    positions: np.ndarray  # (N, 3) initial positions
    faces: np.ndarray  # (M, 3) int64, counter-clockwise in (u, v) for a grid
    uv: np.ndarray | None  # (N, 2) rest coordinates in metres, or None
    grid_shape: tuple | None  # (nx, ny) for a grid
    rest3d: np.ndarray  # (N, 3): the rest shape embedded in 3D, (u, v, 0) when uv is given


def grid_mesh(spec):
    """An nx × ny grid, centred on the origin, in ``spec.plane``; vertex index j·nx + i, row
    ny−1 on top, quads split criss-cross (:func:`clothtool.geometry.grid_triangles`)."""
    nx, ny = spec.nx, spec.ny
    uv = grid_uv(nx, ny, spec.width, spec.height)
    a, b = PLANE_AXES[spec.plane]
    positions = np.zeros((nx * ny, 3))
    positions[:, a] = uv[:, 0]
    positions[:, b] = uv[:, 1]
    return RestMesh(positions, grid_triangles(nx, ny), uv, (nx, ny), _embed(uv))


def ply_mesh(path, uv_scale):
    """A PLY rest mesh; its texture coordinates (× ``uv_scale``) are the rest shape when present."""
    from clothtool.io.ply import read_ply

    ply = read_ply(path)
    if len(ply.faces) == 0:
        raise InputError(f"{path}: mesh.ply has no faces")
    uv = ply.uv
    if uv is not None:
        uv = uv * uv_scale
        if not np.all(np.isfinite(uv)):
            raise InputError(f"{path}: non-finite texture coordinates")
    if not np.all(np.isfinite(ply.vertices)):
        raise InputError(f"{path}: non-finite vertex coordinates")
    rest3d = _embed(uv) if uv is not None else ply.vertices.copy()
    return RestMesh(ply.vertices.copy(), ply.faces.astype(np.int64), uv, None, rest3d)


def build_rest_mesh(mesh_spec):
    if mesh_spec.grid is not None:
        return grid_mesh(mesh_spec.grid)
    return ply_mesh(mesh_spec.ply, mesh_spec.uv_scale)


def _embed(uv):
    return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)


def rest_edge_matrices(mesh):
    """Per-triangle 2×2 rest edge matrix D_r = [ū1 − ū0, ū2 − ū0] (columns).

    From the uv coordinates when present (so that the columns of F = D_d D_r⁻¹ are
    the warp and weft directions w_u, w_v of Baraff–Witkin); otherwise in each
    rest triangle's tangent frame (:func:`clothtool.geometry.tangent_edge_matrices`).
    """
    f = mesh.faces
    if mesh.uv is not None:
        p = mesh.uv[f]  # (M, 3, 2)
        return np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    dm, _ = tangent_edge_matrices(np.ascontiguousarray(mesh.rest3d, np.float64), f, DEGENERATE_TOL)
    return dm
