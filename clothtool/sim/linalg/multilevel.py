"""The mode multigrid: aggregation whose coarse spaces carry cloth's near-null modes
(``solver.preconditioner: amg``), a V-cycle used as the PCG preconditioner.

Its pieces, each a module, in the order pyamg's ``smoothed_aggregation_solver`` names them:

- :mod:`~clothtool.sim.linalg.aggregation`: the aggregates and coarse patterns, once per mesh;
- :mod:`~clothtool.sim.linalg.modes`: the prolongators, rebuilt from the positions at the start
  of every Newton minimisation (:meth:`ModeMultigrid.update`): each aggregate's rigid motions
  and in-plane shears, unsmoothed (one block per row of P);
- :mod:`~clothtool.sim.linalg.galerkin`: the coarse operators Pᵀ A P of every level, per solve
  (:meth:`ModeMultigrid.setup`);
- :mod:`~clothtool.sim.linalg.relaxation`: symmetric block Gauss–Seidel on every level,
  a forward sweep before the coarse correction and a backward one after it (on the fine and
  the first coarse level reading single-precision copies of their matrices, ``SMOOTHER``), and
  a dense Cholesky factor of the coarsest level;
- here: the levels and the cycle (:func:`mode_cycle`).

The fine operator is the filtered S A S + (I − S) that PCG works with: pinned vertices have no
modes and keep a zero correction. The cycle is a symmetric positive definite operator, a
valid CG preconditioner. The pair operator of contact (its off-diagonal blocks, applied
matrix-free) is not in the matrix and so not in the coarse levels, as in
:mod:`~clothtool.sim.linalg.multigrid`.

The prolongators depend on the positions where they were built and on nothing a run carries
from one step to the next, so a resumed run builds the same ones as an uninterrupted run.
"""

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.linalg.aggregation import coarsen, transposes
from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.linalg.galerkin import galerkin, pinned_mask
from clothtool.sim.linalg.modes import (M, coarse_prolongator, coarser_sums, fine_prolongator,
                                        node_frames, node_sums)
from clothtool.sim.linalg.relaxation import (BACKWARD, FORWARD, block_inverses, block_jacobi,
                                             cholesky, cholesky_solve, forward_from_zero,
                                             forward_from_zero3, gauss_seidel, gauss_seidel3,
                                             residual)

COARSEST = 16  # nodes at which the hierarchy stops (a dense Cholesky of ≤ 8·16 unknowns)
# a vertex whose diagonal block exceeds this many times its inertia floor (a contact barrier near
# its singularity, up to 1e22) is left to the fine level's exact block inverse: in a coarse block
# it would bury every other entry below rounding
STIFF = 1e8
# Gauss–Seidel sweeps before and after the coarse correction on the coarse levels below the
# first (one on the fine and first coarse levels): those levels cost a few percent of a cycle,
# and their sweeps are what the V-cycle loses against an exact coarse solve (the captured 64²
# sheet systems of ``benchmarks linalg``, PCG to the run's tolerances: 20.6 iterations a solve
# with one sweep, 16.4 with three, 15.7 with four)
SWEEPS = 4
# the sweeps of the fine and the first coarse level read single-precision copies of their
# matrices (values clamped to its range; the diagonal blocks and their inverses stay double), in
# double-precision arithmetic: the cycle is then exactly that of those matrices rounded to single
# precision, a fixed symmetric positive definite operator, and the sweeps, which at 256² wait on
# memory, read half the bytes. PCG's products and residuals stay in double precision, so no
# solve is less accurate. The captured sheet systems of ``benchmarks linalg``: the same
# iteration counts; the fine copy 0.90× the CPU per solve at 64²; the first coarse level's
# (at 256² its 8×8 blocks hold 34 MB in double), with the forward sweeps' residual from the
# blocks left of the diagonal alone: a cycle at 256² 33.8 → 25.8 ms
SMOOTHER = np.float32


