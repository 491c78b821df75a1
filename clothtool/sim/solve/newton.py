"""Implicit integration as minimisation of the incremental potential: the one Newton loop.

A step of size h minimises over x (Martin et al. 2011, "Example-based elastic
materials"; Gast et al. 2015, "Optimization integrator for large time steps")

    E(x) = 1/(2ĥ²) ‖x − x̃‖²_M − Σ m_v g·x_v + W(x) + Φ(x) + 1/2 (x − b)ᵀ D (x − b)

and sets v_{n+1} = (x − b)/ĥ, where W is the method's elastic energy
(:mod:`clothtool.sim.energies.energy`) and, per ``solver.integrator``:

- ``euler`` (backward Euler): ĥ = h, b = x_n, x̃ = x_n + h v_n;
- ``bdf2``: BDF2, x_{n+1} − (4/3)x_n + (1/3)x_{n−1} = ĥ v_{n+1} and
  v_{n+1} − (4/3)v_n + (1/3)v_{n−1} = ĥ M⁻¹f(x_{n+1}) with ĥ = 2h/3; eliminating
  v_{n+1} gives the minimisation above with b = (4x_n − x_{n−1})/3 and
  x̃ = b + ĥ (4v_n − v_{n−1})/3 (Hairer & Wanner, "Solving ODEs II", §V.1). The first
  step takes its history (x_{−1}, v_{−1}) from a second-order Taylor step back from the
  initial state; later ones from the State.

D = (β/ĥ) K is stiffness-proportional (Rayleigh) damping with β = material.damping
seconds and K the PSD-projected elastic Hessian at x_n (Baraff & Witkin 1998), so that the
damping force is −βK v_{n+1} with the integrator's own velocity, and Φ = 0; with
``material.damping_model: strain`` stretch is taken out of D (its terms then carry β, as
per-panel damping's do) and damped by the dissipation potential Φ of the fibres' length
change (:mod:`clothtool.sim.energies.dissipation`), invariant under rigid motions of each triangle.
Collider friction uses ĥ the same way (:mod:`clothtool.contact.projection`).

Each Newton step solves (M/ĥ² + K(x) + D) Δx = −∇E(x) by filtered PCG
(:mod:`clothtool.sim.linalg.pcg`); with ``line_search`` its length is halved (at most
``MAX_HALVINGS`` times) until E does not increase. Newton starts from the inertia
target x̃ (the motion without forces), its first PCG from the free-fall step ĥ²g (exact
for a falling sheet, whatever the PCG tolerance), and stops after ``newton_iterations`` steps or
after a full (not line-search-shortened) step whose largest velocity correction max|Δx|/h
and whose Newton decrement as a velocity, √(Δxᵀ H Δx / m_free) with m_free the mass of the
free vertices, are both at most ``newton_tolerance`` (m/s). The decrement weighs Δx by the
stiffness it works against: on stiff cloth (1e6–1e7 N/m) the first Newton steps are tiny
but far from converged, and the velocity test alone stopped there (the cloth locked, up
to a metre from the converged step after 0.5 s). It is inexact (Eisenstat &
Walker 1996, "Choosing the forcing terms in an inexact Newton method"): the first
PCG solves to ``solver.tolerance``, later ones to η = 0.9 (‖∇E_k‖/‖∇E_{k−1}‖)², at
least ``solver.tolerance`` and at most 0.15, each warm-started from what the line
search left of the previous step. A single Newton step (``newton_iterations: 1``) starts from x_n instead, with
the PCG guess h v_n: that is exactly Baraff–Witkin's linearised step
(M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f + h ∂f/∂x v_n) for backward Euler.

Vertices held by pins are constrained in the solve through the filter.

With contact (colliders or self-collision, :mod:`clothtool.sim.solve.contact`, for the methods
that support it) the potential gains the contact barrier and the friction potential,
Newton starts from x_n (collision-free) with the PCG guess x̃ − x_n,
and every Newton step is cut to its collision-free fraction before the line search, which
starts there. Moving pins and animated colliders still short of their end-of-step
positions move with the Newton steps: the pins as prescribed components of the solve, the
colliders through the linearised barrier force −H_cX ΔX on the right-hand side; such a
step is taken as far as it is collision-free (E need not fall: the prescribed motion adds
energy), and a step that does not bring them there in four times ``newton_iterations`` is a
numerical failure. A converged step re-lags the friction pairs and goes on while that
changes the velocities by more than ``newton_tolerance``. Without barrier contact,
spheres and planes project vertices out after the step (:mod:`clothtool.contact.projection`).
"""

