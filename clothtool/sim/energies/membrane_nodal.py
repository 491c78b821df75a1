"""Node-based smoothed membrane: Baraff–Witkin stretch and shear on each vertex's smoothed
strain, so that the sheet bends along any line without stretching. ``material.membrane_model:
nodal`` puts the stiff warp and weft stretch here and keeps the soft shear on the triangles
(:mod:`clothtool.sim.energies.membrane`): a selective smoothing of the part that locks.

The smoothing is that of the node-based smoothed finite element method (NS-FEM: G. R. Liu,
T. Nguyen-Thoi, H. Nguyen-Xuan, K. Y. Lam, "A node-based smoothed finite element method
(NS-FEM) for upper bound solutions to solid mechanics problems", Computers & Structures 87
(2009) 14–26), applied to the metric C = FᵀF (the Green strain E = (C − I)/2) rather than to
F. Vertex v owns a third of each triangle t around it, A_v = Σ_{t∋v} A_t/3, and

    C_v = Σ_{t∋v} w_vt F_tᵀF_t,   w_vt = A_t/(3A_v),

so that a sheet bent isometrically (every F_tᵀF_t = I) has C_v = I: averaging F itself would
shorten F_v where the ring is curved and stiffen the bending. With :mod:`clothtool.sim.energies.membrane`'s
density written in C (‖f0‖ = √C₀₀, ‖f1‖ = √C₁₁, f0·f1 = C₀₁),

    W = Σ_v A_v [k_u/2 (√C₀₀ − b_u)² + k_v/2 (√C₁₁ − b_v)² + k_h/2 C₀₁²],

the materials the area-weighted means of the ring's. An affine map gives every C_t and so
every C_v the same value (the patch test); to first order in the displacement C_v is NS-FEM's
smoothed strain.

Why: linear triangles lock. A sheet folded smoothly along a line that is no mesh line cannot
keep its triangles' three strains zero (three conditions per triangle, about six per vertex,
against a vertex's three coordinates), so a fabric stiff along warp and weft drapes stiffer
on some meshes than on others. The smoothed strain sets three conditions per vertex.

Hessian: with J_c = ∂C_c/∂x (c = 00, 11, 01) and Ψ_c = ∂Ψ/∂C_c,

    ∇²W_v = A_v [Jᵀ (∂²Ψ/∂C²) J + Σ_t w_vt (α_t, β_t) M (α_t, β_t)ᵀ ⊗ I₃],
    M = [[2Ψ₀₀, Ψ₀₁], [Ψ₀₁, 2Ψ₁₁]],

α_t, β_t the triangle's shape-function gradients (f0 = Σ α_a x_a, f1 = Σ β_a x_a);
∂²Ψ/∂C² is diagonal (k_u b_u/(4C₀₀^{3/2}), k_v b_v/(4C₁₁^{3/2}), k_h), so the first
part is PSD, and the projected Hessian clamps M's eigenvalues at zero (M is PSD in tension). It couples
a vertex with its two-ring.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner
from clothtool.sim.energies.membrane import deformation
from clothtool.vec3 import dot, load

EPS = 1e-12


def nodal_operator(faces, dr_inv, area, n_vertices, stretch, shear, cells=None):
    """The smoothing cells: each cell's stencil (ptr, index: the vertices of its triangles,
    sorted), its triangles (tri_ptr, tri: CSR over cells), their weights w_vt and their
    corners' places in the stencil (local (K, 3)), the cell areas A_v, and per-cell materials
    (``stretch`` (·, 4), ``shear`` (·,)) averaged over the cell by area.

    ``cells`` (M, 3): the cell of each triangle corner (default: its vertex). Corners share a
    cell only where their triangles' material frames agree: a garment's seam vertex has a
    cell in each panel (:func:`frame_cells`)."""
    cells = faces if cells is None else np.asarray(cells, np.int64)
    n_cells = int(cells.max()) + 1 if cells.size else 0
    third = area / 3.0
    corner_cell = cells.ravel()  # (M·3,): the cell each triangle corner lies in
    cell = np.bincount(corner_cell, np.repeat(third, 3), minlength=n_cells)
    owner = np.repeat(cells, 3, axis=1).ravel()  # (M·9,): the cell of each (corner, j) pair
    corner = np.tile(faces, (1, 3)).ravel()
    key = np.unique(owner * n_vertices + corner)
    index = (key % n_vertices).astype(np.int64)
    ptr = np.concatenate([[0], np.cumsum(np.bincount(key // n_vertices,
                                                     minlength=n_cells))]).astype(np.int64)
    order = np.argsort(corner_cell, kind="stable")
    tri = (order // 3).astype(np.int64)
    tri_ptr = np.concatenate([[0], np.cumsum(np.bincount(corner_cell, minlength=n_cells))])
    tri_ptr = tri_ptr.astype(np.int64)
    owners = corner_cell[order]
    weight = third[tri] / cell[owners]
    local = np.searchsorted(key, owners[:, None] * n_vertices + faces[tri]) - ptr[owners][:, None]
    local = local.astype(np.int64)
    w = np.where(cell > 0.0, cell, 1.0)
    mat_stretch = np.stack([np.bincount(corner_cell, np.repeat(third * stretch[:, c], 3),
                                        minlength=n_cells) / w for c in range(4)], axis=1)
    mat_shear = np.bincount(corner_cell, np.repeat(third * shear, 3), minlength=n_cells) / w
    return ptr, index, tri_ptr, tri, weight, local, cell, mat_stretch, mat_shear


def frame_cells(faces, corner_uv):
    """(M, 3) cells of the corners of a pattern given per corner (garment panels): the
    corners of one vertex with the same rest coordinates (the same panel) share a cell."""
    key = np.concatenate([faces.reshape(-1, 1).astype(np.float64),
                          corner_uv.reshape(-1, 2)], axis=1)
    _, cells = np.unique(key, axis=0, return_inverse=True)
    return cells.reshape(faces.shape).astype(np.int64)


def nodal_pairs(ptr, index):
    """(P, 2) vertex pairs (j, k) of every stencil, row-major per stencil (the Hessian blocks)."""
    size = np.diff(ptr)
    count = size * size
    stencil = np.repeat(np.arange(len(size)), count)
    q = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    row, col = q // size[stencil], q % size[stencil]
    return np.stack([index[ptr[stencil] + row], index[ptr[stencil] + col]], axis=1).astype(np.int64)


@njit_inner(cache=True)
def _metric(x, faces, dr_inv, tri_ptr, tri, weight, v):
    """C_v = Σ_t w_vt F_tᵀF_t as (C₀₀, C₁₁, C₀₁)."""
    c00 = c11 = c01 = 0.0
    for e in range(tri_ptr[v], tri_ptr[v + 1]):
        t = tri[e]
        f0, f1, _, _ = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                    load(x, faces[t, 2]), dr_inv[t])
        w = weight[e]
        c00 += w * (dot(f0, f0))
        c11 += w * (dot(f1, f1))
        c01 += w * (dot(f0, f1))
    return c00, c11, c01


@njit_inner(cache=True)
def _density(c00, c11, c01, st, kh):
    n0 = np.sqrt(max(c00, 0.0))
    n1 = np.sqrt(max(c11, 0.0))
    return 0.5 * st[0] * (n0 - st[2]) ** 2 + 0.5 * st[1] * (n1 - st[3]) ** 2 + 0.5 * kh * c01 * c01


@njit(cache=True)
def nodal_energy(x, faces, dr_inv, ptr, index, tri_ptr, tri, weight, local, cell, stretch, shear):
    """W = Σ_v A_v Ψ(C_v)."""
    total = 0.0
    for v in range(len(cell)):
        if tri_ptr[v + 1] == tri_ptr[v]:
            continue
        c00, c11, c01 = _metric(x, faces, dr_inv, tri_ptr, tri, weight, v)
        total += cell[v] * _density(c00, c11, c01, stretch[v], shear[v])
    return total


@njit(cache=True)
def nodal_assemble(x, faces, dr_inv, ptr, index, tri_ptr, tri, weight, local, cell, stretch,
                   shear, project, slots, grad, values):
    """W(x); adds ∇W to grad (N, 3) and the Hessian blocks (PSD with ``project``, module
    docstring) to values, stencil v's block (j, k) at ``slots[s_v + j·m_v + k]``
    (s_v = Σ_{u<v} m_u², m_v its stencil's size; :func:`nodal_pairs`' order). Each pair of
    the stencil once (the block and its transpose), the shear's row only when the cell has
    a shear stiffness (the default model keeps its shear on the triangles)."""
    total = 0.0
    start = 0
    jac = np.zeros((64, 3, 3))
    scaled = np.zeros((64, 3, 3))
    for v in range(len(cell)):
        lo, hi = ptr[v], ptr[v + 1]
        m = hi - lo
        if tri_ptr[v + 1] == tri_ptr[v]:
            start += m * m
            continue
        if m > jac.shape[0]:
            jac = np.zeros((2 * m, 3, 3))
            scaled = np.zeros((2 * m, 3, 3))
        kh = shear[v]
        ncomp = 3 if kh != 0.0 else 2
        jac[:m] = 0.0
        c00 = c11 = c01 = 0.0
        for e in range(tri_ptr[v], tri_ptr[v + 1]):
            t = tri[e]
            f0, f1, al, be = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                          load(x, faces[t, 2]), dr_inv[t])
            w = weight[e]
            c00 += w * (dot(f0, f0))
            c11 += w * (dot(f1, f1))
            c01 += w * (dot(f0, f1))
            for a in range(3):
                r = local[e, a]
                wa, wb = 2.0 * w * al[a], 2.0 * w * be[a]
                for p in range(3):
                    jac[r, 0, p] += wa * f0[p]
                    jac[r, 1, p] += wb * f1[p]
                if ncomp == 3:
                    for p in range(3):
                        jac[r, 2, p] += w * (al[a] * f1[p] + be[a] * f0[p])
        st, av = stretch[v], cell[v]
        n0s = np.sqrt(max(c00, 0.0))
        n1s = np.sqrt(max(c11, 0.0))
        total += av * (0.5 * st[0] * (n0s - st[2]) ** 2 + 0.5 * st[1] * (n1s - st[3]) ** 2
                       + 0.5 * kh * c01 * c01)
        n0 = max(n0s, EPS)
        n1 = max(n1s, EPS)
        psi0 = 0.5 * st[0] * (n0 - st[2]) / n0
        psi1 = 0.5 * st[1] * (n1 - st[3]) / n1
        psi2 = kh * c01
        cv0 = av * 0.25 * st[0] * st[2] / (n0 * n0 * n0)
        cv1 = av * 0.25 * st[1] * st[3] / (n1 * n1 * n1)
        cv2 = av * kh
        for r in range(m):
            j = index[lo + r]
            for p in range(3):
                grad[j, p] += av * (psi0 * jac[r, 0, p] + psi1 * jac[r, 1, p]
                                    + psi2 * jac[r, 2, p])
                scaled[r, 0, p] = cv0 * jac[r, 0, p]
                scaled[r, 1, p] = cv1 * jac[r, 1, p]
                scaled[r, 2, p] = cv2 * jac[r, 2, p]
        for r in range(m):
            row = start + r * m
            for c in range(r, m):
                k1 = slots[row + c]
                k2 = slots[start + c * m + r]
                for p in range(3):
                    a0, a1, a2 = scaled[r, 0, p], scaled[r, 1, p], scaled[r, 2, p]
                    for q in range(3):
                        b = a0 * jac[c, 0, q] + a1 * jac[c, 1, q]
                        if ncomp == 3:
                            b += a2 * jac[c, 2, q]
                        values[k1, p, q] += b
                        if c != r:
                            values[k2, q, p] += b
        m00, m11, m01 = 2.0 * psi0, 2.0 * psi1, psi2
        if project:
            m00, m11, m01 = clamped_stress(m00, m11, m01)
        for e in range(tri_ptr[v], tri_ptr[v + 1]):
            t = tri[e]
            d = dr_inv[t]
            al0, al1, al2 = -d[0, 0] - d[1, 0], d[0, 0], d[1, 0]
            be0, be1, be2 = -d[0, 1] - d[1, 1], d[0, 1], d[1, 1]
            al = (al0, al1, al2)
            be = (be0, be1, be2)
            s = av * weight[e]
            for a in range(3):
                ra = local[e, a]
                for b in range(3):
                    rb = local[e, b]
                    g = s * (m00 * al[a] * al[b] + m11 * be[a] * be[b]
                             + m01 * (al[a] * be[b] + be[a] * al[b]))
                    k = slots[start + ra * m + rb]
                    values[k, 0, 0] += g
                    values[k, 1, 1] += g
                    values[k, 2, 2] += g
        start += m * m
    return total



@njit_inner(cache=True)
def clamped_stress(m00, m11, m01):
    """The symmetric 2 × 2 [[m00, m01], [m01, m11]] with its negative eigenvalue set to 0."""
    half = 0.5 * (m00 - m11)
    root = np.sqrt(half * half + m01 * m01)
    l1 = 0.5 * (m00 + m11) + root
    l2 = 0.5 * (m00 + m11) - root
    if root > 0.0:
        ux, uy = m01, l1 - m00
        if ux * ux + uy * uy < (l1 - m11) ** 2 + m01 * m01:
            ux, uy = l1 - m11, m01
        norm = np.sqrt(ux * ux + uy * uy)
        ux, uy = ux / norm, uy / norm
    else:
        ux, uy = 1.0, 0.0
    l1, l2 = max(l1, 0.0), max(l2, 0.0)
    return l1 * ux * ux + l2 * uy * uy, l1 * uy * uy + l2 * ux * ux, (l1 - l2) * ux * uy
