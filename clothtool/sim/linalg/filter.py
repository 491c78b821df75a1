"""Baraff–Witkin constraint filter (1998, §5.3) on per-vertex 3-vectors.

S_v = I for a FREE vertex and 0 for a PINNED one. Applied to residuals and search
directions, it keeps the pinned components of a PCG solution at their start values (a
moving pin's prescribed motion, zero for a fixed one).
"""

FREE, PINNED = 0, 1  # constraint kind of a vertex

from clothtool.numba_setup import njit


@njit(cache=True)
def apply_filter(r, kind):
    """r ← S r: zero for pinned vertices."""
    for i in range(r.shape[0]):
        if kind[i] == PINNED:
            r[i, 0] = 0.0
            r[i, 1] = 0.0
            r[i, 2] = 0.0
