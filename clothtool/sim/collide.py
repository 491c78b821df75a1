"""Planes and spheres: contact as Baraff–Witkin constraints, projection as a safety net.

Before each step, every free vertex whose predicted position x_n + h v_n + h² g
comes closer than ``margin`` to a collider surface (signed distance φ < margin)
is held on it for the step: its motion along the surface normal n is prescribed,
n·Δx = margin − φ(x_n), and the filter S = I − n nᵀ leaves it free to slide (see
``linalg.pcg``). The solve then moves its neighbours consistently, which a
projection after the step cannot do: pushing one vertex of stiff cloth back by a
few centimetres strains its triangles by tens of percent and feeds energy in.

After the solve, the constraint force λ = n·(b − AΔx) (N) is the normal force
of the contact. Coulomb friction removes up to μλĥ/m of the tangential velocity (ĥ the
integrator's effective step: h for backward Euler, 2h/3 for BDF2).
A vertex whose λ < 0 (the cloth pulls it off the surface) is released at the
next step. Finally every free vertex still closer than ``margin`` (contacts the
prediction missed) is projected out along n and loses its inward normal
velocity, so no output frame has a vertex inside a collider. Contact is per
vertex: edges and faces can still cut a collider thinner than the mesh spacing.
"""

import numpy as np
from numba import njit

from clothtool.sim.filter import FREE, SLIDING


@njit(cache=True)
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
def contact_constraints(x, predicted, kind, released, spheres, planes, margin, normal, dx, contact):
    """Mark vertices whose prediction reaches a collider as SLIDING (in kind, in place).

    Sets their normal, the prescribed normal part of dx, and the collider id in
    ``contact`` (−1 elsewhere). Returns the number of such vertices.
    """
    count = 0
    for i in range(x.shape[0]):
        contact[i] = -1
        if kind[i] != FREE or released[i]:
            continue
        phi_pred, _, _ = _closest(predicted[i], spheres, planes)
        if phi_pred >= margin:
            continue
        phi, n, cid = _closest(x[i], spheres, planes)
        kind[i] = SLIDING
        contact[i] = cid
        push = margin - phi
        along = dx[i, 0] * n[0] + dx[i, 1] * n[1] + dx[i, 2] * n[2]
        for p in range(3):
            normal[i, p] = n[p]
            dx[i, p] += (push - along) * n[p]
        count += 1
    return count


@njit(cache=True)
def apply_friction(v, mass, h, contact, force, normal, friction):
    """Coulomb friction at held vertices: ‖Δv_t‖ ≤ μ λ h / m for normal force λ = force·n > 0."""
    for i in range(v.shape[0]):
        if contact[i] < 0:
            continue
        lam = force[i, 0] * normal[i, 0] + force[i, 1] * normal[i, 1] + force[i, 2] * normal[i, 2]
        mu = friction[contact[i]]
        if mu <= 0.0 or lam <= 0.0:
            continue
        vn = v[i, 0] * normal[i, 0] + v[i, 1] * normal[i, 1] + v[i, 2] * normal[i, 2]
        t0, t1, t2 = v[i, 0] - vn * normal[i, 0], v[i, 1] - vn * normal[i, 1], v[i, 2] - vn * normal[i, 2]
        vt = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        if vt == 0.0:
            continue
        scale = max(0.0, 1.0 - mu * lam * h / (mass[i] * vt))
        v[i, 0] = vn * normal[i, 0] + scale * t0
        v[i, 1] = vn * normal[i, 1] + scale * t1
        v[i, 2] = vn * normal[i, 2] + scale * t2


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
