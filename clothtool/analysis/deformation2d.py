"""Per-triangle 2D deformation in each triangle's tangent frame, numba kernels.

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
from numba import prange

from clothtool.analysis import kernel_plan
from clothtool.fields import FIELDS_2D, NAMES_2D, parse_fields
from clothtool.analysis.kernel_plan import Slots, fill_nan
from clothtool.geometry import DEGENERATE, DEGENERATE_TOL, NONFINITE, tangent_edge_matrix
from clothtool.numba_setup import njit

FLAG_REFERENCE_DEGENERATE = np.uint8(1)
FLAG_DEFORMED_DEGENERATE = DEGENERATE
FLAG_NONFINITE = NONFINITE
FLAG_UV_FLIPPED = np.uint8(8)
NAN_FLAGS = np.uint8(7)

FIELDS = NAMES_2D


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
    or the ``next_*`` outputs of :func:`deformation_fields_and_next_rest`."""
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


# ---------------------------------------------------------------- the plan of one pair
# Each 2D field of the registry has a slot (clothtool.analysis.kernel_plan).
NEED_C = 1  # C = FᵀF
NEED_POLAR = 2  # F = R·U
NEED_PRINCIPAL = 4  # λ1, λ2 and the eigenvectors of U
# The slot order is written here, not taken from the registry's order: numba freezes these
# globals into its cached kernel, whose cache is keyed on this file only.
SLOTS = Slots("2D", ("F", "C", "U", "R", "strain", "stretch", "directions", "area_ratio", "flags",
                     "thickness", "almansi", "hencky", "engineering", "principal_strain",
                     "max_shear", "von_mises", "directions_deformed"),
              FIELDS_2D, {"C": NEED_C, "polar": NEED_POLAR,
                          "principal": NEED_PRINCIPAL | NEED_POLAR})
_SLOT = SLOTS.index
_FLOAT_SIZES = SLOTS.float_sizes
# Compile-time constants of the kernel below.
S_F, S_C, S_U, S_R = _SLOT["F"], _SLOT["C"], _SLOT["U"], _SLOT["R"]
S_STRAIN, S_STRETCH, S_DIRECTIONS = _SLOT["strain"], _SLOT["stretch"], _SLOT["directions"]
S_AREA_RATIO, S_FLAGS = _SLOT["area_ratio"], _SLOT["flags"]
S_THICKNESS = _SLOT["thickness"]
S_ALMANSI, S_HENCKY, S_ENGINEERING = _SLOT["almansi"], _SLOT["hencky"], _SLOT["engineering"]
S_PRINCIPAL_STRAIN, S_MAX_SHEAR = _SLOT["principal_strain"], _SLOT["max_shear"]
S_VON_MISES, S_DIRECTIONS_DEFORMED = _SLOT["von_mises"], _SLOT["directions_deformed"]


class KernelPlan(kernel_plan.KernelPlan):
    """What :func:`deformation_fields` computes for M triangles
    (:class:`clothtool.analysis.kernel_plan.KernelPlan` over the 2D slots)."""

    slots = SLOTS


# ---------------------------------------------------------------- per-field kernel lines
@njit(cache=True, inline="always")
def _put4(out, i, a, b, c, d):
    """A 2×2 matrix [[a, b], [c, d]] (F, R and the non-symmetric fields)."""
    out[i], out[i + 1], out[i + 2], out[i + 3] = a, b, c, d


@njit(cache=True, inline="always")
def _put_symmetric(out, i, a, b, d):
    """A symmetric 2×2 matrix [[a, b], [b, d]] (C, U)."""
    _put4(out, i, a, b, b, d)


@njit(cache=True, inline="always")
def _write_strain(out, i, c00, c01, c11):
    """E = (C − I)/2."""
    _put4(out, i, 0.5 * (c00 - 1.0), 0.5 * c01, 0.5 * c01, 0.5 * (c11 - 1.0))


@njit(cache=True, inline="always")
def _write_area_ratio(out, i, absdet):
    out[i] = absdet


@njit(cache=True, inline="always")
def _write_thickness(out, i, absdet):
    """λ3 = 1/(λ1λ2) = 1/|det F| (volume kept)."""
    out[i] = 1.0 / absdet


@njit(cache=True, inline="always")
def _write_almansi(out, i, f00, f01, f10, f11, absdet):
    """e = (I − B⁻¹)/2 with B = F·Fᵀ, B⁻¹ = adj(B)/det F² (Bonet & Wood, Nonlinear Continuum
    Mechanics, eq. 3.11)."""
    b00 = f00 * f00 + f01 * f01
    b01 = f00 * f10 + f01 * f11
    b11 = f10 * f10 + f11 * f11
    d = absdet * absdet
    _put4(out, i, 0.5 * (1.0 - b11 / d), 0.5 * b01 / d, 0.5 * b01 / d, 0.5 * (1.0 - b00 / d))


