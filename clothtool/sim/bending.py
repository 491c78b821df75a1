"""Bending across interior edges (hinges): dihedral-angle and quadratic models.

A hinge (i, j, k, l) has the shared edge e = x_j − x_i, triangle (i, j, k) with
normal N_k = (x_j − x_i) × (x_k − x_i) and triangle (j, i, l) with
N_l = (x_i − x_j) × (x_l − x_j). Its dihedral angle is
θ = atan2((n̂_k × n̂_l)·ê, n̂_k·n̂_l) (0 when flat).

Dihedral model (Grinspun et al. 2003, "Discrete Shells"):

    E = c (θ − θ̄)²,   c = k_b ‖ē‖² / (2 (Ā_k + Ā_l))

with k_b in N·m. The constant makes a cylinder bent along either grid axis store
exactly ∫ k_b κ²/2 dA, so the energy is a density over rest area. Gradient of θ
(Bridson et al. 2003, in barycentric form): with L = ‖e‖ and s_k, s_l the
positions of the feet of k and l along e (0 at i, 1 at j),

    ∇_k θ = −L N_k/‖N_k‖²,   ∇_l θ = −L N_l/‖N_l‖²,
    ∇_i θ = −(1 − s_k)∇_k θ − (1 − s_l)∇_l θ,   ∇_j θ = −s_k ∇_k θ − s_l ∇_l θ,

and its Hessian is the derivative of these formulas (Tamstorf & Grinspun 2013
give the same in another notation). The Hessian used by the solver is the
Gauss–Newton part 2c ∇θ∇θᵀ, PSD by construction; the exact one is for tests.

Quadratic model (Bergou et al. 2006, for flat rest states): E = c ‖Σ_v w_v x_v‖²
with w_v = ∇_v θ · n̄ at rest (the linearisation of θ about the flat state);
its Hessian 2c w wᵀ ⊗ I₃ is constant and PSD.

Degenerate hinges: where the shared edge has zero length or a triangle's height is
below HINGE_TOL of the edge (‖N‖ ≤ HINGE_TOL·‖e‖², e.g. cloth pushed onto a collider
or collapsed onto a line), θ is undefined; θ is then NaN, ∇θ = 0, and the hinge adds
no energy, force or stiffness until it opens again.
"""

import numpy as np
from numba import njit

from clothtool.sim.vec3 import cross, dot, load, scale, sub

HINGE_TOL = 1e-12


@njit(cache=True)
def _degenerate(ll, nk, nl):
    """Zero-length edge, or a triangle of the hinge with height ≤ HINGE_TOL·‖e‖."""
    limit = HINGE_TOL * HINGE_TOL * ll * ll
    return ll == 0.0 or dot(nk, nk) <= limit or dot(nl, nl) <= limit


