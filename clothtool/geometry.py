"""Triangle-mesh geometry shared by the analysis and the simulator, each piece written once.

- the **tangent-frame edge matrix** of a triangle (x0, x1, x2), e1 = x1 − x0, e2 = x2 − x0:
  t1 = e1/‖e1‖, n = e1×e2/‖e1×e2‖, t2 = n×t1 and
  D = [[t1·e1, t1·e2], [t2·e1, t2·e2]] = [[‖e1‖, t1·e2], [0, ‖e1×e2‖/‖e1‖]],
  upper triangular with a positive diagonal (the rest matrix D_r of F = D_d·D_r⁻¹);
- the **signed dihedral angle** of a hinge (i, j, k, l): the shared edge e = x_j − x_i, the
  triangles (i, j, k) and (j, i, l) with normals N_k = e × (x_k − x_i) and
  N_l = (x_i − x_j) × (x_l − x_j) (oriented alike), and
  θ = atan2(ê·(N_k × N_l), N_k·N_l), 0 when flat, > 0 when the surface bends away from its
  normal; its gradient (Bridson et al. 2003, "Simulation of clothing with folds and wrinkles")
  and exact Hessian;
- the connectivity tables built by sorting half-edges: interior edges as hinges, one-rings;
- the criss-cross triangulation of a regular grid.

Kernels are numba on scalars and 3-tuples (no heap allocation in per-element loops).
"""

import math

import numpy as np
from numba import prange

from clothtool.numba_setup import njit, njit_inner
from clothtool.vec3 import cross, dot, load, scale, sub

DEGENERATE_TOL = 1e-8
"""A triangle is degenerate when ‖e1×e2‖ ≤ DEGENERATE_TOL·(longest edge)²."""

DEGENERATE = np.uint8(2)
NONFINITE = np.uint8(4)

HINGE_TOL = 1e-12
"""A hinge is degenerate when its edge has zero length or a triangle has ‖N‖ ≤ HINGE_TOL·‖e‖²."""


# ---------------------------------------------------------------- tangent-frame edge matrix

@njit(cache=True, inline="always")
def tangent_edge_matrix(x, i0, i1, i2, tol):
    """Edge matrix of triangle (i0, i1, i2) in its tangent frame, as scalars:
    (a, b, c) = (D00, D01, D11), the frame rows t1, t2 as six scalars, and a status:
    0, DEGENERATE (‖e1×e2‖ ≤ tol·(longest edge)²) or NONFINITE."""
    e1x, e1y, e1z = x[i1, 0] - x[i0, 0], x[i1, 1] - x[i0, 1], x[i1, 2] - x[i0, 2]
    e2x, e2y, e2z = x[i2, 0] - x[i0, 0], x[i2, 1] - x[i0, 1], x[i2, 2] - x[i0, 2]
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    area2 = np.sqrt(nx * nx + ny * ny + nz * nz)
    l1 = e1x * e1x + e1y * e1y + e1z * e1z
    l2 = e2x * e2x + e2y * e2y + e2z * e2z
    l3 = (e2x - e1x) ** 2 + (e2y - e1y) ** 2 + (e2z - e1z) ** 2
    if not np.isfinite(area2 + l1 + l2 + l3):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, NONFINITE
    if area2 <= tol * max(l1, l2, l3):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, DEGENERATE
    a = np.sqrt(l1)
    t1x, t1y, t1z = e1x / a, e1y / a, e1z / a
    nx, ny, nz = nx / area2, ny / area2, nz / area2
    t2x = ny * t1z - nz * t1y
    t2y = nz * t1x - nx * t1z
    t2z = nx * t1y - ny * t1x
    b = t1x * e2x + t1y * e2y + t1z * e2z
    return a, b, area2 / a, t1x, t1y, t1z, t2x, t2y, t2z, np.uint8(0)


@njit(cache=True, parallel=True)
def tangent_edge_matrices(x, faces, tol):
    """D (M, 2, 2) of every triangle (:func:`tangent_edge_matrix`) and its status (M,) uint8;
    D is 0 where the status is not 0."""
    m = faces.shape[0]
    d = np.zeros((m, 2, 2))
    status = np.zeros(m, np.uint8)
    for k in prange(m):
        a, b, c, _, _, _, _, _, _, s = tangent_edge_matrix(x, faces[k, 0], faces[k, 1], faces[k, 2], tol)
        status[k] = s
        d[k, 0, 0], d[k, 0, 1], d[k, 1, 1] = a, b, c
    return d, status


# ---------------------------------------------------------------- dihedral angle

@njit(cache=True, inline="always")
def hinge_normals(xi, xj, xk, xl):
    """Edge e = x_j − x_i and the normals N_k = e × (x_k − x_i), N_l = (x_i − x_j) × (x_l − x_j)."""
    e = sub(xj, xi)
    return e, cross(e, sub(xk, xi)), cross(sub(xi, xj), sub(xl, xj))