import numpy as np

from clothtool.errors import NumericalError
from clothtool.contact.projection import resolve_collisions
from clothtool.sim.solve.contact import BarrierContact
from clothtool.sim.energies.dissipation import StretchDissipation
from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.linalg.filter import apply_filter
from clothtool.sim.solve.integrator import Integrator, StepReport, gravity_potential, mass_weighted
from clothtool.sim.linalg.blocks import BlockMatrix, ConstraintFilter
from clothtool.sim.linalg.pairs import NO_PAIRS
from clothtool.sim.linalg.pcg import filtered_pcg, make_preconditioner

MAX_HALVINGS = 30  # down to 2⁻³⁰: a descent direction always decreases E for a small enough step
REACHED = 1e-9  # m: moving pins and animated colliders this close to their goal have reached it
# Eisenstat–Walker forcing terms, choice 2, at most EW_MAX: a looser PCG (0.5) stops after
# a few iterations with a Newton step far too short, which the stopping test then takes for
# convergence (measured with bench_accuracy's scenes: stiff cloth locks, the plate's error
# grows 12 %); 0.15 was as accurate as 0.1 there and cheaper on the 64×64 sheet
EW_GAMMA, EW_MAX = 0.9, 0.15
# without contact, each Newton solve stops once PCG's estimate of its error energy rᵀB⁻¹r
# is below (ERROR_SHARE · newton_tolerance)² m_free: the error then moves the Newton
# decrement (a velocity, see the module) by at most that share of the tolerance, so a solve
# that only confirms convergence stops as soon as it can tell. With contact it does not:
# friction's stick stiffness hides velocity errors from that energy (a sheet on a sheet at
# 30° that must hold slid 137 mm in 2 s)
ERROR_SHARE = 0.1


def eisenstat_walker(g_norm, g_prev, previous, floor):
    """PCG tolerance of the next Newton step (Eisenstat & Walker 1996, choice 2):
    η = γ(‖g_k‖/‖g_{k−1}‖)², at least γη_{k−1}² when that exceeds 0.1, within [floor, EW_MAX]."""
    eta = EW_GAMMA * (g_norm / g_prev) ** 2 if g_prev > 0.0 else EW_MAX
    safeguard = EW_GAMMA * previous * previous
    if safeguard > 0.1:
        eta = max(eta, safeguard)
    return min(EW_MAX, max(floor, eta))


def _filtered(g, kind, normal, constrained):
    """S g (the gradient on the unconstrained directions), a copy when it differs from g."""
    if constrained:
        g = g.copy()
        apply_filter(g, kind, normal)
    return g


