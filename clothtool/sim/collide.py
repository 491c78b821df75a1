"""Planes and spheres: projection of vertices out of colliders after each step.

After the implicit step, every free vertex closer than ``margin`` to a collider
surface (signed distance φ < margin) is moved along the surface normal n to
φ = margin, its inward normal velocity v_n = v·n < 0 is removed, and Coulomb-like
friction scales its tangential velocity v_t by max(0, 1 − μ|v_n| / ‖v_t‖).
So no output frame has a vertex inside a collider. Contact is per vertex: edges
and faces can still cut a collider thinner than the mesh spacing.
"""

import numpy as np
from numba import njit


@njit(cache=True)
def _respond(x, v, i, normal, depth, mu):
    """Push vertex i out by depth along the unit normal and apply the velocity response."""
    for p in range(3):
        x[i, p] += depth * normal[p]
    vn = v[i, 0] * normal[0] + v[i, 1] * normal[1] + v[i, 2] * normal[2]
    if vn >= 0.0:
        return
    for p in range(3):
        v[i, p] -= vn * normal[p]
    if mu > 0.0:
        vt = np.sqrt(v[i, 0] ** 2 + v[i, 1] ** 2 + v[i, 2] ** 2)
        if vt > 0.0:
            scale = max(0.0, 1.0 - mu * (-vn) / vt)
            for p in range(3):
                v[i, p] *= scale


@njit(cache=True)
def resolve_collisions(x, v, free, spheres, sphere_mu, planes, plane_mu, margin):
    """spheres (S, 4): centre, radius; planes (P, 6): point, unit normal. In place."""
    for i in range(x.shape[0]):
        if not free[i]:
            continue
        for s in range(spheres.shape[0]):
            d = x[i] - spheres[s, :3]
            dist = np.sqrt(d @ d)
            reach = spheres[s, 3] + margin
            if dist < reach:
                if dist > 0.0:
                    normal = d / dist
                else:
                    normal = np.array([0.0, 0.0, 1.0])
                _respond(x, v, i, normal, reach - dist, sphere_mu[s])
        for s in range(planes.shape[0]):
            normal = planes[s, 3:]
            phi = (x[i, 0] - planes[s, 0]) * normal[0] + (x[i, 1] - planes[s, 1]) * normal[1] \
                + (x[i, 2] - planes[s, 2]) * normal[2]
            if phi < margin:
                _respond(x, v, i, normal, margin - phi, plane_mu[s])
