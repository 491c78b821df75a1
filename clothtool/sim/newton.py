"""Implicit integration as minimisation of the incremental potential: the one Newton loop.

One step of size h from (x_n, v_n) minimises over x (Martin et al. 2011, "Example-based
elastic materials"; Gast et al. 2015, "Optimization integrator for large time steps")

    E(x) = 1/(2h²) ‖x − x_n − h v_n‖²_M − Σ m_v g·x_v + W(x) + 1/2 (x − x_n)ᵀ D (x − x_n)

where W is the method's elastic energy (:mod:`clothtool.sim.energy`) and
D = (β/h) K(x_n) is stiffness-proportional (Rayleigh) damping with β =
material.damping seconds and K the PSD-projected elastic Hessian at the start of the
step, so that the damping force is −βKv. Then v_{n+1} = (x_{n+1} − x_n)/h.

Each Newton step solves (M/h² + K(x) + D) Δx = −∇E(x) by filtered PCG
(:mod:`clothtool.sim.blocksparse`), starting from x = x_n; the first one from x_n is
exactly Baraff–Witkin's linearised step (M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f + h ∂f/∂x v_n).
The first PCG starts from the previous motion Δx = h v_n, which is nearly the answer
in slowly changing states (a guess with the free-fall term h² g would be far off at
rest). With ``line_search`` the step length is halved (at most ``MAX_HALVINGS``
times) until E does not increase, so no step raises the energy; Newton stops after
``newton_iterations`` steps or when the largest velocity correction ‖Δx‖∞/h is below
``newton_tolerance``.

Vertices held by pins or (for methods with ``contacts``) collider contacts
(:mod:`clothtool.sim.collide`) are constrained in the solve through the filter.
"""

import numpy as np

from clothtool.errors import NumericalError
from clothtool.contact.barrier import NO_OPERATOR
from clothtool.sim.blocksparse import BlockMatrix, ConstraintFilter, filtered_pcg
from clothtool.sim.collide import apply_friction, contact_constraints, resolve_collisions
from clothtool.sim.contact import BarrierContact
from clothtool.sim.integrator import Integrator, StepReport, gravity_potential, mass_weighted
from clothtool.sim.multigrid import make_preconditioner

MAX_HALVINGS = 30  # down to 2⁻³⁰: a descent direction always decreases E for a small enough step
REACHED = 1e-9  # m: moving pins and animated colliders this close to their goal have reached it


def backtracking_step(energy_at, e0, start=1.0, max_halvings=MAX_HALVINGS):
    """The first step s = start, start/2, … (at most ``max_halvings`` halvings) with
    energy_at(s) ≤ e0 = energy_at(0); 0 when none is found."""
    step = start
    for _ in range(max_halvings):
        if energy_at(step) <= e0:
            return step
        step *= 0.5
    return 0.0


