"""``explicit``: symplectic (semi-implicit) Euler, the baseline.

Same material as ``implicit`` (finite-element Baraff–Witkin membrane, dihedral
or quadratic bending, stiffness-proportional damping), integrated by

    v ← v + h M⁻¹ (−∇W(x) − β K(x) v + M g),   x ← x + h v

on the free vertices. The energy is ``implicit``'s (:class:`~clothtool.sim.energies.energy.FemElastic`)
through the same kernels, without assembling a matrix: the gradient-only forms
:func:`~clothtool.sim.energies.membrane.membrane_gradient` and
:func:`~clothtool.sim.energies.bending.dihedral_gradient`, and the damping force −βKv as a
product with the same projected element Hessians
(:func:`~clothtool.sim.energies.membrane.membrane_hessian_product`,
:func:`~clothtool.sim.energies.bending.quadratic_product`), only when ``material.damping`` > 0.

Stability needs h below the critical step h_c = (2/ω)(√(1 + ζ²) − ζ), ω the
highest natural frequency and ζ = βω/2. With ``cfl`` > 0 (default 0.5) each
solver step is split into ⌈h/(cfl·h_c)⌉ internal steps, with ω² bounded by the
Gershgorin bound of M⁻¹K at rest (times 1.5 for stretched states); with
``cfl: 0`` the step is exactly 1/(fps · substeps) and may blow up.

Known limits: the critical step shrinks like the mesh spacing (∝ 1/√k_stretch)
and, with damping, like 1/(β ω²) — stiff or damped cloth needs thousands of
steps per frame (the stats' ``substeps`` column counts internal steps).
"""

import math

import numpy as np

from clothtool.numba_setup import njit
from clothtool.sim.energies.bending import dihedral_gradient, quadratic_gradient, quadratic_product
from clothtool.contact.projection import resolve_collisions
from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.energies.membrane import membrane_gradient, membrane_hessian_product
from clothtool.sim.energies.plate import hessian_gradient, hessian_product

STRETCH_MARGIN = 1.5


@njit(cache=True)
def symplectic_update(x, v, force, inv_mass, gravity, h, free):
    """v += h (g − M⁻¹ force), then x += h v, on the free vertices."""
    for i in range(x.shape[0]):
        if not free[i]:
            continue
        for p in range(3):
            v[i, p] += h * (gravity[p] - inv_mass[i] * force[i, p])
            x[i, p] += h * v[i, p]


def elastic_forces(model, x, v, out):
    """out = ∇W(x) + β K(x) v (the sign convention of a gradient: the force is −out)."""
    beta = model.damping
    out[:] = 0.0
    if model.has_membrane:
        membrane_gradient(x, model.faces, model.dr_inv, model.area, model.tri_stretch,
                          model.tri_shear, out)
        if beta > 0.0:
            membrane_hessian_product(x, model.faces, model.dr_inv, model.area, model.tri_stretch,
                                     model.tri_shear, beta, v, out)
    if model.bend_model == "hessian":
        hessian_gradient(x, *model.plate, out)
        if beta > 0.0:
            hessian_product(*model.plate, beta, v, out)
    elif model.bend_model == "dihedral":
        dihedral_gradient(x, model.hinge, model.hinge_rest_angle, model.hinge_coef, out, v, beta,
                          out)
    elif model.bend_model == "quadratic":
        quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef, out)
        if beta > 0.0:
            quadratic_product(model.hinge, model.hinge_weights, model.hinge_coef, beta, v, out)
    return out


def critical_step(model):
    """Estimated largest stable symplectic-Euler step h_c of a model (s); inf without elasticity."""
    n = model.n_vertices
    p = model.pattern
    values = p.zeros()
    FemElastic(model).assemble(model.mesh.rest3d, np.zeros((n, 3)), values)
    row_abs = np.abs(values).sum(axis=2)  # (nnzb, 3): Σ_q |K_pq| per block row
    rows = np.add.reduceat(row_abs, p.row_ptr[:-1], axis=0) if p.nnzb else np.zeros((n, 3))
    bound = rows.max(axis=1) / model.mass
    bound = bound[model.free] if model.has_pins else bound
    omega2 = STRETCH_MARGIN * float(bound.max()) if len(bound) else 0.0
    if omega2 <= 0.0:
        return math.inf
    omega = math.sqrt(omega2)
    zeta = 0.5 * model.damping * omega
    return 2.0 / omega * (math.sqrt(1.0 + zeta * zeta) - zeta)


class SymplecticEuler(Integrator):
    energy_class = FemElastic

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        self.h_critical = critical_step(model)
        if solver.cfl > 0 and math.isfinite(self.h_critical):
            self.internal = max(1, math.ceil(h / (solver.cfl * self.h_critical)))
        else:
            self.internal = 1
        self.dt = h / self.internal
        self._force = np.zeros((model.n_vertices, 3))
        self._inv_mass = 1.0 / model.mass

    def step(self, state):
        model = self.model
        x = state.x.copy()
        v = state.v.copy()
        for _ in range(self.internal):
            force = elastic_forces(model, x, v, self._force)
            symplectic_update(x, v, force, self._inv_mass, model.gravity, self.dt, model.free)
            if model.has_colliders:
                resolve_collisions(x, v, model.free, model.spheres, model.planes,
                                   model.collision_margin)
        state.x = x
        state.v = v
        state.time += self.h
        return StepReport(substeps=self.internal)
