"""Edge-based smoothed membrane: Baraff–Witkin stretch and shear on each edge's smoothed
strain, ``material.membrane_model: edge``.

The smoothing is that of the edge-based smoothed finite element method (ES-FEM: G. R. Liu,
T. Nguyen-Thoi, K. Y. Lam, "An edge-based smoothed finite element method (ES-FEM) for static,
free and forced vibration analyses of solids", Journal of Sound and Vibration 320 (2009)
1100–1130), applied to the metric C = FᵀF as :mod:`clothtool.sim.energies.membrane_nodal`
applies it per vertex. Edge e owns a third of each triangle t beside it,
A_e = Σ_{t∋e} A_t/3, and

    C_e = Σ_{t∋e} w_et F_tᵀF_t,   w_et = A_t/(3A_e),   W = Σ_e A_e Ψ(C_e),

Ψ the triangle membrane's density (:mod:`clothtool.sim.energies.membrane`) written in C,
stretch and shear both (ES-FEM has no spurious zero-energy modes, unlike the node-based
smoothing, whose shear therefore stays on the triangles). Ψ is convex in C, so W is never
above the triangles' energy Σ_t A_t Ψ(C_t) at the same positions (Jensen): a sheet bent off
the mesh's lines stores less spurious membrane energy than on linear triangles. An affine
map gives every C_t and so every C_e the same value (the patch test); rigid motions leave
every C_t, so W, unchanged; a fold along a mesh line keeps each triangle rigid and stores
nothing.

Frames: the two triangles of an edge always unfold into one plane, so the cells need no
pattern. With one (uv per vertex or per corner, or a flat mesh's own plane) C_t is read in
the pattern's frame, and an edge whose two triangles' corner uv differ (a garment's seam, a
cut in the pattern) has a cell on each side; without one (a mesh resting curved) each
triangle's frame is turned (or mirrored, where the two triangles' orders disagree) about the
edge onto its partner's, F_t → F_t Qᵀ, C_t → Q C_t Qᵀ.

Hessian. With J_t = ∂C'_t/∂x (C'_t = F_tᵀF_t read in the cell's frame) and Ψ'' = ∂²Ψ/∂C²
(diagonal, ≥ 0: :mod:`~clothtool.sim.energies.membrane_nodal`), a cell's Hessian is

    A_e [J_eᵀ Ψ'' J_e + Σ_t w_et (α_t, β_t) M (α_t, β_t)ᵀ ⊗ I₃],   J_e = Σ_t w_et J_t,

whose first (Gauss–Newton) part couples the two vertices opposite the edge, blocks the
triangles lack. It is replaced by A_e Σ_t w_et J_tᵀ Ψ'' J_t, never below it (Jensen,
Σ_t w_et = 1) and equal where the cell's triangles see the same change of strain (any smooth
motion). Both parts then live on each triangle's own vertices: per unit of its area,
triangle t gathers from each of its edges' cells (A_e w_et/A_t = 1/3)

    ∂Ψ/∂F_t ← ⅓ Σ_c ψ_c ∂C'_c/∂F_t,   ∂²Ψ/∂F_t² ← ⅓ [Σ_c Ψ''_c g_c g_cᵀ + R M Rᵀ ⊗ I₃],

g_c = ∂C'_c/∂vec F_t, R the turn into the cell's frame (F_e = F_t R). The gradient and the
stress part are exact; the matrix has the triangles' blocks, and with strain damping the
triangles' pass assembles it with the dissipation's (:func:`~clothtool.sim.energies.
dissipation.strain_assemble`), as it does the triangle membrane. Each assembly first sums
every cell's C_e and its stresses (:func:`edge_stresses`), then visits the triangles.
"""

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.energies.membrane import add_triangle, deformation, to_vertices
from clothtool.sim.energies.membrane_nodal import clamped_stress
from clothtool.vec3 import dot, load

EPS = 1e-12
ZERO = (0.0, 0.0, 0.0)


def edge_cells(faces, corner_uv=None):
    """(M, 3) the cell of each triangle's edge k (corner k to corner k + 1): one per edge, or
    per edge and side where the corner uv (M, 3, 2) of its two triangles differ."""
    nxt = np.roll(faces, -1, axis=1)
    first = faces < nxt
    cols = [np.minimum(faces, nxt).reshape(-1, 1), np.maximum(faces, nxt).reshape(-1, 1)]
    if corner_uv is not None:
        uv, uv_next = corner_uv, np.roll(corner_uv, -1, axis=1)
        cols += [np.where(first[..., None], uv, uv_next).reshape(-1, 2),
                 np.where(first[..., None], uv_next, uv).reshape(-1, 2)]
    key = np.concatenate(cols, axis=1).astype(np.float64)
    _, cells = np.unique(key, axis=0, return_inverse=True)
    return cells.reshape(faces.shape).astype(np.int64)


