"""Galerkin coarse operators A_c = Pᵀ A P for prolongators with one block per row.

With unsmoothed aggregation every node i of a level belongs to one aggregate a(i) of the next,
and P's block row i is a single block P_i (:mod:`~clothtool.sim.linalg.modes`), so

    A_c[a(i), a(j)] = Σ P_iᵀ A_ij P_j

is one pass over the blocks of the level, each summed into the coarse slot its ``slot_map``
names (Vaněk, Mandel & Brezina 1996; pyamg's ``galerkin`` does the same with sparse
products). The blocks of a row that land in one coarse slot are first summed as A_ij P_j, so
the left product P_iᵀ(…) is taken once per coarse slot of the row, not once per block.

The prolongators' blocks start with the identity (a node's translations are its aggregate's,
:mod:`~clothtool.sim.linalg.modes`): the fine P_i = [I₃ | C_i] (C_i 3×5) and the coarse
T_a = [[I₃, X_a], [0, Y_a]] (X_a 3×5, Y_a 5×5). The products skip what the identity and the zero
block make trivial.
"""

import numpy as np
from numba import njit

from clothtool.sim.linalg.filter import PINNED
from clothtool.sim.linalg.modes import M

SLOTS_PER_ROW = 64  # distinct coarse slots one row can reach (a row has at most a few dozen blocks)


@njit(cache=True)
def _slot(slots, used, target, acc):
    """The index of coarse slot ``target`` among the row's ``used`` slots, a new (zeroed) one if
    it is not there yet; returns (index, used)."""
    k = 0
    while k < used and slots[k] != target:
        k += 1
    if k == used:
        slots[k] = target
        acc[k] = 0.0
        used += 1
    return k, used


@njit(cache=True)
def galerkin_fine(row_ptr, col, values, skip, slot_map, p, out):
    """out = Pᵀ A P for the fine level: ``values`` (nnzb, 3, 3), ``p`` (n, 3, M) with p[i] =
    [I₃ | C_i]; rows and columns of nodes with ``skip`` set (pinned vertices) are left out."""
    out[:, :, :] = 0.0
    acc = np.zeros((SLOTS_PER_ROW, 3, M))
    slots = np.empty(SLOTS_PER_ROW, np.int64)
    for i in range(row_ptr.shape[0] - 1):
        if skip[i]:
            continue
        used = 0
        for s in range(row_ptr[i], row_ptr[i + 1]):
            j = col[s]
            if skip[j]:
                continue
            k, used = _slot(slots, used, slot_map[s], acc)
            a = values[s]
            w = acc[k]
            pj = p[j]
            for r in range(3):
                a0, a1, a2 = a[r, 0], a[r, 1], a[r, 2]
                w[r, 0] += a0
                w[r, 1] += a1
                w[r, 2] += a2
                for c in range(3, M):
                    w[r, c] += a0 * pj[0, c] + a1 * pj[1, c] + a2 * pj[2, c]
        pi = p[i]
        for k in range(used):
            o = out[slots[k]]
            w = acc[k]
            for c in range(M):
                w0, w1, w2 = w[0, c], w[1, c], w[2, c]
                o[0, c] += w0
                o[1, c] += w1
                o[2, c] += w2
                for r in range(3, M):
                    o[r, c] += pi[0, r] * w0 + pi[1, r] * w1 + pi[2, r] * w2


@njit(cache=True)
def galerkin_coarse(row_ptr, col, values, skip, slot_map, t, out):
    """out = Tᵀ A T for a coarse level: ``values`` (nnzb, M, M), ``t`` (n, M, M) with t[a] =
    [[I₃, X_a], [0, Y_a]]; nodes with ``skip`` set (no free vertex) are left out."""
    out[:, :, :] = 0.0
    acc = np.zeros((SLOTS_PER_ROW, M, M))
    slots = np.empty(SLOTS_PER_ROW, np.int64)
    for i in range(row_ptr.shape[0] - 1):
        if skip[i]:
            continue
        used = 0
        for s in range(row_ptr[i], row_ptr[i + 1]):
            j = col[s]
            if skip[j]:
                continue
            k, used = _slot(slots, used, slot_map[s], acc)
            a = values[s]
            w = acc[k]
            tj = t[j]
            for r in range(M):
                for c in range(3):
                    w[r, c] += a[r, c]
                for c in range(3, M):
                    v = 0.0
                    for q in range(M):
                        v += a[r, q] * tj[q, c]
                    w[r, c] += v
        ti = t[i]
        for k in range(used):
            o = out[slots[k]]
            w = acc[k]
            for c in range(M):
                for r in range(3):
                    o[r, c] += w[r, c]
                for r in range(3, M):
                    v = 0.0
                    for q in range(M):
                        v += ti[q, r] * w[q, c]
                    o[r, c] += v


def pinned_mask(kind, constrained):
    """The ``skip`` of :func:`galerkin_fine` under the constraint filter: the pinned vertices."""
    if constrained:
        return kind == PINNED
    return np.zeros(len(kind), dtype=np.bool_)
