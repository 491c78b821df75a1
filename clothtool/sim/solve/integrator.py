"""The protocol every simulation method implements (after warp.sim's Model / State / Integrator).

- the :class:`~clothtool.sim.model.model.Model` holds what does not change during a run
  (rest data, masses, energies, pins, colliders, the spring network);
- the :class:`~clothtool.sim.model.state.State` holds what does (positions, velocities,
  time, contact memory), so a copy of it resumes a run;
- an :class:`Integrator` is built once per run from (model, solver settings, h) and
  advances a state by h in place with :meth:`Integrator.step`, which returns a
  :class:`StepReport`. Whatever an integrator keeps between calls is workspace that
  the next step overwrites, never memory of the motion.

The methods and the config features each supports are listed in one registry,
:mod:`clothtool.sim.model.methods`.
"""

from dataclasses import dataclass

from clothtool.contact.projection import resolve_collisions
from clothtool.numba_setup import njit
from clothtool.sim.energies.membrane import max_principal_stretch


@dataclass
class StepReport:
    """What one step (or the steps of a frame, summed) cost, each count under its own name."""

    newton_iterations: int = 0  # Newton steps (implicit, mass-spring)
    capped: int = 0  # Newton solves stopped by solver.newton_iterations, not converged
    cg_iterations: int = 0  # PCG iterations, summed over the Newton steps
    sweeps: int = 0  # constraint sweeps (pbd, xpbd) or local–global iterations (projective)
    substeps: int = 0  # internal steps (explicit)
    residual: float = 0.0  # largest final relative PCG residual of the step's solves
    contacts: int = 0  # active contact pairs after the (last) step (barrier contact)
    min_separation: float = float("inf")  # smallest contact-pair distance after it, m

    def add(self, other):
        """Accumulate another report (counts add, the residual is the largest, the contact
        figures are the later report's)."""
        self.newton_iterations += other.newton_iterations
        self.capped += other.capped
        self.cg_iterations += other.cg_iterations
        self.sweeps += other.sweeps
        self.substeps += other.substeps
        self.residual = max(self.residual, other.residual)
        self.contacts, self.min_separation = other.contacts, other.min_separation
        return self


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


class Integrator:
    """Base of every method: ``step(state)`` advances by ``h`` in place.

    Subclasses name their elastic energy W (``energy_class``, one of
    :mod:`clothtool.sim.energies.energy`: the statistics report it, Newton methods minimise
    with it) and implement :meth:`step`. ``solver`` is the config's
    :class:`~clothtool.sim.model.config.Solver` section.
    """

    energy_class = None

    def __init__(self, model, solver, h):
        self.model = model
        self.solver = solver
        self.h = h
        self._mass3 = model.mass[:, None]
        self.elastic = self.energy_class(model)

    def elastic_energy(self, x):
        """W(x) of the method's material."""
        return self.elastic.energy(x)

    def step(self, state):
        raise NotImplementedError

    def energies(self, state):
        """(kinetic, elastic, gravitational potential) of a state, J."""
        model = self.model
        return (0.5 * mass_weighted(state.v, state.v, model.mass), self.elastic_energy(state.x),
                gravity_potential(state.x, model.mass, model.gravity))

    def max_stretch(self, state):
        """Largest principal stretch over the triangles."""
        return max_principal_stretch(state.x, self.model.faces, self.model.dr_inv)

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
