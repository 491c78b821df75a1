"""Implicit Euler as minimisation of the incremental potential (Newton + filtered PCG).

One step of size h from (x_n, v_n) minimises over x (Martin et al. 2011; course notes):

    E(x) = 1/(2h²) ‖x − x_n − h v_n‖²_M − Σ m_v g·x_v + W(x) + 1/2 (x − x_n)ᵀ D (x − x_n)

where W is the elastic energy (stretch, shear, bending) and D = (β/h) K(x_n) is
stiffness-proportional (Rayleigh) damping with β = material.damping seconds and
K the PSD-projected elastic Hessian at the start of the step, so that the damping
force is −βKv. Then v_{n+1} = (x_{n+1} − x_n)/h.

Each Newton step solves (M/h² + K(x) + D) Δx = −∇E(x) by PCG, starting from
x = x_n; the first one from x_n is exactly Baraff–Witkin's linearised step
(M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f + h ∂f/∂x v_n). The PCG starts from the
previous motion Δx = h v_n, which is nearly the answer in slowly changing
states (a guess with the free-fall term h² g would be far off at rest). With
``line_search`` the step length is halved until E does not increase, so no
step raises the energy; Newton stops after ``newton_iterations`` steps or when
the largest velocity correction ‖Δx‖∞/h is below ``newton_tolerance``.

Vertices held by pins or collider contacts (``collide``) are constrained in the
solve through the filter of ``filter``/``blocksparse``.
"""

from dataclasses import dataclass

import numpy as np
from numba import njit

from clothtool.errors import NumericalError
from clothtool.sim.bending import dihedral_assemble, dihedral_total_energy, quadratic_gradient
from clothtool.sim.blocksparse import BlockPattern, block_multiply, filtered_pcg, residual
from clothtool.sim.collide import apply_friction, contact_constraints, resolve_collisions
from clothtool.sim.membrane import max_principal_stretch, membrane_assemble, membrane_total_energy
from clothtool.sim.multigrid import COARSEST, NO_MULTIGRID, Hierarchy

MAX_HALVINGS = 30  # down to 2⁻³⁰: a descent direction always decreases E for a small enough step


@njit(cache=True)
def mass_weighted(x, y, mass):
    """Σ_v m_v x_v·y_v (plain loops: numpy's BLAS would start threads that spin on 2 cores)."""
    total = 0.0
    for i in range(x.shape[0]):
        total += mass[i] * (x[i, 0] * y[i, 0] + x[i, 1] * y[i, 1] + x[i, 2] * y[i, 2])
    return total


@njit(cache=True)
def gravity_potential(x, mass, g):
    """−Σ_v m_v g·x_v."""
    total = 0.0
    for i in range(x.shape[0]):
        total -= mass[i] * (g[0] * x[i, 0] + g[1] * x[i, 1] + g[2] * x[i, 2])
    return total


def fem_elastic_energy(model, x):
    """W(x) of the finite-element material: stretch + shear (Kim 2020) + bending."""
    total = 0.0
    if model.has_membrane:
        total += membrane_total_energy(x, model.faces, model.dinv, model.area,
                                       model.k_stretch, model.k_shear)
    if model.bend_model == "dihedral":
        total += dihedral_total_energy(x, model.hinge, model.hinge_rest_angle, model.hinge_coef)
    elif model.bend_model == "quadratic":  # an empty gradient array: energy only
        total += quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef,
                                    np.zeros((0, 3)))
    return total


def backtracking_step(potential, x, dx, e0, max_halvings):
    """The first step 1, 1/2, 1/4, … (at most ``max_halvings`` halvings) with
    potential(x + step·dx) ≤ e0 = potential(x); 0 when none is found."""
    step = 1.0
    for _ in range(max_halvings):
        if potential(x + step * dx) <= e0:
            return step
        step *= 0.5
    return 0.0


@dataclass
class StepReport:
    newton_iterations: int = 0
    cg_iterations: int = 0
    residual: float = 0.0  # largest final relative PCG residual of the step's solves