@njit(cache=True)
def _skew(a):
    """[a]× with [a]× v = a × v."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@njit(cache=True)
def dihedral_angle(xi, xj, xk, xl):
    e = sub(xj, xi)
    nk = cross(e, sub(xk, xi))
    nl = cross(sub(xi, xj), sub(xl, xj))
    if _degenerate(dot(e, e), nk, nl):
        return np.nan
    return np.arctan2(dot(cross(nk, nl), e) / np.sqrt(dot(e, e)), dot(nk, nl))


@njit(cache=True)
def dihedral_angle_gradient(xi, xj, xk, xl, grad):
    """θ and ∇θ (12,), order (i, j, k, l); NaN and ∇θ = 0 for a degenerate hinge."""
    e = sub(xj, xi)
    ll = dot(e, e)
    length = np.sqrt(ll)
    nk = cross(e, sub(xk, xi))
    nl = cross(sub(xi, xj), sub(xl, xj))
    if _degenerate(ll, nk, nl):
        grad[:] = 0.0
        return np.nan
    gk = scale(-length / dot(nk, nk), nk)
    gl = scale(-length / dot(nl, nl), nl)
    sk = dot(sub(xk, xi), e) / ll
    sl = dot(sub(xl, xi), e) / ll
    for p in range(3):
        grad[p] = -(1.0 - sk) * gk[p] - (1.0 - sl) * gl[p]
        grad[3 + p] = -sk * gk[p] - sl * gl[p]
        grad[6 + p] = gk[p]
        grad[9 + p] = gl[p]
    return np.arctan2(dot(cross(nk, nl), e) / length, dot(nk, nl))


@njit(cache=True)
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


@njit(cache=True)
def dihedral_angle_hessian(xi, xj, xk, xl, hess):
    """Exact ∇²θ (12, 12) of the dihedral angle, order (i, j, k, l); xi… are (3,) arrays."""
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


@njit(cache=True)
def dihedral_element(xi, xj, xk, xl, theta_rest, coef, project, grad, hess):
    """E = c (θ − θ̄)²; writes ∇E (12,) and the Hessian (12, 12).

    ``project``: the Gauss–Newton Hessian 2c ∇θ∇θᵀ (PSD); else the exact
    2c (∇θ∇θᵀ + (θ − θ̄)∇²θ).
    """
    theta = dihedral_angle_gradient(xi, xj, xk, xl, grad)  # ∇θ, scaled below
    delta = theta - theta_rest
    for a in range(12):
        for b in range(12):
            hess[a, b] = 2.0 * coef * grad[a] * grad[b]
    if not project:
        h_theta = np.empty((12, 12))
        dihedral_angle_hessian(np.asarray(xi), np.asarray(xj), np.asarray(xk), np.asarray(xl), h_theta)
        for a in range(12):
            for b in range(12):
                hess[a, b] += 2.0 * coef * delta * h_theta[a, b]
    for a in range(12):
        grad[a] *= 2.0 * coef * delta
    return coef * delta * delta


@njit(cache=True)
def dihedral_assemble(x, hinge, theta_rest, coef, slots, grad, values):
    """W_bend(x); adds ∇W to grad (N, 3) and the Gauss–Newton blocks 2c ∇θ∇θᵀ to values."""
    g = np.empty(12)
    total = 0.0
    for h in range(hinge.shape[0]):
        theta = dihedral_angle_gradient(load(x, hinge[h, 0]), load(x, hinge[h, 1]),
                                        load(x, hinge[h, 2]), load(x, hinge[h, 3]), g)
        delta = theta - theta_rest[h]
        if delta != delta:  # degenerate hinge (now or at rest): no bending there
            continue
        c2 = 2.0 * coef[h]
        total += coef[h] * delta * delta
        for a in range(4):
            v = hinge[h, a]
            for p in range(3):
                grad[v, p] += c2 * delta * g[3 * a + p]
            for b in range(4):
                block = values[slots[h, 4 * a + b]]
                for p in range(3):
                    for q in range(3):
                        block[p, q] += c2 * g[3 * a + p] * g[3 * b + q]
    return total


@njit(cache=True)
def dihedral_angles(x, hinge):
    """θ of every hinge (H,)."""
    out = np.empty(hinge.shape[0])
    for h in range(hinge.shape[0]):
        out[h] = dihedral_angle(load(x, hinge[h, 0]), load(x, hinge[h, 1]), load(x, hinge[h, 2]),
                                load(x, hinge[h, 3]))
    return out


@njit(cache=True)
def dihedral_total_energy(x, hinge, theta_rest, coef):
    total = 0.0
    for h in range(hinge.shape[0]):
        d = dihedral_angle(load(x, hinge[h, 0]), load(x, hinge[h, 1]), load(x, hinge[h, 2]),
                           load(x, hinge[h, 3])) - theta_rest[h]
        if d == d:  # NaN: degenerate hinge, no energy
            total += coef[h] * d * d
    return total


@njit(cache=True)
def quadratic_weights(rest3d, hinge):
    """w_v = ∇_v θ · n̄ at the (flat) rest state, per hinge (H, 4)."""
    w = np.empty((hinge.shape[0], 4))
    g = np.empty(12)
    for h in range(hinge.shape[0]):
        xi, xj, xk = load(rest3d, hinge[h, 0]), load(rest3d, hinge[h, 1]), load(rest3d, hinge[h, 2])
        theta = dihedral_angle_gradient(xi, xj, xk, load(rest3d, hinge[h, 3]), g)
        if theta != theta:  # degenerate at rest: no quadratic bending here
            w[h] = 0.0
            continue
        n = cross(sub(xj, xi), sub(xk, xi))
        n = scale(1.0 / np.sqrt(dot(n, n)), n)
        for v in range(4):
            w[h, v] = g[3 * v] * n[0] + g[3 * v + 1] * n[1] + g[3 * v + 2] * n[2]
    return w


@njit(cache=True)
def quadratic_element(xi, xj, xk, xl, w, coef, grad):
    """E = c ‖Σ w_v x_v‖²; writes ∇E (12,). The Hessian is 2c w wᵀ ⊗ I₃."""
    y0 = w[0] * xi[0] + w[1] * xj[0] + w[2] * xk[0] + w[3] * xl[0]
    y1 = w[0] * xi[1] + w[1] * xj[1] + w[2] * xk[1] + w[3] * xl[1]
    y2 = w[0] * xi[2] + w[1] * xj[2] + w[2] * xk[2] + w[3] * xl[2]
    for v in range(4):
        grad[3 * v] = 2.0 * coef * w[v] * y0
        grad[3 * v + 1] = 2.0 * coef * w[v] * y1
        grad[3 * v + 2] = 2.0 * coef * w[v] * y2
    return coef * (y0 * y0 + y1 * y1 + y2 * y2)


@njit(cache=True)
def quadratic_gradient(x, hinge, w, coef, grad):
    """W_bend(x) of the quadratic model; adds ∇W to grad (N, 3) unless grad is empty."""
    g = np.empty(12)
    total = 0.0
    for h in range(hinge.shape[0]):
        total += quadratic_element(load(x, hinge[h, 0]), load(x, hinge[h, 1]), load(x, hinge[h, 2]),
                                   load(x, hinge[h, 3]), w[h], coef[h], g)
        if grad.shape[0] > 0:
            for a in range(4):
                for p in range(3):
                    grad[hinge[h, a], p] += g[3 * a + p]
    return total
