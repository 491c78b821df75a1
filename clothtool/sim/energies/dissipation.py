"""Damping as dissipation potentials of the strain change over the step.

Stiffness-proportional damping with the stiffness frozen at the start of a step,
½(x − b)ᵀ(β/ĥ)K(x_n)(x − b), measures the strain rate along the fibre directions of x_n.
A step that turns a fibre by φ shortens it along its old direction by (1 − cos φ)‖f‖, a
strain that did not happen, and that damping resists it with βk/ĥ: at one step per frame
this is no small correction (a 1 m sheet of 1000 N/m draped on a sphere turning at π rad/s,
φ = 0.1 per step: 0.13 N on a vertex weighing 0.008 N), so the cloth lags the sphere (0.71
of its rate), a crumpled sheet stays stretched (1.29 at frame 8) and a hanging sheet creeps
down where it should swing. Dropping K's stress part (Baraff–Witkin's condition damping
β JᵀK_C J at x_n, linear and rotation-free to first order) keeps this second-order part
(0.79, 1.37). Following Brown, Overby, Narain & Kaufman 2018 ("Accurate dissipative forces
in optimization integrators", SCA), the damping is instead the potential of the actual
change over the step of strain measures that no rigid motion changes:

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
Bending: with the hinge models, the dihedral kernels with c → βc/ĥ and θ̄ → Θ (Gauss–Newton
Hessian); with the plate (:mod:`clothtool.sim.energies.plate`), whose strain (the Hessian of
x over its pattern) is linear in x, 1/(2ĥ) Σ_c (x − b)_cᵀ β k_b Q (x − b)_c on the plate's own
blocks, the term above with Θ = Ĥ(b): a rigid turn of bent cloth feels β ω × its bending
force and nothing of second order (hinges would add 15 % to the blocks of the 64² sheet's
matrix, and with their kernel cost 0.4× a frozen step). The triangles' Φ is assembled in
the same pass as the membrane's W (:func:`strain_assemble`): both read the same F.
"""

import numpy as np

from clothtool.geometry import dihedral_angles
from clothtool.numba_setup import njit, njit_inner
from clothtool.sim.energies.bending import dihedral_assemble, dihedral_total_energy
from clothtool.sim.energies.membrane import (add_triangle, deformation, deformation_gradient,
                                             membrane_density, membrane_total_energy,
                                             shear_outer, to_vertices)
from clothtool.sim.energies.membrane_edge import edge_density
from clothtool.sim.energies.plate import quadratic_form
from clothtool.sim.energies.terms import EdgeMembrane
from clothtool.vec3 import add, dot, load, scale

EPS = 1e-12
ZERO = (0.0, 0.0, 0.0)
NO_GRADIENT = np.zeros((0, 3))  # the energy-only call of the plate's kernel
NO_BLOCKS = np.zeros((0, 3, 3))
NO_EDGES = (None, None, None, None)  # strain_assemble without the edge membrane: numba prunes it


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


@njit_inner(cache=True)
def dissipation_density(f0, f1, coef, base, exact, g0, g1, h_f):
    """φ = ½ Σ_c coef_c (m_c − base_c)² per unit rest area, m = (‖f0‖, ‖f1‖, f0·f1), at
    F = (f0, f1); returns (φ, g0 + ∂φ/∂f0, g1 + ∂φ/∂f1) and adds ∂²φ/∂vec F² to h_f (6, 6):
    exact with ``exact``, else with c clamped at 0 and without the shear's H₆ part."""
    energy = 0.0
    for col in range(2):
        f = f0 if col == 0 else f1
        k = coef[col]
        n = max(np.sqrt(dot(f, f)), EPS)
        gap = n - base[col]
        energy += 0.5 * k * gap * gap
        c = 1.0 - base[col] / n
        if not exact and c < 0.0:
            c = 0.0
        o = 3 * col
        for p in range(3):
            for q in range(3):
                h_f[o + p, o + q] += k * (1.0 - c) * f[p] * f[q] / (n * n)
            h_f[o + p, o + p] += k * c
        if col == 0:
            g0 = add(g0, scale(k * gap / n, f))
        else:
            g1 = add(g1, scale(k * gap / n, f))
    # shear s = f0·f1: ∂s/∂f0 = f1, ∂s/∂f1 = f0, ∂²s/∂f0∂f1 = I
    k = coef[2]
    gap = dot(f0, f1) - base[2]
    energy += 0.5 * k * gap * gap
    g0 = add(g0, scale(k * gap, f1))
    g1 = add(g1, scale(k * gap, f0))
    shear_outer(f0, f1, k, k * gap, exact, h_f)
    return energy, g0, g1


