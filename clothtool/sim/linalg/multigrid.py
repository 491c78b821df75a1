"""Aggregation multigrid, used as the PCG preconditioner (``solver.preconditioner``).

Block-Jacobi PCG needs O(√κ) iterations and κ grows like k h²/m, so stiff cloth
at one step per frame takes hundreds. A multilevel preconditioner removes the
smooth error that Jacobi cannot reach:

- **Setup, once per mesh** (only the pattern): greedy aggregation
  (:mod:`~clothtool.sim.linalg.aggregation`) of the triangle adjacency, then of each coarse
  pattern, until at most ``COARSEST`` nodes remain.
- **Per solve**: with piecewise-constant prolongation P, the Galerkin coarse
  matrix PᵀAP is the sum of the fine 3×3 blocks over each slot map — one pass.
  The fine operator is the filtered S A S + (I − S) that PCG works with, so
  coarse levels see pinned vertices as held. The coarsest level is
  factored densely (Cholesky).
- **Cycle**: on the finest level additive, B = ωD⁻¹ + P B₁ Pᵀ (no product with
  the fine matrix: that costs more than the iterations it saves); on the coarse
  levels a multiplicative V-cycle B₁ with one block-Jacobi sweep ωD⁻¹ before and
  one after each coarse correction. Both parts are symmetric positive definite,
  so B is a valid PCG preconditioner. Measured on the hanging sheet at 64×64
  (tolerance 1e-3): 114 iterations instead of more than 500 with block Jacobi.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner
from clothtool.sim.linalg.filter import FREE, PINNED
from clothtool.sim.linalg.aggregation import coarsen
from clothtool.sim.linalg.blocks import BlockPattern
from clothtool.sim.linalg.relaxation import cholesky, cholesky_solve
from clothtool.vec3 import cofactor_inverse3, copy_into, eigen_inverse3

COARSEST = 48  # nodes at which the hierarchy stops (dense Cholesky of ≤ 3·48 unknowns)
OMEGA = 0.6  # Jacobi smoothing weight (λmax(D⁻¹A) ≤ 2 for these matrices)


class Hierarchy:
    """The multigrid preconditioner: levels of coarse patterns, flattened into arrays with
    per-level offsets for numba (:attr:`arrays`).

    Level 0 is the matrix pattern (``row_ptr``, ``col``); its aggregation follows
    ``graph`` = (row_ptr, col) of the triangle adjacency (bending widens the
    matrix pattern, which would make aggregates too large).
    """

    @classmethod
    def for_mesh(cls, pattern, faces):
        """The hierarchy of a matrix pattern whose aggregation follows the triangles."""
        triangles = BlockPattern(pattern.n, faces)
        return cls(pattern.row_ptr, pattern.col, graph=(triangles.row_ptr, triangles.col))

    def setup(self, matrix, constraints):
        """Coarse matrices of a :class:`~clothtool.sim.linalg.blocks.BlockMatrix` filtered by a
        :class:`~clothtool.sim.linalg.blocks.ConstraintFilter` (done again inside every solve)."""
        pending = setup_levels(matrix.values, constraints.kind, constraints.active,
                               matrix.floor, self.arrays, self.pending, self.pending_floor)
        if pending:  # blocks that lost their small eigenvalues (contact barriers)
            eigen_inverses(self.diag_inv, self.pending[:pending], self.pending_floor[:pending])

    def update(self, x, constraints):
        """Nothing depends on the positions."""

    def apply(self, rhs, out):
        """out = B rhs (one cycle; :meth:`setup` first)."""
        vcycle(rhs, out, self.arrays)

    def __init__(self, row_ptr, col, graph):
        levels, aggs = coarsen(row_ptr, col, graph, COARSEST)
        if not aggs:
            raise ValueError("multigrid needs a mesh with more than COARSEST vertices")
        sizes = [len(rp) - 1 for rp, _ in levels]
        nnz = [len(cl) for _, cl in levels]
        self.node_off = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.block_off = np.concatenate([[0], np.cumsum(nnz)]).astype(np.int64)
        self.row_ptr = np.concatenate([rp for rp, _ in levels]).astype(np.int64)
        self.row_off = np.concatenate([[0], np.cumsum([s + 1 for s in sizes])]).astype(np.int64)
        self.col = np.concatenate([cl for _, cl in levels]).astype(np.int64)
        self.agg = np.concatenate([a for a, _ in aggs]).astype(np.int64)
        self.slot_map = np.concatenate([m for _, m in aggs]).astype(np.int64)
        # coarse matrices only (levels ≥ 1): values[s − block_off[1]] is block s
        self.values = np.zeros((self.block_off[-1] - self.block_off[1], 3, 3))
        self.diag_inv = np.zeros((self.node_off[-1], 3, 3))
        self.coarsest = np.zeros((3 * sizes[-1], 3 * sizes[-1]))
        self.r = np.zeros((self.node_off[-1], 3))
        self.z = np.zeros((self.node_off[-1], 3))
        self.t = np.zeros((self.node_off[-1], 3))
        # the diagonal blocks setup_levels leaves to eigen_inverses: nodes and floors
        self.pending = np.zeros(self.node_off[-1], np.int64)
        self.pending_floor = np.zeros(self.node_off[-1])
        # the tuple the numba kernels take
        self.arrays = (self.node_off, self.block_off, self.row_ptr, self.row_off, self.col,
                       self.agg, self.slot_map, self.values, self.diag_inv, self.coarsest, self.r,
                       self.z, self.t)


@njit_inner(cache=True)
def _filtered_block(b, i, j, kind, out):
    """out = S_i B S_j (+ (I − S_i) on the diagonal, so pinned vertices stay non-singular)."""
    copy_into(b, out)
    if kind[i] == PINNED or kind[j] == PINNED:
        out[:, :] = 0.0
    if i == j and kind[i] == PINNED:
        for p in range(3):
            out[p, p] = 1.0


@njit(cache=True)
def setup_levels(fine, kind, constrained, floor, mg, pending, pending_floor):
    """Coarse matrices, block-diagonal inverses of every level, Cholesky of the coarsest.

    ``floor`` (N,): a lower bound of the eigenvalues of each fine diagonal block (the inertia
    m/ĥ²; zeros when unknown). A coarse block's bound is the sum of its aggregate's (the
    Galerkin block of an aggregate is Σ its fine blocks, PSD terms on top of Σ floors I); a
    pinned vertex's filtered block is I (bound 1).
    The block inverses keep to these bounds (:func:`~clothtool.vec3.spd_inverse3`): contact
    barriers near their singularity store blocks of 1e22·m/ĥ² whose small eigenvalues
    rounding has erased, and the plain cofactor inverse divided by a zero determinant.
    Those blocks (:func:`~clothtool.vec3.cofactor_inverse3` False) are left to
    :func:`eigen_inverses`: each stays in its slot of the inverses, its node and bound in
    ``pending`` and ``pending_floor``; returns their number."""
    node_off, block_off, row_ptr, row_off, col, agg, slot_map, values, diag_inv, coarsest = mg[:10]
    levels = node_off.shape[0] - 1
    base = block_off[1]
    values[:, :, :] = 0.0
    bound = np.empty(node_off[-1])  # zeros, in a loop: np.zeros compiles overloads of its own
    for i in range(node_off[-1]):
        bound[i] = 0.0
    block = np.empty((3, 3))
    count = 0
    # level 0: filtered fine blocks → diagonal inverses and the level-1 sums
    for i in range(node_off[1]):
        lower = floor[i]
        if constrained and kind[i] == PINNED:
            lower = 1.0
        bound[i] = lower
        bound[node_off[1] + agg[i]] += lower
        for s in range(row_ptr[i], row_ptr[i + 1]):
            j = col[s]
            if constrained and (kind[i] != FREE or kind[j] != FREE):
                _filtered_block(fine[s], i, j, kind, block)
            else:
                copy_into(fine[s], block)
            if j == i and not cofactor_inverse3(block, diag_inv[i]):
                copy_into(block, diag_inv[i])
                pending[count], pending_floor[count] = i, lower
                count += 1
            target = values[slot_map[s]]
            for p in range(3):
                for q in range(3):
                    target[p, q] += block[p, q]
    for lev in range(1, levels):
        n0, b0, r0 = node_off[lev], block_off[lev], row_off[lev]
        for i in range(node_off[lev + 1] - n0):
            if lev < levels - 1:
                bound[node_off[lev + 1] + agg[n0 + i]] += bound[n0 + i]
            for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
                src = values[b0 + s - base]
                if col[b0 + s] == i and not cofactor_inverse3(src, diag_inv[n0 + i]):
                    copy_into(src, diag_inv[n0 + i])
                    pending[count], pending_floor[count] = n0 + i, bound[n0 + i]
                    count += 1
                if lev < levels - 1:
                    target = values[block_off[lev + 1] + slot_map[b0 + s] - base]
                    for p in range(3):
                        for q in range(3):
                            target[p, q] += src[p, q]
    last = levels - 1
    n0, b0, r0 = node_off[last], block_off[last], row_off[last]
    coarsest[:, :] = 0.0
    for i in range(node_off[last + 1] - n0):
        for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
            j = col[b0 + s]
            for p in range(3):
                for q in range(3):
                    coarsest[3 * i + p, 3 * j + q] = values[b0 + s - base, p, q]
    cholesky(coarsest)
    return count


@njit(cache=True)
def eigen_inverses(diag_inv, nodes, floor):
    """diag_inv[v] = :func:`~clothtool.vec3.eigen_inverse3` of the block held there, bound
    floor[k], for the nodes v = nodes[k] :func:`setup_levels` left (its own kernel: a scene
    without contact compiles none of it)."""
    block = np.empty((3, 3))
    for k in range(nodes.shape[0]):
        copy_into(diag_inv[nodes[k]], block)
        eigen_inverse3(block, floor[k], diag_inv[nodes[k]])


@njit_inner(cache=True)
def _coarse_multiply(lev, mg, x, y):
    """y = A_lev x for a coarse level (lev ≥ 1)."""
    node_off, block_off, row_ptr, row_off, col, _, _, values = mg[:8]
    n0, b0, r0, base = node_off[lev], block_off[lev], row_off[lev], block_off[1]
    for i in range(node_off[lev + 1] - n0):
        y0 = 0.0
        y1 = 0.0
        y2 = 0.0
        for s in range(row_ptr[r0 + i], row_ptr[r0 + i + 1]):
            j = n0 + col[b0 + s]
            b = values[b0 + s - base]
            y0 += b[0, 0] * x[j, 0] + b[0, 1] * x[j, 1] + b[0, 2] * x[j, 2]
            y1 += b[1, 0] * x[j, 0] + b[1, 1] * x[j, 1] + b[1, 2] * x[j, 2]
            y2 += b[2, 0] * x[j, 0] + b[2, 1] * x[j, 1] + b[2, 2] * x[j, 2]
        y[n0 + i, 0] = y0
        y[n0 + i, 1] = y1
        y[n0 + i, 2] = y2


@njit_inner(cache=True)
def _jacobi_sweep(lo, hi, diag_inv, res, z):
    """z += ω D⁻¹ res on nodes lo..hi."""
    for i in range(lo, hi):
        b = diag_inv[i]
        for p in range(3):
            z[i, p] += OMEGA * (b[p, 0] * res[i, 0] + b[p, 1] * res[i, 1] + b[p, 2] * res[i, 2])


@njit_inner(cache=True)
def _restrict(lo, hi, c0, agg, src, dst):
    """dst[c0 + agg[i]] += src[i] (Pᵀ)."""
    for i in range(lo, hi):
        c = c0 + agg[i]
        for p in range(3):
            dst[c, p] += src[i, p]


@njit(cache=True)
def vcycle(rhs, out, mg):
    """out = B rhs: ωD⁻¹ rhs + P B₁ Pᵀ rhs, B₁ a V-cycle on the coarse levels."""
    node_off, _, _, _, _, agg, _, _, diag_inv, coarsest, r, z, t = mg
    levels = node_off.shape[0] - 1
    # level 0's nodes 0..n as node_off[0]..: a literal 0 would compile the kernels it is
    # passed to once more (numba specialises a jitted callee on each literal argument)
    first, n = node_off[0], node_off[1]
    r[n:] = 0.0
    _restrict(first, n, n, agg, rhs, r)
    for lev in range(1, levels - 1):  # down: pre-smooth, restrict the residual
        lo, hi = node_off[lev], node_off[lev + 1]
        z[lo:hi] = 0.0
        _jacobi_sweep(lo, hi, diag_inv, r, z)
        _coarse_multiply(lev, mg, z, t)
        for i in range(lo, hi):
            for p in range(3):
                t[i, p] = r[i, p] - t[i, p]
        _restrict(lo, hi, hi, agg, t, r)
    lo, hi = node_off[levels - 1], node_off[levels]
    cholesky_solve(coarsest, r[lo:hi], z[lo:hi])
    for lev in range(levels - 2, 0, -1):  # up: prolong the correction, post-smooth
        lo, hi = node_off[lev], node_off[lev + 1]
        for i in range(lo, hi):
            for p in range(3):
                z[i, p] += z[hi + agg[i], p]
        _coarse_multiply(lev, mg, z, t)
        for i in range(lo, hi):
            for p in range(3):
                t[i, p] = r[i, p] - t[i, p]
        _jacobi_sweep(lo, hi, diag_inv, t, z)
    for i in range(n):  # finest level: additive smoother plus prolonged coarse correction
        for p in range(3):
            out[i, p] = z[n + agg[i], p]
    _jacobi_sweep(first, n, diag_inv, rhs, out)
