"""Block-sparse symmetric matrices of 3×3 blocks (block CSR) and the constraint filter.

The pattern (which vertex pairs interact) is built once from the elements; each
element keeps the slots of its blocks, so assembly is a scatter into ``values``
(nnzb, 3, 3) without any search. The matrix is stored in full (both triangles),
so the product is one plain loop over block rows.

The kernels are serial: on the shared 2-core machines this was written on,
numba's parallel loops were 5–50× slower under load from other processes (the
threads wait on each other at every barrier), and serial sums in a fixed order
keep runs bit-for-bit deterministic.
"""

import numpy as np

from clothtool.numba_setup import njit



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


class BlockMatrix:
    """A symmetric block-CSR matrix: a :class:`BlockPattern` and its values (nnzb, 3, 3)."""

    def __init__(self, pattern, values=None):
        self.pattern = pattern
        self.values = pattern.zeros() if values is None else values
        self.floor = np.zeros(pattern.n)  # a lower bound of each diagonal block's eigenvalues

    @property
    def row_ptr(self):
        return self.pattern.row_ptr

    @property
    def col(self):
        return self.pattern.col

    @property
    def diag(self):
        return self.pattern.diag

    def multiply(self, x, out):
        """out = A x."""
        block_multiply(self.pattern.row_ptr, self.pattern.col, self.values, x, out)
        return out

    def residual(self, b, x, out):
        """out = b − A x."""
        residual(self.pattern.row_ptr, self.pattern.col, self.values, b, x, out)
        return out

    def add_diagonal(self, d):
        """A += diag(d_v I₃) for a per-vertex scalar d (N,) ≥ 0, which becomes :attr:`floor`:
        what else the matrix holds is positive semi-definite (PSD-projected element
        Hessians, Gauss–Newton contact blocks), so d_v bounds the eigenvalues of diagonal
        block v from below, and the preconditioners keep to it where rounding has lost it."""
        add_block_diagonal(self.values, self.pattern.diag, d)
        self.floor = np.ascontiguousarray(np.broadcast_to(d, (self.pattern.n,)), dtype=np.float64)

    def to_scipy(self):
        import scipy.sparse as sps

        n = 3 * self.pattern.n
        return sps.bsr_matrix((self.values, self.pattern.col, self.pattern.row_ptr),
                              shape=(n, n)).tocsr()


class ConstraintFilter:
    """Baraff–Witkin's S per vertex (``filter``): ``kind`` (N,) int8 FREE/PINNED; ``active``
    is False when nothing is constrained."""

    def __init__(self, kind, active=True):
        self.kind = kind
        self.active = bool(active)


@njit(cache=True)
def add_block_diagonal(values, diag, d):
    """values[diag[v]] += d[v] I₃."""
    for v in range(diag.shape[0]):
        b = values[diag[v]]
        b[0, 0] += d[v]
        b[1, 1] += d[v]
        b[2, 2] += d[v]


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
def residual(row_ptr, col, values, b, x, r):
    """r = b − A x (unfiltered: at constrained vertices, the constraint force)."""
    block_multiply(row_ptr, col, values, x, r)
    for i in range(r.shape[0]):
        for p in range(3):
            r[i, p] = b[i, p] - r[i, p]