@njit(cache=True)
def dissipation_element(x0, x1, x2, dr_inv, area, coef, base, exact, grad, hess):
    """Φ of one triangle, coef = (βk_u/ĥ, βk_v/ĥ, βk_h/ĥ), base = (L_0, L_1, S); writes its
    gradient (9,) and Hessian (9, 9) (vertex-major): exact with ``exact``, else with c
    clamped at 0 and without the shear's H₆ part."""
    f0, f1, alpha, beta = deformation(x0, x1, x2, dr_inv)
    h_f = np.zeros((6, 6))
    energy, g0, g1 = dissipation_density(f0, f1, coef, base, exact, ZERO, ZERO, h_f)
    to_vertices(alpha, beta, area, g0, g1, h_f, grad, hess)
    return area * energy


@njit(cache=True)
def strain_assemble(x, faces, dr_inv, area, stretch, k_shear, cells, turn, weight, stress, coef,
                    base, slots, grad, values):
    """(W, Φ) of the triangles; adds both gradients and projected Hessian blocks to grad
    (N, 3) and values in one pass: W the membrane's (``stretch`` (M, 4), ``k_shear`` (M,),
    :mod:`clothtool.sim.energies.membrane`), none when ``stretch`` has no rows. With
    ``cells`` (not None), each triangle's share of the edge membrane's gradient and Hessian too
    (:func:`~clothtool.sim.energies.membrane_edge.edge_density`, its cells' ``stress`` from
    :func:`~clothtool.sim.energies.membrane_edge.edge_stresses` at x; its W is not summed
    here). Without the edge membrane ``cells``, ``turn``, ``weight`` and ``stress`` are None
    (``NO_EDGES``): numba then prunes the test of ``cells`` and does not compile
    ``edge_density``."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    h_f = np.empty((6, 6))
    fused = stretch.shape[0] > 0
    membrane, total = 0.0, 0.0
    for t in range(faces.shape[0]):
        f0, f1, alpha, beta = deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                          load(x, faces[t, 2]), dr_inv[t])
        g0, g1 = ZERO, ZERO
        if fused:
            w, g0, g1 = membrane_density(f0, f1, stretch[t], k_shear[t], True, h_f)
            membrane += area[t] * w
        else:
            h_f[:, :] = 0.0
        if cells is not None:
            g0, g1 = edge_density(f0, f1, t, cells, turn, weight, stress, g0, g1, h_f)
        phi, g0, g1 = dissipation_density(f0, f1, coef[t], base[t], False, g0, g1, h_f)
        total += area[t] * phi
        to_vertices(alpha, beta, area[t], g0, g1, h_f, g, hess)
        add_triangle(faces[t], slots[t], g, hess, grad, values)
    return membrane, total


@njit(cache=True)
def strain_energy(x, faces, dr_inv, area, stretch, k_shear, coef, base):
    """W + Φ of the triangles (W as in :func:`strain_assemble`)."""
    total = dissipation_energy(x, faces, dr_inv, area, coef, base)
    if stretch.shape[0] > 0:
        total += membrane_total_energy(x, faces, dr_inv, area, stretch, k_shear)
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


@njit(cache=True)
def plate_dissipation(x, base, ptr, col, coef, slots, grad, values):
    """½ Σ_c (x − b)_cᵀ C (x − b)_c with C (CSR ptr, col, coef); with grad of rows, adds its
    gradient C(x − b) to grad (N, 3) and C's entries to the diagonals of the blocks
    values[slots]."""
    if grad.shape[0] > 0:
        for k in range(col.shape[0]):
            block = values[slots[k]]
            block[0, 0] += coef[k]
            block[1, 1] += coef[k]
            block[2, 2] += coef[k]
    d = np.empty((x.shape[0], 3))  # x − base in a loop: the array expression compiles a ufunc loop
    for i in range(x.shape[0]):
        for p in range(3):
            d[i, p] = x[i, p] - base[i, p]
    return quadratic_form(d, ptr, col, coef, grad)


class StrainDissipation:
    """Φ over the Model's triangles (``strain_damping`` (M, 3): β_t k_u, β_t k_v, β_t k_h)
    and hinges (``bend_damping`` (H,): β_e c_e; none when None); :meth:`begin` sets the
    step's ĥ and the strains its rates are measured from. With ``membrane`` (the Model's
    :class:`~clothtool.sim.energies.terms.Membrane` or
    :class:`~clothtool.sim.energies.terms.EdgeMembrane` term) its energy and assembly are
    W_membrane + Φ, in one pass over the triangles (both read the same F; the edge
    membrane's cells summed first): the Newton loop then leaves that term out of the
    elastic sum."""

    def __init__(self, model, membrane=None):
        self.faces, self.dr_inv, self.area = model.faces, model.dr_inv, model.area
        self.slots = model.tri_slots
        self.membrane, self.h_eff = membrane, 1.0
        self.edge = membrane if isinstance(membrane, EdgeMembrane) else None
        triangles = membrane is not None and self.edge is None
        self.stretch = membrane.stretch if triangles else np.zeros((0, 4))
        self.shear = membrane.shear if triangles else np.zeros(0)
        self.edge_parts = ((self.edge.cells, self.edge.turn, self.edge.weight, self.edge.stress)
                           if self.edge is not None else NO_EDGES)
        self.damping = np.ascontiguousarray(model.strain_damping, dtype=np.float64)
        self.coef = np.zeros_like(self.damping)
        self.base = np.zeros_like(self.damping)
        bend = model.bend_damping
        self.hinge = model.hinge if bend is not None else np.zeros((0, 4), np.int64)
        self.hinge_slots = model.hinge_damping_slots if bend is not None else np.zeros((0, 16), np.int64)
        self.bend = np.zeros(len(self.hinge)) if bend is None else bend
        self.bend_coef = np.zeros_like(self.bend)
        self.angle = np.zeros_like(self.bend)
        self.plate = model.plate_damping
        if self.plate is not None:
            ptr, col, val = self.plate
            rows = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
            self.plate_slots = model.pattern.slots(np.stack([rows, col], axis=1))[:, 1]
            self.plate_coef = np.zeros_like(val)
            self.plate_base = np.zeros((len(ptr) - 1, 3))

    def begin(self, past, h_eff):
        """The step's ĥ and base strains Σ w_i m(x_i) over the (w_i, x_i) of ``past``
        (lengths ≥ 0)."""
        self.h_eff = h_eff
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
        if self.plate is not None:  # the plate's strain is linear: its base is Σ w_i x_i
            np.multiply(self.plate[2], 1.0 / h_eff, out=self.plate_coef)
            self.plate_base[:] = 0.0
            for weight, x in past:
                self.plate_base += weight * x

    def soften(self, factor):
        """The triangles' Φ and the membrane assembled with it × ``factor`` (1 restores them
        exactly; ``solver.stiffness_continuation``); bending's Φ as it is."""
        np.multiply(self.damping, 1.0 / self.h_eff, out=self.coef)
        if factor != 1.0:
            self.coef *= factor
        if self.membrane is not None:
            self.membrane.soften(factor)

    def energy(self, x):
        total = strain_energy(x, self.faces, self.dr_inv, self.area, self.stretch, self.shear,
                              self.coef, self.base)
        if self.edge is not None:
            total += self.edge.energy(x)
        return total + self._bending(x, NO_GRADIENT, None)

    def assemble(self, x, grad, values):
        edge = self.edge.stresses(x, True) if self.edge is not None else 0.0
        membrane, total = strain_assemble(x, self.faces, self.dr_inv, self.area, self.stretch,
                                          self.shear, *self.edge_parts, self.coef, self.base,
                                          self.slots, grad, values)
        total += edge
        return membrane + total + self._bending(x, grad, values)

    def _bending(self, x, grad, values):
        """Bending's Φ; with ``values``, its gradient added to grad and its Hessian to values:
        the hinges' (dihedral kernels, c → βc/ĥ, θ̄ → Θ) or the plate's, 1/(2ĥ) Σ_c
        (x − b)_cᵀ β k_b Q (x − b)_c with constant Hessian β k_b Q/ĥ."""
        if self.plate is not None:
            ptr, col, _ = self.plate
            return plate_dissipation(x, self.plate_base, ptr, col, self.plate_coef,
                                     self.plate_slots, grad, NO_BLOCKS if values is None else values)
        if values is None:
            return dihedral_total_energy(x, self.hinge, self.angle, self.bend_coef)
        return dihedral_assemble(x, self.hinge, self.angle, self.bend_coef, self.hinge_slots,
                                 grad, values)
