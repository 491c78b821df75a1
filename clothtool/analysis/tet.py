"""Per-tetrahedron deformation of volumetric meshes, numba kernels, float64 arithmetic.

For a tetrahedron with corners p1…p4, D = [p1 − p4, p2 − p4, p3 − p4] (3×3, columns);
D_r of the reference, G = D_d of the deformed tetrahedron. The linear FEM deformation
gradient (Müller et al., "Game Physics Pearls" ch. 10, F = G·D⁻¹ with D⁻¹ kept per element)
and what follows from it:

    F = G·D_r⁻¹,   C = FᵀF,   E = (C − I)/2,   J = det F,   F = R·U.

The polar split is the invertible one of Irving, Teran & Fedkiw (2004, "Invertible finite
elements for robust simulation of large deformation"): R is always a proper rotation
(det R = +1) and, for an inverted tetrahedron (det F < 0), U is symmetric with one negative
eigenvalue, the smallest stretch λ3. The eigenvectors V of U² = C come from cyclic Jacobi
rotations (Press et al., *Numerical Recipes*, 3rd ed., §11.1) on C scaled to unit trace, for
a block of tetrahedra at a time so that the rotations vectorise. The stretches are then not
square roots of C's eigenvalues but the norms σ_k of the columns a_k of F·V, the singular
values of F, accurate to about ε·λ1 (√ of an eigenvalue of C would be off by ε·λ1²/λ3, and
an error δ in v_k changes σ_k by O(δ²) only); with V sorted by σ and made
proper (det V = +1), w1 = a1/σ1, w2 = a2/σ2 (made orthogonal to w1), w3 = w1 × w2 and

    λ1 = σ1 ≥ λ2 = σ2 ≥ |λ3| = σ3,  λ3 < 0 iff det F < 0,   U = V·diag(λ)·Vᵀ,
    R = W·Vᵀ = F·U⁻¹ (no inverse taken),   directions: row k = column k of V (reference frame).

Flags (uint8 bits): 1 reference degenerate, 2 deformed degenerate, 4 non-finite input,
16 inverted (det F < 0; fields finite). Degenerate: |det D| ≤ DEGENERATE_TOL · L³ with L the
longest of the six edges (det D is six times the volume; a regular tetrahedron has
|det D| = L³/√2). Where bit 1, 2 or 4 is set the float fields are NaN.

What is computed is a :class:`KernelPlan` (:mod:`clothtool.analysis.kernel_plan`): one flat
output buffer per dtype, a slot per field of the registry.
"""

import math

import numpy as np
from numba import prange

from clothtool.analysis import kernel_plan
from clothtool.fields import FIELDS_TET, NAMES_TET
from clothtool.analysis.kernel_plan import Slots, fill_nan
from clothtool.numba_setup import njit, njit_inner
from clothtool.vec3 import cross, dot, load, scale, sub

DEGENERATE_TOL = 1e-8
"""A tetrahedron is degenerate when |det D| ≤ DEGENERATE_TOL·(longest edge)³."""

FLAG_REFERENCE_DEGENERATE = np.uint8(1)
FLAG_DEFORMED_DEGENERATE = np.uint8(2)
FLAG_NONFINITE = np.uint8(4)
FLAG_INVERTED = np.uint8(16)
NAN_FLAGS = np.uint8(7)

TET_FIELDS = NAMES_TET
"""Every tetrahedron field: the default of :func:`analyze_tet_pair`."""

MAX_SWEEPS = 30  # 3–5 sweeps are typical: convergence is quadratic
BLOCK = 64  # tetrahedra whose eigenproblems are solved together (vectorised)
_EPS2 = 2.0**-106  # (2⁻⁵³)²
_TINY = 1e-150  # keeps u > 0 when a_pq = 0 and a_pp = a_qq (matrices are scaled to unit trace)


@njit_inner(cache=True)
def edge_matrix(x, tets, k, tol):
    """Columns d1, d2, d3 of D of tetrahedron k, det D and a status: 0, degenerate
    (|det D| ≤ tol·L³) or non-finite."""
    p4 = load(x, tets[k, 3])
    d1 = sub(load(x, tets[k, 0]), p4)
    d2 = sub(load(x, tets[k, 1]), p4)
    d3 = sub(load(x, tets[k, 2]), p4)
    det = dot(d1, cross(d2, d3))
    e12, e13, e23 = sub(d1, d2), sub(d1, d3), sub(d2, d3)
    longest = max(dot(d1, d1), dot(d2, d2), dot(d3, d3), dot(e12, e12), dot(e13, e13),
                  dot(e23, e23))
    if not np.isfinite(det + longest):
        return d1, d2, d3, det, FLAG_NONFINITE
    if abs(det) <= tol * longest * math.sqrt(longest):
        return d1, d2, d3, det, FLAG_DEFORMED_DEGENERATE
    return d1, d2, d3, det, np.uint8(0)


