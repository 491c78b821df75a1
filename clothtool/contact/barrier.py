"""The contact barrier: energy, gradient and a Gauss–Newton Hessian over candidate pairs.

Each pair (vertex–triangle or edge–edge, see ``distance``) at distance d with
thickness ξ has u = d² − ξ² and, within the activation distance d̂ beyond ξ
(u < û = (ξ + d̂)² − ξ²), the energy of codimensional IPC (Li et al. 2021, §4),

    E = κ m(c) B(u/û),   B(z) = −(z − 1)² ln z,

which is C² at u = û and infinite at contact (d = ξ); κ is in joules. Edge–edge
pairs carry IPC's mollifier m(c) = (2 − c/ε)c/ε for c = ‖e_a × e_b‖² < ε =
10⁻³‖ē_a‖²‖ē_b‖² (rest lengths; Li et al. 2020, §4.3), which takes nearly parallel
edges out smoothly (their contact is held by the vertex–triangle pairs). The
gradient is exact: ∇E = κ (m B'(z)/û ∇u + B(z) m'(c) ∇c) with ∇_{x_k} u = 2 w_k r.

The Hessian is Gauss–Newton along the contact normal n = r/d:
H = κ m max(g''(d), 0) ∇d ∇dᵀ with g(d) = B((d² − ξ²)/û) and ∇_{x_k} d = w_k n,
so H is positive semi-definite by construction and is kept per pair as
(weights w, normal n, coefficient) for matrix-free products. It is the exact
Hessian along n with the curvature of the distance left out; the part it drops,
g'(d)∇²d, is negative semi-definite for vertex–vertex and vertex–edge pairs and
would be projected away. Following Ando (2024, "A cubic barrier with elasticity-
inclusive dynamic stiffness") in keeping only the normal term.
"""

import numpy as np
from numba import njit

from clothtool.contact.distance import cross_squared, edge_edge_weights, point_triangle_weights

MOLLIFIER_SCALE = 1e-3


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


@njit(cache=True)
def pair_distance(x, st, edge_edge, w):
    """d² of the pair with vertex stencil st (4,), its closest-point weights into w (4,)."""
    if edge_edge:
        return edge_edge_weights(x, st[0], st[1], st[2], st[3], w)
    return point_triangle_weights(x, st[0], st[1], st[2], st[3], w)


@njit(cache=True)
def pair_thickness(st, obstacle, xi_self, xi_obstacle):
    """ξ of a pair: the collider margin when a collider vertex takes part, else the cloth's."""
    for j in range(4):
        if obstacle[st[j]]:
            return xi_obstacle
    return xi_self


@njit(cache=True)
def mollifier_threshold(rest, st):
    """ε = 10⁻³ ‖ē_a‖² ‖ē_b‖² of an edge–edge pair from rest positions."""
    la = 0.0
    lb = 0.0
    for i in range(3):
        la += (rest[st[1], i] - rest[st[0], i]) ** 2
        lb += (rest[st[3], i] - rest[st[2], i]) ** 2
    return MOLLIFIER_SCALE * la * lb


@njit(cache=True)
def contact_energy(x, stencils, n_pt, obstacle, rest, xi_self, xi_obstacle, dhat, kappa):
    """Σ over pairs of κ m B(u/û); +inf when a pair is at or inside its thickness."""
    total = 0.0
    w = np.empty(4)
    for k in range(stencils.shape[0]):
        st = stencils[k]
        ee = k >= n_pt
        xi = pair_thickness(st, obstacle, xi_self, xi_obstacle)
        u = pair_distance(x, st, ee, w) - xi * xi
        uhat = dhat * (2.0 * xi + dhat)
        if u >= uhat:
            continue
        if u <= 0.0:
            return np.inf
        e = barrier(u / uhat)
        if ee:
            e *= mollifier(cross_squared(x, st[0], st[1], st[2], st[3]),
                           mollifier_threshold(rest, st))[0]
        total += e
    return kappa * total