class NewtonIntegrator(Integrator):
    """Newton + filtered PCG on the incremental potential of an elastic energy.

    A subclass names its energy (``energy_class``, see :mod:`clothtool.sim.energies.energy`) and
    whether it uses ``solver.preconditioner`` (``multigrid``; otherwise block Jacobi).
    """

    multigrid = False

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        self.bdf2 = solver.integrator == "bdf2"
        n = model.n_vertices
        pattern = self.elastic.pattern
        self.matrix = BlockMatrix(pattern)
        self._damping = BlockMatrix(pattern) if model.damping > 0 else None
        # per-panel damping (materials): the terms with their stiffness × β_e
        self._panel_damping = (FemElastic(model, model.damping_terms, model.damping_constant)
                               if model.damping_terms is not None else None)
        # damping_model: strain: the dissipation potential Φ of the fibres' length change
        self._dissipation = (StretchDissipation(model.faces, model.dr_inv, model.area,
                                                model.stretch_damping, model.tri_slots)
                             if model.stretch_damping is not None else None)
        self._grad = np.zeros((n, 3))
        self._tmp = np.zeros((n, 3))
        self._damped = np.zeros((n, 3))
        self._normal = np.zeros((n, 3))
        self._free_mass = float(np.sum(model.mass[model.free]))
        self.preconditioner = make_preconditioner(
            solver.preconditioner if self.multigrid else "jacobi", pattern, model.faces)
        self.contact = None  # mesh colliders and self-collision (clothtool.sim.solve.contact)
        if model.contact is not None:
            self.contact = BarrierContact(model.contact, model.mass, model.free, h,
                                          max(model.tri_stretch[:, :2].max(), model.tri_shear.max()),
                                          solver.friction_velocity)
            self.contact.check_initial(model.mesh.positions)

    def potential(self, x, base, inertia_target, h_eff):
        """E(x) = 1/(2ĥ²)‖x − x̃‖²_M − Σ m g·x + W(x) + ½(x − base)ᵀD(x − base), with the
        damping matrix D of the last step."""
        d = x - inertia_target
        kinetic = 0.5 * mass_weighted(d, d, self.model.mass) / (h_eff * h_eff)
        total = kinetic + gravity_potential(x, self.model.mass, self.model.gravity)
        total += self.elastic.energy(x)
        if self._dissipation is not None:
            total += self._dissipation.energy(x)
        if self._damping is not None:
            a = x - base
            total += 0.5 * float(np.sum(a * self._damping.multiply(a, np.empty_like(a))))
        return total

    def along(self, x, dx, base, target, h_eff):
        """E(x + s dx) as a function of s and W(x + s dx), for the line search (Φ, when there
        is one, is evaluated inside). The damping term is quadratic along the line, ½(a + s dx)ᵀD(a + s dx) with a = x − base: from
        D a (kept in self._damped) and D dx (left in self._tmp), no product per trial."""
        mass, g = self.model.mass, self.model.gravity
        inv_h2 = 1.0 / (h_eff * h_eff)
        if self._damping is not None:
            self._damping.multiply(dx, self._tmp)
            at_x = 0.5 * float(np.sum((x - base) * self._damped))
            cross = float(np.sum(dx * self._damped))
            curve = float(np.sum(dx * self._tmp))
        else:
            at_x = cross = curve = 0.0

        dissipation = self._dissipation

        def energy(s, w):
            y = x + s * dx
            d = y - target
            total = (0.5 * mass_weighted(d, d, mass) * inv_h2 + gravity_potential(y, mass, g)
                     + w + at_x + s * cross + 0.5 * s * s * curve)
            return total + (dissipation.energy(y) if dissipation is not None else 0.0)
        return energy

    def _line_search(self, x, dx, base, target, elastic, h_eff, start=1.0, contact=None):
        """The first step s = start, start/2, … (at most ``MAX_HALVINGS`` halvings) with
        E(x + s dx) ≤ E(x), given W(x) = elastic (E with the contact barrier's energy at s,
        ``contact.energy(s)``, and elastic including it, when contact is given); 0 when
        there is none."""
        energy = self.along(x, dx, base, target, h_eff)
        e0 = energy(0.0, elastic)
        s = start
        for _ in range(MAX_HALVINGS):
            w = self.elastic.energy(x + s * dx) + (contact.energy(s) if contact is not None else 0.0)
            if energy(s, w) <= e0:
                return s
            s *= 0.5
        return 0.0

    def discretisation(self, state):
        """(ĥ, base, inertia target) of the step from ``state``: the velocity after the step
        is v = (x − base)/ĥ. Backward Euler: (h, x_n, x_n + h v_n); BDF2:
        (2h/3, (4x_n − x_{n−1})/3, base + ĥ(4v_n − v_{n−1})/3), on the first step with the
        history of :meth:`taylor_history`."""
        h = self.h
        if self.bdf2:
            x_prev, v_prev = ((state.x_prev, state.v_prev) if state.x_prev is not None
                              else self.taylor_history(state))
            h_eff = 2.0 * h / 3.0
            base = (4.0 * state.x - x_prev) / 3.0
            return h_eff, base, base + h_eff * ((4.0 * state.v - v_prev) / 3.0)
        return h, state.x, state.x + h * state.v

    def taylor_history(self, state):
        """(x_{−1}, v_{−1}) = (x_0 − h v_0 + ½h² a_0, v_0 − h a_0): BDF2's missing history from
        a second-order Taylor step back, so that a quadratic motion (free fall) is exact from
        the first step (a backward-Euler first step leaves free fall ¾h²g behind for good).
        a_0 = g + (M + h²K)⁻¹ f on the free vertices (0 on pinned ones), f = −∇W(x_0) − βK v_0
        the elastic and damping force at the start, K its stiffness: M⁻¹f to O(h²) for the
        slow motions, but bounded for stiff ones — with M⁻¹f itself, a crumpled start's
        history lies far off and the run blew up (stretch 1e8 in 12 frames)."""
        model, h, x0, v0 = self.model, self.h, state.x, state.v
        matrix = self.matrix
        grad = np.zeros_like(x0)
        self.elastic.assemble(x0, grad, matrix.values)
        force = -grad
        if self._panel_damping is not None:  # Σ_e β_e K_e v_0 (per-panel damping)
            self._panel_damping.assemble(x0, np.zeros_like(x0), self._damping.values)
            if self._dissipation is not None:  # ĥ = 1: Φ's Hessian at b = x_0 is βK_stretch
                self._dissipation.begin(x0, None, 1.0)
                self._dissipation.assemble(x0, np.zeros_like(x0), self._damping.values)
            force -= self._damping.multiply(v0, np.empty_like(v0))
        elif self._damping is not None:
            force -= model.damping * matrix.multiply(v0, np.empty_like(v0))
        matrix.add_diagonal(model.mass / (h * h))
        elastic = np.zeros_like(x0)
        filtered_pcg(matrix, force / (h * h), elastic, ConstraintFilter(model.kind, self._normal),
                     self.solver.tolerance, self.solver.max_iterations, self.preconditioner)
        a0 = model.gravity + elastic
        if model.has_pins:
            a0[model.pinned] = 0.0
        return x0 - h * v0 + (0.5 * h * h) * a0, v0 - h * a0

    def _freeze_damping(self, k_values, beta_over_h, displacement, x_n):
        """D = (β/ĥ) K(x_n) from the blocks of K(x_n), frozen for the step, and D(x − base);
        with per-panel β, D = (1/ĥ) Σ_e β_e K_e(x_n) from the β-scaled terms."""
        if self._panel_damping is not None:
            self._panel_damping.assemble(x_n, np.zeros_like(x_n), self._damping.values)
            self._damping.values *= beta_over_h / self.model.damping
        else:
            np.multiply(k_values, beta_over_h, out=self._damping.values)
        self._damping.multiply(displacement, self._damped)

    def step(self, state):
        """Advance state by h in place; returns a :class:`~clothtool.sim.solve.integrator.StepReport`."""
        model, solver, h = self.model, self.solver, self.h
        matrix, values = self.matrix, self.matrix.values
        x_n, v_n = state.x, state.v
        h_eff, base, target = self.discretisation(state)
        if self._dissipation is not None:  # BDF2's x_{n−1}; none at the first step
            self._dissipation.begin(x_n, state.x_prev if self.bdf2 else None, h_eff)
        contact = self.contact
        if solver.newton_iterations == 1:  # exactly Baraff–Witkin's linearised step
            x = x_n.copy()
            dx = h * v_n  # PCG guess: the previous motion
        elif contact is not None:  # from x_n, which is collision-free, toward x̃
            x = x_n.copy()
            dx = target - x_n
        else:  # from the inertia target (the motion without forces), the first PCG from ĥ²g
            x = target.copy()
            dx = np.empty_like(x)
            dx[:] = (h_eff * h_eff) * model.gravity
        if model.has_pins:
            x[model.pinned] = x_n[model.pinned]
            dx[model.pinned] = 0.0
        moving = model.moving_pinned
        goal = model.pin_goal(state.time + h) if len(moving) else None  # end-of-step positions
        if contact is not None:
            contact.begin(state, moving, goal, base, h_eff)
        kind = model.kind
        constrained = model.has_pins
        constraints = ConstraintFilter(kind, self._normal, constrained)
        inertia = model.mass / (h_eff * h_eff)
        tol = solver.newton_tolerance
        report = StepReport()
        forcing, g_prev, step, cut = solver.tolerance, 0.0, 1.0, False
        error_floor = ((ERROR_SHARE * tol) ** 2 * self._free_mass
                       if solver.newton_iterations > 1 and contact is None else 0.0)
        damped = self._damping is not None
        from_x_n = solver.newton_iterations == 1 or contact is not None  # x starts equal to x_n
        if damped and not from_x_n:
            if self._panel_damping is None:  # per-panel damping assembles its own terms at x_n
                self.elastic.assemble(x_n, self._grad, values)
            self._freeze_damping(values, model.damping / h_eff, x - base, x_n)
        # moving pins and colliders still short of their goal get three times as many more steps
        for it in range(4 * solver.newton_iterations):
            if it >= solver.newton_iterations and self._behind(x, moving, goal) <= REACHED:
                break
            elastic = self.elastic.assemble(x, self._grad, values)
            if self._dissipation is not None:  # Φ's value enters E in along()
                self._dissipation.assemble(x, self._grad, values)
            if damped:
                if it == 0 and from_x_n:
                    self._freeze_damping(values, model.damping / h_eff, x - base, x_n)
                values += self._damping.values
            matrix.add_diagonal(inertia)
            # ∇E = M(x − x̃)/ĥ² − M g + ∇W + D(x − base)
            grad = self._mass3 * (x - target) / (h_eff * h_eff) - self._mass3 * model.gravity + self._grad
            if damped:
                grad += self._damped
            if contact is not None:
                elastic += contact.assemble(x, grad, matrix)
            free_grad = _filtered(grad, kind, self._normal, constrained)
            g_norm = float(np.sqrt(np.sum(free_grad * free_grad)))
            if it > 0:
                # PCG guess: what the line search left of the last step; after a step that CCD
                # cut short, zero: the barrier it ran into has changed the Hessian by up to
                # 1e22·m/ĥ², and the old direction (into the barrier) still met the loose
                # forcing term with no PCG iteration, so Newton repeated it until it gave up
                dx = np.zeros_like(dx) if cut else (1.0 - step) * dx
                forcing = eisenstat_walker(g_norm, g_prev, forcing, solver.tolerance)
            g_prev = g_norm
            # moving pins and animated colliders short of their end-of-step positions move
            # with this step (see the module docstring)
            prescribed = self._behind(x, moving, goal) > REACHED
            rhs = -grad
            if it > 0 and float(np.sum(rhs * dx)) < 0.0:
                # the rest of the last step climbs the new potential (after a re-lag of the
                # friction, say): a loose PCG from it could stop on an ascent direction
                dx[:] = 0.0
            if prescribed and goal is not None:
                dx[moving] = goal - x[moving]
            if prescribed and contact is not None:
                contact.add_collider_coupling(rhs)
            cg_its, res = filtered_pcg(matrix, rhs, dx, constraints, forcing,
                                       solver.max_iterations, self.preconditioner,
                                       contact.operator if contact is not None else NO_PAIRS,
                                       error_floor)
            report.newton_iterations += 1
            report.cg_iterations += cg_its
            report.residual = max(report.residual, res)
            if not np.all(np.isfinite(dx)):
                raise NumericalError("the linear solve produced non-finite values")
            step = 1.0
            if contact is not None:  # from the collision-free fraction of the step
                step = contact.max_step(dx)
            cut = step < 1.0
            if (solver.line_search or contact is not None) and not prescribed:
                step = self._line_search(x, dx, base, target, elastic, h_eff, step, contact)
            elif damped:
                self._damping.multiply(dx, self._tmp)
            if contact is not None:
                contact.advance(step)
            if step > 0.0:
                x += step * dx
                if prescribed and step == 1.0 and goal is not None:
                    x[moving] = goal  # exactly
                if damped:  # D(x − base) moves by step · D dx (left in self._tmp)
                    self._damped += step * self._tmp
            moved = float(np.max(np.abs(step * dx))) / h
            # converged when a full Newton step is small, in velocity and in its decrement
            # Δxᵀ H Δx = −∇E·Δx; a step the line search shortened is small because the model
            # was poor there, not because x is near the minimum
            converged = step == 0.0 or (step == 1.0 and moved <= tol and -float(
                np.sum(grad * dx)) <= tol * tol * self._free_mass)
            if converged and step > 0.0 and contact is not None and contact.n_lag:
                # friction's stick stiffness 2μλ/(ĥε_v) makes the Newton steps of a sheet that
                # starts sliding tiny: converged only once the residual force would change no
                # velocity by more than tol within the step either
                converged = h_eff * float(np.max(
                    np.sqrt(np.sum(free_grad * free_grad, axis=1)) / model.mass)) <= tol
            # converged: done unless re-lagging the friction pairs changes their force
            if (converged and self._behind(x, moving, goal) <= REACHED
                    and (contact is None or contact.relag(x) <= tol)):
                break
        behind = self._behind(x, moving, goal)
        if behind > REACHED:
            raise NumericalError(
                f"a moving pin or collider could not reach its position without crossing the "
                f"cloth (still {behind:.3g} m away after {report.newton_iterations} Newton steps)")
        state.x_prev, state.v_prev = x_n, v_n
        state.v = (x - base) / h_eff
        state.x = x
        state.time += h
        if contact is not None:
            contact.finish(x)
            report.contacts, report.min_separation = contact.contacts, contact.min_separation
        if model.has_colliders:
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
