"""The terms of the incremental potential, each behind one protocol.

A step (or a stage of one) minimises E(x) = Σ_k E_k(x) over the cloth's positions x; the
Newton loop (:mod:`clothtool.sim.solve.newton`) sums a list of terms and never asks which
kind a term is (Li et al. 2020, "Incremental Potential Contact", Algorithm 1). A term:

- :meth:`~Term.begin` reads the stage (:class:`Stage`: ĥ, the base b with v = (x − b)/ĥ,
  the inertia target x̃, where moving pins go);
- :meth:`~Term.assemble` adds its gradient into grad (N, 3) and its Hessian's blocks into
  the block matrix, returns E_k(x); the elastic term, first in the list, starts the sums
  (it overwrites them), and a term with a matrix-free part leaves it in ``operator``;
- :meth:`~Term.along` gives s ↦ E_k(x + s dx) for the line search;
- :meth:`~Term.max_step` is its largest safe fraction of a step (CCD; 1 without);
- :meth:`~Term.cuts` says whether CCD over its current candidates would cut a motion short
  (a hint for the solve; False without);
- :meth:`~Term.prescribe` moves what the stage prescribes (moving pins, animated
  colliders) with the Newton step, :meth:`~Term.behind` says how far that still is;
- :meth:`~Term.soften` scales its membrane stiffness for ``solver.stiffness_continuation``
  (1 restores it);
- :meth:`~Term.advance` follows the accepted step, :meth:`~Term.settled` and
  :meth:`~Term.relag` are a converged step's extra tests (lagged friction),
  :meth:`~Term.finish` writes its figures into the step's report.
"""

from dataclasses import dataclass

import numpy as np

from clothtool.sim.solve.integrator import gravity_potential, mass_weighted


@dataclass
class Stage:
    """One minimisation: from ``state`` over ``duration`` s, velocity v = (x − base)/h_eff,
    inertia target ``target``; ``past`` the (weight, positions) whose weighted strains are
    the strain the stage's rates are measured from; moving pins bound for ``goal`` at the
    stage's end; Newton starts at ``start`` (state.x when ``from_state``) and its first
    PCG from ``guess``."""

    state: object
    duration: float
    h_eff: float
    base: np.ndarray
    target: np.ndarray
    past: tuple
    moving: np.ndarray
    goal: np.ndarray | None
    start: np.ndarray = None
    guess: np.ndarray = None
    from_state: bool = False


class Term:
    """A term with no matrix-free part, no CCD, nothing prescribed, nothing lagged."""

    operator = None  # contact's pair operator (clothtool.sim.linalg.pairs)
    needs_line_search = False  # every Newton step is line-searched (a barrier)
    starts_at_state = False  # Newton must start at the state's positions (collision-free)

    def begin(self, stage):
        pass

    def energy(self, x):
        raise NotImplementedError

    def assemble(self, x, grad, matrix):
        raise NotImplementedError

    def along(self, x, dx):
        return lambda s: self.energy(x + s * dx)

    def max_step(self, x, dx):
        return 1.0

    def cuts(self, x, dx):
        return False

    def prescribe(self, x, dx, rhs):
        pass

    def soften(self, factor):
        pass

    def advance(self, x, dx, step):
        pass

    def behind(self, x):
        return 0.0

    def settled(self, free_grad, h_eff):
        return 0.0

    def relag(self, x):
        return 0.0

    def lagged(self):
        """Whether lagged friction pairs take part in this stage's potential."""
        return False

    def finish(self, x, report):
        pass


class Wrapped(Term):
    """A term whose energy, assembly (into the matrix's values) and softening are those of
    the energy object it holds."""

    def __init__(self, potential):
        self.potential = potential

    def energy(self, x):
        return self.potential.energy(x)

    def assemble(self, x, grad, matrix):
        return self.potential.assemble(x, grad, matrix.values)

    def soften(self, factor):
        self.potential.soften(factor)


class Elastic(Wrapped):
    """W(x), the method's elastic energy (:mod:`clothtool.sim.energies.energy`); it starts
    the sums: its assembly overwrites grad and the matrix."""


class Inertia(Term):
    """1/(2ĥ²)‖x − x̃‖²_M − Σ m_v g·x_v: gradient M(x − x̃)/ĥ² − Mg, Hessian M/ĥ²."""

    def __init__(self, mass, gravity):
        self.mass, self.gravity = mass, gravity
        self._mass3 = mass[:, None]
        self.target, self.h2 = None, 1.0

    def begin(self, stage):
        self.target, self.h2 = stage.target, stage.h_eff * stage.h_eff

    def energy(self, x):
        d = x - self.target
        return (0.5 * mass_weighted(d, d, self.mass) / self.h2
                + gravity_potential(x, self.mass, self.gravity))

    def assemble(self, x, grad, matrix):
        matrix.add_diagonal(self.mass / self.h2)
        grad += self._mass3 * (x - self.target) / self.h2 - self._mass3 * self.gravity
        return self.energy(x)