@njit(cache=True)
def contact_assemble(x, stencils, n_pt, obstacle, rest, xi_self, xi_obstacle, dhat, kappa,
                     grad, active, weights, normals, coef, force):
    """Energy of the pairs; adds ∇E into grad (N, 3) and stores the Gauss–Newton Hessian of
    each active pair a: stencil index active[a], weights[a] (4,), normal normals[a] (3,),
    coefficient coef[a], and its normal force −∂E/∂d = −κ m g'(d) ≥ 0 in force[a] (arrays
    of the stencils' length).

    Returns (energy, number of active pairs, smallest pair distance d over all stencils).
    """
    total = 0.0
    gap = np.inf
    n_act = 0
    w = np.empty(4)
    r = np.empty(3)
    for k in range(stencils.shape[0]):
        st = stencils[k]
        ee = k >= n_pt
        xi = pair_thickness(st, obstacle, xi_self, xi_obstacle)
        d2 = pair_distance(x, st, ee, w)
        d = np.sqrt(d2)
        gap = min(gap, d)
        u = d2 - xi * xi
        uhat = dhat * (2.0 * xi + dhat)
        if u >= uhat:
            continue
        if u <= 0.0:
            return np.inf, n_act, gap
        z = u / uhat
        b, b1, b2 = barrier(z), barrier_first(z), barrier_second(z)
        m, dm = 1.0, 0.0
        if ee:
            m, dm = mollifier(cross_squared(x, st[0], st[1], st[2], st[3]),
                              mollifier_threshold(rest, st))
        total += m * b
        for i in range(3):
            r[i] = w[0] * x[st[0], i] + w[1] * x[st[1], i] + w[2] * x[st[2], i] + w[3] * x[st[3], i]
        scale = kappa * m * b1 / uhat * 2.0
        for j in range(4):
            for i in range(3):
                grad[st[j], i] += scale * w[j] * r[i]
        if dm != 0.0:
            _add_cross_gradient(x, st, kappa * b * dm, grad)
        g2 = b2 * (2.0 * d / uhat) ** 2 + b1 * 2.0 / uhat
        active[n_act] = k
        for j in range(4):
            weights[n_act, j] = w[j]
        for i in range(3):
            normals[n_act, i] = r[i] / d
        coef[n_act] = kappa * m * max(g2, 0.0)
        force[n_act] = -kappa * m * b1 * 2.0 * d / uhat
        n_act += 1
    return kappa * total, n_act, gap


@njit(cache=True)
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
def gauss_newton_offdiagonal_multiply(operator, v, out, scale):
    """out += scale (H − blockdiag H) v over the vertices below n, the unknowns of a solve (the
    others are held); ``operator`` = (stencils, active, n_active, weights, normals, coef, n),
    see :func:`solve_operator`. The diagonal blocks go into the matrix itself."""
    stencils, active, n_active, weights, normals, coef, n = operator
    for a in range(n_active):
        st = stencils[active[a]]
        s = 0.0
        for j in range(4):
            if st[j] < n:
                s += weights[a, j] * (normals[a, 0] * v[st[j], 0] + normals[a, 1] * v[st[j], 1]
                                      + normals[a, 2] * v[st[j], 2])
        for j in range(4):
            v_j = st[j]
            if v_j < n:
                own = weights[a, j] * (normals[a, 0] * v[v_j, 0] + normals[a, 1] * v[v_j, 1]
                                       + normals[a, 2] * v[v_j, 2])
                c = scale * coef[a] * weights[a, j] * (s - own)
                for i in range(3):
                    out[v_j, i] += c * normals[a, i]


@njit(cache=True)
def gauss_newton_coupling(operator, dy, out, scale):
    """out += scale H_{uh} dy_h: the Hessian blocks between the unknowns (vertices below n)
    and the held vertices, applied to the held vertices' part of dy (all vertices)."""
    stencils, active, n_active, weights, normals, coef, n = operator
    for a in range(n_active):
        st = stencils[active[a]]
        s = 0.0
        for j in range(4):
            if st[j] >= n:
                s += weights[a, j] * (normals[a, 0] * dy[st[j], 0] + normals[a, 1] * dy[st[j], 1]
                                      + normals[a, 2] * dy[st[j], 2])
        if s == 0.0:
            continue
        for j in range(4):
            if st[j] < n:
                c = scale * coef[a] * weights[a, j] * s
                for i in range(3):
                    out[st[j], i] += c * normals[a, i]


def solve_operator(stencils, active, n_active, weights, normals, coef, n):
    """The tuple :func:`gauss_newton_offdiagonal_multiply` takes."""
    return (stencils, active, np.int64(n_active), weights, normals, coef, np.int64(n))


NO_OPERATOR = solve_operator(np.zeros((0, 4), np.int64), np.zeros(0, np.int64), 0,
                             np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), 0)


@njit(cache=True)
def gauss_newton_add_diagonal(operator, diag, values):
    """values[diag[v]] += the 3×3 diagonal blocks coef w_j² n nᵀ of the pair Hessians, for
    the unknowns v < n (``operator`` as in :func:`gauss_newton_offdiagonal_multiply`;
    ``diag``: each vertex's diagonal slot in the block matrix ``values``)."""
    stencils, active, n_active, weights, normals, coef, n = operator
    for a in range(n_active):
        st = stencils[active[a]]
        for j in range(4):
            if st[j] < n:
                s = coef[a] * weights[a, j] * weights[a, j]
                b = values[diag[st[j]]]
                for p in range(3):
                    for q in range(3):
                        b[p, q] += s * normals[a, p] * normals[a, q]
