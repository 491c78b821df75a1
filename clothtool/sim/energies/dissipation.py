"""Stretch damping as a dissipation potential of the strain change over the step.

Stiffness-proportional damping with the stiffness frozen at the start of a step,
½(x − b)ᵀ(β/ĥ)K(x_n)(x − b), measures the strain rate along the fibre directions of x_n.
Over a large step that turns the cloth (a sheet released crumpled unfolding, a hanging
sheet swinging) those directions are stale: the damping resists rotations as if they
were stretching, and at one step per frame a crumpled sheet stays stretched 1.34× for
eight frames. Following Brown, Overby, Narain & Kaufman 2018 ("Accurate dissipative
forces in optimization integrators", SCA), the stretch part of the damping is instead the
potential of the actual strain change over the step,

    Φ(x) = 1/(2ĥ) Σ_t A_t [β_t k_u (‖f0(x)‖ − L_0)² + β_t k_v (‖f1(x)‖ − L_1)²]

(f0, f1 the columns of F, :mod:`clothtool.sim.energies.membrane`), with the integrator's own
strain rate: L = ‖f(x_n)‖ for backward Euler, the BDF2 combination (4‖f(x_n)‖ −
‖f(x_{n−1})‖)/3 for BDF2 (so (‖f(x)‖ − L)/ĥ is BDF2's derivative of the fibre length);
on BDF2's first step L = ‖f(x_0)‖, since its Taylor history x_{−1} is no shape of the
cloth's (pinned vertices stay while the rest moves ½h²a_0: at h = 1 s L came out negative
near the pins and Newton did not converge in 100 iterations).
It is invariant under rigid motions of each triangle; to first order it is the frozen form
with K's stretch part k f̂f̂ᵀ. Its gradient per column is (A βk/ĥ)(‖f‖ − L) f̂ through
∂f/∂x, and its Hessian (A βk/ĥ)[f̂f̂ᵀ + c(I − f̂f̂ᵀ)], c = 1 − L/‖f‖ (the membrane's stretch
block with rest length L); the solver takes it with c clamped at 0 (PSD).
"""

import numpy as np
from numba import njit

from clothtool.sim.energies.membrane import add_triangle, deformation_gradient
from clothtool.vec3 import dot, load

EPS = 1e-12


@njit(cache=True)
def column_lengths(x, faces, dr_inv, out):
    """out (M, 2) = ‖f0‖, ‖f1‖ of every triangle at x."""
    for t in range(faces.shape[0]):
        f0, f1 = deformation_gradient(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                      load(x, faces[t, 2]), dr_inv[t])
        out[t, 0] = np.sqrt(dot(f0, f0))
        out[t, 1] = np.sqrt(dot(f1, f1))
    return out


@njit(cache=True)
def dissipation_element(x0, x1, x2, dr_inv, area, coef, length, exact, grad, hess):
    """Φ of one triangle, coef = (β k_u/ĥ, β k_v/ĥ), length = (L_0, L_1); writes its
    gradient (9,) and Hessian (9, 9) (vertex-major): exact with ``exact``, else with c
    clamped at 0."""
    f0, f1 = deformation_gradient(x0, x1, x2, dr_inv)
    a, b, c, d = dr_inv[0, 0], dr_inv[0, 1], dr_inv[1, 0], dr_inv[1, 1]
    weights = ((-a - c, a, c), (-b - d, b, d))  # f0 = Σ α_v x_v, f1 = Σ β_v x_v
    grad[:] = 0.0
    hess[:, :] = 0.0
    energy = 0.0
    for col in range(2):
        f = f0 if col == 0 else f1
        k = area * coef[col]
        n = max(np.sqrt(dot(f, f)), EPS)
        gap = n - length[col]
        energy += 0.5 * k * gap * gap
        across = k * (1.0 - length[col] / n)
        if not exact and across < 0.0:
            across = 0.0
        w = weights[col]
        for v in range(3):
            for p in range(3):
                grad[3 * v + p] += k * gap * f[p] / n * w[v]
            for u in range(3):
                ww = w[v] * w[u]
                for p in range(3):
                    for q in range(3):
                        ff = f[p] * f[q] / (n * n)
                        hess[3 * v + p, 3 * u + q] += ww * (k * ff + across * ((1.0 if p == q else 0.0) - ff))
    return energy


@njit(cache=True)
def dissipation_assemble(x, faces, dr_inv, area, coef, length, slots, grad, values):
    """Φ(x); adds its gradient to grad (N, 3) and projected Hessian blocks to values."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    total = 0.0
    for t in range(faces.shape[0]):
        total += dissipation_element(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                     load(x, faces[t, 2]), dr_inv[t], area[t], coef[t],
                                     length[t], False, g, hess)
        add_triangle(faces[t], slots[t], g, hess, grad, values)
    return total


@njit(cache=True)
def dissipation_energy(x, faces, dr_inv, area, coef, length):
    """Φ(x) = ½ Σ_t A_t Σ_c coef_tc (‖f_c(x)‖ − length_tc)²."""
    total = 0.0
    for t in range(faces.shape[0]):
        f0, f1 = deformation_gradient(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                      load(x, faces[t, 2]), dr_inv[t])
        g0 = np.sqrt(dot(f0, f0)) - length[t, 0]
        g1 = np.sqrt(dot(f1, f1)) - length[t, 1]
        total += 0.5 * area[t] * (coef[t, 0] * g0 * g0 + coef[t, 1] * g1 * g1)
    return total


class StretchDissipation:
    """Φ over the Model's triangles with β_t k per triangle (``stretch_damping`` (M, 2));
    :meth:`begin` sets the step's ĥ and fibre lengths."""

    def __init__(self, faces, dr_inv, area, stretch_damping, slots):
        self.faces, self.dr_inv, self.area, self.slots = faces, dr_inv, area, slots
        self.damping = np.ascontiguousarray(stretch_damping, dtype=np.float64)
        self.coef = np.zeros_like(self.damping)
        self.length = np.zeros_like(self.damping)

    def begin(self, past, h_eff):
        """The step's ĥ and fibre lengths L_b = Σ w_i L(x_i) over the (w_i, x_i) of ``past``,
        ≥ 0: L(x_n) for backward Euler, BDF2's (4L(x_n) − L(x_{n−1}))/3 (a combination of
        the strains, not the strain of the extrapolated positions, which a large step makes
        no shape of the cloth's), SDIRK2's second stage's likewise."""
        np.multiply(self.damping, 1.0 / h_eff, out=self.coef)
        self.length[:] = 0.0
        scratch = np.empty_like(self.length)
        for weight, x in past:
            self.length += weight * column_lengths(x, self.faces, self.dr_inv, scratch)
        np.maximum(self.length, 0.0, out=self.length)

    def energy(self, x):
        return dissipation_energy(x, self.faces, self.dr_inv, self.area, self.coef, self.length)

    def assemble(self, x, grad, values):
        return dissipation_assemble(x, self.faces, self.dr_inv, self.area, self.coef,
                                    self.length, self.slots, grad, values)