class RayleighDamping(Term):
    """½(x − b)ᵀD(x − b), D = (β/ĥ)K(x_n) frozen at the stage's start (Baraff & Witkin
    1998), or (1/ĥ)Σ_e β_e K_e(x_n) from per-panel β-scaled terms (``panel``); the force
    −D(x − b) = −βK v. It follows the elastic term in the list: from the state, D is frozen
    from that term's first assembly (at x_n), without one of its own."""

    def __init__(self, elastic, matrix, beta, panel=None):
        self.elastic, self.beta, self.panel = elastic, beta, panel
        self.matrix = matrix  # D, on the elastic pattern
        n = matrix.pattern.n
        self._damped = np.zeros((n, 3))  # D(x − b), followed along the steps
        self._line = np.zeros((n, 3))  # D dx of the last line
        self._lined = False
        self.base, self.h_eff, self.frozen = None, 1.0, False

    def begin(self, stage):
        self.base, self.h_eff, self.frozen = stage.base, stage.h_eff, False
        self._x_n = stage.state.x
        if not stage.from_state:
            values = None
            if self.panel is None:
                self.elastic.assemble(self._x_n, np.zeros_like(self._x_n), self.matrix.values)
                values = self.matrix.values
            self._freeze(values, stage.start)

    def _freeze(self, k_values, x):
        """D from K(x_n) (k_values) or from the panel terms, then D(x − b)."""
        if self.panel is not None:
            self.panel.assemble(self._x_n, np.zeros_like(self._x_n), self.matrix.values)
            self.matrix.values *= 1.0 / self.h_eff
        else:
            np.multiply(k_values, self.beta / self.h_eff, out=self.matrix.values)
        self.matrix.multiply(x - self.base, self._damped)
        self.frozen = True

    def energy(self, x):
        a = x - self.base
        return 0.5 * float(np.sum(a * self.matrix.multiply(a, np.empty_like(a))))

    def assemble(self, x, grad, matrix):
        if not self.frozen:  # at x = x_n, right after the elastic term's assembly
            self._freeze(matrix.values, x)
        matrix.values += self.matrix.values
        grad += self._damped
        return 0.5 * float(np.sum((x - self.base) * self._damped))

    def along(self, x, dx):
        """Quadratic along the line: from D(x − b) and D dx, no product per trial."""
        self.matrix.multiply(dx, self._line)
        self._lined = True
        at_x = 0.5 * float(np.sum((x - self.base) * self._damped))
        cross = float(np.sum(dx * self._damped))
        curve = float(np.sum(dx * self._line))
        return lambda s: at_x + s * cross + 0.5 * s * s * curve

    def advance(self, x, dx, step):
        if not self._lined:
            self.matrix.multiply(dx, self._line)
        self._lined = False
        if step > 0.0:
            self._damped += step * self._line


class Dissipation(Wrapped):
    """A dissipation potential of the strain change over the stage
    (:mod:`clothtool.sim.energies.dissipation`), its rates measured from the stage's past."""

    def begin(self, stage):
        self.potential.begin(stage.past, stage.h_eff)


class MovingPins(Term):
    """Moving pins short of their end-of-stage positions move with the Newton step, exactly
    onto them with a full step."""

    def __init__(self):
        self.moving, self.goal, self._prescribed = None, None, False

    def begin(self, stage):
        self.moving, self.goal, self._prescribed = stage.moving, stage.goal, False

    def energy(self, x):
        return 0.0

    def assemble(self, x, grad, matrix):
        return 0.0

    def prescribe(self, x, dx, rhs):
        dx[self.moving] = self.goal - x[self.moving]
        self._prescribed = True

    def advance(self, x, dx, step):
        if self._prescribed and step == 1.0:
            x[self.moving] = self.goal  # exactly
        self._prescribed = False

    def behind(self, x):
        return float(np.max(np.abs(self.goal - x[self.moving])))


class Contact(Term):
    """The barrier and friction potentials of :class:`~clothtool.sim.solve.contact.BarrierContact`:
    Newton starts collision-free at the state, every step is cut to its collision-free
    fraction and line-searched; animated colliders are prescribed through the barrier's
    linearised force. For a stage shorter than the contact's step, its colliders go to
    the stage's end."""

    needs_line_search = True
    starts_at_state = True

    def __init__(self, contact):
        self.contact, self.h = contact, contact.h

    def begin(self, stage):
        self.contact.h = stage.duration
        self.contact.begin(stage.state, stage.moving, stage.goal, stage.base, stage.h_eff)
        self.contact.h = self.h

    def energy(self, x):
        raise NotImplementedError("the contact energy is evaluated along a CCD-checked step")

    def assemble(self, x, grad, matrix):
        energy = self.contact.assemble(x, grad, matrix)
        self.operator = self.contact.operator
        self.x, self.matrix = x.copy(), matrix  # for settled and relag (x moves on)
        return energy

    def along(self, x, dx):
        return self.contact.energy

    def max_step(self, x, dx):
        return self.contact.max_step(dx)

    def cuts(self, x, dx):
        return self.contact.cuts(dx)

    def prescribe(self, x, dx, rhs):
        self.contact.add_collider_coupling(rhs)

    def advance(self, x, dx, step):
        self.contact.advance(step)

    def behind(self, x):
        return self.contact.colliders_behind()

    def settled(self, free_grad, h_eff):
        """Friction's stick stiffness 2μλ/(ĥε_v) makes the Newton steps of cloth that starts
        sliding tiny: settled only once the residual would change the velocities by no more
        than the tolerance within the step either, the rigid motion of each piece of cloth
        against its mass and the rest against Newton's diagonal blocks (returns that change,
        :meth:`~clothtool.sim.solve.contact.BarrierContact.stick_slip`)."""
        if not self.contact.n_lag:
            return 0.0
        return self.contact.stick_slip(self.x, free_grad, self._diagonal(), h_eff)

    def relag(self, x):
        return self.contact.relag(x, self._diagonal())

    def lagged(self):
        return self.contact.n_lag > 0

    def _diagonal(self):
        """The diagonal blocks (N, 3, 3) of Newton's matrix at its last assembly."""
        return self.matrix.values[self.matrix.pattern.diag]

    def finish(self, x, report):
        self.contact.finish(x)
        report.contacts, report.min_separation = self.contact.contacts, self.contact.min_separation
