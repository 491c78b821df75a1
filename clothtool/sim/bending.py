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
"""

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _skew(a):
    """[a]× with [a]× v = a × v."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@njit(cache=True)
def dihedral_angle(xi, xj, xk, xl):
    nk = _cross(xj - xi, xk - xi)
    nl = _cross(xi - xj, xl - xj)
    e = xj - xi
    sin_part = _cross(nk, nl) @ e / np.sqrt(e @ e)
    return np.arctan2(sin_part, nk @ nl)


@njit(cache=True)
def dihedral_angle_gradient(xi, xj, xk, xl, grad):
    """θ and ∇θ (12,), order (i, j, k, l)."""
    e = xj - xi
    ll = e @ e
    length = np.sqrt(ll)
    nk = _cross(e, xk - xi)
    nl = _cross(xi - xj, xl - xj)
    gk = -length * nk / (nk @ nk)
    gl = -length * nl / (nl @ nl)
    sk = (xk - xi) @ e / ll
    sl = (xl - xi) @ e / ll
    grad[0:3] = -(1.0 - sk) * gk - (1.0 - sl) * gl
    grad[3:6] = -sk * gk - sl * gl
    grad[6:9] = gk
    grad[9:12] = gl
    return np.arctan2(_cross(nk, nl) @ e / length, nk @ nl)


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
    """Exact ∇²θ (12, 12) of the dihedral angle, order (i, j, k, l)."""
    e = xj - xi
    ll = e @ e
    length = np.sqrt(ll)
    e_hat = e / length
    nk = _cross(e, xk - xi)
    nl = _cross(xi - xj, xl - xj)
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
    g_theta = np.empty(12)
    theta = dihedral_angle_gradient(xi, xj, xk, xl, g_theta)
    delta = theta - theta_rest
    for a in range(12):
        grad[a] = 2.0 * coef * delta * g_theta[a]
        for b in range(12):
            hess[a, b] = 2.0 * coef * g_theta[a] * g_theta[b]
    if not project:
        h_theta = np.empty((12, 12))
        dihedral_angle_hessian(xi, xj, xk, xl, h_theta)
        hess += 2.0 * coef * delta * h_theta
    return coef * delta * delta


@njit(cache=True, parallel=True)
def dihedral_elements(x, hinge, theta_rest, coef, elem_energy, elem_grad, elem_hess):
    for h in prange(hinge.shape[0]):
        i, j, k, l = hinge[h, 0], hinge[h, 1], hinge[h, 2], hinge[h, 3]
        elem_energy[h] = dihedral_element(x[i], x[j], x[k], x[l], theta_rest[h], coef[h], True,
                                          elem_grad[h], elem_hess[h])


@njit(cache=True)
def dihedral_angles(x, hinge):
    """θ of every hinge (H,)."""
    out = np.empty(hinge.shape[0])
    for h in range(hinge.shape[0]):
        out[h] = dihedral_angle(x[hinge[h, 0]], x[hinge[h, 1]], x[hinge[h, 2]], x[hinge[h, 3]])
    return out


@njit(cache=True, parallel=True)
def dihedral_energies(x, hinge, theta_rest, coef, elem_energy):
    for h in prange(hinge.shape[0]):
        d = dihedral_angle(x[hinge[h, 0]], x[hinge[h, 1]], x[hinge[h, 2]], x[hinge[h, 3]]) - theta_rest[h]
        elem_energy[h] = coef[h] * d * d


@njit(cache=True)
def quadratic_weights(rest3d, hinge):
    """w_v = ∇_v θ · n̄ at the (flat) rest state, per hinge (H, 4)."""
    w = np.empty((hinge.shape[0], 4))
    g = np.empty(12)
    for h in range(hinge.shape[0]):
        xi, xj, xk, xl = rest3d[hinge[h, 0]], rest3d[hinge[h, 1]], rest3d[hinge[h, 2]], rest3d[hinge[h, 3]]
        dihedral_angle_gradient(xi, xj, xk, xl, g)
        n = _cross(xj - xi, xk - xi)
        n /= np.sqrt(n @ n)
        for v in range(4):
            w[h, v] = g[3 * v] * n[0] + g[3 * v + 1] * n[1] + g[3 * v + 2] * n[2]
    return w


@njit(cache=True)
def quadratic_element(xs, w, coef, grad):
    """E = c ‖Σ w_v x_v‖² for xs (4, 3); writes ∇E (12,). The Hessian is 2c w wᵀ ⊗ I₃."""
    y = w[0] * xs[0] + w[1] * xs[1] + w[2] * xs[2] + w[3] * xs[3]
    for v in range(4):
        grad[3 * v:3 * v + 3] = 2.0 * coef * w[v] * y
    return coef * (y @ y)


@njit(cache=True, parallel=True)
def quadratic_elements(x, hinge, w, coef, elem_energy, elem_grad):
    for h in prange(hinge.shape[0]):
        xs = np.empty((4, 3))
        for v in range(4):
            xs[v] = x[hinge[h, v]]
        elem_energy[h] = quadratic_element(xs, w[h], coef[h], elem_grad[h])
