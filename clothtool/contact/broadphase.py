"""Broad phase: axis-aligned boxes of elements and a uniform grid that pairs them.

Every element (vertex, edge, triangle) gets the box of its vertices over a motion
x → x + dx (dx = 0 for positions). The boxes of one set are binned into a uniform
grid (counting sort, one cell list per cell); each box of the other set, grown by
a radius r, visits the cells it covers. Two boxes that overlap after growing by r
hold every pair of elements closer than r anywhere along the motion, since the
Euclidean distance is at least the box distance. Work is proportional to the
number of nearby pairs: far-away parts of the scene cost one visit of their cells.

Pairs are filtered as IPC does: no pair that shares a vertex, no pair of two
collider (``obstacle``) elements, and cloth–cloth pairs only with ``self_contact``.
"""

import numpy as np

from clothtool.contact.barrier import EDGE_EDGE, POINT_PLANE, POINT_TRIANGLE
from clothtool.contact.distance import edge_edge_weights, point_triangle_weights
from clothtool.numba_setup import njit, njit_inner

MAX_CELLS_PER_BOX = 8.0  # cells of the grid per binned box at most (grows the cell size)


@njit_inner(cache=True)
def vertex_boxes(x, dx, rho):
    """(lo, hi), each (N, 3): the boxes of x_v and x_v + dx_v, grown by rho_v."""
    lo = np.empty_like(x)
    hi = np.empty_like(x)
    for i in range(x.shape[0]):
        for k in range(3):
            a, b = x[i, k], x[i, k] + dx[i, k]
            lo[i, k] = min(a, b) - rho[i]
            hi[i, k] = max(a, b) + rho[i]
    return lo, hi


@njit_inner(cache=True)
def element_boxes(vlo, vhi, elements):
    """(lo, hi), each (M, 3): the union of the vertex boxes of each element (M, width)."""
    m = elements.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    for e in range(m):
        for k in range(3):
            lo[e, k] = np.inf
            hi[e, k] = -np.inf
        for j in range(elements.shape[1]):
            v = elements[e, j]
            for k in range(3):
                lo[e, k] = min(lo[e, k], vlo[v, k])
                hi[e, k] = max(hi[e, k], vhi[v, k])
    return lo, hi


@njit_inner(cache=True)
def _mean_extent(lo, hi):
    total = 0.0
    for e in range(lo.shape[0]):
        total += max(hi[e, 0] - lo[e, 0], hi[e, 1] - lo[e, 1], hi[e, 2] - lo[e, 2])
    return total / max(lo.shape[0], 1)


@njit_inner(cache=True)
def _cell_range(lo, hi, origin, cell, dims):
    """Inclusive cell index ranges (i0, i1, j0, j1, k0, k1) of a box, clipped to the grid."""
    i0 = max(int(np.floor((lo[0] - origin[0]) / cell)), 0)
    j0 = max(int(np.floor((lo[1] - origin[1]) / cell)), 0)
    k0 = max(int(np.floor((lo[2] - origin[2]) / cell)), 0)
    i1 = min(int(np.floor((hi[0] - origin[0]) / cell)), dims[0] - 1)
    j1 = min(int(np.floor((hi[1] - origin[1]) / cell)), dims[1] - 1)
    k1 = min(int(np.floor((hi[2] - origin[2]) / cell)), dims[2] - 1)
    return i0, i1, j0, j1, k0, k1


