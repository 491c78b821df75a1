"""The 3D (Kabsch) variant of the deformation analysis (spec §3): numba kernels, float64.

Per vertex, over the vertex and its one-ring (:func:`clothtool.analysis.topology.one_ring`),
each set centred on its own mean, with reference points p and deformed points q:

    H = Σ p qᵀ,   rotation = argmin over proper rotations R of Σ‖R p − q‖²   (Kabsch 1976)

The rotation is found as Horn's unit quaternion (Horn 1987, J. Opt. Soc. Am. A 4:629): the
eigenvector of the largest eigenvalue of the symmetric 4×4 matrix N(H), computed with the
Jacobi solver of :mod:`clothtool.analysis.symeig`. The quaternion is a proper rotation by
construction; in terms of the singular values σ1 ≥ σ2 ≥ σ3 of H and d = sign det H the
eigenvalues of N are σ1+σ2+dσ3, σ1−σ2−dσ3, −σ1+σ2−dσ3, −σ1−σ2+dσ3, so the largest one is the
Kabsch optimum *with* the reflection fix on the smallest singular direction, and planar rings
(σ3 = 0) need no special case. The rotation is determined iff the gap 2(σ2 + dσ3) is positive.

Per face, the full-rank 3×3 deformation gradient F3 = [e1' e2' n'] [e1 e2 n]⁻¹ and its polar
split F3 = R3·U3 (R3 is again Horn's rotation, for H = F3ᵀ; U3 = R3ᵀF3).
"""

import math

import numpy as np
from numba import njit, prange

from clothtool.analysis.symeig import jacobi_eigh, sort_descending

REF_DEGENERATE = 1  # flag bit 0: reference ring / triangle degenerate
DEF_DEGENERATE = 2  # flag bit 1: deformed ring / triangle degenerate
NONFINITE = 4  # flag bit 2: non-finite input coordinates
AMBIGUOUS = 8  # flag bit 3 (vertices): the best rotation is not unique

RING_TOL = 1e-4
"""A ring is degenerate (coincident or collinear points) when I₂ ≤ RING_TOL²·(tr A)², where A = Σ p pᵀ
and I₂ is its second invariant (sum of the principal 2×2 minors); I₂/(tr A)² ≈ (rms width across
the ring's axis / rms length along it)²."""
GAP_TOL = 1e-8
"""The rotation is ambiguous when the eigen-gap 2(σ2 + dσ3) of Horn's matrix is at most
GAP_TOL·√(Σ‖p‖² Σ‖q‖²). For a rigid motion the relative gap is ≈ (width / length)² of the ring,
so GAP_TOL = RING_TOL²; the eigenvector error is ≈ ε/(relative gap), at most ~2e-8 at the limit."""
TRIANGLE_TOL = 1e-10
"""A triangle is degenerate when its area ≤ TRIANGLE_TOL × (its longest edge)²."""

CHUNK = 256  # vertices / faces per parallel work item (scratch arrays are allocated per chunk)


