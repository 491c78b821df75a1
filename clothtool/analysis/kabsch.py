"""The 3D (Kabsch) variant of the deformation analysis: numba kernels, float64.

Per vertex, over the vertex and its one-ring (:func:`clothtool.geometry.one_ring`),
each set centred on its own mean, with reference points p and deformed points q:

    H = Σ p qᵀ,   rotation = argmin over proper rotations R of Σ‖R p − q‖²   (Kabsch 1976)

The rotation is found as Horn's unit quaternion (Horn 1987, J. Opt. Soc. Am. A 4:629): the
eigenvector of the largest eigenvalue of the symmetric 4×4 matrix N(H); the eigenvalues come
from the batched Jacobi solver of :mod:`clothtool.analysis.symeig`, the eigenvector from the
adjugate of N − λI (H is divided by √(Σ‖p‖² Σ‖q‖²) ≥ σ1+σ2+σ3
first, so that the tolerances are relative). The quaternion is a proper rotation by
construction; in terms of the singular values σ1 ≥ σ2 ≥ σ3 of H and d = sign det H the
eigenvalues of N are σ1+σ2+dσ3, σ1−σ2−dσ3, −σ1+σ2−dσ3, −σ1−σ2+dσ3, so the largest one is the
Kabsch optimum *with* the reflection fix on the smallest singular direction, and planar rings
(σ3 = 0) need no special case. The rotation is determined iff the gap 2(σ2 + dσ3) is positive.
"""

import math

import numpy as np
from numba import prange

from clothtool.analysis.symeig import adjugate_eigenvector4, jacobi_eigvals_batch
from clothtool.numba_setup import njit, njit_inner

REF_DEGENERATE = 1  # flag bit 0: reference ring degenerate
DEF_DEGENERATE = 2  # flag bit 1: deformed ring degenerate
NONFINITE = 4  # flag bit 2: non-finite input coordinates
AMBIGUOUS = 8  # flag bit 3: the best rotation is not unique

RING_TOL = 1e-4
"""A ring is degenerate (coincident or collinear points) when I₂ ≤ RING_TOL²·(tr A)², where A = Σ p pᵀ
and I₂ is its second invariant (sum of the principal 2×2 minors); I₂/(tr A)² ≈ (rms width across
the ring's axis / rms length along it)²."""
GAP_TOL = 1e-8
"""The rotation is ambiguous when the eigen-gap 2(σ2 + dσ3) of Horn's matrix is at most
GAP_TOL·√(Σ‖p‖² Σ‖q‖²). For a rigid motion the relative gap is ≈ (width / length)² of the ring,
so GAP_TOL = RING_TOL². The rotation error grows like ε/(relative gap): ~1e-14 on ordinary rings,
a few 1e-8 at the limit (measured in benchmarks/bench_kabsch.py)."""

CHUNK = 64  # vertices per batch: one parallel work item, solved in lockstep by Jacobi


@njit(cache=True, error_model="numpy")
def horn_matrix(h, scale, a, k):
    """Horn's symmetric 4×4 matrix N(H)/scale into ``a[:, :, k]``; its top eigenvector is the unit
    quaternion (w, x, y, z) of the proper rotation maximising tr(R H) (Horn 1987, eq. 43)."""
    inv = 1.0 / scale
    sxx, sxy, sxz = h[0, 0] * inv, h[0, 1] * inv, h[0, 2] * inv
    syx, syy, syz = h[1, 0] * inv, h[1, 1] * inv, h[1, 2] * inv
    szx, szy, szz = h[2, 0] * inv, h[2, 1] * inv, h[2, 2] * inv
    a[0, 0, k] = sxx + syy + szz
    a[1, 1, k] = sxx - syy - szz
    a[2, 2, k] = -sxx + syy - szz
    a[3, 3, k] = -sxx - syy + szz
    a[0, 1, k] = a[1, 0, k] = syz - szy
    a[0, 2, k] = a[2, 0, k] = szx - sxz
    a[0, 3, k] = a[3, 0, k] = sxy - syx
    a[1, 2, k] = a[2, 1, k] = sxy + syx
    a[1, 3, k] = a[3, 1, k] = szx + sxz
    a[2, 3, k] = a[3, 2, k] = syz + szy


@njit_inner(cache=True, error_model="numpy")
def top_quaternion(a, orig, k, b, q):
    """After Jacobi (eigenvalues) on Horn's matrix k (``orig`` holds it unchanged): the unit
    quaternion of the largest eigenvalue into ``q`` (4,), from adj(N − λI); ``b`` is 4×4 scratch.
    Returns the gap from the largest eigenvalue to the next one."""
    top = 0
    for i in range(1, 4):
        if a[i, i, k] > a[top, top, k]:
            top = i
    second = -np.inf
    for i in range(4):
        if i != top and a[i, i, k] > second:
            second = a[i, i, k]
    adjugate_eigenvector4(orig, k, a[top, top, k], b, q)
    return a[top, top, k] - second


