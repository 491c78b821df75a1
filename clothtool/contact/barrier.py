"""The contact barrier: energy, gradient and a Gauss–Newton Hessian over candidate pairs.

A pair is a stencil of four vertex indices and a kind (column 4):

- ``POINT_TRIANGLE`` (p; a, b, c) and ``EDGE_EDGE`` (a0, a1; b0, b1), at the distance of
  their closest points (see ``distance``);
- ``POINT_PLANE`` (p; o, t, o): a vertex and a plane through o with unit normal t − o, at
  the signed distance (p − o)·(t − o) (a vertex behind the plane is in contact).

Vertices carry a radius (0 but for analytic colliders): a sphere is its centre with the
sphere's radius, a capsule its axis segment with the capsule's; a pair's distance to the
surfaces is d − R, R the radius of its vertex or edges. So a sphere against a cloth
triangle is the exact triangle–sphere distance, and a capsule's segment against a cloth
triangle's edges and its end points against the triangle the exact one of a capsule.

With the pair's wall ξ (plus R) and its activation distance d̂ (the collider's when a
collider takes part, the cloth's otherwise; see :mod:`clothtool.sim.solve.contact`), u = d² − ξ²
and, within d̂ beyond ξ (u < û = (ξ + d̂)² − ξ²), the energy of codimensional IPC (Li et
al. 2021, §4) is

    E = κ d̂² m(c) B(u/û),   B(z) = −(z − 1)² ln z,

C² at u = û and infinite at contact (d = ξ); κ d̂² is in joules. Edge–edge pairs of cloth and meshes carry
IPC's mollifier m(c) = (2 − c/ε)c/ε for c = ‖e_a × e_b‖² < ε = 10⁻³‖ē_a‖²‖ē_b‖² (rest
lengths; Li et al. 2020, §4.3), which takes nearly parallel edges out smoothly (their
contact is held by the vertex–triangle pairs); a capsule's edge has none, since no
vertex–triangle pair holds it. The gradient is exact: ∇E = κ d̂² (m B'(z)/û ∇u +
B(z) m'(c) ∇c) with ∇_{x_k} u = 2 w_k r, r the difference of the closest points.

The Hessian is Gauss–Newton along the contact normal n = r/d:
H = κ d̂² m max(g''(d), 0) ∇d ∇dᵀ with g(d) = B((d² − ξ²)/û) and ∇_{x_k} d = w_k n,
so H is positive semi-definite by construction and is kept per pair as
(weights w, normal n, coefficient) for matrix-free products. It is the exact
Hessian along n with the curvature of the distance left out; the part it drops,
g'(d)∇²d, is negative semi-definite for vertex–vertex and vertex–edge pairs and
would be projected away. Following Ando (2024, "A cubic barrier with elasticity-
inclusive dynamic stiffness") in keeping only the normal term.

One part of the curvature is kept: a sphere's centre (or a capsule's axis) lies D = d
from the cloth triangle (or edge) it faces, and tilting that triangle about its
closest point brings its plane closer by D φ²/2. With normal displacements δ of its
vertices the distance is d ≈ D + Σ λ_j δ_j − (D/2)‖Σ_j δ_j ∇λ_j‖² (λ the barycentric
coordinates of the closest point, ∇λ their gradients in the triangle's plane; on an
edge ∂λ/∂s = ∓1/‖e‖), so g'(d)∇²d = (−g'(d)) D (G ⊗ n nᵀ) with G_jk = ∇λ_j·∇λ_k,
positive semi-definite since g' < 0. It is kept as up to two more rank-one terms per
pair (the ``tilt`` weights, G = Σ_k t_k t_kᵀ); without it Newton's model misses that a
cloth triangle draping over a sphere dips into it, and the collision-free step stops
every Newton step a hair's breadth into the motion.

The numba kernels take the pair geometry as one tuple ``geometry`` = (obstacle (N,) bool:
collider vertices, radius (N,), rest (N, 3) rest positions, xi_self, xi_obstacle,
dhat_self, dhat_obstacle), see :func:`pair_geometry`.
"""

import numpy as np

from clothtool.contact.distance import cross_squared, edge_edge_weights, point_triangle_weights
from clothtool.numba_setup import njit, njit_inner

MOLLIFIER_SCALE = 1e-3
POINT_TRIANGLE, EDGE_EDGE, POINT_PLANE = 0, 1, 2


