"""``mass-spring``: implicit Euler on the spring network, Newton + filtered PCG.

The incremental potential is the implicit solver's (see
:mod:`clothtool.sim.integrator`) with the spring energy of
:mod:`clothtool.sim.solvers.springs` in place of the finite-element membrane
and dihedral bending:

    E(x) = 1/(2h²)‖x − x_n − h v_n‖²_M − Σ m g·x + Σ_e ½k_e(‖x_i − x_j‖ − L_e)² + ½(x − x_n)ᵀD(x − x_n)

with D = (β/h) K(x_n) (β = ``material.damping``). The spring Hessian
k[d̂d̂ᵀ + (1 − L/‖d‖)(I − d̂d̂ᵀ)] is indefinite when a spring is compressed
(‖d‖ < L); as in the course notes the negative term is dropped, which keeps
every Newton system positive definite (the Newton direction is then a descent
direction, and the line search never has to halve for indefiniteness).

Parameters: ``newton_iterations``, ``newton_tolerance``, ``line_search``,
``tolerance`` and ``max_iterations`` (PCG), as for ``implicit``.

Known limits: a spring network is a coarser material model than the membrane
(stretch and shear couple through the diagonals, bend springs resist bending only
to second order), so it converges to a slightly different shape than
``implicit``; the difference does not vanish with the step.
"""

import numpy as np

from clothtool.errors import NumericalError
from clothtool.sim.blocksparse import BlockPattern, block_multiply, filtered_pcg
from clothtool.sim.integrator import backtracking_step
from clothtool.sim.multigrid import NO_MULTIGRID
from clothtool.sim.solvers.base import SolverBase, StepReport
from clothtool.sim.solvers.springs import build_springs, spring_assemble, spring_energy

MAX_HALVINGS = 10


class MassSpringImplicit(SolverBase):
    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        sp = self.springs = build_springs(model)
        self.pattern = BlockPattern(model.n_vertices, sp.pairs)
        self.slots = self.pattern.slots(sp.pairs)
        self._grad = np.zeros((model.n_vertices, 3))
        self._values = self.pattern.zeros()
        self._damping = self.pattern.zeros() if model.damping > 0 else None
        self._tmp = np.zeros((model.n_vertices, 3))
        self._normal = np.zeros((model.n_vertices, 3))  # no sliding contacts: pins only

    def elastic_energy(self, x):
        sp = self.springs
        return spring_energy(x, sp.i, sp.j, sp.rest, sp.k)

    def _derivatives(self, x):
        sp = self.springs
        self._grad[:] = 0.0
        self._values[:] = 0.0
        return spring_assemble(x, sp.i, sp.j, sp.rest, sp.k, self.slots, self._grad, self._values)

    def _damping_energy(self, dx):
        if self._damping is None:
            return 0.0
        p = self.pattern
        block_multiply(p.row_ptr, p.col, self._damping, dx, self._tmp)
        return 0.5 * float(np.sum(dx * self._tmp))

    def _potential(self, x, x_n, target, elastic):
        d = x - target
        kinetic = 0.5 * float(np.sum(self._mass3 * d * d)) / (self.h * self.h)
        gravity = -float(self.model.mass @ (x @ self.model.gravity))
        return kinetic + gravity + elastic + self._damping_energy(x - x_n)

    def step(self, state):
        model, solver, h, p = self.model, self.solver, self.h, self.pattern
        x_n = state.x
        target = x_n + h * state.v
        x = x_n.copy()
        report = StepReport()
        diag_mass = (model.mass / (h * h))[:, None, None] * np.eye(3)
        for it in range(solver.newton_iterations):
            elastic = self._derivatives(x)
            values = self._values
            if self._damping is not None:
                if it == 0:
                    np.multiply(values, model.damping / h, out=self._damping)
                values += self._damping
            grad = self._mass3 * (x - target) / (h * h) - self._mass3 * model.gravity + self._grad
            if self._damping is not None and it > 0:
                self._damping_energy(x - x_n)
                grad += self._tmp
            values[p.diag] += diag_mass
            dx = h * state.v if it == 0 else np.zeros_like(x)
            if model.has_pins:
                dx[model.pinned] = 0.0
            cg_its, residual = filtered_pcg(p.row_ptr, p.col, values, p.diag, -grad, dx, model.kind,
                                            self._normal, model.has_pins, solver.tolerance,
                                            solver.max_iterations, NO_MULTIGRID)
            report.newton_iterations += 1
            report.cg_iterations += cg_its
            report.residual = max(report.residual, residual)
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
        self._finish(state, x)
        return report
