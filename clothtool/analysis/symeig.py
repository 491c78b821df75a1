"""Cyclic Jacobi eigen-solver for small symmetric matrices (3×3 and 4×4), numba, float64.

Each step zeroes one off-diagonal entry a_pq with a plane rotation (Rutishauser's form,
Press et al., *Numerical Recipes*, 3rd ed., §11.1):
θ = (a_qq − a_pp) / (2 a_pq), t = sgn θ / (|θ| + √(θ² + 1)), c = 1/√(t² + 1), s = t·c.
Sweeps repeat until the off-diagonal mass is below (2⁻⁵³)² of the Frobenius norm²,
which takes 3–6 sweeps; convergence is quadratic. Jacobi is used because its
eigenvectors are accurate to about ε‖A‖/gap (Demmel & Veselić 1992), better than the
closed-form (trigonometric) 3×3 solution near repeated eigenvalues.
"""

import math

from numba import njit

MAX_SWEEPS = 30
_EPS2 = 2.0**-106  # (2⁻⁵³)²


@njit(cache=True)
def jacobi_eigh(a, v):
    """Diagonalise the symmetric ``a`` (n×n) in place: afterwards diag(a) holds the eigenvalues
    and the columns of ``v`` the orthonormal eigenvectors (unsorted). Returns the sweeps used."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            v[i, j] = 1.0 if i == j else 0.0
    fro2 = 0.0
    for i in range(n):
        for j in range(n):
            fro2 += a[i, j] * a[i, j]
    for sweep in range(MAX_SWEEPS):
        off = 0.0
        for p in range(n - 1):
            for q in range(p + 1, n):
                off += a[p, q] * a[p, q]
        if off <= _EPS2 * fro2:
            return sweep
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = a[p, q]
                if apq == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * apq)
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                a[p, p] -= t * apq
                a[q, q] += t * apq
                a[p, q] = 0.0
                a[q, p] = 0.0
                for r in range(n):
                    if r != p and r != q:
                        arp = a[r, p]
                        arq = a[r, q]
                        a[r, p] = c * arp - s * arq
                        a[p, r] = a[r, p]
                        a[r, q] = s * arp + c * arq
                        a[q, r] = a[r, q]
                    vrp = v[r, p]
                    vrq = v[r, q]
                    v[r, p] = c * vrp - s * vrq
                    v[r, q] = s * vrp + c * vrq
    return MAX_SWEEPS


@njit(cache=True)
def sort_descending(a, v, values, vectors):
    """After :func:`jacobi_eigh`: the eigenvalues into ``values`` in descending order and the
    matching eigenvectors into the rows of ``vectors`` (row k belongs to values[k])."""
    n = a.shape[0]
    for k in range(n):
        rank = 0
        for j in range(n):
            if a[j, j] > a[k, k] or (a[j, j] == a[k, k] and j < k):
                rank += 1
        values[rank] = a[k, k]
        for r in range(n):
            vectors[rank, r] = v[r, k]
