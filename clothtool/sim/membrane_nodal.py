"""Node-based smoothed membrane (NS-FEM): Baraff–Witkin stretch and shear on each vertex's
smoothed deformation gradient, so that the sheet bends along any line without stretching.

G. R. Liu, T. Nguyen-Thoi, H. Nguyen-Xuan, K. Y. Lam, "A node-based smoothed finite element
method (NS-FEM) for upper bound solutions to solid mechanics problems", Computers &
Structures 87 (2009) 14–26. Vertex v owns a third of each triangle t around it,
A_v = Σ_{t∋v} A_t/3, and the deformation gradient averaged over that cell,

    F_v = Σ_{t∋v} (A_t/3) F_t / A_v = Σ_j x_j ⊗ (a_vj, b_vj),

a linear map of the ring's positions (a_vj, b_vj: the cell-averaged gradients of vertex j's
hat function, from each triangle's D_r⁻¹). The energy is W = Σ_v A_v Ψ(F_v) with the density Ψ
of :mod:`clothtool.sim.membrane` and the area-weighted mean of the ring's (k_u, k_v, b_u, b_v,
k_shear). An affine map gives every F_t and so every F_v the same value: the patch test holds.

Why: linear triangles lock. A sheet folded smoothly along a line that is no mesh line cannot
keep its triangles' three strains zero (three conditions per triangle, about six per vertex,
against a vertex's three coordinates), so a fabric stiff along warp and weft drapes stiffer
on some meshes than on others. The smoothed gradient sets three conditions per vertex.

Hessian: A_v Σ_jk (a_j, b_j) H_F⁺ (a_k, b_k)ᵀ, H_F⁺ the projected ∂²Ψ/∂vec F² of
:func:`clothtool.sim.membrane.membrane_element`; it couples a vertex with its two-ring.
"""

import numpy as np
from numba import njit

from clothtool.sim.membrane import _density, _shear_hessian, _stress, _stretch_block


def nodal_operator(faces, dr_inv, area, n_vertices, stretch, shear):
    """The smoothed-gradient stencils: (ptr, index, a, b) in CSR form (row v: the vertices j
    of F_v = Σ_j x_j ⊗ (a_vj, b_vj)), the cell areas A_v (n,), and per-vertex materials
    (``stretch`` (n, 4), ``shear`` (n,)) averaged over the ring by area."""
    d = dr_inv
    alpha = np.stack([-d[:, 0, 0] - d[:, 1, 0], d[:, 0, 0], d[:, 1, 0]], axis=1)  # (M, 3)
    beta = np.stack([-d[:, 0, 1] - d[:, 1, 1], d[:, 0, 1], d[:, 1, 1]], axis=1)
    third = area / 3.0
    cell = np.bincount(faces.ravel(), np.repeat(third, 3), minlength=n_vertices)
    owner = np.repeat(faces, 3, axis=1).ravel()  # (M·9,): the cell v of each (v, j) corner pair
    corner = np.tile(faces, (1, 3)).ravel()
    weight = np.repeat(third, 9) / cell[owner]
    key, which = np.unique(owner * n_vertices + corner, return_inverse=True)
    a = np.bincount(which, weight * np.tile(alpha, (1, 3)).ravel(), minlength=len(key))
    b = np.bincount(which, weight * np.tile(beta, (1, 3)).ravel(), minlength=len(key))
    index = (key % n_vertices).astype(np.int64)
    ptr = np.concatenate([[0], np.cumsum(np.bincount(key // n_vertices,
                                                     minlength=n_vertices))]).astype(np.int64)
    own = np.bincount(faces.ravel(), minlength=n_vertices) > 0
    w = np.where(own, cell, 1.0)
    mat_stretch = np.zeros((n_vertices, 4))
    for c in range(4):
        mat_stretch[:, c] = np.bincount(faces.ravel(), np.repeat(third * stretch[:, c], 3),
                                        minlength=n_vertices) / w
    mat_shear = np.bincount(faces.ravel(), np.repeat(third * shear, 3),
                            minlength=n_vertices) / w
    return ptr, index, a, b, cell, mat_stretch, mat_shear


def nodal_pairs(ptr, index):
    """(P, 2) vertex pairs (j, k) of every stencil, row-major per stencil (the Hessian blocks)."""
    pairs = []
    for v in range(len(ptr) - 1):
        s = index[ptr[v]:ptr[v + 1]]
        pairs.append(np.stack([np.repeat(s, len(s)), np.tile(s, len(s))], axis=1))
    return np.concatenate(pairs).astype(np.int64) if pairs else np.zeros((0, 2), np.int64)


@njit(cache=True)
def _smoothed(x, ptr, index, a, b, v):
    f0 = np.zeros(3)
    f1 = np.zeros(3)
    for e in range(ptr[v], ptr[v + 1]):
        j = index[e]
        for p in range(3):
            f0[p] += a[e] * x[j, p]
            f1[p] += b[e] * x[j, p]
    return (f0[0], f0[1], f0[2]), (f1[0], f1[1], f1[2])


@njit(cache=True)
def nodal_energy(x, ptr, index, a, b, cell, stretch, shear):
    """W = Σ_v A_v Ψ(F_v)."""
    total = 0.0
    for v in range(len(cell)):
        if ptr[v + 1] == ptr[v]:
            continue
        f0, f1 = _smoothed(x, ptr, index, a, b, v)
        total += cell[v] * _density(f0, f1, stretch[v], shear[v])
    return total


@njit(cache=True)
def nodal_assemble(x, ptr, index, a, b, cell, stretch, shear, project, slots, grad, values):
    """W(x); adds ∇W to grad (N, 3) and the Hessian blocks (PSD-projected with ``project``) to
    values, stencil v's block (j, k) at ``slots[s_v + j·m_v + k]`` (s_v = Σ_{u<v} m_u²,
    m_v its stencil's size; :func:`nodal_pairs`' order)."""
    h_f = np.empty((6, 6))
    total = 0.0
    start = 0
    for v in range(len(cell)):
        lo, hi = ptr[v], ptr[v + 1]
        m = hi - lo
        if m == 0:
            continue
        f0, f1 = _smoothed(x, ptr, index, a, b, v)
        st, kh, av = stretch[v], shear[v], cell[v]
        total += av * _density(f0, f1, st, kh)
        g0, g1 = _stress(f0, f1, st, kh)
        h_f[:, :] = 0.0
        if st[0] > 0.0:
            _stretch_block(f0, st[0], st[2], project, h_f, 0)
        if st[1] > 0.0:
            _stretch_block(f1, st[1], st[3], project, h_f, 3)
        if kh > 0.0:
            _shear_hessian(f0, f1, kh, project, h_f)
        for r in range(m):
            ej = lo + r
            j = index[ej]
            for p in range(3):
                grad[j, p] += av * (a[ej] * g0[p] + b[ej] * g1[p])
            for c in range(m):
                ek = lo + c
                aa = av * a[ej] * a[ek]
                ab = av * a[ej] * b[ek]
                ba = av * b[ej] * a[ek]
                bb = av * b[ej] * b[ek]
                block = values[slots[start + r * m + c]]
                for p in range(3):
                    for q in range(3):
                        block[p, q] += (aa * h_f[p, q] + ab * h_f[p, 3 + q]
                                        + ba * h_f[3 + p, q] + bb * h_f[3 + p, 3 + q])
        start += m * m
    return total
