"""Per-triangle 2D deformation in each triangle's tangent frame (spec §2), numba kernels.

Tangent frame of a triangle (x0, x1, x2) with e1 = x1 − x0, e2 = x2 − x0:
t1 = e1/‖e1‖, n = e1×e2/‖e1×e2‖, t2 = n×t1. Its edge matrix
D = [[t1·e1, t1·e2], [t2·e1, t2·e2]] = [[‖e1‖, t1·e2], [0, ‖e1×e2‖/‖e1‖]]
is upper triangular with a positive diagonal. With D_r of the reference and D_d
of the deformed triangle (Rohmer et al. 2010; the FEM form F = G·D⁻¹, Müller's
"Game Physics Pearls" ch. 10):

    F = D_d · D_r⁻¹,   C = FᵀF,   F = R·U,   E = (C − I)/2,   J = λ1·λ2 = |det F|.

The 2×2 polar split is closed form: for det F ≥ 0, R is the rotation by
atan2(F10 − F01, F00 + F11) (for det F < 0, possible only against a flipped uv
reference, the reflection with angle atan2(F10 + F01, F00 − F11)); U = RᵀF. The
principal stretches are the eigenvalues of U, λ1 = m + d, λ2 = |det F|/λ1 with
m = tr(U)/2, d = √(((U00 − U11)/2)² + U01²): no square root of C and no
cancellation in λ2, so small stretches keep full relative precision.

Flags (uint8 bits): 1 reference degenerate, 2 deformed degenerate, 4 non-finite
input, 8 uv triangle flipped. Degenerate: ‖e1×e2‖ ≤ DEGENERATE_TOL · (longest
edge)², i.e. the triangle's height is below DEGENERATE_TOL of its longest edge.
Where bit 1, 2 or 4 is set the float fields are NaN.
"""

import numpy as np
from numba import njit, prange

from clothtool import numba_setup  # noqa: F401  (threading layer, before the first kernel)
from clothtool.geometry import DEGENERATE, DEGENERATE_TOL, NONFINITE, tangent_edge_matrix

FLAG_REFERENCE_DEGENERATE = np.uint8(1)
FLAG_DEFORMED_DEGENERATE = DEGENERATE
FLAG_NONFINITE = NONFINITE
FLAG_UV_FLIPPED = np.uint8(8)
NAN_FLAGS = np.uint8(7)

FIELDS = ("F", "C", "U", "R", "strain", "stretch", "directions", "area_ratio", "flags")


@njit(cache=True, inline="always")
def _store_rest(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag, dinv, basis, flags):
    """Rest-state data of triangle k from its edge matrix: D_r⁻¹ = [[1/a, −b/(ac)], [0, 1/c]],
    the tangent basis rows t1, t2, and its flag (a degenerate triangle is bit 0 here)."""
    if flag == FLAG_DEFORMED_DEGENERATE:
        flag = FLAG_REFERENCE_DEGENERATE
    flags[k] = flag
    if flag != 0:
        dinv[k] = np.nan
        basis[k] = np.nan
        return
    dinv[k, 0, 0] = 1.0 / a
    dinv[k, 0, 1] = -b / (a * c)
    dinv[k, 1, 0] = 0.0
    dinv[k, 1, 1] = 1.0 / c
    basis[k, 0, 0], basis[k, 0, 1], basis[k, 0, 2] = t1x, t1y, t1z
    basis[k, 1, 0], basis[k, 1, 1], basis[k, 1, 2] = t2x, t2y, t2z


def allocate_rest(m):
    """Empty (D_r⁻¹ (M,2,2), basis (M,2,3), flags (M,)) for :func:`reference_from_positions`
    or the ``next_rest`` outputs of :func:`deformation_fields`."""
    return np.empty((m, 2, 2)), np.empty((m, 2, 3)), np.empty(m, np.uint8)


@njit(cache=True, parallel=True, nogil=True)
def _rest_from_positions(x, faces, tol, dinv, basis, flags):
    for k in prange(faces.shape[0]):
        a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag = tangent_edge_matrix(
            x, faces[k, 0], faces[k, 1], faces[k, 2], tol)
        _store_rest(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag, dinv, basis, flags)


def reference_from_positions(x, faces, tol):
    """Rest-state data of every triangle from 3D positions.

    Returns D_r⁻¹ (M, 2, 2), the reference tangent basis (M, 2, 3) (rows t1, t2),
    and flags (M,) uint8 (bit 0 degenerate, bit 2 non-finite).
    """
    rest = allocate_rest(faces.shape[0])
    _rest_from_positions(x, faces, tol, *rest)
    return rest