def pair_geometry(obstacle, radius, rest, xi_self, xi_obstacle, dhat_self, dhat_obstacle):
    """The ``geometry`` tuple of the kernels (see the module)."""
    return (np.ascontiguousarray(obstacle, dtype=np.bool_), np.ascontiguousarray(radius, dtype=np.float64),
            np.ascontiguousarray(rest, dtype=np.float64), float(xi_self), float(xi_obstacle),
            float(dhat_self), float(dhat_obstacle))


@njit(cache=True)
def barrier(z):
    """B(z) = −(z − 1)² ln z on 0 < z < 1 (0 beyond)."""
    if z >= 1.0:
        return 0.0
    return -(z - 1.0) ** 2 * np.log(z)


@njit(cache=True)
def barrier_first(z):
    """B'(z) = −2(z − 1) ln z − (z − 1)²/z."""
    if z >= 1.0:
        return 0.0
    return -2.0 * (z - 1.0) * np.log(z) - (z - 1.0) ** 2 / z


@njit(cache=True)
def barrier_second(z):
    """B''(z) = −2 ln z − 4(z − 1)/z + (z − 1)²/z²."""
    if z >= 1.0:
        return 0.0
    return -2.0 * np.log(z) - 4.0 * (z - 1.0) / z + (z - 1.0) ** 2 / (z * z)


@njit(cache=True)
def mollifier(c, eps):
    """(m(c), m'(c)) with m = (2 − c/ε)c/ε below ε, 1 above."""
    if c >= eps:
        return 1.0, 0.0
    q = c / eps
    return (2.0 - q) * q, (2.0 - 2.0 * q) / eps


@njit_inner(cache=True)
def point_plane_weights(x, p, o, t, w):
    """Fill w (4,) for vertex p and the plane through o with unit normal t − o; returns
    the squared distance when p is in front of the plane, 0 (contact) when it is not."""
    d = ((x[p, 0] - x[o, 0]) * (x[t, 0] - x[o, 0]) + (x[p, 1] - x[o, 1]) * (x[t, 1] - x[o, 1])
         + (x[p, 2] - x[o, 2]) * (x[t, 2] - x[o, 2]))
    w[0] = 1.0
    w[1] = -1.0
    w[2] = 0.0
    w[3] = 0.0
    return d * d if d > 0.0 else 0.0


@njit(cache=True)
def pair_distance(x, st, w, r):
    """d² of the pair st (5,), its closest-point weights into w (4,) and the difference of
    its closest points into r (3,), so that ∇_{x_k} d² = 2 w_k r."""
    kind = st[4]
    if kind == EDGE_EDGE:
        d2 = edge_edge_weights(x, st[0], st[1], st[2], st[3], w)
    elif kind == POINT_TRIANGLE:
        d2 = point_triangle_weights(x, st[0], st[1], st[2], st[3], w)
    else:
        d2 = point_plane_weights(x, st[0], st[1], st[2], w)
        d = np.sqrt(d2)
        for i in range(3):
            r[i] = d * (x[st[2], i] - x[st[1], i])
        return d2
    for i in range(3):
        r[i] = w[0] * x[st[0], i] + w[1] * x[st[1], i] + w[2] * x[st[2], i] + w[3] * x[st[3], i]
    return d2


@njit_inner(cache=True)
def pair_radius(st, radius):
    """R of a pair: its point's radius (vertex–triangle) or its edges' (edge–edge)."""
    if st[4] == EDGE_EDGE:
        return radius[st[0]] + radius[st[2]]
    if st[4] == POINT_TRIANGLE:
        return radius[st[0]]
    return 0.0


@njit(cache=True)
def pair_thickness(st, geometry):
    """(ξ, d̂, R) of a pair: the collider wall and activation when a collider vertex takes
    part, else the cloth's; ξ includes the pair's radius R."""
    obstacle, radius, _, xi_self, xi_obstacle, dhat_self, dhat_obstacle = geometry
    big_r = pair_radius(st, radius)
    for j in range(4):
        if obstacle[st[j]]:
            return xi_obstacle + big_r, dhat_obstacle, big_r
    return xi_self + big_r, dhat_self, big_r


@njit_inner(cache=True)
def mollifier_threshold(rest, st):
    """ε = 10⁻³ ‖ē_a‖² ‖ē_b‖² of an edge–edge pair from rest positions."""
    la = 0.0
    lb = 0.0
    for i in range(3):
        la += (rest[st[1], i] - rest[st[0], i]) ** 2
        lb += (rest[st[3], i] - rest[st[2], i]) ** 2
    return MOLLIFIER_SCALE * la * lb