@njit_inner(cache=True)
def build_grid(lo, hi, cell):
    """Bin boxes (lo, hi) into cells of size ≥ ``cell``:
    (origin, cell, dims, start, items, item_lo, item_hi, item_cell).

    Items of cell c are items[start[c]:start[c+1]], their boxes item_lo and item_hi at the
    same places (copied, so that a cell's boxes are read in order), and the cell (i, j, k)
    of each box's low corner in item_cell; cells are numbered x fastest.
    The cell size grows until there are at most MAX_CELLS_PER_BOX cells per box.
    """
    m = lo.shape[0]
    origin = np.zeros(3)
    top = np.zeros(3)
    if m > 0:
        for k in range(3):
            origin[k] = np.inf
            top[k] = -np.inf
    for e in range(m):
        for k in range(3):
            origin[k] = min(origin[k], lo[e, k])
            top[k] = max(top[k], hi[e, k])
    cell = max(cell, 1e-12)
    dims = np.ones(3, dtype=np.int64)
    while True:
        n_cells = 1
        for k in range(3):
            dims[k] = int((top[k] - origin[k]) / cell) + 1
            n_cells *= dims[k]
        if n_cells <= MAX_CELLS_PER_BOX * m + 64:
            break
        cell *= 1.5
    start = np.zeros(n_cells + 1, dtype=np.int64)
    for e in range(m):
        i0, i1, j0, j1, k0, k1 = _cell_range(lo[e], hi[e], origin, cell, dims)
        for kk in range(k0, k1 + 1):
            for jj in range(j0, j1 + 1):
                for ii in range(i0, i1 + 1):
                    start[ii + dims[0] * (jj + dims[1] * kk) + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    items = np.empty(start[n_cells], dtype=np.int64)
    item_lo = np.empty((start[n_cells], 3))
    item_hi = np.empty((start[n_cells], 3))
    item_cell = np.empty((start[n_cells], 3), dtype=np.int64)
    fill = start[:-1].copy()
    for e in range(m):
        i0, i1, j0, j1, k0, k1 = _cell_range(lo[e], hi[e], origin, cell, dims)
        for kk in range(k0, k1 + 1):
            for jj in range(j0, j1 + 1):
                for ii in range(i0, i1 + 1):
                    c = ii + dims[0] * (jj + dims[1] * kk)
                    q = fill[c]
                    items[q] = e
                    for k in range(3):
                        item_lo[q, k] = lo[e, k]
                        item_hi[q, k] = hi[e, k]
                    item_cell[q, 0], item_cell[q, 1], item_cell[q, 2] = i0, j0, k0
                    fill[c] += 1
    return origin, cell, dims, start, items, item_lo, item_hi, item_cell


@njit_inner(cache=True)
def _allowed(a, b, elem_a, elem_b, obstacle, self_contact):
    """IPC's pair filter: no shared vertex, not two colliders, cloth–cloth only with self contact."""
    for i in range(elem_a.shape[1]):
        for j in range(elem_b.shape[1]):
            if elem_a[a, i] == elem_b[b, j]:
                return False
    oa = obstacle[elem_a[a, 0]]
    ob = obstacle[elem_b[b, 0]]
    if oa and ob:
        return False
    return oa or ob or self_contact


@njit_inner(cache=True)
def box_pairs(alo, ahi, elem_a, blo, bhi, elem_b, r, obstacle, self_contact, same):
    """(K, 2) index pairs (a, b) whose boxes overlap once the a-box grows by r, filtered.

    ``same``: both sets are the same elements; each unordered pair comes once, a < b.
    """
    cell = max(_mean_extent(blo, bhi), _mean_extent(alo, ahi) + 2.0 * r)
    origin, cell, dims, start, items, item_lo, item_hi, item_cell = build_grid(blo, bhi, cell)
    out = np.empty((max(16, 4 * alo.shape[0]), 2), dtype=np.int64)
    n = 0
    qlo = np.empty(3)
    qhi = np.empty(3)
    for a in range(alo.shape[0]):
        for k in range(3):
            qlo[k] = alo[a, k] - r
            qhi[k] = ahi[a, k] + r
        i0, i1, j0, j1, k0, k1 = _cell_range(qlo, qhi, origin, cell, dims)
        for kk in range(k0, k1 + 1):
            for jj in range(j0, j1 + 1):
                for ii in range(i0, i1 + 1):
                    c = ii + dims[0] * (jj + dims[1] * kk)
                    for q in range(start[c], start[c + 1]):
                        b = items[q]
                        if same and b <= a:
                            continue
                        if (item_lo[q, 0] > qhi[0] or item_hi[q, 0] < qlo[0]
                                or item_lo[q, 1] > qhi[1] or item_hi[q, 1] < qlo[1]
                                or item_lo[q, 2] > qhi[2] or item_hi[q, 2] < qlo[2]):
                            continue
                        # each pair once: in the cell of the low corner of the boxes' overlap,
                        # the larger of the two low corners' cells (floor is monotone; an
                        # item's low corner is in the grid, so the query's clip at 0 is moot)
                        if (max(i0, item_cell[q, 0]) != ii or max(j0, item_cell[q, 1]) != jj
                                or max(k0, item_cell[q, 2]) != kk):
                            continue
                        if not _allowed(a, b, elem_a, elem_b, obstacle, self_contact):
                            continue
                        if n == out.shape[0]:
                            grown = np.empty((2 * n, 2), dtype=np.int64)
                            grown[:n] = out
                            out = grown
                        out[n, 0] = a
                        out[n, 1] = b
                        n += 1
    return out[:n].copy()


@njit_inner(cache=True)
def motion_bound(dx, rho, st):
    """How much the pair's distance at x can change for vertices anywhere within ρ of their
    motion x + t dx, t ∈ [0, 1]: the relative displacement bound of additive CCD (the
    displacements less their mean, the largest on each side added; a common translation
    does not count), plus the largest ρ on each side."""
    edge_edge = st[4] == EDGE_EDGE
    m0 = 0.25 * (dx[st[0], 0] + dx[st[1], 0] + dx[st[2], 0] + dx[st[3], 0])
    m1 = 0.25 * (dx[st[0], 1] + dx[st[1], 1] + dx[st[2], 1] + dx[st[3], 1])
    m2 = 0.25 * (dx[st[0], 2] + dx[st[1], 2] + dx[st[2], 2] + dx[st[3], 2])
    a = b = ra = rb = 0.0
    for j in range(4):
        q = (dx[st[j], 0] - m0) ** 2 + (dx[st[j], 1] - m1) ** 2 + (dx[st[j], 2] - m2) ** 2
        if j == 0 or (edge_edge and j == 1):
            a, ra = max(a, q), max(ra, rho[st[j]])
        else:
            b, rb = max(b, q), max(rb, rho[st[j]])
    return np.sqrt(a) + np.sqrt(b) + ra + rb


@njit(cache=True)
def contact_stencils(x, dx, rho, points, faces, edges, planes, n_cloth, obstacle, radius,
                     self_contact, r):
    """Candidate pairs over the motion x → x + dx as (K, 5) stencils, the fifth column their
    kind (``barrier.POINT_TRIANGLE``: (p, a, b, c); ``EDGE_EDGE``: (a0, a1, b0, b1);
    ``POINT_PLANE``: (p, o, t, o) for each plane (o, t) of ``planes`` (P, 2)).

    Holds every allowed pair whose surfaces come closer than r while each vertex v is
    within rho_v (N,) of its motion x_v + t dx_v, t ∈ [0, 1]: the pairs of overlapping
    boxes (a vertex's grown by its radius), less those whose surface distance at x exceeds
    r plus their motion bound (see ``motion_bound``); and the cloth vertices (the first
    n_cloth) that can come within r of a plane. ``points``: the vertices that are points of
    a surface (all but the planes' o and t); ``obstacle`` (N,) marks collider vertices,
    ``radius`` (N,) their radii; cloth–cloth pairs only with ``self_contact``.
    """
    grown = rho + radius
    vlo, vhi = vertex_boxes(x, dx, grown)
    flo, fhi = element_boxes(vlo, vhi, faces)
    elo, ehi = element_boxes(vlo, vhi, edges)
    vf = box_pairs(vlo[points], vhi[points], points.reshape(-1, 1), flo, fhi, faces, r, obstacle,
                   self_contact, False)
    ee = box_pairs(elo, ehi, edges, elo, ehi, edges, r, obstacle, self_contact, True)
    stencils = np.empty((vf.shape[0] + ee.shape[0] + n_cloth * planes.shape[0], 5),
                        dtype=np.int64)
    w = np.empty(4)
    n = 0
    for k in range(vf.shape[0]):
        f = vf[k, 1]
        st = stencils[n]
        st[0], st[1], st[2], st[3] = points[vf[k, 0]], faces[f, 0], faces[f, 1], faces[f, 2]
        st[4] = POINT_TRIANGLE
        d = np.sqrt(point_triangle_weights(x, st[0], st[1], st[2], st[3], w)) - radius[st[0]]
        if d - motion_bound(dx, rho, st) < r:
            n += 1
    for k in range(ee.shape[0]):
        st = stencils[n]
        st[0], st[1] = edges[ee[k, 0], 0], edges[ee[k, 0], 1]
        st[2], st[3] = edges[ee[k, 1], 0], edges[ee[k, 1], 1]
        st[4] = EDGE_EDGE
        d = np.sqrt(edge_edge_weights(x, st[0], st[1], st[2], st[3], w)) - radius[st[0]] - radius[st[2]]
        if d - motion_bound(dx, rho, st) < r:
            n += 1
    for q in range(planes.shape[0]):
        o, t = planes[q, 0], planes[q, 1]
        for p in range(n_cloth):
            st = stencils[n]
            st[0], st[1], st[2], st[3], st[4] = p, o, t, o, POINT_PLANE
            if _plane_reach(x, dx, rho, p, o, t) < r:
                n += 1
    return stencils[:n].copy()


@njit_inner(cache=True)
def _plane_reach(x, dx, rho, p, o, t):
    """A lower bound of vertex p's distance to the plane (o, t) along the motion, within
    rho of it: the distance at x less the bound of ``ccd``'s vertex–plane rate."""
    d = 0.0
    rel = 0.0
    dn = 0.0
    lever = 0.0
    for i in range(3):
        n_i = x[t, i] - x[o, i]
        d += (x[p, i] - x[o, i]) * n_i
        rel += (dx[p, i] - dx[o, i]) ** 2
        dn += (dx[t, i] - dx[o, i]) ** 2
        lever += (x[p, i] - x[o, i]) ** 2
    rel, dn, lever = np.sqrt(rel), np.sqrt(dn), np.sqrt(lever)
    return d - (rel * (1.0 + dn) + (lever + rel) * dn) - rho[p] - rho[o]


def mesh_edges(faces):
    """(E, 2) int64: the undirected edges of a triangle mesh, each once, lower index first."""
    faces = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    return np.unique(e, axis=0)
