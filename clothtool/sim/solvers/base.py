"""What every solver shares: the step report, energies, max stretch, the collision pass."""

import numpy as np

from clothtool.sim.collide import resolve_collisions
from clothtool.sim.integrator import StepReport
from clothtool.sim.membrane import max_principal_stretch

__all__ = ["SolverBase", "StepReport"]


class SolverBase:
    """Base of the alternative solvers: ``step(state)`` advances by ``h`` in place.

    Subclasses implement :meth:`elastic_energy` (their own elastic model, used in
    the statistics) and :meth:`step`. ``newton_iterations`` in the report counts
    Newton steps, constraint sweeps or local–global iterations, whichever the
    method has; ``cg_iterations`` is 0 for methods without a CG solve.
    """

    def __init__(self, model, solver, h):
        self.model = model
        self.solver = solver
        self.h = h
        self._mass3 = model.mass[:, None]

    def elastic_energy(self, x):
        raise NotImplementedError

    def energies(self, state):
        """(kinetic, elastic, gravitational potential) of a state, J."""
        model = self.model
        kinetic = 0.5 * float(model.mass @ np.einsum("ij,ij->i", state.v, state.v))
        return kinetic, self.elastic_energy(state.x), -float(model.mass @ (state.x @ model.gravity))

    def max_stretch(self, state):
        return max_principal_stretch(state.x, self.model.faces, self.model.dinv)

    def _inertial_target(self, state):
        """y = x_n + h v_n + h² g on free vertices; pinned vertices stay where they are."""
        h = self.h
        y = state.x + h * state.v + (h * h) * self.model.gravity
        if self.model.has_pins:
            y[self.model.pinned] = state.x[self.model.pinned]
        return y

    def _finish(self, state, x):
        """v = (x − x_n)/h, x_n ← x, t += h, then the collision pass (only with colliders)."""
        model = self.model
        state.v = (x - state.x) / self.h
        state.x = x
        state.time += self.h
        if model.has_colliders:
            resolve_collisions(state.x, state.v, model.free, model.spheres, model.planes,
                               model.collision_margin)

    def _inverse_mass(self):
        w = 1.0 / self.model.mass
        if self.model.has_pins:
            w[self.model.pinned] = 0.0
        return w