class NewtonIntegrator(Integrator):
    """Newton + filtered PCG on the incremental potential of an elastic energy.

    A subclass names its energy (``energy_class``, see :mod:`clothtool.sim.energy`),
    whether collider contacts are constraints of the solve with Coulomb friction
    (``contacts``; otherwise colliders only project vertices out after the step) and
    whether it uses ``solver.preconditioner`` (``multigrid``; otherwise block Jacobi).
    """

    contacts = False
    multigrid = False

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        n = model.n_vertices
        pattern = self.elastic.pattern
        self.matrix = BlockMatrix(pattern)
        self._damping = BlockMatrix(pattern) if model.damping > 0 else None
        self._grad = np.zeros((n, 3))
        self._tmp = np.zeros((n, 3))
        self._normal = np.zeros((n, 3))
        self._contact = np.full(n, -1, dtype=np.int64)
        self.preconditioner = make_preconditioner(
            solver.preconditioner if self.multigrid else "jacobi", pattern, model.faces)
        self.contact = None  # mesh colliders and self-collision (clothtool.sim.contact)
        if model.contact is not None:
            self.contact = BarrierContact(model.contact, model.mass, model.free, h,
                                          max(model.k_stretch, model.k_shear))
            self.contact.check_initial(model.mesh.positions)

    def _damping_energy(self, dx):
        """1/2 dxᵀ D dx, and D dx left in self._tmp."""
        if self._damping is None:
            return 0.0
        self._damping.multiply(dx, self._tmp)
        return 0.5 * float(np.sum(dx * self._tmp))  # elementwise: no BLAS

    def _potential(self, x, x_n, inertia_target, elastic):
        """E(x) given W(x) = elastic."""
        d = x - inertia_target
        kinetic = 0.5 * mass_weighted(d, d, self.model.mass) / (self.h * self.h)
        gravity = gravity_potential(x, self.model.mass, self.model.gravity)
        return kinetic + gravity + elastic + self._damping_energy(x - x_n)

    def step(self, state):
        """Advance state by h in place; returns a :class:`~clothtool.sim.integrator.StepReport`."""
        model, solver, h = self.model, self.solver, self.h
        matrix, values = self.matrix, self.matrix.values
        x_n = state.x
        target = x_n + h * state.v
        x = x_n.copy()
        kind = model.kind.copy()
        dx = h * state.v  # PCG guess: the previous motion
        if model.has_pins:
            dx[model.pinned] = 0.0
        moving = model.moving_pinned
        goal = model.pin_goal(state.time + h) if len(moving) else None  # end-of-step positions
        contact = self.contact
        if contact is not None:
            contact.begin(x_n, state.v, state.time, moving, goal)
        constrained = model.has_pins
        contacts = self.contacts and model.has_colliders
        if contacts:
            predicted = target + (h * h) * model.gravity
            held = contact_constraints(x_n, predicted, kind, state.released, model.spheres,
                                       model.planes, model.collision_margin, self._normal, dx,
                                       self._contact)
            constrained = constrained or held > 0
        constraints = ConstraintFilter(kind, self._normal, constrained)
        inertia = model.mass / (h * h)
        report = StepReport()
        for it in range(solver.newton_iterations):
            elastic = self.elastic.assemble(x, self._grad, values)
            if self._damping is not None:
                if it == 0:  # D = (β/h) K(x_n), frozen for the step
                    np.multiply(values, model.damping / h, out=self._damping.values)
                values += self._damping.values
            # ∇E = M(x − x_n − h v_n)/h² − M g + ∇W + D(x − x_n)
            grad = self._mass3 * (x - target) / (h * h) - self._mass3 * model.gravity + self._grad
            if self._damping is not None and it > 0:
                self._damping_energy(x - x_n)
                grad += self._tmp
            if contact is not None:
                elastic += contact.assemble(x, grad, matrix)
            matrix.add_diagonal(inertia)
            if it > 0:
                dx = np.zeros_like(x)  # constrained components were reached in the first step
            # moving pins and animated colliders still short of their end-of-step positions
            # move with this Newton step: the pins as prescribed components of the solve, the
            # colliders through the linearised barrier force, −H_cX ΔX on the right-hand side
            prescribed = self._behind(x, moving, goal) > REACHED
            rhs = -grad
            if prescribed and goal is not None:
                dx[moving] = goal - x[moving]
            if prescribed and contact is not None:
                contact.add_collider_coupling(rhs)
            cg_its, res = filtered_pcg(matrix, rhs, dx, constraints, solver.tolerance,
                                       solver.max_iterations, self.preconditioner,
                                       contact.operator if contact is not None else NO_OPERATOR)
            report.newton_iterations += 1
            report.cg_iterations += cg_its
            report.residual = max(report.residual, res)
            if not np.all(np.isfinite(dx)):
                raise NumericalError("the linear solve produced non-finite values")
            # a step with prescribed motion is taken as far as it is collision-free (E need not
            # fall: the prescribed part adds energy); otherwise the line search from there
            step = 1.0
            if contact is not None:
                step = contact.max_step(dx)
                if not prescribed:
                    step = backtracking_step(
                        lambda s: (self._potential(x + s * dx, x_n, target,
                                                   self.elastic_energy(x + s * dx))
                                   + contact.energy(s)),
                        self._potential(x, x_n, target, elastic), start=step)
                contact.advance(step)
            elif solver.line_search and not prescribed:
                step = backtracking_step(
                    lambda s: self._potential(x + s * dx, x_n, target,
                                              self.elastic_energy(x + s * dx)),
                    self._potential(x, x_n, target, elastic))
            if step > 0.0:
                x += step * dx
                if prescribed and step == 1.0 and goal is not None:
                    x[moving] = goal  # exactly
            done = step == 0.0 or np.max(np.abs(step * dx)) <= solver.newton_tolerance * h
            if done and self._behind(x, moving, goal) <= REACHED:
                break
        behind = self._behind(x, moving, goal)
        if behind > REACHED:
            raise NumericalError(
                f"a moving pin or collider could not reach its position without crossing the "
                f"cloth (still {behind:.3g} m away after {report.newton_iterations} Newton steps)")
        state.v = (x - x_n) / h
        state.x = x
        state.time += h
        if contact is not None:
            contact.finish(state)
            report.contacts, report.min_separation = contact.contacts, contact.min_separation
        if contacts:
            self._contact_response(state, -grad, dx)
        elif model.has_colliders:
            resolve_collisions(state.x, state.v, model.free, model.spheres, model.planes,
                               model.collision_margin)
        return report

    def _behind(self, x, moving, goal):
        """How far (m) moving pins and animated colliders are from their end-of-step positions."""
        worst = 0.0
        if goal is not None:
            worst = float(np.max(np.abs(goal - x[moving])))
        if self.contact is not None:
            worst = max(worst, self.contact.colliders_behind())
        return worst

    def _contact_response(self, state, b, dx):
        """Friction from the constraint forces, release of pulling contacts, projection."""
        model = self.model
        force = self.matrix.residual(b, dx, self._tmp)
        apply_friction(state.v, model.mass, self.h, self._contact, force, self._normal,
                       model.friction)
        held = self._contact >= 0
        state.released = held & (np.einsum("ij,ij->i", force, self._normal) < 0.0)
        resolve_collisions(state.x, state.v, model.free, model.spheres, model.planes,
                           model.collision_margin)