@njit_inner(cache=True)
def _store_rest(k, d1, d2, d3, det, flag, dinv, flags):
    """D_r⁻¹ of tetrahedron k (rows (d2×d3, d3×d1, d1×d2)/det D) and its flag (a degenerate
    tetrahedron is bit 0 here)."""
    if flag == FLAG_DEFORMED_DEGENERATE:
        flag = FLAG_REFERENCE_DEGENERATE
    flags[k] = flag
    if flag != 0:
        dinv[k] = np.nan
        return
    r = 1.0 / det
    for i, row in enumerate((cross(d2, d3), cross(d3, d1), cross(d1, d2))):
        dinv[k, i, 0], dinv[k, i, 1], dinv[k, i, 2] = row[0] * r, row[1] * r, row[2] * r


def allocate_rest(m):
    """Empty (D_r⁻¹ (M, 3, 3), flags (M,)) for :func:`rest_from_positions` or the ``next_*``
    outputs of :func:`tet_fields_and_next_rest`."""
    return np.empty((m, 3, 3)), np.empty(m, np.uint8)


@njit(cache=True, parallel=True, nogil=True)
def _rest_kernel(x, tets, tol, dinv, flags):
    for k in prange(tets.shape[0]):
        d1, d2, d3, det, flag = edge_matrix(x, tets, k, tol)
        _store_rest(k, d1, d2, d3, det, flag, dinv, flags)


def rest_from_positions(x, tets, tol=DEGENERATE_TOL):
    """Rest-state data of every tetrahedron: D_r⁻¹ (M, 3, 3) and flags (M,) uint8 (bit 0
    degenerate, bit 2 non-finite)."""
    rest = allocate_rest(tets.shape[0])
    _rest_kernel(x, tets, tol, *rest)
    return rest


# C's six entries in a block array: rows c00, c11, c22, c01, c02, c12; for each rotated pair
# (p, q): the rows of a_pp, a_qq, a_pq, of a_rp, a_rq (r the third index), and p, q
_PAIRS = ((0, 1, 3, 4, 5, 0, 1), (0, 2, 4, 3, 5, 0, 2), (1, 2, 5, 3, 4, 1, 2))


@njit_inner(cache=True, error_model="numpy")
def jacobi_block(c, v, n):
    """Eigenvectors of the symmetric 3×3 matrices ``c[:, i]`` (rows c00, c11, c22, c01, c02,
    c12; scaled to about unit norm), i < n, by cyclic Jacobi: afterwards ``v[3j:3j + 3, i]`` is
    the unit eigenvector of the eigenvalue ``c[j, i]`` (unsorted). The matrices of the block are
    rotated in lockstep so that the compiler vectorises across them; each rotation is the
    branch-free form of :mod:`clothtool.analysis.symeig`. Sweeps repeat until the off-diagonal
    mass of every matrix is below (2⁻⁵³)² of its Frobenius norm²."""
    for i in range(n):
        for j in range(9):
            v[j, i] = 1.0 if j % 4 == 0 else 0.0
    for _ in range(MAX_SWEEPS):
        done = True
        for i in range(n):
            off = c[3, i] * c[3, i] + c[4, i] * c[4, i] + c[5, i] * c[5, i]
            diag = c[0, i] * c[0, i] + c[1, i] * c[1, i] + c[2, i] * c[2, i]
            if off > _EPS2 * (diag + 2.0 * off):
                done = False
        if done:
            return
        for ipp, iqq, ipq, irp, irq, p, q in _PAIRS:
            for i in range(n):
                apq = c[ipq, i]
                d = c[iqq, i] - c[ipp, i]
                g = 2.0 * apq if d >= 0.0 else -2.0 * apq
                u = abs(d) + math.sqrt(d * d + 4.0 * apq * apq) + _TINY
                w = math.sqrt(u * u + g * g)
                z = 1.0 / (u * w)
                cs = u * u * z  # cos φ = u/w
                sn = g * u * z  # sin φ = g/w
                ta = g * w * z * apq  # tan φ · a_pq
                c[ipp, i] -= ta
                c[iqq, i] += ta
                c[ipq, i] = 0.0
                arp, arq = c[irp, i], c[irq, i]
                c[irp, i] = cs * arp - sn * arq
                c[irq, i] = sn * arp + cs * arq
                for j in range(3):
                    vp, vq = v[3 * p + j, i], v[3 * q + j, i]
                    v[3 * p + j, i] = cs * vp - sn * vq
                    v[3 * q + j, i] = sn * vp + cs * vq