@njit(cache=True)
def horn_rotation(h, a, v, rot):
    """Proper rotation maximising tr(R H) (= minimising Σ‖R p − q‖² for H = Σ p qᵀ), written
    into ``rot`` (3×3). ``a``, ``v`` are 4×4 scratch. Returns (λ_max, gap, angle): the largest
    eigenvalue of Horn's N(H), its distance to the next one, and the rotation angle
    2·atan2(‖q_xyz‖, |q_w|) in [0, π]."""
    sxx, sxy, sxz = h[0, 0], h[0, 1], h[0, 2]
    syx, syy, syz = h[1, 0], h[1, 1], h[1, 2]
    szx, szy, szz = h[2, 0], h[2, 1], h[2, 2]
    a[0, 0] = sxx + syy + szz
    a[1, 1] = sxx - syy - szz
    a[2, 2] = -sxx + syy - szz
    a[3, 3] = -sxx - syy + szz
    a[0, 1] = a[1, 0] = syz - szy
    a[0, 2] = a[2, 0] = szx - sxz
    a[0, 3] = a[3, 0] = sxy - syx
    a[1, 2] = a[2, 1] = sxy + syx
    a[1, 3] = a[3, 1] = szx + sxz
    a[2, 3] = a[3, 2] = syz + szy
    jacobi_eigh(a, v)
    top = 0
    for k in range(1, 4):
        if a[k, k] > a[top, top]:
            top = k
    second = -np.inf
    for k in range(4):
        if k != top and a[k, k] > second:
            second = a[k, k]
    w, x, y, z = v[0, top], v[1, top], v[2, top], v[3, top]
    nrm = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / nrm, x / nrm, y / nrm, z / nrm
    rot[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    rot[0, 1] = 2.0 * (x * y - w * z)
    rot[0, 2] = 2.0 * (x * z + w * y)
    rot[1, 0] = 2.0 * (x * y + w * z)
    rot[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    rot[1, 2] = 2.0 * (y * z - w * x)
    rot[2, 0] = 2.0 * (x * z - w * y)
    rot[2, 1] = 2.0 * (y * z + w * x)
    rot[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    angle = 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))
    return a[top, top], a[top, top] - second, angle


@njit(cache=True)
def _ring_degenerate(a00, a11, a22, a01, a02, a12):
    """Coincident or collinear points, from the scatter matrix A = Σ p pᵀ (see RING_TOL)."""
    tr = a00 + a11 + a22
    i2 = a00 * a11 - a01 * a01 + a00 * a22 - a02 * a02 + a11 * a22 - a12 * a12
    return i2 <= RING_TOL * RING_TOL * tr * tr


@njit(cache=True)
def _vertex_rotation(i, x_ref, x_def, offsets, neighbours, h, a, v, rot):
    """Kabsch over vertex i and its one-ring; fills ``rot``, returns (flags, angle, residual)."""
    lo, hi = offsets[i], offsets[i + 1]
    m = hi - lo + 1
    mp0 = mp1 = mp2 = mq0 = mq1 = mq2 = 0.0
    for k in range(lo - 1, hi):
        j = i if k < lo else neighbours[k]
        mp0 += x_ref[j, 0]
        mp1 += x_ref[j, 1]
        mp2 += x_ref[j, 2]
        mq0 += x_def[j, 0]
        mq1 += x_def[j, 1]
        mq2 += x_def[j, 2]
    mp0, mp1, mp2 = mp0 / m, mp1 / m, mp2 / m
    mq0, mq1, mq2 = mq0 / m, mq1 / m, mq2 / m
    if not (np.isfinite(mp0 + mp1 + mp2) and np.isfinite(mq0 + mq1 + mq2)):
        return NONFINITE, np.nan, np.nan
    for r in range(3):
        for c in range(3):
            h[r, c] = 0.0
    p00 = p11 = p22 = p01 = p02 = p12 = 0.0
    q00 = q11 = q22 = q01 = q02 = q12 = 0.0
    for k in range(lo - 1, hi):
        j = i if k < lo else neighbours[k]
        p0, p1, p2 = x_ref[j, 0] - mp0, x_ref[j, 1] - mp1, x_ref[j, 2] - mp2
        q0, q1, q2 = x_def[j, 0] - mq0, x_def[j, 1] - mq1, x_def[j, 2] - mq2
        h[0, 0] += p0 * q0
        h[0, 1] += p0 * q1
        h[0, 2] += p0 * q2
        h[1, 0] += p1 * q0
        h[1, 1] += p1 * q1
        h[1, 2] += p1 * q2
        h[2, 0] += p2 * q0
        h[2, 1] += p2 * q1
        h[2, 2] += p2 * q2
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
    flags = 0
    if _ring_degenerate(p00, p11, p22, p01, p02, p12):
        flags |= REF_DEGENERATE
    if _ring_degenerate(q00, q11, q22, q01, q02, q12):
        flags |= DEF_DEGENERATE
    if flags:
        return flags, np.nan, np.nan
    _, gap, angle = horn_rotation(h, a, v, rot)
    if gap <= GAP_TOL * math.sqrt((p00 + p11 + p22) * (q00 + q11 + q22)):
        return AMBIGUOUS, np.nan, np.nan
    ss = 0.0
    for k in range(lo - 1, hi):
        j = i if k < lo else neighbours[k]
        p0, p1, p2 = x_ref[j, 0] - mp0, x_ref[j, 1] - mp1, x_ref[j, 2] - mp2
        d0 = rot[0, 0] * p0 + rot[0, 1] * p1 + rot[0, 2] * p2 - (x_def[j, 0] - mq0)
        d1 = rot[1, 0] * p0 + rot[1, 1] * p1 + rot[1, 2] * p2 - (x_def[j, 1] - mq1)
        d2 = rot[2, 0] * p0 + rot[2, 1] * p1 + rot[2, 2] * p2 - (x_def[j, 2] - mq2)
        ss += d0 * d0 + d1 * d1 + d2 * d2
    return 0, angle, math.sqrt(ss / m)


@njit(cache=True, parallel=True)
def vertex_rotations(x_ref, x_def, offsets, neighbours):
    """Per-vertex Kabsch rotation of the one-ring from ``x_ref`` (N, 3) to ``x_def`` (N, 3).

    Returns ``rotation`` (N, 3, 3), ``angle`` (N,) in radians [0, π], ``residual`` (N,)
    = √(mean over the ring of ‖R p − q‖²) and ``flags`` (N,) uint8: REF_DEGENERATE /
    DEF_DEGENERATE (coincident or collinear ring, RING_TOL), NONFINITE, AMBIGUOUS (GAP_TOL).
    Where a flag is set, rotation, angle and residual are NaN.
    """
    n = offsets.shape[0] - 1
    rotation = np.empty((n, 3, 3))
    angle = np.empty(n)
    residual = np.empty(n)
    flags = np.zeros(n, np.uint8)
    for c in prange((n + CHUNK - 1) // CHUNK):
        h = np.empty((3, 3))
        a = np.empty((4, 4))
        v = np.empty((4, 4))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            f, ang, res = _vertex_rotation(i, x_ref, x_def, offsets, neighbours, h, a, v,
                                           rotation[i])
            flags[i] = f
            angle[i] = ang
            residual[i] = res
            if f:
                rotation[i, :, :] = np.nan
    return rotation, angle, residual, flags


@njit(cache=True)
def triangle_frame(x, i0, i1, i2, e):
    """Edges e1 = x1 − x0, e2 = x2 − x0 and unit normal n of a triangle into the rows of ``e``
    (3×3). Returns (|e1 × e2|, degenerate) with degenerate = area ≤ TRIANGLE_TOL·(longest edge)²
    or non-finite."""
    for k in range(3):
        e[0, k] = x[i1, k] - x[i0, k]
        e[1, k] = x[i2, k] - x[i0, k]
    c0 = e[0, 1] * e[1, 2] - e[0, 2] * e[1, 1]
    c1 = e[0, 2] * e[1, 0] - e[0, 0] * e[1, 2]
    c2 = e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0]
    dbl_area = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    l1 = e[0, 0] ** 2 + e[0, 1] ** 2 + e[0, 2] ** 2
    l2 = e[1, 0] ** 2 + e[1, 1] ** 2 + e[1, 2] ** 2
    l3 = (e[1, 0] - e[0, 0]) ** 2 + (e[1, 1] - e[0, 1]) ** 2 + (e[1, 2] - e[0, 2]) ** 2
    degenerate = not (0.5 * dbl_area > TRIANGLE_TOL * max(l1, l2, l3))  # NaN → degenerate
    if not degenerate:
        e[2, 0], e[2, 1], e[2, 2] = c0 / dbl_area, c1 / dbl_area, c2 / dbl_area
    return dbl_area, degenerate


@njit(cache=True)
def _face_gradient(x_ref, x_def, tri, er, ed, h, a, v, w, f3, r3, u3, stretch, directions):
    """F3, R3, U3, stretches and directions of one triangle; returns its flags."""
    i0, i1, i2 = tri[0], tri[1], tri[2]
    finite = True
    for j in (i0, i1, i2):
        for k in range(3):
            finite = finite and np.isfinite(x_ref[j, k]) and np.isfinite(x_def[j, k])
    if not finite:
        return NONFINITE
    d, ref_bad = triangle_frame(x_ref, i0, i1, i2, er)
    _, def_bad = triangle_frame(x_def, i0, i1, i2, ed)
    flags = (REF_DEGENERATE if ref_bad else 0) | (DEF_DEGENERATE if def_bad else 0)
    if flags:
        return flags
    # [e1 e2 n]⁻¹ has the rows (e2 × n)/d, (n × e1)/d, n with d = |e1 × e2| = det [e1 e2 n]
    n0, n1, n2 = er[2, 0], er[2, 1], er[2, 2]
    g00 = (er[1, 1] * n2 - er[1, 2] * n1) / d
    g01 = (er[1, 2] * n0 - er[1, 0] * n2) / d
    g02 = (er[1, 0] * n1 - er[1, 1] * n0) / d
    g10 = (n1 * er[0, 2] - n2 * er[0, 1]) / d
    g11 = (n2 * er[0, 0] - n0 * er[0, 2]) / d
    g12 = (n0 * er[0, 1] - n1 * er[0, 0]) / d
    for r in range(3):
        f3[r, 0] = ed[0, r] * g00 + ed[1, r] * g10 + ed[2, r] * n0
        f3[r, 1] = ed[0, r] * g01 + ed[1, r] * g11 + ed[2, r] * n1
        f3[r, 2] = ed[0, r] * g02 + ed[1, r] * g12 + ed[2, r] * n2
    for r in range(3):
        for c in range(3):
            h[r, c] = f3[c, r]
    horn_rotation(h, a, v, r3)  # det F3 = area'/area > 0, so this is the polar rotation
    for r in range(3):
        for c in range(3):
            u3[r, c] = r3[0, r] * f3[0, c] + r3[1, r] * f3[1, c] + r3[2, r] * f3[2, c]
    for r in range(3):
        for c in range(r):
            u3[r, c] = u3[c, r] = 0.5 * (u3[r, c] + u3[c, r])
    for r in range(3):
        for c in range(3):
            h[r, c] = u3[r, c]
    jacobi_eigh(h, w)
    sort_descending(h, w, stretch, directions)
    return 0


@njit(cache=True, parallel=True)
def face_gradients3(x_ref, x_def, faces):
    """Per-triangle 3×3 deformation gradient that also maps the reference unit normal n to the
    deformed n': F3 = [e1' e2' n'] [e1 e2 n]⁻¹, with F3 = R3·U3 (R3 proper, U3 symmetric
    positive definite, both in the reference configuration).

    Returns ``F3``, ``R3``, ``U3`` (M, 3, 3), ``stretch3`` (M, 3) the eigenvalues of U3 in
    descending order, ``directions3`` (M, 3, 3) the unit eigenvectors (row k belongs to
    stretch3[k], sign free) and ``flags`` (M,) uint8 (REF_DEGENERATE, DEF_DEGENERATE,
    NONFINITE; TRIANGLE_TOL). Since F3ᵀ n' = n, one stretch is exactly 1 with direction n; the
    other two are the in-plane (2D) principal stretches.
    """
    m = faces.shape[0]
    f3 = np.empty((m, 3, 3))
    r3 = np.empty((m, 3, 3))
    u3 = np.empty((m, 3, 3))
    stretch = np.empty((m, 3))
    directions = np.empty((m, 3, 3))
    flags = np.zeros(m, np.uint8)
    for c in prange((m + CHUNK - 1) // CHUNK):
        er = np.empty((3, 3))
        ed = np.empty((3, 3))
        h = np.empty((3, 3))
        a = np.empty((4, 4))
        v = np.empty((4, 4))
        w = np.empty((3, 3))
        for t in range(c * CHUNK, min(m, (c + 1) * CHUNK)):
            f = _face_gradient(x_ref, x_def, faces[t], er, ed, h, a, v, w,
                               f3[t], r3[t], u3[t], stretch[t], directions[t])
            flags[t] = f
            if f:
                f3[t] = np.nan
                r3[t] = np.nan
                u3[t] = np.nan
                stretch[t] = np.nan
                directions[t] = np.nan
    return f3, r3, u3, stretch, directions, flags
