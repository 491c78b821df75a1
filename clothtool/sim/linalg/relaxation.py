"""Block Gauss–Seidel relaxation, the smoother of the mode multigrid, and its diagonal inverses.

A sweep visits the block rows in order (``forward``) or in reverse and sets each node's
unknowns so that its row of A x = r holds: x_i = D_i⁻¹ (r_i − Σ_{j≠i} A_ij x_j), D_i the diagonal
block (never multiplied by x_i, so a contact barrier's block of 1e22 × the inertia adds no
rounding) (Saad, "Iterative Methods for Sparse Linear Systems", §4.1; block form as pyamg's
``block_gauss_seidel``). A forward sweep before the coarse correction and a backward one after
it make the V-cycle a symmetric operator, so it preconditions CG; Gauss–Seidel converges for
every symmetric positive definite A, so no damping weight or spectral estimate is needed.

Nodes whose inverse block is zero (pinned vertices, coarse nodes with no free vertex) keep
their unknowns: with a filtered right-hand side those stay zero, as the filter wants.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner
from clothtool.sim.linalg.filter import PINNED
from clothtool.sim.linalg.modes import M
from clothtool.vec3 import spd_inverse3

PIVOT = 1e-12  # smallest Cholesky pivot relative to its diagonal entry
# a sweep's direction, as values numba types as plain bool: a literal True / False argument
# would compile a sweep once per direction
FORWARD, BACKWARD = np.bool_(True), np.bool_(False)


@njit(cache=True, inline="always")
def _subtract_products(lo, hi, col, values, x, t):
    """t −= Σ A_s x_col[s] over the M×M blocks lo ≤ s < hi of a row (a coarse level; M a
    constant, so the loops unroll)."""
    for s in range(lo, hi):
        a = values[s]
        j = col[s]
        for p in range(M):
            v = 0.0
            for q in range(M):
                v += a[p, q] * x[j, q]
            t[p] -= v


@njit(cache=True, inline="always")
def _solve_node(d, t, x, i):
    """x[i] = D_i⁻¹ t (an M×M block)."""
    for p in range(M):
        v = 0.0
        for q in range(M):
            v += d[p, q] * t[q]
        x[i, p] = v


@njit_inner(cache=True)
def residual(row_ptr, col, values, r, x, out):
    """out = r − A x (a coarse level)."""
    for i in range(x.shape[0]):
        for p in range(M):
            out[i, p] = r[i, p]
        _subtract_products(row_ptr[i], row_ptr[i + 1], col, values, x, out[i])


@njit(cache=True)
def gauss_seidel(row_ptr, col, diag, values, diag_inv, r, x, forward):
    """One block Gauss–Seidel sweep on A x = r, x (n, M) updated in place (a coarse level);
    ``diag`` the slot of each row's diagonal block, ``diag_inv`` the inverses of those blocks
    (zero: the node keeps zero)."""
    n = x.shape[0]
    t = np.empty(M)
    for step in range(n):
        i = step if forward else n - 1 - step
        for p in range(M):
            t[p] = r[i, p]
        _subtract_products(row_ptr[i], diag[i], col, values, x, t)
        _subtract_products(diag[i] + 1, row_ptr[i + 1], col, values, x, t)
        _solve_node(diag_inv[i], t, x, i)


@njit(cache=True)
def forward_from_zero(row_ptr, col, diag, values, diagonal, diag_inv, r, x, res):
    """:func:`forward_from_zero3` for a coarse level (M×M blocks, exactly symmetric): a forward
    sweep from x = 0 and res = r − A x, reading each block left of the diagonal once and no
    block right of it; the diagonal blocks from ``diagonal``."""
    n = x.shape[0]
    t = np.empty(M)
    for i in range(n):
        for p in range(M):
            t[p] = r[i, p]
        _subtract_products(row_ptr[i], diag[i], col, values, x, t)
        _solve_node(diag_inv[i], t, x, i)
        for p in range(M):
            res[i, p] = t[p]
        _subtract_products(diag[i], diag[i] + 1, col, diagonal, x, res[i])
        for s in range(row_ptr[i], diag[i]):  # res_j −= A_ijᵀ x_i = A_ji x_i, j < i
            a = values[s]
            j = col[s]
            for p in range(M):
                v = 0.0
                for q in range(M):
                    v += a[q, p] * x[i, q]
                res[j, p] -= v


@njit(cache=True)
def cholesky(a):
    """In-place Cholesky factor (lower triangle) of a symmetric positive semi-definite matrix.

    A pivot that rounding (or a mode with no support: a zero row and column) has made
    non-positive is replaced by the matrix's own diagonal entry, or 1 where that is zero: the
    factor is then that of A + E with E ≥ 0 diagonal, still a valid SPD preconditioner, and an
    unknown with no support stays uncoupled."""
    _factor(a, a.shape[0])


@njit(cache=True, inline="always")
def _factor(a, n):
    """:func:`cholesky` of the leading n×n block of a (n a constant where the caller's size is
    one, so the loops unroll)."""
    for j in range(n):
        diagonal = a[j, j]
        d = diagonal
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > PIVOT * diagonal:
            d = diagonal if diagonal > 0.0 else 1.0
        d = np.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d


@njit(cache=True, inline="always")
def _substitute(lower, y, n):
    """y = (L Lᵀ)⁻¹ y in place for the leading n×n factor L: forward substitution with L, then
    backward with Lᵀ."""
    for i in range(n):
        s = y[i]
        for k in range(i):
            s -= lower[i, k] * y[k]
        y[i] = s / lower[i, i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= lower[k, i] * y[k]
        y[i] = s / lower[i, i]


@njit_inner(cache=True)
def cholesky_solve(lower, r, z):
    """z = A⁻¹ r with A = L Lᵀ (L from :func:`cholesky`), for (n, b) arrays flattened
    row-major."""
    b = r.shape[1]
    n = r.shape[0] * b
    y = np.empty(n)
    for i in range(n):
        y[i] = r[i // b, i % b]
    _substitute(lower, y, n)
    for i in range(n):
        z[i // b, i % b] = y[i]


@njit(cache=True)
def block_inverses(values, diag, skip, out):
    """out[i] = D_i⁻¹ for the M×M diagonal block of every node (zero for nodes with ``skip``),
    through :func:`cholesky` (so a block with an unsupported mode is inverted on the rest)."""
    work = np.empty((M, M))
    y = np.empty(M)
    for i in range(out.shape[0]):
        out[i] = 0.0
        if skip[i]:
            continue
        for p in range(M):  # scalar loops: an array assignment costs seconds of compilation
            for q in range(M):
                work[p, q] = values[diag[i], p, q]
        _factor(work, M)
        for c in range(M):  # column c of the inverse: L⁻ᵀ L⁻¹ e_c
            y[:] = 0.0
            y[c] = 1.0
            _substitute(work, y, M)
            for p in range(M):
                out[i, p, c] = y[p]


@njit(cache=True)
def block_jacobi(values, diag, kind, floor, inv):
    """inv = inverses of the diagonal blocks (zero for pinned vertices), each with its
    eigenvalues at least floor[v] (:func:`~clothtool.vec3.spd_inverse3`)."""
    for i in range(diag.shape[0]):
        if kind[i] != PINNED:
            spd_inverse3(values[diag[i]], floor[i], inv[i])
        else:
            inv[i] = 0.0


@njit(cache=True, inline="always")
def _minus_block3(a, xj, t0, t1, t2):
    """(t0, t1, t2) − a xj for one 3×3 block a."""
    x0, x1, x2 = xj[0], xj[1], xj[2]
    t0 -= a[0, 0] * x0 + a[0, 1] * x1 + a[0, 2] * x2
    t1 -= a[1, 0] * x0 + a[1, 1] * x1 + a[1, 2] * x2
    t2 -= a[2, 0] * x0 + a[2, 1] * x1 + a[2, 2] * x2
    return t0, t1, t2


@njit(cache=True, inline="always")
def _row_product3(first, stop, col, values, x, t0, t1, t2):
    """(t0, t1, t2) − Σ A_ij x_j over the blocks first ≤ s < stop of a row, in ascending order."""
    for s in range(first, stop):
        t0, t1, t2 = _minus_block3(values[s], x[col[s]], t0, t1, t2)
    return t0, t1, t2


@njit(cache=True, inline="always")
def _row_product3_down(first, stop, col, values, x, t0, t1, t2):
    """:func:`_row_product3` with the blocks in descending order, the last (stop − 1) first (a
    count from zero: a range with a negative step made the backward sweep a fifth slower)."""
    for k in range(stop - first):
        s = stop - 1 - k
        t0, t1, t2 = _minus_block3(values[s], x[col[s]], t0, t1, t2)
    return t0, t1, t2


@njit(cache=True)
def gauss_seidel3(row_ptr, col, diag, values, diag_inv, r, x, forward):
    """:func:`gauss_seidel` for 3×3 blocks, unrolled (the fine level). The backward sweep reads
    each row's blocks last first, so the matrix is read in one descending stream (a row's
    blocks ascending while the rows descend read 3.6 times slower at 256²)."""
    n = x.shape[0]
    for step in range(n):
        if forward:
            i = step
            t0, t1, t2 = _row_product3(row_ptr[i], diag[i], col, values, x, r[i, 0], r[i, 1],
                                       r[i, 2])
            t0, t1, t2 = _row_product3(diag[i] + 1, row_ptr[i + 1], col, values, x, t0, t1, t2)
        else:
            i = n - 1 - step
            t0, t1, t2 = _row_product3_down(diag[i] + 1, row_ptr[i + 1], col, values, x,
                                            r[i, 0], r[i, 1], r[i, 2])
            t0, t1, t2 = _row_product3_down(row_ptr[i], diag[i], col, values, x, t0, t1, t2)
        d = diag_inv[i]
        x[i, 0] = d[0, 0] * t0 + d[0, 1] * t1 + d[0, 2] * t2
        x[i, 1] = d[1, 0] * t0 + d[1, 1] * t1 + d[1, 2] * t2
        x[i, 2] = d[2, 0] * t0 + d[2, 1] * t1 + d[2, 2] * t2


@njit(cache=True)
def forward_from_zero3(row_ptr, col, diag, values, diagonal, diag_inv, r, x, res):
    """A forward :func:`gauss_seidel3` sweep from x = 0 and the residual res = r − A x after it,
    reading each block left of the diagonal once and no block right of it (``values`` exactly
    symmetric): the sweep reads only the blocks left of the diagonal (the others multiply
    zeros); row i's residual is what the sweep left of it, t_i − A_ii x_i, minus Σ_{j>i} A_ij x_j,
    whose terms A_ji ᵀ x_j row j subtracts while its blocks are at hand, once x_j is known (in
    the order of j, as a pass over row i's blocks right of the diagonal would). The diagonal
    blocks A_ii are read from ``diagonal`` (n, 3, 3), one after the other (double precision
    when ``values`` is a single-precision copy; read from the whole matrix at their slots, one
    cache miss a row, the sweep took 1.6 times as long at 256²)."""
    n = x.shape[0]
    for i in range(n):
        t0, t1, t2 = _row_product3(row_ptr[i], diag[i], col, values, x, r[i, 0], r[i, 1], r[i, 2])
        d = diag_inv[i]
        y0 = d[0, 0] * t0 + d[0, 1] * t1 + d[0, 2] * t2
        y1 = d[1, 0] * t0 + d[1, 1] * t1 + d[1, 2] * t2
        y2 = d[2, 0] * t0 + d[2, 1] * t1 + d[2, 2] * t2
        x[i, 0], x[i, 1], x[i, 2] = y0, y1, y2
        a = diagonal[i]  # D⁻¹ may differ from the block's inverse (a floor, rounding)
        res[i, 0] = t0 - (a[0, 0] * y0 + a[0, 1] * y1 + a[0, 2] * y2)
        res[i, 1] = t1 - (a[1, 0] * y0 + a[1, 1] * y1 + a[1, 2] * y2)
        res[i, 2] = t2 - (a[2, 0] * y0 + a[2, 1] * y1 + a[2, 2] * y2)
        for s in range(row_ptr[i], diag[i]):  # res_j −= A_ijᵀ x_i = A_ji x_i, j < i
            b = values[s]
            j = col[s]
            res[j, 0] -= b[0, 0] * y0 + b[1, 0] * y1 + b[2, 0] * y2
            res[j, 1] -= b[0, 1] * y0 + b[1, 1] * y1 + b[2, 1] * y2
            res[j, 2] -= b[0, 2] * y0 + b[1, 2] * y1 + b[2, 2] * y2