class ModeMultigrid:
    """The levels of a mesh's mode multigrid, flattened into arrays for numba (:attr:`modes`).

    Level 0 is the matrix pattern; its aggregates follow the triangle graph, the coarser ones
    each coarse pattern. Coarse level c (c = 0 the first) has nodes node_off[c]:node_off[c+1]
    of the coarse arrays, blocks block_off[c]:block_off[c+1] and its CSR row pointers at
    row_off[c] (local indices)."""

    def __init__(self, pattern, faces, smoother=SMOOTHER):
        triangles = BlockPattern(pattern.n, faces)
        levels, maps = coarsen(pattern.row_ptr, pattern.col,
                               (triangles.row_ptr, triangles.col), COARSEST)
        if not maps:
            raise ValueError("the mode multigrid needs a mesh with more than COARSEST vertices")
        coarse = levels[1:]
        sizes = [len(rp) - 1 for rp, _ in coarse]
        self.n = pattern.n
        self.sizes = sizes
        self.diag = pattern.diag
        self.agg0, self.slot0 = maps[0]
        self.node_off = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.block_off = np.concatenate([[0], np.cumsum([len(c) for _, c in coarse])]).astype(
            np.int64)
        self.row_off = np.concatenate([[0], np.cumsum([s + 1 for s in sizes])]).astype(np.int64)
        self.row_ptr = np.concatenate([rp for rp, _ in coarse]).astype(np.int64)
        self.col = np.concatenate([c for _, c in coarse]).astype(np.int64)
        self.cdiag = [np.searchsorted(self.col[self.block_off[c]:self.block_off[c + 1]]
                                      + np.repeat(np.arange(n) * n, np.diff(rp)),
                                      np.arange(n) * (n + 1)).astype(np.int64)
                      for c, (n, (rp, _)) in enumerate(zip(sizes, coarse))]
        total = self.node_off[-1]
        self.cagg = np.concatenate([a for a, _ in maps[1:]] + [np.zeros(sizes[-1], np.int64)])
        self.cslot = [m for _, m in maps[1:]]
        self.mirror = [transposes(rp, c) for rp, c in coarse]
        self.q0 = np.zeros((pattern.n, 3, M))  # the modes of every free vertex (update)
        self.q = np.zeros((pattern.n, 3, M))  # those the coarse levels take this solve (setup)
        self.dinv0 = np.zeros((pattern.n, 3, 3))
        self.values = np.zeros((self.block_off[-1], M, M))
        self.dinv = np.zeros((total, M, M))
        self.transfer = np.zeros((total, M, M))
        self.coarsest = np.zeros((M * sizes[-1], M * sizes[-1]))
        self.skip = [np.zeros(s, dtype=np.bool_) for s in sizes]
        self.fine = np.zeros((len(pattern.col), 3, 3), dtype=smoother)
        self.fine_mirror = transposes(pattern.row_ptr, pattern.col)
        self.diagonal = np.zeros((pattern.n, 3, 3))  # the fine diagonal blocks, one after another
        self.first = np.zeros((self.block_off[1], M, M), dtype=smoother)  # first coarse level
        # the kernels unpack it by position: 0–13 the levels, 14–17 the cycle's work arrays
        # (r, z, t on the coarse levels, t0 the fine residual), 18 the fine diagonal slots,
        # 19 and 20 the single-precision copies of the fine and first coarse level, 21 the fine
        # diagonal blocks in double precision
        self.modes = (self.q, self.agg0, self.dinv0, self.node_off, self.block_off,
                       self.row_off, self.row_ptr, self.col, self.values, self.dinv,
                       self.transfer, self.cagg, self.coarsest, np.concatenate(self.cdiag),
                       np.zeros((total, M)), np.zeros((total, M)), np.zeros((total, M)),
                       np.zeros((pattern.n, 3)), pattern.diag, self.fine, self.first,
                       self.diagonal)

    def _level(self, c):
        """Coarse level c's (row_ptr, col, values, nodes slice)."""
        lo, hi = self.node_off[c], self.node_off[c + 1]
        r0 = self.row_off[c]
        b0, b1 = self.block_off[c], self.block_off[c + 1]
        return (self.row_ptr[r0:r0 + hi - lo + 1], self.col[b0:b1], self.values[b0:b1],
                slice(lo, hi))

    def update(self, x, constraints):
        """The prolongators at positions x (N, 3): every level's aggregates' modes
        (:mod:`~clothtool.sim.linalg.modes`)."""
        free = ~pinned_mask(constraints.kind, constraints.active)
        count, first, second = node_sums(x, free, self.agg0, self.sizes[0])
        centroid, radius, frame = node_frames(count, first, second)
        fine_prolongator(x, free, self.agg0, centroid, radius, frame, self.q0)
        for c in range(len(self.sizes)):
            self.skip[c] = count == 0.0
            if c + 1 == len(self.sizes):
                break
            nodes = self._level(c)[3]
            agg = self.cagg[nodes]
            sums = coarser_sums(count, first, second, agg, self.sizes[c + 1])
            geometry = node_frames(*sums)
            coarse_prolongator(count, centroid, radius, frame, agg, *geometry,
                               self.transfer[nodes])
            (count, first, second), (centroid, radius, frame) = sums, geometry

    def setup(self, matrix, constraints):
        """Per solve: the fine diagonal inverses, every level's Galerkin operator and diagonal
        inverses, the coarsest level's Cholesky factor. Pinned vertices and those held by a
        stiff barrier (``STIFF``) take no part in the coarse levels."""
        np.take(matrix.values, matrix.pattern.diag, axis=0, out=self.diagonal)
        held = pinned_mask(constraints.kind, constraints.active) | _stiff(self.diagonal,
                                                                          matrix.floor)
        block_jacobi(matrix.values, matrix.pattern.diag, constraints.kind, matrix.floor,
                     self.dinv0)
        _single(matrix.values, self.fine_mirror, float(np.finfo(self.fine.dtype).max),
                self.fine)
        self.q[:] = self.q0
        self.q[held] = 0.0
        galerkin(matrix.row_ptr, matrix.col, matrix.values, held, self.slot0, self.mirror[0],
                 self.q, self._level(0)[2])
        for c in range(len(self.sizes)):
            level = self._level(c)
            if c > 0:
                galerkin(row_ptr, col, values, skip, slot_map, self.mirror[c], p, level[2])
            if c + 1 < len(self.sizes):
                block_inverses(level[2], self.cdiag[c], self.skip[c], self.dinv[level[3]])
                row_ptr, col, values = level[:3]
                skip, slot_map, p = self.skip[c], self.cslot[c], self.transfer[level[3]]
        _clamped(self._level(0)[2], float(np.finfo(self.first.dtype).max), self.first)
        _dense(*self._level(len(self.sizes) - 1)[:3], self.coarsest)
        cholesky(self.coarsest)
        self.matrix = matrix

    def apply(self, rhs, out):
        """out = B rhs, one cycle of the matrix of the last :meth:`setup`."""
        m = self.matrix
        mode_cycle(rhs, out, m.row_ptr, m.col, m.values, self.modes)