def unfolded_frames(faces, dr, cells):
    """(M, 3, 2, 2) Q per (triangle, edge): the orthogonal map of the triangle's rest frame
    onto that of the first triangle of the edge's cell, unfolded about their edge (rest edge
    matrices ``dr`` (M, 2, 2), columns x1 − x0 and x2 − x0 in each triangle's frame); a
    rotation where the two triangles run along the edge in opposite senses (consistently
    oriented), else a reflection."""
    m = len(faces)
    p = np.zeros((m, 3, 2))
    p[:, 1], p[:, 2] = dr[:, :, 0], dr[:, :, 1]
    edge = np.roll(p, -1, axis=1) - p  # (M, 3, 2): corner k to corner k + 1
    forward = faces < np.roll(faces, -1, axis=1)
    s = np.where(forward[..., None], edge, -edge).reshape(-1, 2)  # low vertex to high
    s = s / np.linalg.norm(s, axis=1, keepdims=True)
    flat = cells.ravel()
    _, lead = np.unique(flat, return_index=True)
    ref = lead[flat]  # the entry each entry is turned onto
    c1, s1 = s[ref, 0], s[ref, 1]
    c2, s2 = s[:, 0], s[:, 1]
    cos, sin = c1 * c2 + s1 * s2, s1 * c2 - c1 * s2  # the rotation taking s2 to s1
    cos2, sin2 = c1 * c2 - s1 * s2, s1 * c2 + c1 * s2  # the mirror taking s2 to s1
    mirror = forward.ravel() == forward.ravel()[ref]
    mirror[ref == np.arange(len(flat))] = False
    q = np.empty((len(flat), 2, 2))
    q[:, 0, 0] = np.where(mirror, cos2, cos)
    q[:, 0, 1] = np.where(mirror, sin2, -sin)
    q[:, 1, 0] = np.where(mirror, sin2, sin)
    q[:, 1, 1] = np.where(mirror, -cos2, cos)
    q[ref == np.arange(len(flat))] = np.eye(2)
    return q.reshape(m, 3, 2, 2)


def edge_parts(area, stretch, shear, cells, frames=None):
    """Per triangle edge (M, 3): its cell's turn R (M, 3, 2, 2), F_e = F_t R (Qᵀ of
    ``frames`` (M, 3, 2, 2), :func:`unfolded_frames`; I with the pattern's frame), and weight
    w_et = A_t/(3A_e); per cell: A_e and its materials averaged by area (``stretch`` (·, 4),
    ``shear`` (·,))."""
    cells = np.ascontiguousarray(cells, np.int64)
    flat = cells.ravel()
    n_cells = int(flat.max()) + 1 if flat.size else 0
    third = np.repeat(area / 3.0, 3)
    cell_area = np.bincount(flat, third, minlength=n_cells)
    weight = (third / cell_area[flat]).reshape(cells.shape)
    tri = np.repeat(np.arange(len(cells)), 3)
    mat_stretch = np.stack([np.bincount(flat, third * stretch[tri, c], minlength=n_cells)
                            / cell_area for c in range(4)], axis=1)
    mat_shear = np.bincount(flat, third * shear[tri], minlength=n_cells) / cell_area
    if frames is None:
        turn = np.broadcast_to(np.eye(2), (len(cells), 3, 2, 2))
    else:
        turn = np.asarray(frames).transpose(0, 1, 3, 2)
    return np.ascontiguousarray(turn), weight, cell_area, mat_stretch, mat_shear


@njit(cache=True)
def _turned(f0, f1, r):
    """The columns of F R."""
    return ((f0[0] * r[0, 0] + f1[0] * r[1, 0], f0[1] * r[0, 0] + f1[1] * r[1, 0],
             f0[2] * r[0, 0] + f1[2] * r[1, 0]),
            (f0[0] * r[0, 1] + f1[0] * r[1, 1], f0[1] * r[0, 1] + f1[1] * r[1, 1],
             f0[2] * r[0, 1] + f1[2] * r[1, 1]))


