"""Closest points of vertex–triangle and edge–edge pairs, as weights on the four vertices.

A pair (p; a, b, c) or (a0, a1; b0, b1) has the difference vector between its closest
points r = Σ_k w_k x_k, with w = (1, −α, −β, −γ) for the barycentric closest point
αa + βb + γc on the triangle and w = (1−s, s, −(1−t), −t) for the segment parameters
s, t. The distance is d = ‖r‖. The region of the closest point (vertex, edge or face
of the triangle; end point or interior of each segment) is the distance type of IPC
(Li et al. 2020, §4); here it shows only in which weights are 0 or 1. By Danskin's
theorem ∇_{x_k} d² = 2 w_k r in every region, the weights held fixed.
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner


@njit(cache=True, inline="always")
def _sub(x, i, j):
    return x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]


@njit(cache=True, inline="always")
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(cache=True)
def point_triangle_weights(x, p, a, b, c, w):
    """Fill w (4,) with the closest-point weights of vertex p to the triangle (a, b, c) of
    x (N, 3); returns d². Voronoi-region walk of Ericson, "Real-Time Collision Detection"
    (2005), §5.1.5.
    """
    ab, ac, ap = _sub(x, b, a), _sub(x, c, a), _sub(x, p, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        v, t = 0.0, 0.0
    else:
        bp, cp = _sub(x, p, b), _sub(x, p, c)
        d3, d4 = _dot(ab, bp), _dot(ac, bp)
        d5, d6 = _dot(ab, cp), _dot(ac, cp)
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            v, t = 1.0, 0.0
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            v, t = d1 / (d1 - d3), 0.0
        elif d6 >= 0.0 and d5 <= d6:
            v, t = 0.0, 1.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            v, t = 0.0, d2 / (d2 - d6)
        elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            v = 1.0 - t
        else:
            s = va + vb + vc
            v, t = vb / s, vc / s
    w[0] = 1.0
    w[1] = -(1.0 - v - t)
    w[2] = -v
    w[3] = -t
    r0 = ap[0] - v * ab[0] - t * ac[0]
    r1 = ap[1] - v * ab[1] - t * ac[1]
    r2 = ap[2] - v * ab[2] - t * ac[2]
    return r0 * r0 + r1 * r1 + r2 * r2


@njit(cache=True, inline="always")
def _clamp01(s):
    return min(max(s, 0.0), 1.0)


@njit(cache=True)
def edge_edge_weights(x, a0, a1, b0, b1, w):
    """Fill w (4,) with the closest-point weights of the segments (a0, a1) and (b0, b1) of
    x (N, 3); returns d². Ericson (2005), §5.1.9; parallel segments take s = 0 (any
    minimiser will do).
    """
    d1, d2, r = _sub(x, a1, a0), _sub(x, b1, b0), _sub(x, a0, b0)
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    if a <= 0.0 and e <= 0.0:
        s, t = 0.0, 0.0
    elif a <= 0.0:
        s, t = 0.0, _clamp01(f / e)
    else:
        c = _dot(d1, r)
        if e <= 0.0:
            s, t = _clamp01(-c / a), 0.0
        else:
            b = _dot(d1, d2)
            denom = a * e - b * b
            s = _clamp01((b * f - c * e) / denom) if denom > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = _clamp01(-c / a), 0.0
            elif t > 1.0:
                s, t = _clamp01((b - c) / a), 1.0
    w[0] = 1.0 - s
    w[1] = s
    w[2] = -(1.0 - t)
    w[3] = -t
    q0 = r[0] + s * d1[0] - t * d2[0]
    q1 = r[1] + s * d1[1] - t * d2[1]
    q2 = r[2] + s * d1[2] - t * d2[2]
    return q0 * q0 + q1 * q1 + q2 * q2


@njit_inner(cache=True)
def cross_squared(x, a0, a1, b0, b1):
    """‖(x_a1 − x_a0) × (x_b1 − x_b0)‖², small when the edges are nearly parallel."""
    u, v = _sub(x, a1, a0), _sub(x, b1, b0)
    c0 = u[1] * v[2] - u[2] * v[1]
    c1 = u[2] * v[0] - u[0] * v[2]
    c2 = u[0] * v[1] - u[1] * v[0]
    return c0 * c0 + c1 * c1 + c2 * c2


@njit(cache=True)
def closest_offsets(x, faces, first, points, candidates, out):
    """The offset p − c from its closest point c on the candidate triangles, for each row r:
    p = x[first + points[r]], candidates[r] triangle indices into ``faces`` (−1: none);
    written to ``out[r]``, the distance returned."""
    w = np.empty(4)
    dist = np.empty(len(points))
    for r in range(len(points)):
        p = first + points[r]
        best = np.inf
        for f in candidates[r]:
            if f < 0:
                continue
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            d2 = point_triangle_weights(x, p, a, b, c, w)
            if d2 < best:
                best = d2
                for i in range(3):
                    out[r, i] = x[p, i] + w[1] * x[a, i] + w[2] * x[b, i] + w[3] * x[c, i]
        dist[r] = np.sqrt(best)
    return dist
