"""Damping as dissipation potentials of the strain change over the step.

Stiffness-proportional damping with the stiffness frozen at the start of a step,
½(x − b)ᵀ(β/ĥ)K(x_n)(x − b), measures the strain rate along the fibre directions of x_n.
Over a large step that turns the cloth (a sheet released crumpled unfolding, a hanging
sheet swinging, cloth carried round on a turntable) those directions are stale: the
damping resists rotations as if they were stretching (a crumpled sheet at one step per
frame stayed stretched 1.34× for eight frames; a sheet on a turntable at π rad/s followed
it at 1.83 rad/s). Following Brown, Overby, Narain & Kaufman 2018 ("Accurate dissipative
forces in optimization integrators", SCA), the damping is instead the potential of the
actual change over the step of strain measures that no rigid motion changes:

    Φ(x) = 1/(2ĥ) Σ_t A_t β_t [k_u (‖f0‖ − L_0)² + k_v (‖f1‖ − L_1)² + k_h (f0·f1 − S)²]
         + 1/ĥ Σ_e β_e c_e (θ_e − Θ_e)²

(f0, f1 the columns of F, :mod:`clothtool.sim.energies.membrane`; θ_e the dihedral angle of
hinge e and c_e its coefficient, :mod:`clothtool.sim.energies.bending`), with the
integrator's own strain rate: (‖f(x)‖ − L)/ĥ is the discretisation's derivative of the
fibre length when L is the same combination of the past's lengths as its base b is of
the past's positions (L = ‖f(x_n)‖ for backward Euler, (4‖f(x_n)‖ − ‖f(x_{n−1})‖)/3 for
BDF2; a combination of the strains, not the strain of the combined positions, which a
large step makes no shape of the cloth's), likewise S and Θ. To first order each part is
the frozen form with the matching part of K: its Gauss–Newton Hessian. Stretch: gradient
per column (A βk/ĥ)(‖f‖ − L) f̂ through ∂f/∂x, Hessian (A βk/ĥ)[f̂f̂ᵀ + c(I − f̂f̂ᵀ)],
c = 1 − L/‖f‖, taken with c clamped at 0 (PSD). Shear: gradient (A βk_h/ĥ)(s − S)(f1, f0),
Hessian (A βk_h/ĥ)[(f1, f0)(f1, f0)ᵀ + (s − S)H₆], taken without the H₆ part (PSD).
Bending: the dihedral kernels with c → βc/ĥ and θ̄ → Θ (Gauss–Newton Hessian).
"""

import numpy as np
from numba import njit

from clothtool.geometry import dihedral_angles
from clothtool.sim.energies.bending import dihedral_assemble, dihedral_total_energy
from clothtool.sim.energies.membrane import add_triangle, deformation_gradient
from clothtool.vec3 import dot, load

EPS = 1e-12


@njit(cache=True)
def strain_measures(x, faces, dr_inv, out):
    """out (M, 3) = ‖f0‖, ‖f1‖, f0·f1 of every triangle at x."""
    for t in range(faces.shape[0]):
        f0, f1 = deformation_gradient(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                      load(x, faces[t, 2]), dr_inv[t])
        out[t, 0] = np.sqrt(dot(f0, f0))
        out[t, 1] = np.sqrt(dot(f1, f1))
        out[t, 2] = dot(f0, f1)
    return out


@njit(cache=True)
def dissipation_element(x0, x1, x2, dr_inv, area, coef, base, exact, grad, hess):
    """Φ of one triangle, coef = (βk_u/ĥ, βk_v/ĥ, βk_h/ĥ), base = (L_0, L_1, S); writes its
    gradient (9,) and Hessian (9, 9) (vertex-major): exact with ``exact``, else with c
    clamped at 0 and without the shear's H₆ part."""
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
        gap = n - base[col]
        energy += 0.5 * k * gap * gap
        across = k * (1.0 - base[col] / n)
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
    # shear s = f0·f1: ∂s/∂x_v = α_v f1 + β_v f0, ∂²s/∂x_v∂x_u = (α_v β_u + β_v α_u) I
    k = area * coef[2]
    gap = dot(f0, f1) - base[2]
    energy += 0.5 * k * gap * gap
    al, be = weights[0], weights[1]
    for v in range(3):
        for p in range(3):
            gv = al[v] * f1[p] + be[v] * f0[p]
            grad[3 * v + p] += k * gap * gv
            for u in range(3):
                for q in range(3):
                    hess[3 * v + p, 3 * u + q] += k * gv * (al[u] * f1[q] + be[u] * f0[q])
            if exact:
                for u in range(3):
                    hess[3 * v + p, 3 * u + p] += k * gap * (al[v] * be[u] + be[v] * al[u])
    return energy


