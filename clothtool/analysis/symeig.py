"""Eigen-pairs of small symmetric matrices, numba, float64: cyclic Jacobi for the eigenvalues of a
batch, the adjugate for the eigenvector of one simple eigenvalue.

Each step zeroes one off-diagonal entry a_pq with a plane rotation by the smaller angle φ with
tan φ = t (Rutishauser's form, Press et al., *Numerical Recipes*, 3rd ed., §11.1):

    d = a_qq − a_pp,  g = 2 a_pq sgn(d),  u = |d| + √(d² + 4 a_pq²),  w = √(u² + g²)
    t = g/u,  c = u/w,  s = g/w,  a_pp −= t a_pq,  a_qq += t a_pq

evaluated with one division, 1/(u·w), and no branch (u gets 1e-150 added so that a_pq = d = 0
gives c = 1, s = 0; the matrices are expected scaled to about unit norm). Only the upper triangle
is updated. The B matrices of a batch are rotated in lockstep along the last axis so that the
compiler vectorises the rotations across matrices; sweeps repeat until, in every matrix, the
off-diagonal mass is below (2⁻⁵³)² of its Frobenius norm² (4–6 sweeps for 4×4; convergence is
quadratic), so the eigenvalues are accurate to a few ε‖A‖. Eigenvectors are not accumulated:
for the one that is needed, :func:`adjugate_eigenvector4` takes a column of adj(A − λI) at a
fraction of the cost. Its angle to the exact vector is at most
√5(δλ + 4εm)/gap + √5·60εm³/Π_(j≠i)|λ_j − λ| (δλ the error of λ, m = max|A − λI|; derived in
tests/test_kabsch.py): Davis–Kahan's bound, as for a Jacobi vector, except next to a near-double
eigenvalue, where the cofactors' rounding (the second term) is the larger.
"""

import math

import numpy as np

from clothtool.numba_setup import njit, njit_inner

MAX_SWEEPS = 30
_EPS2 = 2.0**-106  # (2⁻⁵³)²
_TINY = 1e-150  # u > 0 even when a_pq = 0 and a_pp = a_qq; (1e-150)² is still a normal number


@njit(cache=True, error_model="numpy")
def jacobi_eigvals_batch(a):
    """Eigenvalues of the symmetric matrices ``a[:, :, k]`` (n, n, B, C-contiguous), in place:
    afterwards ``a[i, i, k]`` are the eigenvalues (unsorted); the off-diagonal entries are
    undefined. Returns the number of sweeps. A matrix with NaN stops the iteration for itself
    only (its results are NaN)."""
    n, _, m = a.shape
    fro2 = np.zeros(m)
    off = np.empty(m)
    c = np.empty(m)
    s = np.empty(m)
    for i in range(n):
        for j in range(n):
            for k in range(m):
                fro2[k] += a[i, j, k] * a[i, j, k]
    for sweep in range(MAX_SWEEPS):
        off[:] = 0.0
        for p in range(n - 1):
            for q in range(p + 1, n):
                for k in range(m):
                    off[k] += a[p, q, k] * a[p, q, k]
        converged = True
        for k in range(m):
            if off[k] > _EPS2 * fro2[k]:
                converged = False
        if converged:
            return sweep
        for p in range(n - 1):
            for q in range(p + 1, n):
                for k in range(m):
                    apq = a[p, q, k]
                    d = a[q, q, k] - a[p, p, k]
                    g = 2.0 * apq if d >= 0.0 else -2.0 * apq
                    u = abs(d) + math.sqrt(d * d + 4.0 * apq * apq) + _TINY
                    w = math.sqrt(u * u + g * g)
                    z = 1.0 / (u * w)
                    c[k] = u * u * z  # u/w
                    s[k] = g * u * z  # g/w
                    ta = g * w * z * apq  # t·a_pq, t = g/u
                    a[p, p, k] -= ta
                    a[q, q, k] += ta
                    a[p, q, k] = 0.0
                for r in range(n):
                    if r != p and r != q:  # only the upper triangle is kept up to date
                        i1, j1 = min(r, p), max(r, p)
                        i2, j2 = min(r, q), max(r, q)
                        for k in range(m):
                            arp = a[i1, j1, k]
                            arq = a[i2, j2, k]
                            a[i1, j1, k] = c[k] * arp - s[k] * arq
                            a[i2, j2, k] = s[k] * arp + c[k] * arq
    return MAX_SWEEPS


@njit_inner(cache=True, error_model="numpy")
def _minor3(b, skip_row, skip_col):
    """Determinant of the 4×4 ``b`` without row ``skip_row`` and column ``skip_col``."""
    r0, r1, r2 = int(skip_row == 0), 1 + int(skip_row <= 1), 2 + int(skip_row <= 2)
    c0, c1, c2 = int(skip_col == 0), 1 + int(skip_col <= 1), 2 + int(skip_col <= 2)
    return (b[r0, c0] * (b[r1, c1] * b[r2, c2] - b[r1, c2] * b[r2, c1])
            - b[r0, c1] * (b[r1, c0] * b[r2, c2] - b[r1, c2] * b[r2, c0])
            + b[r0, c2] * (b[r1, c0] * b[r2, c1] - b[r1, c1] * b[r2, c0]))


@njit(cache=True, error_model="numpy")
def adjugate_eigenvector4(a, k, lam, b, x):
    """Unit eigenvector of the symmetric 4×4 matrix ``a[:, :, k]`` for its simple eigenvalue
    ``lam``, into ``x`` (4,); ``b`` is 4×4 scratch. B = A − λI has rank 3, so every column of
    adj(B) = Σ_i Π_(j≠i)(λ_j − λ) v_i v_iᵀ is a multiple of v; the column with the largest
    diagonal cofactor (∝ v_i²) is taken. Its error: the module's bound."""
    for i in range(4):
        for j in range(4):
            b[i, j] = a[i, j, k] - (lam if i == j else 0.0)
    col = 0
    best = -1.0
    for i in range(4):
        c = abs(_minor3(b, i, i))
        if c > best:
            best = c
            col = i
    norm = 0.0
    for i in range(4):
        x[i] = _minor3(b, i, col) * (1.0 if (i + col) % 2 == 0 else -1.0)
        norm += x[i] * x[i]
    inv = 1.0 / math.sqrt(norm)
    for i in range(4):
        x[i] *= inv
