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
preconditioner (the inverses of the 3×3 diagonal blocks), and constraints are
handled by Baraff–Witkin's filter (1998, §5.3): S_v = I for a free vertex, 0 for
a pinned one, I − n nᵀ for one held on a collider surface with normal n. The
residual and every search direction are filtered, so the constrained components
of the solution keep their initial (prescribed) values exactly. The stop
test is on the true relative residual ‖S(b − Ax)‖ / ‖S b‖: when the recurrence
says converged, the residual is recomputed from its definition and iteration
continues if that one is not.

The Python side passes a :class:`BlockMatrix` (pattern + values), a
:class:`ConstraintFilter` (kind, normal) and a preconditioner object
(:class:`BlockJacobi` or :class:`~clothtool.sim.multigrid.Hierarchy`); the numba
kernels underneath take the plain arrays these unpack to.
"""

import numpy as np
from numba import njit

from clothtool.contact.barrier import NO_OPERATOR, gauss_newton_offdiagonal_multiply
from clothtool.sim.filter import PINNED, apply_filter
from clothtool.sim.multigrid import NO_MULTIGRID, vcycle
from clothtool.vec3 import spd_inverse3


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
    """Baraff–Witkin's S per vertex (``filter``): ``kind`` (N,) int8 FREE/PINNED/SLIDING and
    ``normal`` (N, 3) for the sliding ones; ``active`` is False when nothing is constrained."""

    def __init__(self, kind, normal, active=True):
        self.kind = kind
        self.normal = normal
        self.active = bool(active)


class BlockJacobi:
    """The block-Jacobi preconditioner: the inverses of the 3×3 diagonal blocks."""

    arrays = NO_MULTIGRID

    def __init__(self, n_vertices):
        self.inverse = np.zeros((n_vertices, 3, 3))

    def setup(self, matrix, constraints):
        """Invert the diagonal blocks of a :class:`BlockMatrix` (pinned vertices: zero)."""
        block_jacobi(matrix.values, matrix.pattern.diag, constraints.kind, matrix.floor,
                     self.inverse)


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
def block_jacobi(values, diag, kind, floor, inv):
    """inv = inverses of the diagonal blocks (zero for pinned vertices), each with its
    eigenvalues at least floor[v] (:func:`~clothtool.vec3.spd_inverse3`)."""
    for i in range(diag.shape[0]):
        if kind[i] != PINNED:
            spd_inverse3(values[diag[i]], floor[i], inv[i])
        else:
            inv[i] = 0.0


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
def residual(row_ptr, col, values, b, x, r):
    """r = b − A x (unfiltered: at constrained vertices, the constraint force)."""
    block_multiply(row_ptr, col, values, x, r)
    for i in range(r.shape[0]):
        for p in range(3):
            r[i, p] = b[i, p] - r[i, p]


@njit(cache=True)
def _precondition(inv, r, kind, normal, constrained, z, mg):
    """z = S P⁻¹ r: block Jacobi, or the multigrid V-cycle when mg holds a hierarchy."""
    if len(mg[0]) > 1:
        vcycle(r, z, mg)
    else:
        _apply_inverse(inv, r, z)
    if constrained:
        apply_filter(z, kind, normal)


def filtered_pcg(matrix, b, x, constraints, tol, max_iter, preconditioner, extra=NO_OPERATOR):
    """Solve S(A x − b) = 0 from x, whose constrained components (I − S)x stay as given.

    ``matrix``: a :class:`BlockMatrix`; ``constraints``: a :class:`ConstraintFilter`
    (S); ``preconditioner``: :class:`BlockJacobi` or a
    :class:`~clothtool.sim.multigrid.Hierarchy`, set up here for this matrix and filter;
    ``extra``: off-diagonal contact blocks applied matrix-free
    (:func:`~clothtool.contact.barrier.solve_operator`), whose diagonal blocks are already in
    the matrix. Stops when the true relative residual ‖S(b − Ax)‖ / ‖S b‖ ≤ ``tol`` or after
    ``max_iter`` iterations. Returns (iterations, relative true residual).
    """
    preconditioner.setup(matrix, constraints)
    return filtered_pcg_arrays(matrix.pattern.row_ptr, matrix.pattern.col, matrix.values, b, x,
                               constraints.kind, constraints.normal, constraints.active, tol,
                               max_iter, preconditioner.inverse, preconditioner.arrays, extra)


@njit(cache=True)
def _residual_with(row_ptr, col, values, extra, b, x, r):
    """r = b − (A + H_extra) x."""
    residual(row_ptr, col, values, b, x, r)
    if extra[2] > 0:
        gauss_newton_offdiagonal_multiply(extra, x, r, -1.0)


@njit(cache=True)
def filtered_pcg_arrays(row_ptr, col, values, b, x, kind, normal, constrained, tol, max_iter,
                        inv, mg, extra):
    """:func:`filtered_pcg` on plain arrays: ``constrained`` False skips the filter; ``inv``
    the block-Jacobi inverses (:func:`block_jacobi`) and ``mg`` ``NO_MULTIGRID``, or ``mg``
    the arrays of a multigrid hierarchy after ``setup_levels``; ``extra`` the matrix-free
    contact blocks (``NO_OPERATOR`` for none)."""
    n = b.shape[0]
    sb = b.copy()
    if constrained:
        apply_filter(sb, kind, normal)
    b_norm = np.sqrt(_dot(sb, sb))
    r = np.empty((n, 3))
    z = np.empty((n, 3))
    q = np.empty((n, 3))
    _residual_with(row_ptr, col, values, extra, b, x, r)
    if constrained:
        apply_filter(r, kind, normal)
    if b_norm == 0.0:
        b_norm = 1.0  # nothing to solve for but the prescribed components: absolute test
    _precondition(inv, r, kind, normal, constrained, z, mg)
    p = z.copy()
    rz = _dot(r, z)
    res = np.sqrt(_dot(r, r)) / b_norm
    it = 0
    while it < max_iter:
        if res <= tol:
            # confirm on the true residual before stopping
            _residual_with(row_ptr, col, values, extra, b, x, r)
            if constrained:
                apply_filter(r, kind, normal)
            res = np.sqrt(_dot(r, r)) / b_norm
            if res <= tol:
                break
            _precondition(inv, r, kind, normal, constrained, z, mg)
            p[:] = z
            rz = _dot(r, z)
        block_multiply(row_ptr, col, values, p, q)
        if extra[2] > 0:
            gauss_newton_offdiagonal_multiply(extra, p, q, 1.0)
        if constrained:
            apply_filter(q, kind, normal)
        pq = _dot(p, q)
        if pq <= 0.0:
            break
        alpha = rz / pq
        _axpy(alpha, p, x)
        _axpy(-alpha, q, r)
        _precondition(inv, r, kind, normal, constrained, z, mg)
        rz_new = _dot(r, z)
        _xpby(z, rz_new / rz, p)
        rz = rz_new
        res = np.sqrt(_dot(r, r)) / b_norm
        it += 1
    if it == max_iter:
        _residual_with(row_ptr, col, values, extra, b, x, r)
        if constrained:
            apply_filter(r, kind, normal)
        res = np.sqrt(_dot(r, r)) / b_norm
    return it, res
