"""Per-triangle 3×3 deformation gradient of the 3D variant, closed form, numba, float64.

With e1 = x1 − x0, e2 = x2 − x0 and the unit normal n in each frame,

    F3 = [e1′ e2′ n′] [e1 e2 n]⁻¹

maps the reference triangle onto the deformed one and the reference unit normal onto the
deformed one. In the tangent frames T = [t1 t2 n] and T′ = [t1′ t2′ n′] (clothtool.geometry) it is block
diagonal, F3 = T′ diag(F, 1) Tᵀ with F the 2D gradient (upper triangular, det F = area′/area > 0),
so its polar split and eigen-pairs follow from the 2D closed forms of
:mod:`clothtool.analysis.deformation2d` (F = R·U, principal stretches λ1 ≥ λ2):

    R3 = T′ diag(R, 1) Tᵀ,   U3 = T diag(U, 1) Tᵀ,   stretches {λ1, λ2, 1}, directions {d1, d2, n}

One stretch is exactly 1 with direction n (F3ᵀn′ = n); the new information against the 2D
analysis is R3, the rotation of the triangle in space (R3 n = n′). The frames, the degeneracy
test and the flags are the 2D kernel's own, so bits 0–2 agree with /face/flags.
"""

import numpy as np
from numba import prange

from clothtool.analysis.deformation2d import (FLAG_DEFORMED_DEGENERATE, FLAG_NONFINITE,
                                              FLAG_REFERENCE_DEGENERATE, polar_2x2, principal_2x2)
from clothtool.geometry import DEGENERATE_TOL, tangent_edge_matrix
from clothtool.numba_setup import njit


@njit(cache=True, inline="always")
def _frame_product(out, t, c00, c01, c10, c11, u1, u2, un, v1, v2, vn):
    """out[t] = c00 u1 v1ᵀ + c01 u1 v2ᵀ + c10 u2 v1ᵀ + c11 u2 v2ᵀ + un vnᵀ (3-tuples)."""
    for i in range(3):
        for j in range(3):
            out[t, i, j] = (c00 * u1[i] * v1[j] + c01 * u1[i] * v2[j] + c10 * u2[i] * v1[j]
                            + c11 * u2[i] * v2[j] + un[i] * vn[j])


@njit(cache=True, parallel=True, error_model="numpy")
def face_fields3(x_ref, x_def, faces, tol, F3, R3, U3, stretch3, directions3, flags):
    """Fill ``F3``, ``R3``, ``U3`` (M, 3, 3), ``stretch3`` (M, 3) in descending order,
    ``directions3`` (M, 3, 3) (row k: the unit direction of stretch3[k] in the reference
    configuration, sign free) and ``flags`` (M,) uint8 — bit 0 reference degenerate, bit 1
    deformed degenerate, bit 2 non-finite, as in the 2D analysis with the same ``tol``; flagged
    triangles are NaN. Each output is full size or empty (then it is not written); they may be
    float32, the arithmetic is float64.
    """
    for t in prange(faces.shape[0]):
        i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
        a, b, c, r1x, r1y, r1z, r2x, r2y, r2z, ref = tangent_edge_matrix(x_ref, i0, i1, i2, tol)
        ad, bd, cd, d1x, d1y, d1z, d2x, d2y, d2z, dfm = tangent_edge_matrix(x_def, i0, i1, i2, tol)
        flag = (ref | dfm) & FLAG_NONFINITE
        if ref == FLAG_DEFORMED_DEGENERATE:
            flag |= FLAG_REFERENCE_DEGENERATE
        if dfm == FLAG_DEFORMED_DEGENERATE:
            flag |= FLAG_DEFORMED_DEGENERATE
        if flags.shape[0]:
            flags[t] = flag
        if flag:
            if F3.shape[0]:
                F3[t, :, :] = np.nan
            if R3.shape[0]:
                R3[t, :, :] = np.nan
            if U3.shape[0]:
                U3[t, :, :] = np.nan
            if stretch3.shape[0]:
                stretch3[t, :] = np.nan
            if directions3.shape[0]:
                directions3[t, :, :] = np.nan
            continue
        t1, t2 = (r1x, r1y, r1z), (r2x, r2y, r2z)
        n = (r1y * r2z - r1z * r2y, r1z * r2x - r1x * r2z, r1x * r2y - r1y * r2x)
        s1, s2 = (d1x, d1y, d1z), (d2x, d2y, d2z)
        m = (d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x)
        # F = D_d · D_r⁻¹ with D = [[a, b], [0, c]]
        f00, f01, f10, f11 = ad / a, (bd - ad * b / a) / c, 0.0, cd / c
        if F3.shape[0]:
            _frame_product(F3, t, f00, f01, f10, f11, s1, s2, m, t1, t2, n)
        r00, r01, r10, r11, u00, u01, u11 = polar_2x2(f00, f01, f10, f11)
        if R3.shape[0]:
            _frame_product(R3, t, r00, r01, r10, r11, s1, s2, m, t1, t2, n)
        if U3.shape[0]:
            _frame_product(U3, t, u00, u01, u01, u11, t1, t2, n, t1, t2, n)
        if not (stretch3.shape[0] or directions3.shape[0]):
            continue
        lam1, lam2, v0, v1 = principal_2x2(u00, u01, u11, f00 * f11)
        # positions of λ1, λ2 and the normal's 1 in descending order
        k1, k2, kn = (1, 2, 0) if lam1 <= 1.0 else ((0, 2, 1) if lam2 <= 1.0 else (0, 1, 2))
        if stretch3.shape[0]:
            stretch3[t, k1], stretch3[t, k2], stretch3[t, kn] = lam1, lam2, 1.0
        if directions3.shape[0]:
            for j in range(3):
                directions3[t, k1, j] = v0 * t1[j] + v1 * t2[j]
                directions3[t, k2, j] = -v1 * t1[j] + v0 * t2[j]
                directions3[t, kn, j] = n[j]


def face_gradients3(x_ref, x_def, faces, tol=DEGENERATE_TOL):
    """:func:`face_fields3` into new float64 arrays: (F3, R3, U3, stretch3, directions3, flags)."""
    m = len(faces)
    out = (np.empty((m, 3, 3)), np.empty((m, 3, 3)), np.empty((m, 3, 3)), np.empty((m, 3)),
           np.empty((m, 3, 3)), np.empty(m, np.uint8))
    face_fields3(np.ascontiguousarray(x_ref, np.float64), np.ascontiguousarray(x_def, np.float64),
                 np.ascontiguousarray(faces, np.int64), tol, *out)
    return out
