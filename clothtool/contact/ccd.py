"""Collision-free step fraction by additive CCD (Li et al. 2021, "Codimensional IPC", Alg. 1).

For a pair moving linearly x + t dx, the displacements are made relative (their
mean removed) and bounded by l_p = ‖δp‖ + max_k ‖δt_k‖ (vertex–triangle) or
max ‖δa‖ + max ‖δb‖ (edge–edge), so the distance can shrink by at most l_p·Δt in
Δt. The time advances by t_l = η (d − ξ)/l_p, evaluating d anew each time, until
d − ξ falls below the gap (1 − η)(d₀ − ξ) or t passes t_max: the returned t is
the last time before that, at which the pair is still farther apart than ξ.
η = 0.9 as in the paper. Steps are capped at MAX_ITERATIONS (then the time
reached so far is returned, which is conservative).
"""

import numpy as np
from numba import njit

from clothtool.contact.barrier import pair_distance, pair_thickness
from clothtool.contact.broadphase import motion_bound

ETA = 0.9
MAX_ITERATIONS = 2000


@njit(cache=True)
def _norm(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True)
def additive_ccd(x4, dx4, edge_edge, xi, eta, tmax):
    """Collision-free time in [0, t_max] of one pair (x4, dx4: (4, 3) positions and motions)."""
    st = np.arange(4)
    w = np.empty(4)
    p = dx4.copy()
    for i in range(3):
        mean = 0.25 * (p[0, i] + p[1, i] + p[2, i] + p[3, i])
        for j in range(4):
            p[j, i] -= mean
    if edge_edge:
        lp = max(_norm(p[0]), _norm(p[1])) + max(_norm(p[2]), _norm(p[3]))
    else:
        lp = _norm(p[0]) + max(_norm(p[1]), _norm(p[2]), _norm(p[3]))
    if lp == 0.0:
        return tmax
    x = x4.copy()
    d2 = pair_distance(x, st, edge_edge, w)
    if d2 <= xi * xi:
        return 0.0
    d = np.sqrt(d2)
    if d - xi > lp * tmax:  # cannot close the gap before t_max
        return tmax
    gap = (1.0 - eta) * (d2 - xi * xi) / (d + xi)
    t = 0.0
    for _ in range(MAX_ITERATIONS):
        tl = eta * (d2 - xi * xi) / ((d + xi) * lp)
        for j in range(4):
            for i in range(3):
                x[j, i] += tl * p[j, i]
        d2 = pair_distance(x, st, edge_edge, w)
        d = np.sqrt(d2)
        if t > 0.0 and (d2 - xi * xi) / (d + xi) < gap:
            return t
        t += tl
        if t > tmax:
            return tmax
    return t


@njit(cache=True)
def collision_free_step(x, dx, stencils, n_pt, obstacle, xi_self, xi_obstacle, tmax):
    """The largest t ≤ t_max such that every candidate pair stays farther than its ξ on
    x + [0, t] dx (stencils from ``broadphase.contact_stencils`` over the same motion)."""
    t = tmax
    x4 = np.empty((4, 3))
    dx4 = np.empty((4, 3))
    for k in range(stencils.shape[0]):
        st = stencils[k]
        for j in range(4):
            for i in range(3):
                x4[j, i] = x[st[j], i]
                dx4[j, i] = dx[st[j], i]
        xi = pair_thickness(st, obstacle, xi_self, xi_obstacle)
        t = min(t, additive_ccd(x4, dx4, k >= n_pt, xi, ETA, t))
        if t == 0.0:
            break
    return t


@njit(cache=True)
def near_pairs(x, dx, stencils, n_pt, reach):
    """(stencils, count of vertex–triangle ones) of the candidates that can come within
    ``reach`` somewhere on x + [0, 1] dx: distance at x minus the relative motion bound
    (:func:`~clothtool.contact.broadphase.motion_bound`; a common translation of the pair
    does not count) below reach."""
    w = np.empty(4)
    no_reach = np.zeros(x.shape[0])
    keep = np.empty(stencils.shape[0], dtype=np.bool_)
    n_near_pt = 0
    for k in range(stencils.shape[0]):
        st = stencils[k]
        ee = k >= n_pt
        d = np.sqrt(pair_distance(x, st, ee, w))
        keep[k] = d - motion_bound(dx, no_reach, st, ee) < reach
        if keep[k] and not ee:
            n_near_pt += 1
    return stencils[keep].copy(), n_near_pt
