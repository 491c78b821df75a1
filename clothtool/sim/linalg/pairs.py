"""The pair operator: a sum of small Hessians Σ_k (w_k w_kᵀ) ⊗ B_k over vertex stencils.

Contact fills it (:mod:`clothtool.sim.solve.contact`), and the PCG applies it (:mod:`clothtool.sim.linalg.pcg`): each barrier pair with its Gauss–Newton
block B = c n nᵀ along its normal, each friction pair with its tangent block (see
:mod:`clothtool.contact.friction`), on the closest-point weights w_k of its four vertices.
The diagonal 3×3 blocks go into the system matrix (so that its preconditioners see them),
the rest is applied matrix-free inside the PCG; only the unknowns (vertices below n) take
part, the others are held and enter through :func:`pairs_coupling`.

The operator is the tuple (rows (K, 4) int64, weights (K, 4), blocks (K, 3, 3), count, n).
"""

import numpy as np

from clothtool.numba_setup import njit


def pair_operator(rows, weights, blocks, count, n):
    """The tuple the functions below take."""
    return (rows, weights, blocks, np.int64(count), np.int64(n))


@njit(cache=True)
def pairs_offdiagonal_multiply(operator, v, out, scale):
    """out += scale (H − blockdiag H) v over the unknowns (vertices below n)."""
    rows, weights, blocks, count, n = operator
    bv = np.empty(3)
    for k in range(count):
        st = rows[k]
        s0 = s1 = s2 = 0.0
        for j in range(4):
            if st[j] < n and weights[k, j] != 0.0:
                s0 += weights[k, j] * v[st[j], 0]
                s1 += weights[k, j] * v[st[j], 1]
                s2 += weights[k, j] * v[st[j], 2]
        b = blocks[k]
        for j in range(4):
            vj = st[j]
            wj = weights[k, j]
            if vj < n and wj != 0.0:
                o0 = s0 - wj * v[vj, 0]
                o1 = s1 - wj * v[vj, 1]
                o2 = s2 - wj * v[vj, 2]
                for i in range(3):
                    bv[i] = b[i, 0] * o0 + b[i, 1] * o1 + b[i, 2] * o2
                c = scale * wj
                for i in range(3):
                    out[vj, i] += c * bv[i]


@njit(cache=True)
def pairs_coupling(operator, dy, out, scale):
    """out += scale H_uh dy_h: the blocks between the unknowns (below n) and the held
    vertices (n and above), applied to the held vertices' part of dy."""
    rows, weights, blocks, count, n = operator
    for k in range(count):
        st = rows[k]
        s0 = s1 = s2 = 0.0
        for j in range(4):
            if st[j] >= n:
                s0 += weights[k, j] * dy[st[j], 0]
                s1 += weights[k, j] * dy[st[j], 1]
                s2 += weights[k, j] * dy[st[j], 2]
        if s0 == 0.0 and s1 == 0.0 and s2 == 0.0:
            continue
        b = blocks[k]
        for j in range(4):
            if st[j] < n:
                c = scale * weights[k, j]
                for i in range(3):
                    out[st[j], i] += c * (b[i, 0] * s0 + b[i, 1] * s1 + b[i, 2] * s2)


@njit(cache=True)
def pairs_add_diagonal(operator, diag, values):
    """values[diag[v]] += Σ_k w_kv² B_k for the unknowns v < n (``diag``: each vertex's
    diagonal slot in the block matrix ``values``)."""
    rows, weights, blocks, count, n = operator
    for k in range(count):
        st = rows[k]
        for j in range(4):
            if st[j] < n:
                s = weights[k, j] * weights[k, j]
                if s == 0.0:
                    continue
                b = values[diag[st[j]]]
                for p in range(3):
                    for q in range(3):
                        b[p, q] += s * blocks[k, p, q]
