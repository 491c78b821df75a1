"""Collision-free step fraction by additive CCD (Li et al. 2021, "Codimensional IPC", Alg. 1).

For a pair moving linearly x + t dx, the displacements are made relative (their
mean removed) and bounded by l_p = ‖δp‖ + max_k ‖δt_k‖ (vertex–triangle) or
max ‖δa‖ + max ‖δb‖ (edge–edge), so the distance can shrink by at most l_p·Δt in
Δt. The time advances by t_l = η (d − ξ)/l_p, evaluating d anew each time, until
d − ξ falls below the gap (1 − η)(d₀ − ξ) or t passes t_max: the returned t is
the last time before that, at which the pair is still farther apart than ξ.
η = 0.9 as in the paper. Steps are capped at MAX_ITERATIONS (then the time
reached so far is returned, which is conservative). A vertex against a moving plane
(p; o, t) has d(t) = (p − o)·(t − o) along the motion, whose rate is bounded by
l_p = ‖δp − δo‖(1 + ‖δn‖) + (‖p − o‖ + ‖δp − δo‖)‖δn‖ with δn = δt − δo.
"""

import numpy as np

from clothtool.contact.barrier import (EDGE_EDGE, POINT_PLANE, pair_distance, pair_radius,
                                       pair_thickness)
from clothtool.contact.broadphase import motion_bound
from clothtool.numba_setup import njit, njit_inner

ETA = 0.9
MAX_ITERATIONS = 2000


@njit_inner(cache=True)
def _norm(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit_inner(cache=True)
def _relative_bound(x4, dx4, kind):
    """l_p of a pair (see the module): how fast its distance can shrink along the motion."""
    if kind == POINT_PLANE:
        rel = dx4[0] - dx4[1]
        dn = dx4[2] - dx4[1]
        lever = x4[0] - x4[1]
        return _norm(rel) * (1.0 + _norm(dn)) + (_norm(lever) + _norm(rel)) * _norm(dn)
    p = dx4.copy()
    for i in range(3):
        mean = 0.25 * (p[0, i] + p[1, i] + p[2, i] + p[3, i])
        for j in range(4):
            p[j, i] -= mean
    if kind == EDGE_EDGE:
        return max(_norm(p[0]), _norm(p[1])) + max(_norm(p[2]), _norm(p[3]))
    return _norm(p[0]) + max(_norm(p[1]), _norm(p[2]), _norm(p[3]))


@njit(cache=True)
def additive_ccd(x4, dx4, kind, xi, eta, tmax):
    """Collision-free time in [0, t_max] of one pair (x4, dx4: (4, 3) positions and motions
    of its stencil's vertices, ``kind`` its stencil kind)."""
    st = np.array([0, 1, 2, 3, kind])
    w = np.empty(4)
    r = np.empty(3)
    lp = _relative_bound(x4, dx4, kind)
    if lp == 0.0:
        return tmax
    x = x4.copy()
    d2 = pair_distance(x, st, w, r)
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
                x[j, i] = x4[j, i] + (t + tl) * dx4[j, i]
        d2 = pair_distance(x, st, w, r)
        d = np.sqrt(d2)
        if t > 0.0 and (d2 - xi * xi) / (d + xi) < gap:
            return t
        t += tl
        if t > tmax:
            return tmax
    return t


@njit(cache=True)
def collision_free_step(x, dx, stencils, geometry, tmax):
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
        xi = pair_thickness(st, geometry)[0]
        t = min(t, additive_ccd(x4, dx4, st[4], xi, ETA, t))
        if t == 0.0:
            break
    return t


@njit(cache=True)
def near_pairs(x, dx, stencils, geometry, reach):
    """The candidates that can come within ``reach`` of their thickness somewhere on
    x + [0, 1] dx: surface distance at x minus the relative motion bound
    (:func:`~clothtool.contact.broadphase.motion_bound`; a common translation of the pair
    does not count) below reach. Vertex–plane pairs are all kept (few, and their bound
    depends on the lever)."""
    w = np.empty(4)
    r = np.empty(3)
    radius = geometry[1]
    no_reach = np.zeros(x.shape[0])
    keep = np.empty(stencils.shape[0], dtype=np.bool_)
    for k in range(stencils.shape[0]):
        st = stencils[k]
        if st[4] == POINT_PLANE:
            keep[k] = True
            continue
        d = np.sqrt(pair_distance(x, st, w, r)) - pair_radius(st, radius)
        keep[k] = d - motion_bound(dx, no_reach, st) < reach
    return stencils[keep].copy()
