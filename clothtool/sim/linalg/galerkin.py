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
T_a = [[I₃, X_a], [0, Y_a]] (X_a 3×5, Y_a 5×5). The products skip what the identity makes trivial,
and the zeros the modes put in the other columns: a rotation's column e_k × d has no k-th
entry, and a node's own rotations and shears do not mix (Y_a = diag(ρ_a/ρ_A I₃, S_a), S_a 2×2).
"""

import numpy as np

from clothtool.numba_setup import njit
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


@njit(cache=True, inline="always")
def _mode_dot(p, c, y, b):
    """Σ_q y[q] p[q, c] over the q where column c of a block p (b × M) of the modes' form can be
    non-zero: the rotation c = 3 + k has no k-th translation row; on a coarse level (b = M) a
    rotation's column has its own rotation alone below the translations, a shear's the two
    shears."""
    v = 0.0
    for q in range(3):
        if q + 3 != c:
            v += y[q] * p[q, c]
    if b == M:
        if c < 6:
            v += y[c] * p[c, c]
        else:
            v += y[6] * p[6, c]
            v += y[7] * p[7, c]
    return v


@njit(cache=True, inline="always")
def _right(a, p, out, b):
    """out += a p for a b×b block a and a block p (b × M) of the modes' form (the module):
    p[:, :3] = [I₃; 0] (b a constant of the caller's branch, so the loops unroll)."""
    for r in range(b):
        for c in range(3):
            out[r, c] += a[r, c]
        for c in range(3, M):
            out[r, c] += _mode_dot(p, c, a[r], b)


@njit(cache=True, inline="always")
def _left(p, acc, out, b):
    """out += pᵀ acc for a block p (b × M) of the modes' form and acc (b × M)."""
    for r in range(3):
        for c in range(M):
            out[r, c] += acc[r, c]
    for r in range(3, M):
        for c in range(M):
            out[r, c] += _mode_dot(p, r, acc[:, c], b)


@njit(cache=True)
def galerkin(row_ptr, col, values, skip, slot_map, mirror, p, out):
    """out = Pᵀ A P: ``values`` (nnzb, b, b) the level's blocks, ``p`` (n, b, M) its
    prolongator's, of the modes' form (the module: the fine P_i = [I₃ | C_i], b = 3, and the
    coarse T_a = [[I₃, X_a], [0, Y_a]], b = M, zero where the modes are); rows and
    columns of nodes with ``skip`` set (pinned vertices, nodes without a free vertex) are left
    out. A_c is symmetric: only its blocks on and above the diagonal are summed, those below are
    their transposes (``mirror``: the slot of each coarse block's transpose,
    :func:`~clothtool.sim.linalg.aggregation.transposes`)."""
    if values.shape[1] == 3:
        _galerkin(row_ptr, col, values, skip, slot_map, mirror, p, out, 3)
    else:
        _galerkin(row_ptr, col, values, skip, slot_map, mirror, p, out, M)
    for t in range(out.shape[0]):  # scalar loops: an array assignment costs seconds of compilation
        u = mirror[t]
        if u > t:
            for p in range(out.shape[1]):
                for q in range(out.shape[2]):
                    out[u, p, q] = out[t, q, p]


@njit(cache=True, inline="always")
def _galerkin(row_ptr, col, values, skip, slot_map, mirror, p, out, b):
    """:func:`galerkin`'s blocks on and above the diagonal, for blocks of the constant size b."""
    out[:, :, :] = 0.0
    acc = np.zeros((SLOTS_PER_ROW, b, M))
    slots = np.empty(SLOTS_PER_ROW, np.int64)
    for i in range(row_ptr.shape[0] - 1):
        if skip[i]:
            continue
        used = np.int64(0)  # not the literal 0: numba would compile _slot for it too
        for s in range(row_ptr[i], row_ptr[i + 1]):  # acc[slot] += A_ij P_j
            j = col[s]
            if skip[j] or mirror[slot_map[s]] < slot_map[s]:
                continue
            k, used = _slot(slots, used, slot_map[s], acc)
            _right(values[s], p[j], acc[k], b)
        for k in range(used):  # out[slot] += P_iᵀ acc[slot]
            _left(p[i], acc[k], out[slots[k]], b)


def pinned_mask(kind, constrained):
    """The ``skip`` of :func:`galerkin` on the fine level under the constraint filter: the
    pinned vertices."""
    if constrained:
        return kind == PINNED
    return np.zeros(len(kind), dtype=np.bool_)
