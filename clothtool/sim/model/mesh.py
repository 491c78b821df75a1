"""The rest mesh: a grid, a PLY or an OBJ file, with the rest coordinates of each vertex or corner.

The rest shape of Baraff–Witkin cloth is its flat pattern: (u, v) in metres. A grid's
(u, v) are its own in-plane coordinates; a PLY's are its ``s t`` / ``u v`` texture
coordinates times ``uv_scale``; a PLY without them is its own rest state (``uv`` is None
and each triangle is measured in its tangent frame). A garment's pattern is per corner
(``corner_uv``): an OBJ's ``vt`` or a PLY's face ``texcoord`` × ``uv_scale``, so each
triangle rests at its own panel's pattern and a seam (one vertex, a texture position in
each panel) is right. The file's positions are the initial state.
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
    corner_uv: np.ndarray | None = None  # (M, 3, 2) per-corner rest coordinates in metres
    groups: dict | None = None  # OBJ group (g) and material (usemtl) name → triangle indices
    path: object = None  # the file, for messages


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


def flat_pattern(mesh):
    """Does the mesh rest in a flat pattern (uv per vertex or per corner)?"""
    return mesh.uv is not None or mesh.corner_uv is not None


def ply_mesh(path, uv_scale):
    """A PLY rest mesh; its texture coordinates (× ``uv_scale``) are the rest shape when
    present: per corner (face ``texcoord``) before per vertex (``s t``)."""
    from clothtool.io.ply import read_ply

    ply = read_ply(path)
    if len(ply.faces) == 0:
        raise InputError(f"{path}: mesh.ply has no faces")
    if ply.corner_uv is not None:
        return _corner_mesh(ply, path, uv_scale, "mesh.ply", None)
    uv = ply.uv
    if uv is not None:
        uv = uv * uv_scale
        if not np.all(np.isfinite(uv)):
            raise InputError(f"{path}: non-finite texture coordinates")
    _check_positions(ply, path)
    rest3d = _embed(uv) if uv is not None else ply.vertices.copy()
    return RestMesh(ply.vertices.copy(), ply.faces.astype(np.int64), uv, None, rest3d, path=path)


def obj_mesh(path, uv_scale):
    """An OBJ rest mesh: per-corner ``vt`` × ``uv_scale`` are each triangle's rest shape; its
    ``g`` and ``usemtl`` names are the panels ``materials:`` refers to."""
    from clothtool.io.obj import read_obj
    from clothtool.io.obj_groups import face_groups

    obj = read_obj(path)
    if len(obj.faces) == 0:
        raise InputError(f"{path}: mesh.obj has no faces")
    if obj.corner_uv is None:
        raise InputError(f"{path}: mesh.obj has no texture coordinates (vt): each triangle "
                         "rests at its corners' uv × mesh.uv_scale")
    return _corner_mesh(obj, path, uv_scale, "mesh.obj", face_groups(path, obj))


def _corner_mesh(read, path, uv_scale, key, groups):
    missing = read.corner_uv_missing
    if missing is not None and missing.any():
        k = int(np.argmax(missing))
        where = (f"line {int(read.source_lines[read.face_source[k]])}"
                 if read.source_lines is not None else f"face {int(read.face_source[k])}")
        raise InputError(f"{path}: {where}: {key} needs texture coordinates on every corner "
                         "(each triangle rests at its corners' uv × mesh.uv_scale)")
    corner = np.ascontiguousarray(read.corner_uv, np.float64) * uv_scale
    if not np.all(np.isfinite(corner)):
        raise InputError(f"{path}: non-finite texture coordinates")
    _check_positions(read, path)
    x = read.vertices.astype(np.float64)
    return RestMesh(x.copy(), read.faces.astype(np.int64), None, None, x.copy(), corner,
                    groups, path)


def _check_positions(read, path):
    if not np.all(np.isfinite(read.vertices)):
        raise InputError(f"{path}: non-finite vertex coordinates")


def build_rest_mesh(mesh_spec):
    if mesh_spec.grid is not None:
        return grid_mesh(mesh_spec.grid)
    if mesh_spec.obj is not None:
        return obj_mesh(mesh_spec.obj, mesh_spec.uv_scale)
    return ply_mesh(mesh_spec.ply, mesh_spec.uv_scale)


def _embed(uv):
    return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)


PLANAR = 1e-9  # a rest shape within this × its extent of a plane is flat (its own pattern)


def plane_pattern(rest3d):
    """(N, 2) coordinates of a rest shape in its own plane (its principal axes), or None when
    it is not flat (a vertex farther than PLANAR × its extent from the least-squares plane)."""
    centred = rest3d - rest3d.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    if sv[2] > PLANAR * sv[0] or np.max(np.abs(centred @ vt[2])) > PLANAR * np.ptp(centred @ vt[0]):
        return None
    return np.ascontiguousarray(centred @ vt[:2].T)


def rest_edge_matrices(mesh):
    """Per-triangle 2×2 rest edge matrix D_r = [ū1 − ū0, ū2 − ū0] (columns).

    From the uv coordinates when present, per corner or per vertex (so that the columns of
    F = D_d D_r⁻¹ are the warp and weft directions w_u, w_v of Baraff–Witkin); a flat mesh
    without uv is its own pattern (:func:`plane_pattern`: warp along its longest principal
    axis, one frame for every triangle); otherwise in each rest triangle's tangent frame
    (:func:`clothtool.geometry.tangent_edge_matrices`).
    """
    f = mesh.faces
    if mesh.corner_uv is not None:
        p = mesh.corner_uv
        return np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    uv = mesh.uv if mesh.uv is not None else plane_pattern(mesh.rest3d)
    if uv is not None:
        p = uv[f]  # (M, 3, 2)
        return np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    dm, _ = tangent_edge_matrices(np.ascontiguousarray(mesh.rest3d, np.float64), f, DEGENERATE_TOL)
    return dm
