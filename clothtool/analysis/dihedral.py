"""Dihedral-angle change per interior edge: a direct measure of bending (numba, float64).

For an edge (i, j) with opposite corners k0, k1 (:func:`clothtool.analysis.topology.interior_edges`)
the triangles (i, j, k0) and (j, i, k1) have the normals n0 = (xj − xi) × (xk0 − xi) and
n1 = (xi − xj) × (xk1 − xj), oriented alike, and the signed bending angle is

    θ = atan2(ê · (n0 × n1), n0 · n1),   ê = (xj − xi)/‖xj − xi‖,

the angle by which the normal turns across the edge (the exterior dihedral angle; 0 when the
pair is flat). θ > 0 when the surface bends away from its normal (convex: on a closed surface
with outward normals every edge has θ > 0), θ < 0 when it folds towards it. The change is
θ_deformed − θ_reference wrapped to (−π, π].
"""

import math

import numpy as np
from numba import njit, prange

from clothtool.analysis.deformation2d import (DEGENERATE_TOL, FLAG_DEFORMED_DEGENERATE, FLAG_NONFINITE,
                                              FLAG_REFERENCE_DEGENERATE)


@njit(cache=True, error_model="numpy")
def _bend(x, i, j, k0, k1, tol):
    """Signed bending angle θ of edge (i, j) and whether either triangle is degenerate."""
    e0, e1, e2 = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
    a0, a1, a2 = x[k0, 0] - x[i, 0], x[k0, 1] - x[i, 1], x[k0, 2] - x[i, 2]
    b0, b1, b2 = x[k1, 0] - x[j, 0], x[k1, 1] - x[j, 1], x[k1, 2] - x[j, 2]
    n00, n01, n02 = e1 * a2 - e2 * a1, e2 * a0 - e0 * a2, e0 * a1 - e1 * a0  # e × a
    n10, n11, n12 = b1 * e2 - b2 * e1, b2 * e0 - b0 * e2, b0 * e1 - b1 * e0  # (−e) × b
    ee = e0 * e0 + e1 * e1 + e2 * e2
    aa = a0 * a0 + a1 * a1 + a2 * a2
    bb = b0 * b0 + b1 * b1 + b2 * b2
    ab = (a0 - e0) ** 2 + (a1 - e1) ** 2 + (a2 - e2) ** 2  # ‖xk0 − xj‖²
    ba = (b0 + e0) ** 2 + (b1 + e1) ** 2 + (b2 + e2) ** 2  # ‖xk1 − xi‖²
    dbl_area0 = math.sqrt(n00 * n00 + n01 * n01 + n02 * n02)
    dbl_area1 = math.sqrt(n10 * n10 + n11 * n11 + n12 * n12)
    degenerate = dbl_area0 <= tol * max(ee, aa, ab) or dbl_area1 <= tol * max(ee, bb, ba)
    c0 = n01 * n12 - n02 * n11
    c1 = n02 * n10 - n00 * n12
    c2 = n00 * n11 - n01 * n10
    sin_part = (c0 * e0 + c1 * e1 + c2 * e2) / math.sqrt(ee)
    return math.atan2(sin_part, n00 * n10 + n01 * n11 + n02 * n12), degenerate


@njit(cache=True, parallel=True, error_model="numpy")
def dihedral_fields(x_ref, x_def, edges, opposite, tol, change, flags):
    """Fill the signed dihedral-angle change θ_def − θ_ref (radians, wrapped to (−π, π]) per edge
    into ``change`` (E,) and ``flags`` (E,) uint8: bit 0 / bit 1 when a triangle of the edge is
    degenerate in the reference / deformed frame (‖e1 × e2‖ ≤ tol·(longest edge)², as in the 2D
    analysis), bit 2 non-finite input; flagged changes are NaN. Each output is full size or empty
    (then not written).
    """
    for t in prange(edges.shape[0]):
        i, j, k0, k1 = edges[t, 0], edges[t, 1], opposite[t, 0], opposite[t, 1]
        finite = True
        for v in (i, j, k0, k1):
            for k in range(3):
                finite = finite and np.isfinite(x_ref[v, k]) and np.isfinite(x_def[v, k])
        d = np.nan
        f = FLAG_NONFINITE
        if finite:
            theta_ref, ref_bad = _bend(x_ref, i, j, k0, k1, tol)
            theta_def, def_bad = _bend(x_def, i, j, k0, k1, tol)
            f = ((FLAG_REFERENCE_DEGENERATE if ref_bad else 0)
                 | (FLAG_DEFORMED_DEGENERATE if def_bad else 0))
            if f == 0:
                d = theta_def - theta_ref
                if d > math.pi:
                    d -= 2.0 * math.pi
                elif d <= -math.pi:
                    d += 2.0 * math.pi
        if change.shape[0]:
            change[t] = d
        if flags.shape[0]:
            flags[t] = f


def dihedral_change(x_ref, x_def, edges, opposite, tol=DEGENERATE_TOL):
    """:func:`dihedral_fields` into new arrays: (change float64 (E,), flags uint8 (E,))."""
    out = (np.empty(len(edges)), np.empty(len(edges), np.uint8))
    dihedral_fields(np.ascontiguousarray(x_ref, np.float64), np.ascontiguousarray(x_def, np.float64),
                    edges, opposite, tol, *out)
    return out
