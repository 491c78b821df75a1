"""Planes and spheres by projection, for the methods without barrier contact.

After each step every free vertex closer than ``margin`` to a collider surface (signed
distance φ < margin) is projected out along the surface normal n to φ = margin and loses
its inward normal velocity, so no output frame has a vertex inside a collider. Contact
is per vertex: edges and faces can still cut a collider thinner than the mesh spacing.
The implicit method puts every collider into its contact barrier instead
(:mod:`clothtool.sim.solve.contact`).
"""

import numpy as np

from clothtool.numba_setup import njit, njit_inner



@njit_inner(cache=True)
def _closest(x, spheres, planes):
    """(signed distance, unit normal, collider id) of the nearest collider surface to x."""
    best, best_n, best_id = np.inf, (0.0, 0.0, 1.0), -1
    for s in range(spheres.shape[0]):
        d0, d1, d2 = x[0] - spheres[s, 0], x[1] - spheres[s, 1], x[2] - spheres[s, 2]
        dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        phi = dist - spheres[s, 3]
        if phi < best:
            best, best_id = phi, s
            best_n = (d0 / dist, d1 / dist, d2 / dist) if dist > 0.0 else (0.0, 0.0, 1.0)
    for s in range(planes.shape[0]):
        phi = ((x[0] - planes[s, 0]) * planes[s, 3] + (x[1] - planes[s, 1]) * planes[s, 4]
               + (x[2] - planes[s, 2]) * planes[s, 5])
        if phi < best:
            best, best_id = phi, spheres.shape[0] + s
            best_n = (planes[s, 3], planes[s, 4], planes[s, 5])
    return best, best_n, best_id


@njit(cache=True)
def resolve_collisions(x, v, free, spheres, planes, margin):
    """Project free vertices closer than margin out to φ = margin; drop inward normal velocity."""
    for i in range(x.shape[0]):
        if not free[i]:
            continue
        for _ in range(4):  # a few passes for vertices between two colliders
            phi, n, _ = _closest(x[i], spheres, planes)
            if phi >= margin:
                break
            for p in range(3):
                x[i, p] += (margin - phi) * n[p]
            vn = v[i, 0] * n[0] + v[i, 1] * n[1] + v[i, 2] * n[2]
            if vn < 0.0:
                for p in range(3):
                    v[i, p] -= vn * n[p]
