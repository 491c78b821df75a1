"""Preconditioned conjugate gradients on a filtered block matrix, and its preconditioners.

The solver is preconditioned conjugate gradients (Hestenes & Stiefel 1952), and
pins are handled by Baraff–Witkin's filter (1998, §5.3): S_v = I for a free vertex, 0 for
a pinned one. The residual and every search direction are filtered, so the pinned components
of the solution keep their initial (prescribed) values exactly. The stop test is on
the true relative residual ‖S(b − Ax)‖ / ‖S b‖: when the recurrence says converged,
the residual is recomputed from its definition and iteration continues if that one
is not.

The Python side passes a :class:`~clothtool.sim.linalg.blocks.BlockMatrix` (pattern +
values), a :class:`~clothtool.sim.linalg.blocks.ConstraintFilter` (kind) and a
preconditioner object (:class:`BlockJacobi` or
:class:`~clothtool.sim.linalg.multigrid.Hierarchy`, :func:`make_preconditioner`); the
numba kernels underneath take the plain arrays these unpack to. A pair operator
(:mod:`clothtool.sim.linalg.pairs`, ``extra``) adds its off-diagonal part matrix-free.
"""

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.linalg.filter import apply_filter
from clothtool.sim.linalg.blocks import block_multiply, residual
from clothtool.sim.linalg.multigrid import COARSEST, Hierarchy, vcycle
from clothtool.sim.linalg.multilevel import COARSEST as MODES_COARSEST
from clothtool.sim.linalg.multilevel import ModeMultigrid, mode_cycle
from clothtool.sim.linalg.pairs import pairs_offdiagonal_multiply
from clothtool.sim.linalg.relaxation import block_jacobi
from clothtool.vec3 import copy_into


class BlockJacobi:
    """The block-Jacobi preconditioner: the inverses of the 3×3 diagonal blocks."""

    def __init__(self, n_vertices):
        self.inverse = np.zeros((n_vertices, 3, 3))

    def setup(self, matrix, constraints):
        """Invert the diagonal blocks of a :class:`BlockMatrix` (pinned vertices: zero)."""
        block_jacobi(matrix.values, matrix.pattern.diag, constraints.kind, matrix.floor,
                     self.inverse)


    def update(self, x, constraints):
        """Nothing depends on the positions."""


# ``hybrid``: a solve asking for a relative residual at most this takes ``amg``'s cycle, a looser
# one ``multigrid``'s. At the default tolerance (1e-6) that is each step's first solve, where amg
# takes 53 iterations to multigrid's 363 (0.85× the time, the captured 64² sheet systems of
# ``benchmarks linalg``); on the loose Eisenstat–Walker solves after it amg's fewer iterations
# (7.6 against 40) cost 1.4× the time, and the samples' 1e-2 never asks for a tight solve
TIGHT = 1e-4


class Hybrid:
    """``solver.preconditioner: hybrid``: the mode multigrid for the tight solves, the multigrid
    of translations for the loose ones (``TIGHT``). The choice is a function of the solve's
    tolerance, and the mode multigrid's prolongators are built, at the first tight solve of a
    Newton minimisation, from the positions the minimisation started at: nothing but the state
    decides either, so a resumed run matches an uninterrupted one."""

    def __init__(self, pattern, faces):
        self.tight = make_preconditioner("amg", pattern, faces)
        self.loose = make_preconditioner("multigrid", pattern, faces)
        self._start = None

    def update(self, x, constraints):
        """Keep the positions a Newton minimisation starts at (the prolongators wait for a tight
        solve: the samples' loose tolerance never asks for one)."""
        self._start = (x.copy(), constraints)

    def pick(self, tol):
        """The preconditioner of a solve to relative residual ``tol``."""
        if tol > TIGHT:
            return self.loose
        if self._start is not None:
            self.tight.update(*self._start)
            self._start = None
        return self.tight


# ``auto``: a model whose stiffness ratio k h²/m (``stiffness``: its stiffest membrane over the
# free vertices' mean mass, at the solver step h) is at least this takes ``amg`` for every solve,
# a softer one ``multigrid``. multigrid's PCG iterations grow with the ratio and amg's hardly
# do, so amg's dearer cycle pays on the stiff sheets and not on the soft ones (per solve, on
# systems captured from each run at its own tolerance: the 64² hanging sheet of ``benchmarks
# linalg``, ratio 3.5e5 at 1e-6, 0.95× multigrid's time; the hanging sheet sample, 3.0e4 at 1e-2,
# 1.38×; the drape and twist samples, 1.5e3 and 2.3e3 at 1e-2, 1.83× and 1.86×)
AUTO_RATIO = 1e5


def make_preconditioner(name, pattern, faces, stiffness=0.0):
    """``solver.preconditioner`` for a matrix pattern: a :class:`Hierarchy` for
    ``multigrid``, a :class:`~clothtool.sim.linalg.multilevel.ModeMultigrid` for ``amg`` (block
    Jacobi on meshes too small to coarsen), a :class:`Hybrid` of the two for ``hybrid``, for
    ``auto`` ``amg`` when the model's ``stiffness`` ratio k h²/m is at least ``AUTO_RATIO`` and
    ``multigrid`` below, else block Jacobi."""
    if name == "auto":
        name = "amg" if stiffness >= AUTO_RATIO else "multigrid"
    if name == "multigrid" and pattern.n > COARSEST:
        return Hierarchy.for_mesh(pattern, faces)
    if name == "amg" and pattern.n > MODES_COARSEST:
        return ModeMultigrid(pattern, faces)
    if name == "hybrid" and pattern.n > MODES_COARSEST:
        return Hybrid(pattern, faces)
    return BlockJacobi(pattern.n)


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
def _precondition(inv, r, kind, constrained, z, mg, row_ptr, col, values, modes):
    """z = S P⁻¹ r: the mode multigrid's cycle when ``modes`` holds one, the multigrid V-cycle
    when ``mg`` does, block Jacobi when ``inv`` does. The two absent are ``None``: numba prunes
    a test of a ``None`` argument (not an ``elif`` or ``else`` after a test it kept), so a run
    compiles only the cycle it uses."""
    if modes is not None:
        mode_cycle(r, z, row_ptr, col, values, modes)
    if mg is not None:
        vcycle(r, z, mg)
    if inv is not None:
        _apply_inverse(inv, r, z)
    if constrained:
        apply_filter(z, kind)