@njit_inner(cache=True)
def _mollified(x, st, geometry, big_r):
    """(m, m') of a pair: IPC's mollifier for edge–edge pairs without a radius, else (1, 0)."""
    if st[4] != EDGE_EDGE or big_r > 0.0:
        return 1.0, 0.0
    return mollifier(cross_squared(x, st[0], st[1], st[2], st[3]),
                     mollifier_threshold(geometry[2], st))


@njit_inner(cache=True)
def barrier_argument(x, st, geometry, w, r):
    """(d², u = d² − ξ², û = d̂ (2ξ + d̂), d̂, R) of a pair (:func:`pair_thickness`,
    :func:`pair_distance` filling ``w`` and ``r``): its barrier acts where 0 < u < û."""
    xi, dhat, big_r = pair_thickness(st, geometry)
    d2 = pair_distance(x, st, w, r)
    return d2, d2 - xi * xi, dhat * (2.0 * xi + dhat), dhat, big_r


@njit(cache=True)
def contact_energy(x, stencils, geometry, kappa):
    """Σ over pairs of κ d̂² m B(u/û); +inf when a pair is at or inside its thickness."""
    total = 0.0
    w = np.empty(4)
    r = np.empty(3)
    for st in stencils:
        _, u, uhat, dhat, big_r = barrier_argument(x, st, geometry, w, r)
        if u >= uhat:
            continue
        if u <= 0.0:
            return np.inf
        total += dhat * dhat * _mollified(x, st, geometry, big_r)[0] * barrier(u / uhat)
    return kappa * total


@njit(cache=True)
def contact_assemble(x, stencils, geometry, kappa, grad, active, weights, normals, coef, force,
                     tilt):
    """Energy of the pairs; adds ∇E into grad (N, 3) and stores the Gauss–Newton Hessian of
    each active pair a: stencil index active[a], weights[a] (4,), normal normals[a] (3,),
    coefficient coef[a], its normal force −∂E/∂d = −κ d̂² m g'(d) ≥ 0 in force[a], and the
    weights of its tilt terms in tilt[a] (2, 4), each with the coefficient force·d along n
    (zero but for pairs with a radius, see the module); arrays of the stencils' length.

    Returns (energy, number of active pairs, smallest surface distance d − R over all
    stencils).
    """
    total = 0.0
    gap = np.inf
    n_act = 0
    w = np.empty(4)
    r = np.empty(3)
    for k, st in enumerate(stencils):
        d2, u, uhat, dhat, big_r = barrier_argument(x, st, geometry, w, r)
        d = np.sqrt(d2)
        gap = min(gap, d - big_r)
        if u >= uhat:
            continue
        if u <= 0.0:
            return np.inf, n_act, gap
        z = u / uhat
        b, b1, b2 = barrier(z), barrier_first(z), barrier_second(z)
        m, dm = _mollified(x, st, geometry, big_r)
        kap = kappa * dhat * dhat
        total += kap * m * b
        scale = kap * m * b1 / uhat * 2.0
        for j in range(4):
            for i in range(3):
                grad[st[j], i] += scale * w[j] * r[i]
        if dm != 0.0:
            _add_cross_gradient(x, st, kap * b * dm, grad)
        g2 = b2 * (2.0 * d / uhat) ** 2 + b1 * 2.0 / uhat
        active[n_act] = k
        for j in range(4):
            weights[n_act, j] = w[j]
        for i in range(3):
            normals[n_act, i] = r[i] / d
        coef[n_act] = kap * m * max(g2, 0.0)
        force[n_act] = -kap * m * b1 * 2.0 * d / uhat
        tilt[n_act] = 0.0
        if big_r > 0.0:
            tilt_weights(x, st, w, geometry[1], tilt[n_act])
        n_act += 1
    return total, n_act, gap


