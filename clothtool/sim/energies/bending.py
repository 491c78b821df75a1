"""Bending across interior edges (hinges): dihedral-angle and quadratic models.

A hinge (i, j, k, l) and its signed dihedral angle θ (0 when flat), with its gradient and
Hessian, are those of :mod:`clothtool.geometry`.

Dihedral model (Grinspun et al. 2003, "Discrete Shells"):

    E = c (θ − θ̄)²,   c = k_b ‖ē‖² / (2 (Ā_k + Ā_l))

with k_b in N·m. The constant makes a cylinder bent along either grid axis store
exactly ∫ k_b κ²/2 dA, so the energy is a density over rest area. The Hessian used by
the solver is the Gauss–Newton part 2c ∇θ∇θᵀ, PSD by construction; the exact one is
for tests.

Quadratic model (Bergou et al. 2006, for flat rest states): E = c ‖Σ_v w_v x_v‖²
with w_v = ∇_v θ · n̄ at rest (the linearisation of θ about the flat state);
its Hessian 2c w wᵀ ⊗ I₃ is constant and PSD.

Degenerate hinges: where the shared edge has zero length or a triangle's height is
below geometry.HINGE_TOL of the edge (‖N‖ ≤ HINGE_TOL·‖e‖², e.g. cloth pushed onto a collider
or collapsed onto a line), θ is undefined; θ is then NaN, ∇θ = 0, and the hinge adds
no energy, force or stiffness until it opens again. The simulator does the same for
slivers, triangles whose height is at most ``THIN`` (1e-4) of the shared edge: there
∇θ ∝ 1/height, and the Gauss–Newton blocks (up to 10³³ for a sheet released flattened
onto a line) would swamp the system matrix in rounding.
"""

import numpy as np

from clothtool.geometry import (dihedral_angle, dihedral_angle_gradient, dihedral_angle_hessian,
                                hinge_normals)
from clothtool.numba_setup import njit, njit_inner
from clothtool.vec3 import cross, dot, load, scale, sub

THIN = 1e-4  # a hinge triangle this much lower than the shared edge is a sliver: no bending


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


@njit_inner(cache=True)
def _sliver(xi, xj, xk, xl):
    """A hinge with a triangle whose height is at most THIN times the shared edge."""
    e, nk, nl = hinge_normals(xi, xj, xk, xl)
    limit = THIN * THIN * dot(e, e) * dot(e, e)
    return dot(nk, nk) <= limit or dot(nl, nl) <= limit


@njit_inner(cache=True)
def _hinge_gradient(x, hinge, h, theta_rest, g):
    """θ − θ̄ of hinge h, with ∇θ (12,) in g; NaN for a degenerate or sliver hinge."""
    xi, xj = load(x, hinge[h, 0]), load(x, hinge[h, 1])
    xk, xl = load(x, hinge[h, 2]), load(x, hinge[h, 3])
    if _sliver(xi, xj, xk, xl):
        return np.nan
    return dihedral_angle_gradient(xi, xj, xk, xl, g) - theta_rest[h]


@njit(cache=True)
def dihedral_assemble(x, hinge, theta_rest, coef, slots, grad, values):
    """W_bend(x); adds ∇W = 2c(θ − θ̄)∇θ to grad (N, 3) and the Gauss–Newton blocks
    2c ∇θ∇θᵀ to values."""
    g = np.empty(12)
    total = 0.0
    for h in range(hinge.shape[0]):
        delta = _hinge_gradient(x, hinge, h, theta_rest, g)
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
def dihedral_gradient(x, hinge, theta_rest, coef, grad, v, damp, out):
    """Adds ∇W_bend to grad, without assembling; with damp > 0 also adds
    damp · 2c ∇θ(∇θ·v) (the Gauss–Newton Hessian of :func:`dihedral_assemble` times v) to out."""
    g = np.empty(12)
    for h in range(hinge.shape[0]):
        delta = _hinge_gradient(x, hinge, h, theta_rest, g)
        c2 = 2.0 * coef[h]
        if delta != delta:  # degenerate hinge: no bending there
            continue
        gv = 0.0
        if damp > 0.0:
            for a in range(4):
                for p in range(3):
                    gv += g[3 * a + p] * v[hinge[h, a], p]
        for a in range(4):
            i = hinge[h, a]
            for p in range(3):
                grad[i, p] += c2 * delta * g[3 * a + p]
                if damp > 0.0:
                    out[i, p] += damp * c2 * gv * g[3 * a + p]


@njit(cache=True)
def dihedral_total_energy(x, hinge, theta_rest, coef):
    """W_bend(x) = Σ c (θ − θ̄)² over the hinges that are neither degenerate nor slivers."""
    total = 0.0
    for h in range(hinge.shape[0]):
        if _sliver(load(x, hinge[h, 0]), load(x, hinge[h, 1]), load(x, hinge[h, 2]),
                   load(x, hinge[h, 3])):
            continue
        d = dihedral_angle(x, hinge[h]) - theta_rest[h]
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


@njit(cache=True)
def quadratic_product(hinge, w, coef, damp, v, out):
    """out += damp · 2c w(wᵀv) per hinge (the constant quadratic-bending Hessian times v)."""
    for h in range(hinge.shape[0]):
        for p in range(3):
            wv = 0.0
            for a in range(4):
                wv += w[h, a] * v[hinge[h, a], p]
            for a in range(4):
                out[hinge[h, a], p] += damp * 2.0 * coef[h] * w[h, a] * wv
