"""Baraff–Witkin constraint filter (1998, §5.3) on per-vertex 3-vectors.

S_v = I for a FREE vertex, 0 for a PINNED one, I − n nᵀ for one SLIDING on a
collider surface with unit normal n. Applied to residuals and search directions,
it keeps the constrained components of a PCG solution at their start values.
"""

from numba import njit

FREE, PINNED, SLIDING = 0, 1, 2  # constraint kind of a vertex


@njit(cache=True)
def apply_filter(r, kind, normal):
    """r ← S r: zero for pinned vertices, the tangential part for sliding ones."""
    for i in range(r.shape[0]):
        if kind[i] == PINNED:
            r[i, 0] = 0.0
            r[i, 1] = 0.0
            r[i, 2] = 0.0
        elif kind[i] == SLIDING:
            rn = r[i, 0] * normal[i, 0] + r[i, 1] * normal[i, 1] + r[i, 2] * normal[i, 2]
            r[i, 0] -= rn * normal[i, 0]
            r[i, 1] -= rn * normal[i, 1]
            r[i, 2] -= rn * normal[i, 2]
