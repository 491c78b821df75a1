"""Dihedral-angle change per interior edge: a direct measure of bending (numba, float64).

For an interior edge with its hinge (i, j, k0, k1) (:func:`clothtool.geometry.hinges`) the signed
bending angle θ is :func:`clothtool.geometry.angle_of_normals`: the angle by which the normal
turns across the edge (the exterior dihedral angle; 0 when the pair is flat), θ > 0 when the
surface bends away from its normal (convex: on a closed surface with outward normals every
edge has θ > 0), θ < 0 when it folds towards it. The change is θ_deformed − θ_reference
wrapped to (−π, π].
"""

import math

import numpy as np
from numba import prange

from clothtool.analysis.deformation2d import (FLAG_DEFORMED_DEGENERATE, FLAG_NONFINITE,
                                              FLAG_REFERENCE_DEGENERATE)
from clothtool.geometry import DEGENERATE_TOL, angle_of_normals, hinge_normals
from clothtool.numba_setup import njit, njit_inner
from clothtool.vec3 import dot, load, sub


@njit_inner(cache=True, error_model="numpy")
def _bend(x, i, j, k0, k1, tol):
    """Signed bending angle θ of edge (i, j) and whether either triangle is degenerate
    (‖N‖ ≤ tol·(its longest edge)², as in the 2D analysis)."""
    xi, xj, xk, xl = load(x, i), load(x, j), load(x, k0), load(x, k1)
    e, n0, n1 = hinge_normals(xi, xj, xk, xl)
    ak, bk, al, bl = sub(xk, xi), sub(xk, xj), sub(xl, xi), sub(xl, xj)
    ee = dot(e, e)
    degenerate = (math.sqrt(dot(n0, n0)) <= tol * max(ee, dot(ak, ak), dot(bk, bk))
                  or math.sqrt(dot(n1, n1)) <= tol * max(ee, dot(al, al), dot(bl, bl)))
    return angle_of_normals(e, n0, n1), degenerate


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