@njit_inner(cache=True)
def tilt_weights(x, st, w, radius, out):
    """The tilt terms t_k (out (2, 4)) of a pair whose point (vertex–triangle) or one edge
    (edge–edge) has a radius: the in-plane gradients of the other side's barycentric
    coordinates of the closest point (w), G = Σ_k t_k t_kᵀ (see the module); zero when
    the closest point is a vertex."""
    first, last = 1, 4  # the side facing the sphere or capsule
    if st[4] == EDGE_EDGE:
        first, last = (2, 4) if radius[st[0]] > 0.0 else (0, 2)
    nz = 0
    for j in range(first, last):
        if w[j] != 0.0:
            nz += 1
    if nz == 2:  # an edge of the other side: ∂λ/∂s = ∓1/‖e‖ along it
        a = -1
        b = -1
        for j in range(first, last):
            if w[j] != 0.0:
                if a < 0:
                    a = j
                else:
                    b = j
        length = np.sqrt((x[st[b], 0] - x[st[a], 0]) ** 2 + (x[st[b], 1] - x[st[a], 1]) ** 2
                         + (x[st[b], 2] - x[st[a], 2]) ** 2)
        out[0, a] = -1.0 / length
        out[0, b] = 1.0 / length
    elif nz == 3:  # the triangle's interior: ∇λ_j = n × (x_{j+2} − x_{j+1}) / 2A
        e1 = np.empty(3)
        e2 = np.empty(3)
        for i in range(3):
            e1[i] = x[st[2], i] - x[st[1], i]
            e2[i] = x[st[3], i] - x[st[1], i]
        nrm = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]])
        area2 = np.sqrt(nrm[0] ** 2 + nrm[1] ** 2 + nrm[2] ** 2)
        nrm /= area2
        t1 = e1 / np.sqrt(e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2)
        t2 = np.array([nrm[1] * t1[2] - nrm[2] * t1[1], nrm[2] * t1[0] - nrm[0] * t1[2],
                       nrm[0] * t1[1] - nrm[1] * t1[0]])
        for j in range(3):
            p = st[1 + (j + 1) % 3]
            q = st[1 + (j + 2) % 3]
            g = np.array([x[q, 0] - x[p, 0], x[q, 1] - x[p, 1], x[q, 2] - x[p, 2]])
            grad = np.array([nrm[1] * g[2] - nrm[2] * g[1], nrm[2] * g[0] - nrm[0] * g[2],
                             nrm[0] * g[1] - nrm[1] * g[0]]) / area2
            out[0, 1 + j] = grad[0] * t1[0] + grad[1] * t1[1] + grad[2] * t1[2]
            out[1, 1 + j] = grad[0] * t2[0] + grad[1] * t2[1] + grad[2] * t2[2]


@njit_inner(cache=True)
def _add_cross_gradient(x, st, scale, grad):
    """grad += scale ∇c for c = ‖u × v‖², u = x1 − x0, v = x3 − x2:
    ∂c/∂u = 2(u‖v‖² − v(u·v)), ∂c/∂v = 2(v‖u‖² − u(u·v))."""
    u = (x[st[1], 0] - x[st[0], 0], x[st[1], 1] - x[st[0], 1], x[st[1], 2] - x[st[0], 2])
    v = (x[st[3], 0] - x[st[2], 0], x[st[3], 1] - x[st[2], 1], x[st[3], 2] - x[st[2], 2])
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
    for i in range(3):
        gu = scale * 2.0 * (u[i] * vv - v[i] * uv)
        gv = scale * 2.0 * (v[i] * uu - u[i] * uv)
        grad[st[0], i] -= gu
        grad[st[1], i] += gu
        grad[st[2], i] -= gv
        grad[st[3], i] += gv


@njit(cache=True)
def barrier_blocks(stencils, active, n_active, weights, normals, coef, force, tilt, x, rows,
                   w_out, blocks):
    """Write each active pair's Hessian as pair-operator entries from index 0: its stencil,
    its weights and the block coef n nᵀ, then each nonzero tilt term t_k with the block
    force·d n nᵀ (d the pair's distance at x). Returns the number of entries written."""
    count = 0
    w = np.empty(4)
    r = np.empty(3)
    for a in range(n_active):
        st = stencils[active[a]]
        for j in range(4):
            rows[count, j] = st[j]
            w_out[count, j] = weights[a, j]
        for p in range(3):
            for q in range(3):
                blocks[count, p, q] = coef[a] * normals[a, p] * normals[a, q]
        count += 1
        for k in range(2):
            if tilt[a, k, 0] == 0.0 and tilt[a, k, 1] == 0.0 and tilt[a, k, 2] == 0.0 and tilt[a, k, 3] == 0.0:
                continue
            c = force[a] * np.sqrt(pair_distance(x, st, w, r))
            for j in range(4):
                rows[count, j] = st[j]
                w_out[count, j] = tilt[a, k, j]
            for p in range(3):
                for q in range(3):
                    blocks[count, p, q] = c * normals[a, p] * normals[a, q]
            count += 1
    return count