@njit(cache=True, inline="always")
def angle_of_normals(e, nk, nl):
    """θ = atan2(ê·(N_k × N_l), N_k·N_l)."""
    return math.atan2(dot(cross(nk, nl), e) / math.sqrt(dot(e, e)), dot(nk, nl))


@njit_inner(cache=True)
def _hinge_degenerate(ll, nk, nl):
    limit = HINGE_TOL * HINGE_TOL * ll * ll
    return ll == 0.0 or dot(nk, nk) <= limit or dot(nl, nl) <= limit


@njit(cache=True)
def dihedral_angle(x, hinge):
    """θ of hinge (i, j, k, l) = ``hinge`` over positions x (N, 3); NaN for a degenerate hinge."""
    e, nk, nl = hinge_normals(load(x, hinge[0]), load(x, hinge[1]), load(x, hinge[2]), load(x, hinge[3]))
    if _hinge_degenerate(dot(e, e), nk, nl):
        return np.nan
    return angle_of_normals(e, nk, nl)


@njit(cache=True)
def dihedral_angles(x, hinges):
    """θ of every hinge (H,)."""
    out = np.empty(hinges.shape[0])
    for h in range(hinges.shape[0]):
        out[h] = dihedral_angle(x, hinges[h])
    return out


@njit(cache=True)
def dihedral_angle_gradient(xi, xj, xk, xl, grad):
    """θ and ∇θ (12,), order (i, j, k, l) (Bridson et al. 2003): with L = ‖e‖ and s_k, s_l the
    feet of k and l along e (0 at i, 1 at j),
    ∇_k θ = −L N_k/‖N_k‖², ∇_l θ = −L N_l/‖N_l‖², ∇_i θ = −(1 − s_k)∇_k θ − (1 − s_l)∇_l θ,
    ∇_j θ = −s_k ∇_k θ − s_l ∇_l θ. NaN and ∇θ = 0 for a degenerate hinge."""
    e, nk, nl = hinge_normals(xi, xj, xk, xl)
    ll = dot(e, e)
    if _hinge_degenerate(ll, nk, nl):
        grad[:] = 0.0
        return np.nan
    length = np.sqrt(ll)
    gk = scale(-length / dot(nk, nk), nk)
    gl = scale(-length / dot(nl, nl), nl)
    sk = dot(sub(xk, xi), e) / ll
    sl = dot(sub(xl, xi), e) / ll
    for p in range(3):
        grad[p] = -(1.0 - sk) * gk[p] - (1.0 - sl) * gl[p]
        grad[3 + p] = -sk * gk[p] - sl * gl[p]
        grad[6 + p] = gk[p]
        grad[9 + p] = gl[p]
    return angle_of_normals(e, nk, nl)