@njit_inner(cache=True, error_model="numpy")
def quaternion_matrix(q, rot):
    """The rotation matrix of the unit quaternion q = (w, x, y, z) into ``rot`` (3×3); returns
    its angle 2·atan2(‖(x, y, z)‖, |w|) ∈ [0, π] (accurate near 0 and π, unlike arccos)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    rot[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    rot[0, 1] = 2.0 * (x * y - w * z)
    rot[0, 2] = 2.0 * (x * z + w * y)
    rot[1, 0] = 2.0 * (x * y + w * z)
    rot[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    rot[1, 2] = 2.0 * (y * z - w * x)
    rot[2, 0] = 2.0 * (x * z - w * y)
    rot[2, 1] = 2.0 * (y * z + w * x)
    rot[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))


@njit_inner(cache=True, error_model="numpy")
def _ring_degenerate(a00, a11, a22, a01, a02, a12):
    """Coincident or collinear points, from the scatter matrix A = Σ p pᵀ (see RING_TOL)."""
    tr = a00 + a11 + a22
    i2 = a00 * a11 - a01 * a01 + a00 * a22 - a02 * a02 + a11 * a22 - a12 * a12
    return i2 <= RING_TOL * RING_TOL * tr * tr


@njit_inner(cache=True, error_model="numpy")
def _ring_matrix(i, x_ref, x_def, offsets, neighbours, h, a, k, mean):
    """Horn's N(H)/√(Σ‖p‖² Σ‖q‖²) of the ring of vertex i into ``a[:, :, k]`` (zeros for a flagged
    ring) and the ring means into ``mean`` (6,). Returns the ring's flags.

    One pass over the ring in coordinates relative to vertex i (no cancellation from the distance
    to the origin); the centring on the means is applied to the sums afterwards:
    H = Σ p' q'ᵀ − m p̄' q̄'ᵀ, and likewise the scatter matrices A = Σ p pᵀ, B = Σ q qᵀ."""
    a[:, :, k] = 0.0
    lo, hi = offsets[i], offsets[i + 1]
    m = hi - lo + 1
    o0, o1, o2 = x_ref[i, 0], x_ref[i, 1], x_ref[i, 2]
    r0, r1, r2 = x_def[i, 0], x_def[i, 1], x_def[i, 2]
    sp0 = sp1 = sp2 = sq0 = sq1 = sq2 = 0.0
    h00 = h01 = h02 = h10 = h11 = h12 = h20 = h21 = h22 = 0.0
    p00 = p11 = p22 = p01 = p02 = p12 = 0.0
    q00 = q11 = q22 = q01 = q02 = q12 = 0.0
    for kk in range(lo, hi):
        j = neighbours[kk]
        p0, p1, p2 = x_ref[j, 0] - o0, x_ref[j, 1] - o1, x_ref[j, 2] - o2
        q0, q1, q2 = x_def[j, 0] - r0, x_def[j, 1] - r1, x_def[j, 2] - r2
        sp0 += p0
        sp1 += p1
        sp2 += p2
        sq0 += q0
        sq1 += q1
        sq2 += q2
        h00 += p0 * q0
        h01 += p0 * q1
        h02 += p0 * q2
        h10 += p1 * q0
        h11 += p1 * q1
        h12 += p1 * q2
        h20 += p2 * q0
        h21 += p2 * q1
        h22 += p2 * q2
        p00 += p0 * p0
        p11 += p1 * p1
        p22 += p2 * p2
        p01 += p0 * p1
        p02 += p0 * p2
        p12 += p1 * p2
        q00 += q0 * q0
        q11 += q1 * q1
        q22 += q2 * q2
        q01 += q0 * q1
        q02 += q0 * q2
        q12 += q1 * q2
    mp0, mp1, mp2 = sp0 / m, sp1 / m, sp2 / m  # p̄' (the vertex itself adds p' = 0)
    mq0, mq1, mq2 = sq0 / m, sq1 / m, sq2 / m
    mean[0], mean[1], mean[2] = o0 + mp0, o1 + mp1, o2 + mp2
    mean[3], mean[4], mean[5] = r0 + mq0, r1 + mq1, r2 + mq2
    if not (np.isfinite(mean[0] + mean[1] + mean[2]) and np.isfinite(mean[3] + mean[4] + mean[5])):
        return NONFINITE
    h[0, 0], h[0, 1], h[0, 2] = h00 - sp0 * mq0, h01 - sp0 * mq1, h02 - sp0 * mq2
    h[1, 0], h[1, 1], h[1, 2] = h10 - sp1 * mq0, h11 - sp1 * mq1, h12 - sp1 * mq2
    h[2, 0], h[2, 1], h[2, 2] = h20 - sp2 * mq0, h21 - sp2 * mq1, h22 - sp2 * mq2
    p00, p11, p22 = p00 - sp0 * mp0, p11 - sp1 * mp1, p22 - sp2 * mp2
    p01, p02, p12 = p01 - sp0 * mp1, p02 - sp0 * mp2, p12 - sp1 * mp2
    q00, q11, q22 = q00 - sq0 * mq0, q11 - sq1 * mq1, q22 - sq2 * mq2
    q01, q02, q12 = q01 - sq0 * mq1, q02 - sq0 * mq2, q12 - sq1 * mq2
    flags = 0
    if _ring_degenerate(p00, p11, p22, p01, p02, p12):
        flags |= REF_DEGENERATE
    if _ring_degenerate(q00, q11, q22, q01, q02, q12):
        flags |= DEF_DEGENERATE
    if flags == 0:
        horn_matrix(h, math.sqrt((p00 + p11 + p22) * (q00 + q11 + q22)), a, k)
    return flags


@njit_inner(cache=True, error_model="numpy")
def _ring_residual(i, x_ref, x_def, offsets, neighbours, mean, rot):
    """√(mean over the ring of ‖R p − q‖²), summed directly (no cancellation)."""
    lo, hi = offsets[i], offsets[i + 1]
    ss = 0.0
    for kk in range(lo - 1, hi):
        j = i if kk < lo else neighbours[kk]
        p0, p1, p2 = x_ref[j, 0] - mean[0], x_ref[j, 1] - mean[1], x_ref[j, 2] - mean[2]
        d0 = rot[0, 0] * p0 + rot[0, 1] * p1 + rot[0, 2] * p2 - (x_def[j, 0] - mean[3])
        d1 = rot[1, 0] * p0 + rot[1, 1] * p1 + rot[1, 2] * p2 - (x_def[j, 1] - mean[4])
        d2 = rot[2, 0] * p0 + rot[2, 1] * p1 + rot[2, 2] * p2 - (x_def[j, 2] - mean[5])
        ss += d0 * d0 + d1 * d1 + d2 * d2
    return math.sqrt(ss / (hi - lo + 1))


@njit(cache=True, parallel=True, error_model="numpy")
def vertex_fields(x_ref, x_def, offsets, neighbours, rotation, angle, residual, flags):
    """Per-vertex Kabsch rotation of the one-ring from ``x_ref`` (N, 3) to ``x_def`` (N, 3).

    Fills ``rotation`` (N, 3, 3), ``angle`` (N,) in radians [0, π], ``residual`` (N,)
    = √(mean over the ring of ‖R p − q‖²) and ``flags`` (N,) uint8: REF_DEGENERATE /
    DEF_DEGENERATE (coincident or collinear ring, RING_TOL), NONFINITE, AMBIGUOUS (GAP_TOL).
    Where a flag is set, rotation, angle and residual are NaN. Each output is full size or
    empty (then it is not written); they may be float32, the arithmetic is float64.
    """
    n = offsets.shape[0] - 1
    for c in prange((n + CHUNK - 1) // CHUNK):
        first = c * CHUNK
        m = min(n, first + CHUNK) - first
        h = np.empty((3, 3))
        b = np.empty((4, 4))
        q = np.empty(4)
        rot = np.empty((3, 3))
        a = np.empty((4, 4, m))
        mean = np.empty((m, 6))
        flag = np.empty(m, np.uint8)
        for k in range(m):
            flag[k] = _ring_matrix(first + k, x_ref, x_def, offsets, neighbours, h, a, k, mean[k])
        orig = a.copy()
        jacobi_eigvals_batch(a)
        for k in range(m):
            i = first + k
            ang = res = np.nan
            rot[:, :] = np.nan
            if flag[k] == 0:
                gap = top_quaternion(a, orig, k, b, q)
                ang = quaternion_matrix(q, rot)
                if gap <= GAP_TOL:
                    flag[k] = AMBIGUOUS
                    ang = np.nan
                    rot[:, :] = np.nan
                elif residual.shape[0]:
                    res = _ring_residual(i, x_ref, x_def, offsets, neighbours, mean[k], rot)
            if rotation.shape[0]:
                rotation[i] = rot
            if angle.shape[0]:
                angle[i] = ang
            if residual.shape[0]:
                residual[i] = res
            if flags.shape[0]:
                flags[i] = flag[k]


def vertex_rotations(x_ref, x_def, offsets, neighbours):
    """:func:`vertex_fields` into new float64 arrays: (rotation, angle, residual, flags)."""
    n = len(offsets) - 1
    out = (np.empty((n, 3, 3)), np.empty(n), np.empty(n), np.empty(n, np.uint8))
    vertex_fields(np.ascontiguousarray(x_ref, np.float64), np.ascontiguousarray(x_def, np.float64),
                  offsets, neighbours, *out)
    return out