def _stiff(diagonal, floor):
    """The vertices whose diagonal block (``diagonal``: (n, 3, 3)) has a trace above ``STIFF``
    times 3·floor."""
    trace = np.einsum("vii->v", diagonal)
    return (floor > 0.0) & (trace > 3.0 * STIFF * floor)


@njit(cache=True)
def _single(values, mirror, big, out):
    """out = values in out's precision, clamped to its largest finite magnitude ``big`` (a contact
    barrier's block near its singularity must not become infinite: its vertex's zero modes would
    multiply it into NaN); each block below the diagonal the transpose of its mirror above
    (``mirror``: the slot of each block's transpose), so the copy is exactly symmetric and the
    forward and backward sweeps are each other's transposes."""
    for s in range(values.shape[0]):
        t = mirror[s]
        for p in range(3):
            for q in range(3):
                v = values[s, p, q] if t >= s else values[t, q, p]
                out[s, p, q] = min(max(v, -big), big)


@njit(cache=True)
def _clamped(values, big, out):
    """out = values in out's precision, clamped to its largest finite magnitude ``big`` (the
    Galerkin operators are exactly symmetric, and so is the copy)."""
    for s in range(values.shape[0]):
        for p in range(values.shape[1]):
            for q in range(values.shape[2]):
                out[s, p, q] = min(max(values[s, p, q], -big), big)


@njit(cache=True)
def _dense(row_ptr, col, values, out):
    """out = the level's block matrix as a dense array."""
    m = values.shape[1]
    out[:, :] = 0.0
    for i in range(row_ptr.shape[0] - 1):
        for s in range(row_ptr[i], row_ptr[i + 1]):
            j = col[s]
            for p in range(m):
                for q in range(m):
                    out[m * i + p, m * j + q] = values[s, p, q]


@njit(cache=True)
def _restrict(p, agg, src, dst):
    """dst[agg[i]] += p[i]ᵀ src[i] (Pᵀ), dst zeroed first."""
    dst[:, :] = 0.0
    for i in range(src.shape[0]):
        _transfer(p[i], src[i], dst[agg[i]], True)


@njit(cache=True)
def _prolong(p, agg, src, dst):
    """dst[i] += p[i] src[agg[i]] (P)."""
    for i in range(dst.shape[0]):
        _transfer(p[i], src[agg[i]], dst[i], False)


@njit(cache=True)
def _restrict3(q, agg, src, dst):
    """:func:`_restrict` from the fine level (3×M blocks), unrolled."""
    dst[:, :] = 0.0
    for i in range(src.shape[0]):
        a = agg[i]
        s0, s1, s2 = src[i, 0], src[i, 1], src[i, 2]
        b = q[i]
        for c in range(M):
            dst[a, c] += b[0, c] * s0 + b[1, c] * s1 + b[2, c] * s2