def filtered_pcg(matrix, b, x, constraints, tol, max_iter, preconditioner, extra=None):
    """Solve S(A x − b) = 0 from x, whose constrained components (I − S)x stay as given.

    ``matrix``: a :class:`BlockMatrix`; ``constraints``: a :class:`ConstraintFilter`
    (S); ``preconditioner``: :class:`BlockJacobi`, a
    :class:`~clothtool.sim.linalg.multigrid.Hierarchy`, a
    :class:`~clothtool.sim.linalg.multilevel.ModeMultigrid` or a :class:`Hybrid` (which picks
    one of its two by ``tol``), set up here for this matrix and filter;
    ``extra``: a pair operator (:mod:`clothtool.sim.linalg.pairs`) whose off-diagonal part is
    applied matrix-free, its diagonal blocks already in the matrix (``None`` in a scene
    without contact: numba then compiles no pair product). Stops when the true relative residual ‖S(b − Ax)‖ / ‖S b‖ ≤ ``tol`` or after
    ``max_iter`` iterations. Returns (iterations, relative true residual).
    """
    if isinstance(preconditioner, Hybrid):
        preconditioner = preconditioner.pick(tol)
    preconditioner.setup(matrix, constraints)
    return filtered_pcg_arrays(matrix.pattern.row_ptr, matrix.pattern.col, matrix.values, b, x,
                               constraints.kind, constraints.active, tol, max_iter,
                               *_arrays(preconditioner), extra)


def _arrays(preconditioner):
    """What the kernels take of a preconditioner: (block-Jacobi inverses, multigrid arrays,
    mode-multigrid arrays), ``None`` for the kinds it is not."""
    if isinstance(preconditioner, ModeMultigrid):
        return None, None, preconditioner.modes
    if isinstance(preconditioner, Hierarchy):
        return None, preconditioner.arrays, None
    return preconditioner.inverse, None, None


@njit(cache=True)
def _residual_with(row_ptr, col, values, extra, b, x, r):
    """r = b − (A + H_extra) x."""
    residual(row_ptr, col, values, b, x, r)
    if extra is not None and extra[3] > 0:
        pairs_offdiagonal_multiply(extra, x, r, -1.0)


@njit(cache=True)
def filtered_pcg_arrays(row_ptr, col, values, b, x, kind, constrained, tol, max_iter,
                        inv, mg, modes, extra):
    """:func:`filtered_pcg` on plain arrays: ``constrained`` False skips the filter; ``inv``
    the block-Jacobi inverses (:func:`block_jacobi`), or ``mg`` the arrays of a multigrid
    hierarchy after ``setup_levels``, or ``modes`` those of a mode multigrid after its
    ``setup`` (``None`` for the ones not used); ``extra`` the matrix-free contact blocks
    (``None`` for none)."""
    n = b.shape[0]
    sb = b.copy()
    if constrained:
        apply_filter(sb, kind)
    b_norm = np.sqrt(_dot(sb, sb))
    r = np.empty((n, 3))
    z = np.empty((n, 3))
    q = np.empty((n, 3))
    _residual_with(row_ptr, col, values, extra, b, x, r)
    if constrained:
        apply_filter(r, kind)
    if b_norm == 0.0:
        b_norm = 1.0  # nothing to solve for but the prescribed components: absolute test
    _precondition(inv, r, kind, constrained, z, mg, row_ptr, col, values, modes)
    p = z.copy()
    rz = _dot(r, z)
    res = np.sqrt(_dot(r, r)) / b_norm
    it = 0
    while it < max_iter:
        if res <= tol:
            # confirm on the true residual before stopping
            _residual_with(row_ptr, col, values, extra, b, x, r)
            if constrained:
                apply_filter(r, kind)
            res = np.sqrt(_dot(r, r)) / b_norm
            if res <= tol:
                break
            _precondition(inv, r, kind, constrained, z, mg, row_ptr, col, values, modes)
            copy_into(z, p)
            rz = _dot(r, z)
        block_multiply(row_ptr, col, values, p, q)
        if extra is not None and extra[3] > 0:
            pairs_offdiagonal_multiply(extra, p, q, 1.0)
        if constrained:
            apply_filter(q, kind)
        pq = _dot(p, q)
        if pq <= 0.0:
            break
        alpha = rz / pq
        _axpy(alpha, p, x)
        _axpy(-alpha, q, r)
        _precondition(inv, r, kind, constrained, z, mg, row_ptr, col, values, modes)
        rz_new = _dot(r, z)
        _xpby(z, rz_new / rz, p)
        rz = rz_new
        res = np.sqrt(_dot(r, r)) / b_norm
        it += 1
    if it == max_iter:
        _residual_with(row_ptr, col, values, extra, b, x, r)
        if constrained:
            apply_filter(r, kind)
        res = np.sqrt(_dot(r, r)) / b_norm
    return it, res