@njit(cache=True, inline="always")
def _write_engineering(out, i, u00, u01, u11):
    """Biot strain U − I."""
    _put4(out, i, u00 - 1.0, u01, u01, u11 - 1.0)


@njit(cache=True, inline="always")
def _write_hencky(out, i, lam1, lam2, v0, v1):
    """ln U = ln λ1 v1v1ᵀ + ln λ2 v2v2ᵀ with v1 = (v0, v1), v2 = (−v1, v0)."""
    l1, l2 = np.log(lam1), np.log(lam2)
    h01 = (l1 - l2) * v0 * v1
    _put4(out, i, l1 * v0 * v0 + l2 * v1 * v1, h01, h01, l1 * v1 * v1 + l2 * v0 * v0)


@njit(cache=True, inline="always")
def _write_principal_strain(out, i, lam1, lam2):
    out[i], out[i + 1] = 0.5 * (lam1 * lam1 - 1.0), 0.5 * (lam2 * lam2 - 1.0)


@njit(cache=True, inline="always")
def _write_max_shear(out, i, lam1, lam2):
    """(E1 − E2)/2 = (λ1² − λ2²)/4."""
    out[i] = 0.25 * (lam1 - lam2) * (lam1 + lam2)


@njit(cache=True, inline="always")
def _write_von_mises(out, i, lam1, lam2):
    """√(2/3 (ε1² + ε2² + ε3²)), εk = ln λk, ε3 = −(ε1 + ε2) (incompressible)."""
    e1, e2 = np.log(lam1), np.log(lam2)
    e3 = -(e1 + e2)
    out[i] = np.sqrt((2.0 / 3.0) * (e1 * e1 + e2 * e2 + e3 * e3))


@njit(cache=True, inline="always")
def _write_directions_deformed(out, i, r00, r01, r10, r11, v0, v1, d1x, d1y, d1z, d2x, d2y, d2z):
    """Rows R·v1 and R·v2 (= F·vk/λk) in 3D through the deformed tangent basis (d1, d2)."""
    p, q = r00 * v0 + r01 * v1, r10 * v0 + r11 * v1  # R·(v0, v1)
    s, t = -r00 * v1 + r01 * v0, -r10 * v1 + r11 * v0  # R·(−v1, v0)
    out[i], out[i + 1], out[i + 2] = p * d1x + q * d2x, p * d1y + q * d2y, p * d1z + q * d2z
    out[i + 3], out[i + 4], out[i + 5] = s * d1x + t * d2x, s * d1y + t * d2y, s * d1z + t * d2z


@njit(cache=True, inline="always")
def _write_stretch(out, i, lam1, lam2):
    out[i], out[i + 1] = lam1, lam2


@njit(cache=True, inline="always")
def _write_directions(out, i, v0, v1, basis, k):
    """Rows v1 = v0·t1 + v1·t2 and v2 = −v1·t1 + v0·t2 in 3D (reference tangent basis)."""
    for j in range(3):
        out[i + j] = v0 * basis[k, 0, j] + v1 * basis[k, 1, j]
        out[i + 3 + j] = -v1 * basis[k, 0, j] + v0 * basis[k, 1, j]