@njit(cache=True)
def edge_stresses(x, faces, dr_inv, cells, turn, weight, cell_area, stretch, shear, project,
                  metric, stress):
    """W = Σ_e A_e Ψ(C_e); writes each cell's C_e into metric (E, 3) and into stress (E, 9)
    its ∂Ψ/∂C (ψ₀₀, ψ₁₁, ψ₀₁), M = [[2ψ₀₀, ψ₀₁], [ψ₀₁, 2ψ₁₁]] (PSD-projected with
    ``project``) and ∂²Ψ/∂C² (diagonal)."""
    metric[:, :] = 0.0
    for t in range(faces.shape[0]):
        f0, f1, _, _ = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                   load(x, faces[t, 2]), dr_inv[t])
        for k in range(3):
            g0, g1 = _turned(f0, f1, turn[t, k])
            e, w = cells[t, k], weight[t, k]
            metric[e, 0] += w * dot(g0, g0)
            metric[e, 1] += w * dot(g1, g1)
            metric[e, 2] += w * dot(g0, g1)
    total = 0.0
    for e in range(len(cell_area)):
        c00, c11, c01 = metric[e, 0], metric[e, 1], metric[e, 2]
        st, kh = stretch[e], shear[e]
        n0s = np.sqrt(max(c00, 0.0))
        n1s = np.sqrt(max(c11, 0.0))
        total += cell_area[e] * (0.5 * st[0] * (n0s - st[2]) ** 2
                                 + 0.5 * st[1] * (n1s - st[3]) ** 2 + 0.5 * kh * c01 * c01)
        n0 = max(n0s, EPS)
        n1 = max(n1s, EPS)
        psi0 = 0.5 * st[0] * (n0 - st[2]) / n0
        psi1 = 0.5 * st[1] * (n1 - st[3]) / n1
        psi2 = kh * c01
        m00, m11, m01 = 2.0 * psi0, 2.0 * psi1, psi2
        if project:
            m00, m11, m01 = clamped_stress(m00, m11, m01)
        stress[e, 0], stress[e, 1], stress[e, 2] = psi0, psi1, psi2
        stress[e, 3], stress[e, 4], stress[e, 5] = m00, m11, m01
        stress[e, 6] = 0.25 * st[0] * st[2] / (n0 * n0 * n0)
        stress[e, 7] = 0.25 * st[1] * st[3] / (n1 * n1 * n1)
        stress[e, 8] = kh
    return total


@njit(cache=True)
def edge_density(f0, f1, t, cells, turn, weight, stress, g0, g1, h_f):
    """Triangle t's share of its edges' cells per unit of its area, at its F = (f0, f1):
    returns (g0, g1) + ∂W/∂F_t / A_t and adds to h_f (6, 6) the Hessian of the module
    docstring (the stress part exact, the Gauss–Newton part majorised: Jensen per cell)."""
    a0, a1, a2 = g0
    b0, b1, b2 = g1
    for k in range(3):
        r, s = turn[t, k], stress[cells[t, k]]
        u, v = _turned(f0, f1, r)  # the cell's frame: C'_t = (u·u, v·v, u·v)
        third = 1.0 / 3.0
        for p in range(3):
            # ∂C'/∂f0 and ∂C'/∂f1 of each component (00, 11, 01)
            d00, e00 = 2.0 * r[0, 0] * u[p], 2.0 * r[1, 0] * u[p]
            d11, e11 = 2.0 * r[0, 1] * v[p], 2.0 * r[1, 1] * v[p]
            d01, e01 = r[0, 0] * v[p] + r[0, 1] * u[p], r[1, 0] * v[p] + r[1, 1] * u[p]
            gp = third * (s[0] * d00 + s[1] * d11 + s[2] * d01)
            hp = third * (s[0] * e00 + s[1] * e11 + s[2] * e01)
            if p == 0:
                a0, b0 = a0 + gp, b0 + hp
            elif p == 1:
                a1, b1 = a1 + gp, b1 + hp
            else:
                a2, b2 = a2 + gp, b2 + hp
            for q in range(3):
                d00q, e00q = 2.0 * r[0, 0] * u[q], 2.0 * r[1, 0] * u[q]
                d11q, e11q = 2.0 * r[0, 1] * v[q], 2.0 * r[1, 1] * v[q]
                d01q = r[0, 0] * v[q] + r[0, 1] * u[q]
                e01q = r[1, 0] * v[q] + r[1, 1] * u[q]
                h_f[p, q] += third * (s[6] * d00 * d00q + s[7] * d11 * d11q + s[8] * d01 * d01q)
                h_f[p, 3 + q] += third * (s[6] * d00 * e00q + s[7] * d11 * e11q + s[8] * d01 * e01q)
                h_f[3 + p, q] += third * (s[6] * e00 * d00q + s[7] * e11 * d11q + s[8] * e01 * d01q)
                h_f[3 + p, 3 + q] += third * (s[6] * e00 * e00q + s[7] * e11 * e11q
                                          + s[8] * e01 * e01q)
        # the stress part: (R M Rᵀ)/3 ⊗ I₃
        m00, m11, m01 = s[3], s[4], s[5]
        q00 = r[0, 0] * (m00 * r[0, 0] + m01 * r[0, 1]) + r[0, 1] * (m01 * r[0, 0] + m11 * r[0, 1])
        q01 = r[0, 0] * (m00 * r[1, 0] + m01 * r[1, 1]) + r[0, 1] * (m01 * r[1, 0] + m11 * r[1, 1])
        q11 = r[1, 0] * (m00 * r[1, 0] + m01 * r[1, 1]) + r[1, 1] * (m01 * r[1, 0] + m11 * r[1, 1])
        for p in range(3):
            h_f[p, p] += third * q00
            h_f[p, 3 + p] += third * q01
            h_f[3 + p, p] += third * q01
            h_f[3 + p, 3 + p] += third * q11
    return (a0, a1, a2), (b0, b1, b2)