@njit_inner(cache=True)
def polar_from_eigenvectors(f0, f1, f2, v0, v1, v2):
    """The invertible polar split of F (columns f0, f1, f2) from unit eigenvectors v0, v1, v2
    of C (see the module doc). Returns (λ1, λ2, λ3), the columns v1, v2, v3 of V (sorted,
    proper) and w1, w2, w3 of W, so that U = V·diag(λ)·Vᵀ and R = W·Vᵀ."""
    # the columns of F·V and their norms, the singular values (no square root of C's eigenvalues)
    a0 = _times(f0, f1, f2, v0)
    a1 = _times(f0, f1, f2, v1)
    a2 = _times(f0, f1, f2, v2)
    s0, s1, s2 = math.sqrt(dot(a0, a0)), math.sqrt(dot(a1, a1)), math.sqrt(dot(a2, a2))
    if s0 < s1:
        s0, s1, a0, a1, v0, v1 = s1, s0, a1, a0, v1, v0
    if s1 < s2:
        s1, s2, a1, a2, v1, v2 = s2, s1, a2, a1, v2, v1
    if s0 < s1:
        s0, s1, a0, a1, v0, v1 = s1, s0, a1, a0, v1, v0
    if dot(v0, cross(v1, v2)) < 0.0:  # make V proper
        v2, a2 = scale(-1.0, v2), scale(-1.0, a2)
    w0 = scale(1.0 / s0, a0)
    a1 = sub(a1, scale(dot(w0, a1), w0))
    w1 = scale(1.0 / math.sqrt(dot(a1, a1)), a1)
    w2 = cross(w0, w1)
    lam2 = math.copysign(s2, dot(w2, a2))  # the Irving sign: negative iff det F < 0
    return s0, s1, lam2, v0, v1, v2, w0, w1, w2


@njit_inner(cache=True)
def _times(f0, f1, f2, v):
    """F·v for F given by its columns."""
    return (f0[0] * v[0] + f1[0] * v[1] + f2[0] * v[2], f0[1] * v[0] + f1[1] * v[1] + f2[1] * v[2],
            f0[2] * v[0] + f1[2] * v[1] + f2[2] * v[2])


@njit_inner(cache=True)
def _column(g1, g2, g3, dinv, k, j):
    """Column j of F = G·D_r⁻¹: g1·D⁻¹[0, j] + g2·D⁻¹[1, j] + g3·D⁻¹[2, j]."""
    a, b, c = dinv[k, 0, j], dinv[k, 1, j], dinv[k, 2, j]
    return (g1[0] * a + g2[0] * b + g3[0] * c, g1[1] * a + g2[1] * b + g3[1] * c,
            g1[2] * a + g2[2] * b + g3[2] * c)


# ---------------------------------------------------------------- the plan of one pair
# Each tet field of the registry has a slot (clothtool.analysis.kernel_plan).
NEED_C = 1  # C = FᵀF
NEED_POLAR = 2  # the eigenvectors of C and from them F = R·U, λk, vk
# The slot order is written here, not taken from the registry's order: numba freezes these
# globals into its cached kernel, whose cache is keyed on this file only.
SLOTS = Slots("tet", ("F", "C", "U", "R", "strain", "stretch", "directions", "volume_ratio",
                      "flags"), FIELDS_TET, {"C": NEED_C, "polar": NEED_POLAR | NEED_C})
_SLOT = SLOTS.index
_FLOAT_SIZES = SLOTS.float_sizes
# Compile-time constants of the kernel below.
S_F, S_C, S_U, S_R = _SLOT["F"], _SLOT["C"], _SLOT["U"], _SLOT["R"]
S_STRAIN, S_STRETCH, S_DIRECTIONS = _SLOT["strain"], _SLOT["stretch"], _SLOT["directions"]
S_VOLUME_RATIO, S_FLAGS = _SLOT["volume_ratio"], _SLOT["flags"]


class KernelPlan(kernel_plan.KernelPlan):
    """What :func:`tet_fields` computes for M tetrahedra
    (:class:`clothtool.analysis.kernel_plan.KernelPlan` over the tet slots)."""

    slots = SLOTS


