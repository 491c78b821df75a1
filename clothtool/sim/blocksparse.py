"""Block-sparse symmetric matrices of 3×3 blocks (block CSR) and a filtered PCG.

The pattern (which vertex pairs interact) is built once from the elements; each
element keeps the slots of its blocks, so assembly is a scatter into ``values``
(nnzb, 3, 3) without any search. The matrix is stored in full (both triangles),
so the product is one plain loop over block rows.

The kernels are serial: on the shared 2-core machines this was written on,
numba's parallel loops were 5–50× slower under load from other processes (the
threads wait on each other at every barrier), and serial sums in a fixed order
keep runs bit-for-bit deterministic.

The solver is preconditioned conjugate gradients with the block-Jacobi
preconditioner (the inverses of the 3×3 diagonal blocks), and pinned vertices
are handled by Baraff–Witkin's filter (1998, §5.3): with S_v = 0 for pinned and
I for free vertices, the residual and every search direction are filtered, so
the pinned components of the solution keep their initial value exactly. The stop
test is on the true relative residual ‖S(b − Ax)‖ / ‖S b‖: when the recurrence
says converged, the residual is recomputed from its definition and iteration
continues if that one is not.
"""

import numpy as np
from numba import njit


class BlockPattern:
    """Block-CSR pattern from element vertex tuples, with each element's block slots."""

    def __init__(self, n_vertices, *element_sets):
        rows, cols = [np.arange(n_vertices)], [np.arange(n_vertices)]
        for elems in element_sets:
            k = elems.shape[1]
            rows.append(np.repeat(elems, k, axis=1).ravel())
            cols.append(np.tile(elems, (1, k)).ravel())
        key = np.unique(np.concatenate(rows) * n_vertices + np.concatenate(cols))
        self.n = n_vertices
        self.col = (key % n_vertices).astype(np.int64)
        counts = np.bincount(key // n_vertices, minlength=n_vertices)
        self.row_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self._key = key
        self.diag = self.slots(np.arange(n_vertices)[:, None])[:, 0]

    @property
    def nnzb(self):
        return len(self.col)

    def slots(self, elems):
        """(E, k·k) slot of block (a, b) of each element, row-major over (a, b)."""
        k = elems.shape[1]
        rows = np.repeat(elems, k, axis=1)
        cols = np.tile(elems, (1, k))
        return np.searchsorted(self._key, rows * self.n + cols).astype(np.int64)

    def zeros(self):
        return np.zeros((self.nnzb, 3, 3))


@njit(cache=True)
def scatter_blocks(elem_hess, slots, values):
    """values[slot] += the (a, b) 3×3 block of each element Hessian (k·3 × k·3)."""
    k = int(np.sqrt(slots.shape[1]))
    for e in range(slots.shape[0]):
        for a in range(k):
            for b in range(k):
                s = slots[e, a * k + b]
                for p in range(3):
                    for q in range(3):
                        values[s, p, q] += elem_hess[e, 3 * a + p, 3 * b + q]


@njit(cache=True)
def block_multiply(row_ptr, col, values, x, y):
    """y = A x."""
    for i in range(row_ptr.shape[0] - 1):
        y0 = 0.0
        y1 = 0.0
        y2 = 0.0
        for s in range(row_ptr[i], row_ptr[i + 1]):
            j = col[s]
            b = values[s]
            x0, x1, x2 = x[j, 0], x[j, 1], x[j, 2]
            y0 += b[0, 0] * x0 + b[0, 1] * x1 + b[0, 2] * x2
            y1 += b[1, 0] * x0 + b[1, 1] * x1 + b[1, 2] * x2
            y2 += b[2, 0] * x0 + b[2, 1] * x1 + b[2, 2] * x2
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2


@njit(cache=True)
def _dot(a, b):
    """Σ a·b over (N, 3) arrays."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return total


@njit(cache=True)
def _apply_inverse(inv, r, z):
    for i in range(r.shape[0]):
        b = inv[i]
        z[i, 0] = b[0, 0] * r[i, 0] + b[0, 1] * r[i, 1] + b[0, 2] * r[i, 2]
        z[i, 1] = b[1, 0] * r[i, 0] + b[1, 1] * r[i, 1] + b[1, 2] * r[i, 2]
        z[i, 2] = b[2, 0] * r[i, 0] + b[2, 1] * r[i, 1] + b[2, 2] * r[i, 2]


@njit(cache=True)
def block_jacobi(values, diag, free):
    """Inverses of the diagonal blocks (zero for pinned vertices: S P⁻¹ S)."""
    n = diag.shape[0]
    inv = np.zeros((n, 3, 3))
    for i in range(n):
        if free[i]:
            inv[i] = np.linalg.inv(values[diag[i]])
    return inv


@njit(cache=True)
def _filter(r, free):
    for i in range(r.shape[0]):
        if not free[i]:
            r[i, 0] = 0.0
            r[i, 1] = 0.0
            r[i, 2] = 0.0


@njit(cache=True)
def _axpy(alpha, x, y):
    """y += alpha x."""
    for i in range(x.shape[0]):
        y[i, 0] += alpha * x[i, 0]
        y[i, 1] += alpha * x[i, 1]
        y[i, 2] += alpha * x[i, 2]


@njit(cache=True)
def _xpby(x, beta, y):
    """y = x + beta y."""
    for i in range(x.shape[0]):
        y[i, 0] = x[i, 0] + beta * y[i, 0]
        y[i, 1] = x[i, 1] + beta * y[i, 1]
        y[i, 2] = x[i, 2] + beta * y[i, 2]


@njit(cache=True)
def _true_residual(row_ptr, col, values, b, x, free, has_pins, r):
    """r = S(b − A x)."""
    block_multiply(row_ptr, col, values, x, r)
    for i in range(r.shape[0]):
        for p in range(3):
            r[i, p] = b[i, p] - r[i, p]
    if has_pins:
        _filter(r, free)


@njit(cache=True)
def filtered_pcg(row_ptr, col, values, diag, b, x, free, has_pins, tol, max_iter):
    """Solve A x = b on the free vertices, starting from x (pinned rows of x kept as given).

    Returns (iterations, relative true residual).
    """
    n = b.shape[0]
    inv = block_jacobi(values, diag, free)
    sb = b.copy()
    if has_pins:
        _filter(sb, free)
    b_norm = np.sqrt(_dot(sb, sb))
    if b_norm == 0.0:
        x[:] = 0.0
        return 0, 0.0
    r = np.empty((n, 3))
    _true_residual(row_ptr, col, values, b, x, free, has_pins, r)
    z = np.empty((n, 3))
    q = np.empty((n, 3))
    _apply_inverse(inv, r, z)
    p = z.copy()
    rz = _dot(r, z)
    res = np.sqrt(_dot(r, r)) / b_norm
    it = 0
    while it < max_iter:
        if res <= tol:
            # confirm on the true residual before stopping
            _true_residual(row_ptr, col, values, b, x, free, has_pins, r)
            res = np.sqrt(_dot(r, r)) / b_norm
            if res <= tol:
                break
            _apply_inverse(inv, r, z)
            p[:] = z
            rz = _dot(r, z)
        block_multiply(row_ptr, col, values, p, q)
        if has_pins:
            _filter(q, free)
        pq = _dot(p, q)
        if pq <= 0.0:
            break
        alpha = rz / pq
        _axpy(alpha, p, x)
        _axpy(-alpha, q, r)
        _apply_inverse(inv, r, z)
        rz_new = _dot(r, z)
        _xpby(z, rz_new / rz, p)
        rz = rz_new
        res = np.sqrt(_dot(r, r)) / b_norm
        it += 1
    if it == max_iter:
        _true_residual(row_ptr, col, values, b, x, free, has_pins, r)
        res = np.sqrt(_dot(r, r)) / b_norm
    return it, res