class ImplicitEuler:
    """Advances a :class:`~clothtool.sim.state.State` of a :class:`~clothtool.sim.model.Model`."""

    def __init__(self, model, solver, h):
        self.model = model
        self.solver = solver
        self.h = h
        n = model.n_vertices
        self._mass3 = model.mass[:, None]
        self._grad = np.zeros((n, 3))
        self._values = model.pattern.zeros()
        self._damping = model.pattern.zeros() if model.damping > 0 else None
        self._tmp = np.zeros((n, 3))
        self._normal = np.zeros((n, 3))
        self._contact = np.full(n, -1, dtype=np.int64)
        self._released = np.zeros(n, dtype=np.bool_)  # contacts that pulled last step
        self._mg = NO_MULTIGRID  # block Jacobi; also for meshes too small to coarsen
        if solver.preconditioner == "multigrid" and n > COARSEST:
            triangles = BlockPattern(n, model.faces)
            self._mg = Hierarchy(model.pattern.row_ptr, model.pattern.col,
                                 graph=(triangles.row_ptr, triangles.col)).arrays()

    # ------------------------------------------------------------------ energies

    def elastic_energy(self, x):
        """W(x): stretch + shear + bending."""
        return fem_elastic_energy(self.model, x)

    def _elastic_derivatives(self, x):
        """W(x); fills self._grad with ∇W and self._values with the projected Hessian K."""
        model = self.model
        grad, values = self._grad, self._values
        grad[:] = 0.0
        if model.constant_hessian is not None:
            values[:] = model.constant_hessian
        else:
            values[:] = 0.0
        total = 0.0
        if model.has_membrane:
            total += membrane_assemble(x, model.faces, model.dinv, model.area, model.k_stretch,
                                       model.k_shear, model.tri_slots, grad, values)
        if model.bend_model == "dihedral":
            total += dihedral_assemble(x, model.hinge, model.hinge_rest_angle, model.hinge_coef,
                                       model.hinge_slots, grad, values)
        elif model.bend_model == "quadratic":
            total += quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef, grad)
        return total

    def _damping_energy(self, dx):
        """1/2 dxᵀ D dx, and D dx left in self._tmp."""
        if self._damping is None:
            return 0.0
        p = self.model.pattern
        block_multiply(p.row_ptr, p.col, self._damping, dx, self._tmp)
        return 0.5 * float(np.sum(dx * self._tmp))  # elementwise: no BLAS

    def _potential(self, x, x_n, inertia_target, elastic):
        """E(x) given W(x) = elastic."""
        d = x - inertia_target
        kinetic = 0.5 * mass_weighted(d, d, self.model.mass) / (self.h * self.h)
        gravity = gravity_potential(x, self.model.mass, self.model.gravity)
        return kinetic + gravity + elastic + self._damping_energy(x - x_n)

    def energies(self, state):
        """(kinetic, elastic, gravitational potential) of a state, J."""
        model = self.model
        kinetic = 0.5 * mass_weighted(state.v, state.v, model.mass)
        return (kinetic, self.elastic_energy(state.x),
                gravity_potential(state.x, model.mass, model.gravity))

    def max_stretch(self, state):
        return max_principal_stretch(state.x, self.model.faces, self.model.dinv)

    # ------------------------------------------------------------------ stepping

    def step(self, state):
        """Advance state by h in place; returns a :class:`StepReport`."""
        model, solver, h = self.model, self.solver, self.h
        pattern = model.pattern
        x_n = state.x
        target = x_n + h * state.v
        x = x_n.copy()
        kind = model.kind.copy()
        dx = h * state.v  # PCG guess: the previous motion
        if model.has_pins:
            dx[model.pinned] = 0.0
        constrained = model.has_pins
        if model.has_colliders:
            predicted = target + (h * h) * model.gravity
            held = contact_constraints(x_n, predicted, kind, self._released, model.spheres,
                                       model.planes, model.collision_margin, self._normal, dx,
                                       self._contact)
            constrained = constrained or held > 0
        report = StepReport()
        for it in range(solver.newton_iterations):
            elastic = self._elastic_derivatives(x)
            values = self._values
            if self._damping is not None:
                if it == 0:  # D = (β/h) K(x_n), frozen for the step
                    np.multiply(values, model.damping / h, out=self._damping)
                values += self._damping
            # ∇E = M(x − x_n − h v_n)/h² − M g + ∇W + D(x − x_n)
            grad = self._mass3 * (x - target) / (h * h) - self._mass3 * model.gravity + self._grad
            if self._damping is not None and it > 0:
                self._damping_energy(x - x_n)
                grad += self._tmp
            values[pattern.diag] += (model.mass / (h * h))[:, None, None] * np.eye(3)
            if it > 0:
                dx = np.zeros_like(x)  # constrained components were reached in the first step
            cg_its, res = filtered_pcg(pattern.row_ptr, pattern.col, values, pattern.diag, -grad,
                                       dx, kind, self._normal, constrained, solver.tolerance,
                                       solver.max_iterations, self._mg)
            report.newton_iterations += 1
            report.cg_iterations += cg_its
            report.residual = max(report.residual, res)
            if not np.all(np.isfinite(dx)):
                raise NumericalError("the linear solve produced non-finite values")
            step = 1.0
            if solver.line_search:
                step = backtracking_step(
                    lambda y: self._potential(y, x_n, target, self.elastic_energy(y)),
                    x, dx, self._potential(x, x_n, target, elastic), MAX_HALVINGS)
            if step > 0.0:
                x += step * dx
            if step == 0.0 or np.max(np.abs(step * dx)) <= solver.newton_tolerance * h:
                break
        state.v = (x - x_n) / h
        state.x = x
        state.time += h
        if model.has_colliders:
            self._contact_response(state, values, -grad, dx)
        return report

    def _contact_response(self, state, values, b, dx):
        """Friction from the constraint forces, release of pulling contacts, projection."""
        model = self.model
        force = self._tmp
        residual(model.pattern.row_ptr, model.pattern.col, values, b, dx, force)
        apply_friction(state.v, model.mass, self.h, self._contact, force, self._normal,
                       model.friction)
        held = self._contact >= 0
        self._released[:] = held & (np.einsum("ij,ij->i", force, self._normal) < 0.0)
        resolve_collisions(state.x, state.v, model.free, model.spheres, model.planes,
                           model.collision_margin)