# ---------------------------------------------------------------- per-field kernel lines
# A 3×3 field of element k is stored row after row from out[i], i = start + 9k.
@njit(cache=True, inline="always")
def _put_symmetric(out, i, a00, a11, a22, a01, a02, a12):
    """A symmetric 3×3 matrix (C, E)."""
    out[i], out[i + 1], out[i + 2] = a00, a01, a02
    out[i + 3], out[i + 4], out[i + 5] = a01, a11, a12
    out[i + 6], out[i + 7], out[i + 8] = a02, a12, a22


@njit(cache=True, inline="always")
def _write_F(out, i, f0, f1, f2):
    """F from its columns f0, f1, f2."""
    for r in range(3):
        out[i + 3 * r], out[i + 3 * r + 1], out[i + 3 * r + 2] = f0[r], f1[r], f2[r]


@njit(cache=True, inline="always")
def _write_strain(out, i, c00, c11, c22, c01, c02, c12):
    """E = (C − I)/2."""
    _put_symmetric(out, i, 0.5 * (c00 - 1.0), 0.5 * (c11 - 1.0), 0.5 * (c22 - 1.0), 0.5 * c01,
                   0.5 * c02, 0.5 * c12)


@njit(cache=True, inline="always")
def _write_volume_ratio(out, i, det):
    """J = det F."""
    out[i] = det


@njit(cache=True, inline="always")
def _write_stretch(out, i, l0, l1, l2):
    out[i], out[i + 1], out[i + 2] = l0, l1, l2


@njit(cache=True, inline="always")
def _write_directions(out, i, v0, v1, v2):
    """Rows v1, v2, v3: the columns of V."""
    for j in range(3):
        out[i + j], out[i + 3 + j], out[i + 6 + j] = v0[j], v1[j], v2[j]


@njit(cache=True, inline="always")
def _write_U(out, i, l0, l1, l2, v0, v1, v2):
    """U = V·diag(λ)·Vᵀ = Σ λk vk vkᵀ."""
    for r in range(3):
        for j in range(r, 3):
            urj = l0 * v0[r] * v0[j] + l1 * v1[r] * v1[j] + l2 * v2[r] * v2[j]
            out[i + 3 * r + j] = urj
            out[i + 3 * j + r] = urj


@njit(cache=True, inline="always")
def _write_R(out, i, v0, v1, v2, w0, w1, w2):
    """R = W·Vᵀ = Σ wk vkᵀ."""
    for r in range(3):
        for j in range(3):
            out[i + 3 * r + j] = w0[r] * v0[j] + w1[r] * v1[j] + w2[r] * v2[j]