@njit(cache=True)
def edge_assemble(x, faces, dr_inv, area, cells, turn, weight, stress, slots, grad, values):
    """Adds ∇W and the Hessian blocks (:func:`edge_density`) triangle by triangle to grad
    (N, 3) and values[slots] (the cells' ``stress`` from :func:`edge_stresses` at x)."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    h_f = np.empty((6, 6))
    for t in range(faces.shape[0]):
        f0, f1, alpha, beta = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                          load(x, faces[t, 2]), dr_inv[t])
        h_f[:, :] = 0.0
        g0, g1 = edge_density(f0, f1, t, cells, turn, weight, stress, ZERO, ZERO, h_f)
        to_vertices(alpha, beta, area[t], g0, g1, h_f, g, hess)
        add_triangle(faces[t], slots[t], g, hess, grad, values)


def edge_exact_remainder(x, faces, dr_inv, cells, turn, weight, cell_area, stress):
    """The exact Hessian minus the assembled one (:func:`edge_assemble` with the stress part
    unprojected), a sparse (3N, 3N) matrix: Σ_e A_e [J_eᵀ Ψ''_e J_e − Σ_t w_et J_tᵀ Ψ''_e J_t]
    (module docstring; each cell's term ≤ 0 by Jensen), with J_t = ∂C'_t/∂x on triangle t's
    vertices and J_e = Σ_t w_et J_t on the cell's four; the cells' ``stress`` from
    :func:`edge_stresses` at x. With a triangle's u = Σ_i a_i x_i and v = Σ_i b_i x_i (the
    columns of F_t R), ∂(u·u)/∂x_i = 2a_i u, ∂(v·v)/∂x_i = 2b_i v, ∂(u·v)/∂x_i = a_i v + b_i u.
    For the static finish only (statics' ``exact_hessian``): the flap pairs it couples are
    outside the triangles' pattern."""
    import scipy.sparse as sps

    m, n = len(faces), len(x)
    a, b = dr_inv[:, 0, 0], dr_inv[:, 0, 1]
    c, d = dr_inv[:, 1, 0], dr_inv[:, 1, 1]
    alpha = np.stack([-a - c, a, c], axis=1)  # (M, 3): f0 = Σ α_i x_i
    beta = np.stack([-b - d, b, d], axis=1)
    xs = x[faces]  # (M, 3 vertices, 3)
    r = turn  # (M, 3 edges, 2, 2)
    ai = r[:, :, None, 0, 0] * alpha[:, None, :] + r[:, :, None, 1, 0] * beta[:, None, :]
    bi = r[:, :, None, 0, 1] * alpha[:, None, :] + r[:, :, None, 1, 1] * beta[:, None, :]
    u = np.einsum("mki,mip->mkp", ai, xs)  # (M, 3, 3)
    v = np.einsum("mki,mip->mkp", bi, xs)
    g = np.empty((m, 3, 3, 3, 3))  # (triangle, edge, component, vertex, coordinate)
    g[:, :, 0] = 2.0 * ai[..., None] * u[:, :, None, :]
    g[:, :, 1] = 2.0 * bi[..., None] * v[:, :, None, :]
    g[:, :, 2] = ai[..., None] * v[:, :, None, :] + bi[..., None] * u[:, :, None, :]
    col = np.broadcast_to((3 * faces[:, None, None, :, None] + np.arange(3)), g.shape).ravel()
    own = np.broadcast_to(np.arange(3 * m * 3).reshape(m, 3, 3, 1, 1), g.shape).ravel()
    cell_row = np.broadcast_to(3 * cells[:, :, None, None, None]
                               + np.arange(3)[:, None, None], g.shape).ravel()
    n_cells = len(cell_area)
    j_t = sps.csr_matrix((g.ravel(), (own, col)), shape=(9 * m, 3 * n))
    j_e = sps.csr_matrix(((weight[:, :, None, None, None] * g).ravel(), (cell_row, col)),
                         shape=(3 * n_cells, 3 * n))
    curvature = cell_area[:, None] * stress[:, 6:9]  # A_e Ψ''_e (E, 3)
    d_e = sps.diags(curvature.ravel())
    d_t = sps.diags((weight[:, :, None] * curvature[cells]).ravel())
    return (j_e.T @ d_e @ j_e - j_t.T @ d_t @ j_t).tocsr()