@njit(cache=True)
def _prolong3(q, agg, src, dst):
    """:func:`_prolong` to the fine level (3×M blocks), unrolled."""
    for i in range(dst.shape[0]):
        s = src[agg[i]]
        b = q[i]
        v0 = v1 = v2 = 0.0
        for c in range(M):
            v0 += b[0, c] * s[c]
            v1 += b[1, c] * s[c]
            v2 += b[2, c] * s[c]
        dst[i, 0] += v0
        dst[i, 1] += v1
        dst[i, 2] += v2


@njit(cache=True, inline="always")
def _transfer(block, src, dst, transpose):
    """dst += block src, or blockᵀ src with ``transpose`` (one node's share of P or Pᵀ)."""
    rows, cols = block.shape
    if transpose:
        for c in range(cols):
            v = 0.0
            for r in range(rows):
                v += block[r, c] * src[r]
            dst[c] += v
    else:
        for r in range(rows):
            v = 0.0
            for c in range(cols):
                v += block[r, c] * src[c]
            dst[r] += v


@njit(cache=True)
def _coarse_vcycle(mg, r, z, t):
    """z = a V-cycle on the coarse levels for right-hand side r on the first of them (the first
    level's sweeps reading its single-precision copy, its diagonal blocks the double ones)."""
    (_, _, _, node_off, block_off, row_off, c_row_ptr, c_col, c_values, c_dinv,
     transfer, c_agg, coarsest, c_diag) = mg[:14]
    first = mg[20]  # the first coarse level's single-precision copy
    levels = node_off.shape[0] - 1
    for c in range(levels - 1):  # down: pre-smooth, restrict the residual
        lo, hi = node_off[c], node_off[c + 1]
        rp = c_row_ptr[row_off[c]:row_off[c] + hi - lo + 1]
        cl, vals = c_col[block_off[c]:block_off[c + 1]], c_values[block_off[c]:block_off[c + 1]]
        if c == 0:
            forward_from_zero(rp, cl, c_diag[lo:hi], first, vals, c_dinv[lo:hi], r[lo:hi],
                              z[lo:hi], t[lo:hi])
        else:
            forward_from_zero(rp, cl, c_diag[lo:hi], vals, vals, c_dinv[lo:hi], r[lo:hi],
                              z[lo:hi], t[lo:hi])
            for _ in range(SWEEPS - 1):
                gauss_seidel(rp, cl, c_diag[lo:hi], vals, c_dinv[lo:hi], r[lo:hi], z[lo:hi],
                             FORWARD)
            residual(rp, cl, vals, r[lo:hi], z[lo:hi], t[lo:hi])
        _restrict(transfer[lo:hi], c_agg[lo:hi], t[lo:hi], r[hi:node_off[c + 2]])
    last = levels - 1
    cholesky_solve(coarsest, r[node_off[last]:node_off[last + 1]],
                   z[node_off[last]:node_off[last + 1]])
    for c in range(levels - 2, -1, -1):  # up: prolong the correction, post-smooth
        lo, hi = node_off[c], node_off[c + 1]
        rp = c_row_ptr[row_off[c]:row_off[c] + hi - lo + 1]
        cl, vals = c_col[block_off[c]:block_off[c + 1]], c_values[block_off[c]:block_off[c + 1]]
        _prolong(transfer[lo:hi], c_agg[lo:hi], z[hi:node_off[c + 2]], z[lo:hi])
        if c == 0:
            gauss_seidel(rp, cl, c_diag[lo:hi], first, c_dinv[lo:hi], r[lo:hi], z[lo:hi],
                         BACKWARD)
        else:
            for _ in range(SWEEPS):
                gauss_seidel(rp, cl, c_diag[lo:hi], vals, c_dinv[lo:hi], r[lo:hi], z[lo:hi],
                             BACKWARD)


@njit(cache=True)
def mode_cycle(rhs, out, row_ptr, col, values, mg):
    """out = B rhs: a forward block Gauss–Seidel sweep, the coarse correction (a V-cycle on the
    coarse levels, the coarsest solved by its Cholesky factor), a backward sweep."""
    q0, agg0, dinv0, node_off = mg[:4]
    r, z, t, t0, diag, single, _, diagonal = mg[14:22]
    forward_from_zero3(row_ptr, col, diag, single, diagonal, dinv0, rhs, out, t0)
    lo, hi = node_off[0], node_off[1]
    _restrict3(q0, agg0, t0, r[lo:hi])
    _coarse_vcycle(mg, r, z, t)
    _prolong3(q0, agg0, z[lo:hi], out)
    gauss_seidel3(row_ptr, col, diag, single, dinv0, rhs, out, False)
