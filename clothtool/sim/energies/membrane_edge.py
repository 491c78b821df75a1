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

The kernels are the nodal membrane's (:func:`~clothtool.sim.energies.membrane_nodal.
nodal_assemble`) over edge cells: each triangle enters once per edge, with its cell's
frame. A cell's stencil is its edge's two triangles (four vertices): the dihedral hinges'
blocks.
"""

import numpy as np


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


def edge_operator(faces, dr_inv, area, n_vertices, stretch, shear, cells, frames=None):
    """(faces_e, dr_inv_e, operator): the triangles once per edge cell, grouped by cell, with
    their cells' frames (``frames`` (M, 3, 2, 2): :func:`unfolded_frames`, None: the
    pattern's), and the nodal membrane's operator over the edge cells (ptr, index, tri_ptr,
    tri, weight, local, cell areas A_e, materials averaged by area:
    :func:`~clothtool.sim.energies.membrane_nodal.nodal_operator`'s order)."""
    m = len(faces)
    cell = np.asarray(cells, np.int64).ravel()
    n_cells = int(cell.max()) + 1 if cell.size else 0
    order = np.argsort(cell, kind="stable")
    owner = cell[order]
    tri_of = order // 3
    faces_e = np.ascontiguousarray(faces[tri_of])
    dr_e = dr_inv[tri_of]
    if frames is not None:  # D_r → Q D_r, so D_r⁻¹ → D_r⁻¹ Qᵀ
        dr_e = np.einsum("eij,ekj->eik", dr_e, frames.reshape(-1, 2, 2)[order])
    dr_e = np.ascontiguousarray(dr_e)
    third = area[tri_of] / 3.0
    cell_area = np.bincount(owner, third, minlength=n_cells)
    tri_ptr = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=n_cells))])
    tri = np.arange(3 * m, dtype=np.int64)
    weight = third / cell_area[owner]
    key = np.unique(np.repeat(owner, 3) * n_vertices + faces_e.ravel())
    index = (key % n_vertices).astype(np.int64)
    ptr = np.concatenate([[0], np.cumsum(np.bincount(key // n_vertices, minlength=n_cells))])
    local = np.searchsorted(key, owner[:, None] * n_vertices + faces_e) - ptr[owner][:, None]
    mat_stretch = np.stack([np.bincount(owner, third * stretch[tri_of, c], minlength=n_cells)
                            / cell_area for c in range(4)], axis=1)
    mat_shear = np.bincount(owner, third * shear[tri_of], minlength=n_cells) / cell_area
    return faces_e, dr_e, (ptr.astype(np.int64), index, tri_ptr.astype(np.int64), tri, weight,
                           local.astype(np.int64), cell_area, mat_stretch, mat_shear)