@njit_inner(cache=True)
def _skew(a):
    """[a]× with [a]× v = a × v."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@njit_inner(cache=True)
def _normal_gradient_jacobian(n, length, e_hat, d_n, jac):
    """Jacobian (3×12) of g = −L N/‖N‖² given ∂N/∂x_v = d_n[v] (3×3 each).

    dg = −(N/‖N‖²) dL − (L/‖N‖²)(I − 2 n̂ n̂ᵀ) dN, with dL = ê·(dx_j − dx_i).
    """
    nn = n @ n
    proj = np.eye(3) - 2.0 * np.outer(n, n) / nn
    for v in range(4):
        block = -(length / nn) * (proj @ d_n[v])
        if v == 0:
            block += np.outer(n, e_hat) / nn
        elif v == 1:
            block -= np.outer(n, e_hat) / nn
        jac[:, 3 * v:3 * v + 3] = block


@njit_inner(cache=True)
def dihedral_angle_hessian(xi, xj, xk, xl, hess):
    """Exact ∇²θ (12, 12), order (i, j, k, l), the derivative of :func:`dihedral_angle_gradient`'s
    formulas (Tamstorf & Grinspun 2013 give the same in another notation); xi… are (3,) arrays."""
    e = xj - xi
    ll = e @ e
    length = np.sqrt(ll)
    e_hat = e / length
    nk = np.cross(e, xk - xi)
    nl = np.cross(xi - xj, xl - xj)
    gk = -length * nk / (nk @ nk)
    gl = -length * nl / (nl @ nl)
    sk = (xk - xi) @ e / ll
    sl = (xl - xi) @ e / ll
    zero = np.zeros((3, 3))
    d_nk = np.empty((4, 3, 3))
    d_nk[0], d_nk[1], d_nk[2], d_nk[3] = _skew(xk - xj), _skew(xi - xk), _skew(xj - xi), zero
    d_nl = np.empty((4, 3, 3))
    d_nl[0], d_nl[1], d_nl[2], d_nl[3] = _skew(xj - xl), _skew(xl - xi), zero, _skew(xi - xj)
    jk = np.empty((3, 12))
    jl = np.empty((3, 12))
    _normal_gradient_jacobian(nk, length, e_hat, d_nk, jk)
    _normal_gradient_jacobian(nl, length, e_hat, d_nl, jl)
    # ∇s for s = (x_w − x_i)·e/L²: ∂/∂x_w = e/L², ∂/∂x_j = (x_w − x_i)/L² − 2 s e/L², ∂/∂x_i = −both
    dsk = np.zeros(12)
    dsl = np.zeros(12)
    dsk[6:9] = e / ll
    dsk[3:6] = (xk - xi) / ll - 2.0 * sk * e / ll
    dsk[0:3] = -dsk[6:9] - dsk[3:6]
    dsl[9:12] = e / ll
    dsl[3:6] = (xl - xi) / ll - 2.0 * sl * e / ll
    dsl[0:3] = -dsl[9:12] - dsl[3:6]
    hess[0:3, :] = -(1.0 - sk) * jk + np.outer(gk, dsk) - (1.0 - sl) * jl + np.outer(gl, dsl)
    hess[3:6, :] = -sk * jk - np.outer(gk, dsk) - sl * jl - np.outer(gl, dsl)
    hess[6:9, :] = jk
    hess[9:12, :] = jl


# ---------------------------------------------------------------- connectivity

def _half_edges(faces):
    """(source, destination, opposite corner, face) of the 3·M half-edges, zero-length ones dropped."""
    faces = np.asarray(faces, dtype=np.int64)
    src = faces[:, [0, 1, 2]].ravel()
    dst = faces[:, [1, 2, 0]].ravel()
    opp = faces[:, [2, 0, 1]].ravel()
    face = np.repeat(np.arange(len(faces), dtype=np.int64), 3)
    keep = src != dst
    return src[keep], dst[keep], opp[keep], face[keep]


def hinges(faces, n_vertices):
    """Interior edges (shared by exactly two faces) as hinges (i, j, k, l), with their two faces.

    Sorted by edge, i < j; k is the third corner of a face that runs i → j (so the triangle
    (i, j, k) carries the mesh orientation, and (j, i, l) the other face's), or, for an
    inconsistently oriented pair, of the face listed first. Boundary edges (one face) and
    non-manifold edges (three or more) have no hinge. Returns (hinge (H, 4), hinge_faces (H, 2)),
    int64, hinge_faces[h, 0] holding k.
    """
    src, dst, opp, face = _half_edges(faces)
    n = np.int64(n_vertices)
    lo, hi = np.minimum(src, dst), np.maximum(src, dst)
    key = lo * n + hi
    order = np.lexsort((src > dst, key))  # by edge, then the i → j half-edge first
    key, lo, hi, opp, face = key[order], lo[order], hi[order], opp[order], face[order]
    _, start, count = np.unique(key, return_index=True, return_counts=True)
    first = start[count == 2]
    hinge = np.stack([lo[first], hi[first], opp[first], opp[first + 1]], axis=1)
    return hinge, np.stack([face[first], face[first + 1]], axis=1)


def one_ring(faces, n_vertices):
    """Compressed one-ring table: the neighbours of vertex i are ``neighbours[offsets[i]:offsets[i+1]]``.

    A neighbour is a vertex sharing an edge with i; each is listed once, in increasing order,
    and i itself is not listed. Vertices on no face have an empty ring.
    Returns ``offsets`` (N+1,) and ``neighbours`` (K,), both int64.
    """
    src, dst, _, _ = _half_edges(faces)
    n = np.int64(n_vertices)
    key = np.unique(np.concatenate([src * n + dst, dst * n + src]))  # sorted by (source, dest)
    owner = key // n
    offsets = np.searchsorted(owner, np.arange(n + 1, dtype=np.int64)).astype(np.int64)
    return offsets, (key % n).astype(np.int64)


def grid_triangles(nx, ny):
    """The (2(nx−1)(ny−1), 3) int64 triangles of an nx × ny vertex grid, vertex index j·nx + i.

    Quads are split along alternating diagonals (criss-cross by parity of i + j) so that the
    grid has no preferred shear direction; every triangle is counter-clockwise in (i, j).
    """
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    i, j = i.ravel(), j.ravel()
    v00, v10 = j * nx + i, j * nx + i + 1
    v01, v11 = v00 + nx, v10 + nx
    even = (i + j) % 2 == 0
    # even: diagonal v00–v11; odd: diagonal v10–v01
    t1 = np.where(even[:, None], np.stack([v00, v10, v11], 1), np.stack([v00, v10, v01], 1))
    t2 = np.where(even[:, None], np.stack([v00, v11, v01], 1), np.stack([v10, v11, v01], 1))
    return np.concatenate([t1, t2]).astype(np.int64)


def grid_uv(nx, ny, width, height):
    """(nx·ny, 2) in-plane coordinates of that grid, centred on the origin, row j = ny − 1 on top."""
    uu, vv = np.meshgrid(np.linspace(-width / 2, width / 2, nx),
                         np.linspace(-height / 2, height / 2, ny))  # (ny, nx): row j, column i
    return np.stack([uu.ravel(), vv.ravel()], axis=1)