@njit(cache=True, inline="always")
def _triangle_fields(k, a, b, c, d1x, d1y, d1z, d2x, d2y, d2z, flag, dinv, basis, starts, needs,
                     out, out_flags):
    """The requested fields of triangle k from its deformed edge matrix [[a, b], [0, c]] and
    deformed tangent basis (d1, d2)."""
    if starts[S_FLAGS] >= 0:
        out_flags[starts[S_FLAGS] + k] = flag
    if flag & NAN_FLAGS:
        fill_nan(k, starts, _FLOAT_SIZES, out)
        return
    # F = D_d · D_r⁻¹ with D_d = [[a, b], [0, c]]
    g00, g01, g10, g11 = dinv[k, 0, 0], dinv[k, 0, 1], dinv[k, 1, 0], dinv[k, 1, 1]
    f00 = a * g00 + b * g10
    f01 = a * g01 + b * g11
    f10 = c * g10
    f11 = c * g11
    if starts[S_F] >= 0:
        _put4(out, starts[S_F] + 4 * k, f00, f01, f10, f11)
    if needs & NEED_C:
        c00 = f00 * f00 + f10 * f10
        c01 = f00 * f01 + f10 * f11
        c11 = f01 * f01 + f11 * f11
        if starts[S_C] >= 0:
            _put_symmetric(out, starts[S_C] + 4 * k, c00, c01, c11)
        if starts[S_STRAIN] >= 0:
            _write_strain(out, starts[S_STRAIN] + 4 * k, c00, c01, c11)
    absdet = abs(f00 * f11 - f01 * f10)
    if starts[S_AREA_RATIO] >= 0:
        _write_area_ratio(out, starts[S_AREA_RATIO] + k, absdet)
    if starts[S_THICKNESS] >= 0:
        _write_thickness(out, starts[S_THICKNESS] + k, absdet)
    if starts[S_ALMANSI] >= 0:
        _write_almansi(out, starts[S_ALMANSI] + 4 * k, f00, f01, f10, f11, absdet)
    if not needs & NEED_POLAR:
        return
    r00, r01, r10, r11, u00, u01, u11 = polar_2x2(f00, f01, f10, f11)
    if starts[S_R] >= 0:
        _put4(out, starts[S_R] + 4 * k, r00, r01, r10, r11)
    if starts[S_U] >= 0:
        _put_symmetric(out, starts[S_U] + 4 * k, u00, u01, u11)
    if starts[S_ENGINEERING] >= 0:
        _write_engineering(out, starts[S_ENGINEERING] + 4 * k, u00, u01, u11)
    if not needs & NEED_PRINCIPAL:
        return
    lam1, lam2, v0, v1 = principal_2x2(u00, u01, u11, absdet)
    if starts[S_STRETCH] >= 0:
        _write_stretch(out, starts[S_STRETCH] + 2 * k, lam1, lam2)
    if starts[S_DIRECTIONS] >= 0:
        _write_directions(out, starts[S_DIRECTIONS] + 6 * k, v0, v1, basis, k)
    if starts[S_HENCKY] >= 0:
        _write_hencky(out, starts[S_HENCKY] + 4 * k, lam1, lam2, v0, v1)
    if starts[S_PRINCIPAL_STRAIN] >= 0:
        _write_principal_strain(out, starts[S_PRINCIPAL_STRAIN] + 2 * k, lam1, lam2)
    if starts[S_MAX_SHEAR] >= 0:
        _write_max_shear(out, starts[S_MAX_SHEAR] + k, lam1, lam2)
    if starts[S_VON_MISES] >= 0:
        _write_von_mises(out, starts[S_VON_MISES] + k, lam1, lam2)
    if starts[S_DIRECTIONS_DEFORMED] >= 0:
        _write_directions_deformed(out, starts[S_DIRECTIONS_DEFORMED] + 6 * k, r00, r01, r10, r11,
                                   v0, v1, d1x, d1y, d1z, d2x, d2y, d2z)


# ---------------------------------------------------------------- the kernels
@njit(cache=True, parallel=True, nogil=True)
def deformation_fields(x, faces, dinv, basis, ref_flags, tol, starts, needs, out, out_flags):
    """The per-triangle fields of one pair from deformed positions ``x`` and the rest-state
    data (D_r⁻¹, basis, flags), into the buffers of a :class:`KernelPlan` (``starts``,
    ``needs``). ``out`` may be float32 or float64; all arithmetic is float64."""
    for k in prange(faces.shape[0]):
        a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag = tangent_edge_matrix(
            x, faces[k, 0], faces[k, 1], faces[k, 2], tol)
        _triangle_fields(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag | ref_flags[k], dinv,
                         basis, starts, needs, out, out_flags)


@njit(cache=True, parallel=True, nogil=True)
def deformation_fields_and_next_rest(x, faces, dinv, basis, ref_flags, tol, starts, needs,
                                     out, out_flags, next_dinv, next_basis, next_flags):
    """:func:`deformation_fields`, and from the same pass the rest-state data of ``x`` itself
    (as :func:`reference_from_positions`, into ``next_*`` from :func:`allocate_rest`): the
    reference of the next pair of a 'previous' sequence, for a few stores instead of a pass."""
    for k in prange(faces.shape[0]):
        a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag = tangent_edge_matrix(
            x, faces[k, 0], faces[k, 1], faces[k, 2], tol)
        _store_rest(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag,
                    next_dinv, next_basis, next_flags)
        _triangle_fields(k, a, b, c, t1x, t1y, t1z, t2x, t2y, t2z, flag | ref_flags[k], dinv,
                         basis, starts, needs, out, out_flags)


def analyze_pair(reference, deformed, faces, *, fields=FIELDS, uv=None, uv_scale=1.0,
                 dtype=np.float64, tol=DEGENERATE_TOL):
    """Per-triangle fields of one pair, as a dict name → array (``fields``: names or a
    string as ``analyze_sequence`` takes; default every 2D field).

    ``reference``/``deformed``: (N, 3) positions; with ``uv`` (N, 2) the rest shape is
    the texture coordinates times ``uv_scale`` and ``reference`` is ignored.
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if uv is not None:
        ref = reference_from_uv(np.ascontiguousarray(uv, dtype=np.float64), faces, float(uv_scale), tol)
    else:
        ref = reference_from_positions(np.ascontiguousarray(reference, dtype=np.float64), faces, tol)
    plan = KernelPlan(len(faces), parse_fields(fields) if isinstance(fields, str) else fields)
    out, out_flags, views = plan.allocate(dtype)
    deformation_fields(np.ascontiguousarray(deformed, dtype=np.float64), faces, *ref, tol,
                       plan.starts, plan.needs, out, out_flags)
    return views
