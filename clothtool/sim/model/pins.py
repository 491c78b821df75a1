"""Named pin sets on a grid: vertex index = j·nx + i, row j = ny−1 is the top."""

import numpy as np

from clothtool.errors import InputError

PIN_SETS = ("top_corners", "bottom_corners", "corners", "top_edge", "bottom_edge",
            "left_edge", "right_edge")


def grid_pin_set(name, nx, ny):
    """Vertex indices of the named set on an nx × ny grid."""
    top, right = ny - 1, nx - 1
    rows = np.arange(ny)
    cols = np.arange(nx)
    sets = {
        "top_corners": [top * nx, top * nx + right],
        "bottom_corners": [0, right],
        "corners": [0, right, top * nx, top * nx + right],
        "top_edge": top * nx + cols,
        "bottom_edge": cols,
        "left_edge": rows * nx,
        "right_edge": rows * nx + right,
    }
    return np.asarray(sets[name], dtype=np.int64)


def pin_entry_vertices(entry, n_vertices, grid_shape, key):
    """Vertex indices of one pin entry (a set name or an index); ``key`` names it in errors."""
    if isinstance(entry, str):
        if grid_shape is None:
            raise InputError(f"{key}: pin set {entry!r} needs a grid mesh; "
                             "give vertex indices for a PLY mesh")
        return grid_pin_set(entry, *grid_shape)
    if entry >= n_vertices:
        raise InputError(f"{key}: vertex index {entry} out of range "
                         f"(the mesh has {n_vertices} vertices)")
    return np.array([entry], dtype=np.int64)


def resolve_pins(entries, n_vertices, grid_shape, key="scene.pins"):
    """Sorted unique pinned vertex indices from names and indices.

    ``grid_shape`` is (nx, ny) for a grid mesh, None for a PLY mesh (where only
    vertex indices are allowed).
    """
    picked = [pin_entry_vertices(entry, n_vertices, grid_shape, f"{key}[{k}]")
              for k, entry in enumerate(entries)]
    if not picked:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate(picked))