@njit(cache=True)
def dissipation_assemble(x, faces, dr_inv, area, coef, base, slots, grad, values):
    """Φ(x) of the triangles; adds its gradient to grad (N, 3) and projected Hessian blocks
    to values."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    total = 0.0
    for t in range(faces.shape[0]):
        total += dissipation_element(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                     load(x, faces[t, 2]), dr_inv[t], area[t], coef[t],
                                     base[t], False, g, hess)
        add_triangle(faces[t], slots[t], g, hess, grad, values)
    return total


@njit(cache=True)
def dissipation_energy(x, faces, dr_inv, area, coef, base):
    """Φ(x) of the triangles = ½ Σ_t A_t Σ_c coef_tc (m_c(x) − base_tc)², m = (‖f0‖, ‖f1‖, f0·f1)."""
    total = 0.0
    for t in range(faces.shape[0]):
        f0, f1 = deformation_gradient(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                      load(x, faces[t, 2]), dr_inv[t])
        g0 = np.sqrt(dot(f0, f0)) - base[t, 0]
        g1 = np.sqrt(dot(f1, f1)) - base[t, 1]
        g2 = dot(f0, f1) - base[t, 2]
        total += 0.5 * area[t] * (coef[t, 0] * g0 * g0 + coef[t, 1] * g1 * g1
                                  + coef[t, 2] * g2 * g2)
    return total


class StrainDissipation:
    """Φ over the Model's triangles (``strain_damping`` (M, 3): β_t k_u, β_t k_v, β_t k_h)
    and hinges (``bend_damping`` (H,): β_e c_e; none when None); :meth:`begin` sets the
    step's ĥ and the strains its rates are measured from."""

    def __init__(self, model):
        self.faces, self.dr_inv, self.area = model.faces, model.dr_inv, model.area
        self.slots = model.tri_slots
        self.damping = np.ascontiguousarray(model.strain_damping, dtype=np.float64)
        self.coef = np.zeros_like(self.damping)
        self.base = np.zeros_like(self.damping)
        bend = model.bend_damping
        self.hinge = model.hinge if bend is not None else np.zeros((0, 4), np.int64)
        self.hinge_slots = model.hinge_damping_slots if bend is not None else np.zeros((0, 16), np.int64)
        self.bend = np.zeros(len(self.hinge)) if bend is None else bend
        self.bend_coef = np.zeros_like(self.bend)
        self.angle = np.zeros_like(self.bend)

    def begin(self, past, h_eff):
        """The step's ĥ and base strains Σ w_i m(x_i) over the (w_i, x_i) of ``past``
        (lengths ≥ 0)."""
        np.multiply(self.damping, 1.0 / h_eff, out=self.coef)
        np.multiply(self.bend, 1.0 / h_eff, out=self.bend_coef)
        self.base[:] = 0.0
        self.angle[:] = 0.0
        scratch = np.empty_like(self.base)
        for weight, x in past:
            self.base += weight * strain_measures(x, self.faces, self.dr_inv, scratch)
            if len(self.hinge):
                self.angle += weight * dihedral_angles(x, self.hinge)
        np.maximum(self.base[:, :2], 0.0, out=self.base[:, :2])

    def energy(self, x):
        total = dissipation_energy(x, self.faces, self.dr_inv, self.area, self.coef, self.base)
        return total + dihedral_total_energy(x, self.hinge, self.angle, self.bend_coef)

    def assemble(self, x, grad, values):
        total = dissipation_assemble(x, self.faces, self.dr_inv, self.area, self.coef,
                                     self.base, self.slots, grad, values)
        return total + dihedral_assemble(x, self.hinge, self.angle, self.bend_coef,
                                         self.hinge_slots, grad, values)