@njit(cache=True, parallel=True, nogil=True)
def reference_from_uv(uv, faces, scale, tol):
    """Rest-state data from texture coordinates (Baraff–Witkin): D_r is the uv edge
    matrix [[Δu1, Δu2], [Δv1, Δv2]]·scale itself; the basis rows are (1,0,0), (0,1,0)
    so directions come out as (u, v, 0). Flags: bit 0 degenerate, bit 2 non-finite,
    bit 3 flipped (det D_r < 0)."""
    m = faces.shape[0]
    dinv = np.full((m, 2, 2), np.nan)
    basis = np.zeros((m, 2, 3))
    flags = np.zeros(m, np.uint8)
    for k in prange(m):
        basis[k, 0, 0] = 1.0
        basis[k, 1, 1] = 1.0
        i0, i1, i2 = faces[k, 0], faces[k, 1], faces[k, 2]
        du1 = (uv[i1, 0] - uv[i0, 0]) * scale
        dv1 = (uv[i1, 1] - uv[i0, 1]) * scale
        du2 = (uv[i2, 0] - uv[i0, 0]) * scale
        dv2 = (uv[i2, 1] - uv[i0, 1]) * scale
        if not (np.isfinite(du1) and np.isfinite(dv1) and np.isfinite(du2) and np.isfinite(dv2)):
            flags[k] = FLAG_NONFINITE
            continue
        det = du1 * dv2 - du2 * dv1
        longest = max(du1 * du1 + dv1 * dv1, du2 * du2 + dv2 * dv2,
                      (du2 - du1) ** 2 + (dv2 - dv1) ** 2)
        if abs(det) <= tol * longest:
            flags[k] = FLAG_REFERENCE_DEGENERATE
            continue
        if det < 0.0:
            flags[k] = FLAG_UV_FLIPPED
        dinv[k, 0, 0] = dv2 / det
        dinv[k, 0, 1] = -du2 / det
        dinv[k, 1, 0] = -dv1 / det
        dinv[k, 1, 1] = du1 / det
    return dinv, basis, flags


@njit(cache=True, inline="always")
def polar_2x2(f00, f01, f10, f11):
    """Closed-form polar split F = R·U of a 2×2 matrix.

    Returns R (r00, r01, r10, r11) and symmetric U (u00, u01, u11)."""
    det = f00 * f11 - f01 * f10
    if det >= 0.0:
        c, s = f00 + f11, f10 - f01
        h = np.sqrt(c * c + s * s)
        c, s = c / h, s / h
        r00, r01, r10, r11 = c, -s, s, c
    else:
        c, s = f00 - f11, f10 + f01
        h = np.sqrt(c * c + s * s)
        c, s = c / h, s / h
        r00, r01, r10, r11 = c, s, s, -c
    u00 = r00 * f00 + r10 * f10
    u01 = 0.5 * ((r00 * f01 + r10 * f11) + (r01 * f00 + r11 * f10))
    u11 = r01 * f01 + r11 * f11
    return r00, r01, r10, r11, u00, u01, u11


@njit(cache=True, inline="always")
def principal_2x2(u00, u01, u11, absdet):
    """Eigen-decomposition of a symmetric positive (semi)definite 2×2 U.

    Returns λ1 ≥ λ2 and the unit eigenvector (v0, v1) of λ1 (that of λ2 is (−v1, v0))."""
    half = 0.5 * (u00 - u11)
    d = np.sqrt(half * half + u01 * u01)
    lam1 = 0.5 * (u00 + u11) + d
    lam2 = min(absdet / lam1, lam1) if lam1 > 0.0 else 0.0  # min: rounding when λ1 ≈ λ2
    if d == 0.0:
        return lam1, lam2, 1.0, 0.0
    if half >= 0.0:
        v0, v1 = half + d, u01
    else:
        v0, v1 = u01, d - half
    h = np.sqrt(v0 * v0 + v1 * v1)
    return lam1, lam2, v0 / h, v1 / h