# ---------------------------------------------------------------- the kernels
@njit_inner(cache=True)
def _tet_block(lo, n, x, tets, dinv, ref_flags, tol, starts, needs, out, out_flags, next_dinv,
               next_flags):
    """The requested fields of tetrahedra lo … lo + n − 1, whose eigenproblems are solved
    together; with ``next_flags`` not None also their rest-state data as deformed."""
    polar = needs & NEED_POLAR
    size = BLOCK if polar else 0
    cb = np.empty((6, size))  # C/tr C of each tetrahedron of the block
    fb = np.empty((9, size))  # F, column after column
    vb = np.empty((9, size))
    valid = np.zeros(size, np.bool_)
    for i in range(n):
        k = lo + i
        g1, g2, g3, det_g, flag = edge_matrix(x, tets, k, tol)
        if next_flags is not None:
            _store_rest(k, g1, g2, g3, det_g, flag, next_dinv, next_flags)
        flag |= ref_flags[k]
        if polar:  # the identity for a skipped tetrahedron: converged at once
            cb[0, i], cb[1, i], cb[2, i] = 1.0, 1.0, 1.0
            cb[3, i], cb[4, i], cb[5, i] = 0.0, 0.0, 0.0
        if flag & NAN_FLAGS:
            if starts[S_FLAGS] >= 0:
                out_flags[starts[S_FLAGS] + k] = flag
            fill_nan(k, starts, _FLOAT_SIZES, out)
            continue
        f0 = _column(g1, g2, g3, dinv, k, 0)
        f1 = _column(g1, g2, g3, dinv, k, 1)
        f2 = _column(g1, g2, g3, dinv, k, 2)
        det = dot(f0, cross(f1, f2))
        if det < 0.0:
            flag |= FLAG_INVERTED
        if starts[S_FLAGS] >= 0:
            out_flags[starts[S_FLAGS] + k] = flag
        if starts[S_VOLUME_RATIO] >= 0:
            _write_volume_ratio(out, starts[S_VOLUME_RATIO] + k, det)
        if starts[S_F] >= 0:
            _write_F(out, starts[S_F] + 9 * k, f0, f1, f2)
        if not needs & NEED_C:
            continue
        c00, c11, c22 = dot(f0, f0), dot(f1, f1), dot(f2, f2)
        c01, c02, c12 = dot(f0, f1), dot(f0, f2), dot(f1, f2)
        if starts[S_C] >= 0:
            _put_symmetric(out, starts[S_C] + 9 * k, c00, c11, c22, c01, c02, c12)
        if starts[S_STRAIN] >= 0:
            _write_strain(out, starts[S_STRAIN] + 9 * k, c00, c11, c22, c01, c02, c12)
        if not polar:
            continue
        valid[i] = True
        for r in range(3):
            fb[r, i], fb[3 + r, i], fb[6 + r, i] = f0[r], f1[r], f2[r]
        trace = c00 + c11 + c22
        cb[0, i], cb[1, i], cb[2, i] = c00 / trace, c11 / trace, c22 / trace
        cb[3, i], cb[4, i], cb[5, i] = c01 / trace, c02 / trace, c12 / trace
    if not polar:
        return
    jacobi_block(cb, vb, n)
    for i in range(n):
        if not valid[i]:
            continue
        k = lo + i
        l0, l1, l2, v0, v1, v2, w0, w1, w2 = polar_from_eigenvectors(
            (fb[0, i], fb[1, i], fb[2, i]), (fb[3, i], fb[4, i], fb[5, i]),
            (fb[6, i], fb[7, i], fb[8, i]), (vb[0, i], vb[1, i], vb[2, i]),
            (vb[3, i], vb[4, i], vb[5, i]), (vb[6, i], vb[7, i], vb[8, i]))
        if starts[S_STRETCH] >= 0:
            _write_stretch(out, starts[S_STRETCH] + 3 * k, l0, l1, l2)
        if starts[S_DIRECTIONS] >= 0:
            _write_directions(out, starts[S_DIRECTIONS] + 9 * k, v0, v1, v2)
        if starts[S_U] >= 0:
            _write_U(out, starts[S_U] + 9 * k, l0, l1, l2, v0, v1, v2)
        if starts[S_R] >= 0:
            _write_R(out, starts[S_R] + 9 * k, v0, v1, v2, w0, w1, w2)


@njit(cache=True, parallel=True, nogil=True)
def tet_fields(x, tets, dinv, ref_flags, tol, starts, needs, out, out_flags):
    """The per-tetrahedron fields of one pair from deformed positions ``x`` (N, 3) and the
    rest-state data (D_r⁻¹, flags), into the buffers of a :class:`KernelPlan` (``starts``,
    ``needs``). ``out`` may be float32 or float64; all arithmetic is float64. Tetrahedra are
    taken in blocks of :data:`BLOCK`, whose eigenproblems are solved together."""
    m = tets.shape[0]
    for b in prange((m + BLOCK - 1) // BLOCK):
        lo = b * BLOCK
        _tet_block(lo, min(m, lo + BLOCK) - lo, x, tets, dinv, ref_flags, tol, starts, needs,
                   out, out_flags, None, None)


@njit(cache=True, parallel=True, nogil=True)
def tet_fields_and_next_rest(x, tets, dinv, ref_flags, tol, starts, needs, out, out_flags,
                             next_dinv, next_flags):
    """:func:`tet_fields`, and from the same pass the rest-state data of ``x`` itself (as
    :func:`rest_from_positions`, into ``next_*`` from :func:`allocate_rest`): the reference of
    the next pair of a 'previous' sequence."""
    m = tets.shape[0]
    for b in prange((m + BLOCK - 1) // BLOCK):
        lo = b * BLOCK
        _tet_block(lo, min(m, lo + BLOCK) - lo, x, tets, dinv, ref_flags, tol, starts, needs,
                   out, out_flags, next_dinv, next_flags)


def analyze_tet_pair(reference, deformed, tets, *, fields=TET_FIELDS, dtype=np.float64,
                     tol=DEGENERATE_TOL):
    """Per-tetrahedron fields of one pair, as a dict name → array.

    ``reference``/``deformed``: (N, 3) positions; ``tets``: (M, 4) vertex indices.
    """
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    ref = rest_from_positions(np.ascontiguousarray(reference, dtype=np.float64), tets, tol)
    plan = KernelPlan(len(tets), fields)
    out, out_flags, views = plan.allocate(dtype)
    tet_fields(np.ascontiguousarray(deformed, dtype=np.float64), tets, *ref, tol, plan.starts,
               plan.needs, out, out_flags)
    return views