@njit(cache=True, parallel=True, nogil=True)
def deformation_fields(x, faces, dinv, basis, ref_flags, tol,
                       F, C, U, R, strain, stretch, directions, area_ratio, flags,
                       next_dinv, next_basis, next_flags):
    """Fill the per-triangle fields of one pair from deformed positions ``x``.

    Every output is either full size (M, …) or empty (shape[0] == 0), in which case
    it is neither computed nor written. Outputs may be float32 or float64; all
    arithmetic is float64. ``next_*``: if full size, also the rest-state data of ``x``
    (as :func:`reference_from_positions`), for the next pair of a 'previous' sequence,
    at the cost of a few stores instead of a second pass.
    """
    m = faces.shape[0]
    for k in prange(m):
        a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag = tangent_edge_matrix(
            x, faces[k, 0], faces[k, 1], faces[k, 2], tol)
        if next_flags.shape[0]:
            _store_rest(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag,
                        next_dinv, next_basis, next_flags)
        flag |= ref_flags[k]
        if flags.shape[0]:
            flags[k] = flag
        if flag & NAN_FLAGS:
            _fill_nan(k, F, C, U, R, strain, stretch, directions, area_ratio)
            continue
        # F = D_d · D_r⁻¹ with D_d = [[a, b], [0, c]]
        g00, g01, g10, g11 = dinv[k, 0, 0], dinv[k, 0, 1], dinv[k, 1, 0], dinv[k, 1, 1]
        f00 = a * g00 + b * g10
        f01 = a * g01 + b * g11
        f10 = c * g10
        f11 = c * g11
        if F.shape[0]:
            F[k, 0, 0], F[k, 0, 1], F[k, 1, 0], F[k, 1, 1] = f00, f01, f10, f11
        if C.shape[0] or strain.shape[0]:
            c00 = f00 * f00 + f10 * f10
            c01 = f00 * f01 + f10 * f11
            c11 = f01 * f01 + f11 * f11
            if C.shape[0]:
                C[k, 0, 0], C[k, 0, 1], C[k, 1, 0], C[k, 1, 1] = c00, c01, c01, c11
            if strain.shape[0]:
                strain[k, 0, 0] = 0.5 * (c00 - 1.0)
                strain[k, 0, 1] = 0.5 * c01
                strain[k, 1, 0] = 0.5 * c01
                strain[k, 1, 1] = 0.5 * (c11 - 1.0)
        if not (U.shape[0] or R.shape[0] or stretch.shape[0] or directions.shape[0]
                or area_ratio.shape[0]):
            continue
        absdet = abs(f00 * f11 - f01 * f10)
        if area_ratio.shape[0]:
            area_ratio[k] = absdet
        if not (U.shape[0] or R.shape[0] or stretch.shape[0] or directions.shape[0]):
            continue
        r00, r01, r10, r11, u00, u01, u11 = polar_2x2(f00, f01, f10, f11)
        if R.shape[0]:
            R[k, 0, 0], R[k, 0, 1], R[k, 1, 0], R[k, 1, 1] = r00, r01, r10, r11
        if U.shape[0]:
            U[k, 0, 0], U[k, 0, 1], U[k, 1, 0], U[k, 1, 1] = u00, u01, u01, u11
        if stretch.shape[0] or directions.shape[0]:
            lam1, lam2, v0, v1 = principal_2x2(u00, u01, u11, absdet)
            if stretch.shape[0]:
                stretch[k, 0] = lam1
                stretch[k, 1] = lam2
            if directions.shape[0]:
                for j in range(3):
                    directions[k, 0, j] = v0 * basis[k, 0, j] + v1 * basis[k, 1, j]
                    directions[k, 1, j] = -v1 * basis[k, 0, j] + v0 * basis[k, 1, j]


@njit(cache=True, inline="always")
def _fill_nan(k, F, C, U, R, strain, stretch, directions, area_ratio):
    nan = np.nan
    if F.shape[0]:
        F[k] = nan
    if C.shape[0]:
        C[k] = nan
    if U.shape[0]:
        U[k] = nan
    if R.shape[0]:
        R[k] = nan
    if strain.shape[0]:
        strain[k] = nan
    if stretch.shape[0]:
        stretch[k] = nan
    if directions.shape[0]:
        directions[k] = nan
    if area_ratio.shape[0]:
        area_ratio[k] = nan


def allocate_fields(m, fields, dtype):
    """Output arrays for :func:`deformation_fields`: full size for the requested
    ``fields``, empty for the others."""
    shapes = {"F": (2, 2), "C": (2, 2), "U": (2, 2), "R": (2, 2), "strain": (2, 2),
              "stretch": (2,), "directions": (2, 3), "area_ratio": ()}
    out = {name: np.empty((m if name in fields else 0, *shape), dtype) for name, shape in shapes.items()}
    out["flags"] = np.empty(m if "flags" in fields else 0, np.uint8)
    return out


def analyze_pair(reference, deformed, faces, *, fields=FIELDS, uv=None, uv_scale=1.0,
                 dtype=np.float64, tol=DEGENERATE_TOL):
    """Per-triangle fields of one pair, as a dict name → array (spec §2).

    ``reference``/``deformed``: (N, 3) positions; with ``uv`` (N, 2) the rest shape is
    the texture coordinates times ``uv_scale`` and ``reference`` is ignored.
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if uv is not None:
        ref = reference_from_uv(np.ascontiguousarray(uv, dtype=np.float64), faces, float(uv_scale), tol)
    else:
        ref = reference_from_positions(np.ascontiguousarray(reference, dtype=np.float64), faces, tol)
    out = allocate_fields(len(faces), fields, dtype)
    deformation_fields(np.ascontiguousarray(deformed, dtype=np.float64), faces, *ref, tol,
                       *(out[name] for name in FIELDS), *allocate_rest(0))
    return {name: out[name] for name in FIELDS if name in fields}
