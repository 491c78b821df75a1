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
  x̃ = b + ĥ (4v_n − v_{n−1})/3 (Hairer & Wanner, "Solving ODEs II", §V.1), x_{n−1} and
  v_{n−1} from the State. The first step has no past and invents none: it is a one-step
  second-order method, two stages of SDIRK2 (:meth:`NewtonIntegrator.first_step`).

Damping (β = material.damping seconds): with ``material.damping_model: strain`` (the
default), D = 0 and Φ is the dissipation potential of the change of stretch, shear and
bending over the step (:mod:`clothtool.sim.energies.dissipation`), which no rigid motion
changes; with ``frozen``, Φ = 0 and D = (β/ĥ) K is stiffness-proportional (Rayleigh)
damping with K the PSD-projected elastic Hessian at x_n (Baraff & Witkin 1998), so that the
damping force is −βK v_{n+1} with the integrator's own velocity (per panel: Σ_e β_e K_e).
Collider friction uses ĥ the same way (:mod:`clothtool.contact.projection`). Each piece of
E is a term of :mod:`clothtool.sim.solve.potential`; the loop sums their list.

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
to a metre from the converged step after 0.5 s). With ``solver.friction_velocity_test``,
a step while friction pairs are lagged has also converged when the whole Newton proposal,
cut or not, has max|Δx|/h at most ``newton_tolerance``, its decrement not asked (IPC's
test; Li et al. 2020, "Incremental Potential Contact"): friction's stick stiffness
2μλ/(ĥε_v) gives a tiny Δx a large decrement, and at stick–slip Newton ran to its cap of
steps within the tolerance in velocity; friction's settled and re-lag tests still apply,
and frictionless steps keep the decrement. It is inexact (Eisenstat &
Walker 1996, "Choosing the forcing terms in an inexact Newton method"): the first
PCG solves to ``solver.tolerance``, later ones to η = 0.9 (‖∇E_k‖/‖∇E_{k−1}‖)², at
least ``solver.tolerance`` and at most 0.15 (with ``solver.forcing_from_second``, the second
at 0.15 when Newton starts at x_n: that start is no iterate of the minimisation, and with
friction BDF2's velocity there turns every slip; with ``solver.first_forcing`` η₀, the first
at η₀ when Newton starts at x_n: at impact that step is long and CCD cuts it to a tenth or
a quarter, and a PCG to 1e-6 over it ran to its cap of iterations for a direction the next
steps replace; with ``solver.first_cut_iterations`` k, that first PCG stops after k
iterations when CCD over the step's candidates already cuts its guess short, except
while a garment is sewn; with ``solver.short_step_forcing``, after a step the line search
shortened to a fraction s, the next at s times η), each warm-started from what the line
search left of the previous step. A single Newton step
(``newton_iterations: 1``) starts from x_n instead, with the PCG guess h v_n: that is
exactly Baraff–Witkin's linearised step
(M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f + h ∂f/∂x v_n) for backward Euler.

With ``solver.stiffness_continuation`` n > 0 each minimisation is first solved with the
membrane's stretch and shear (and, with strain damping, the triangles' Φ) 10ⁿ, …, 10× softer,
each solve starting from the last's solution, then as it is (a homotopy in the stiffness;
Nocedal & Wright 2006, "Numerical Optimization", §11.3). Near-inextensible cloth at large
steps swings through turns whose linearisation stretches its fibres at second order, so Newton
on it alone takes steps of millimetres (a 1e6 N/m sheet at h = 1 s crawls to its cap, 0.99 m
short of its converged swing); a softer membrane swings there in a few steps, and the next
one only tightens it. With ``stiffness_continuation: auto``, n is the fewest levels that
bring the stage's stiffness-to-inertia ratio k·ĥ²/m to ``CONTINUATION_TARGET`` (none for
ordinary cloth at ordinary steps). With ``solver.continuation_after`` k as well, Newton first
runs alone; only a solve unconverged after k steps of which at least ``STALLED`` were bound by the
stiffness (velocity correction within ``newton_tolerance``, decrement not: the stiff sheet's
stall) is solved again from the stage's start through the levels; any other goes on alone.
A solve that converges within k steps is exactly the one without the continuation. The
zigzag of a few vertices in a fold (a crumpled start, a sheet on a turning sphere) is the
other way round, velocity corrections of 0.05–0.1 m/s at a decrement within the tolerance,
and softening the membrane does not cure it.

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
from clothtool.sim.solve.potential import (Contact, Dissipation, Elastic, Inertia, MovingPins,
                                           RayleighDamping, Stage)
from clothtool.sim.energies.dissipation import StrainDissipation
from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.energies.terms import EdgeMembrane, Membrane
from clothtool.sim.linalg.filter import apply_filter
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.linalg.blocks import BlockMatrix, ConstraintFilter
from clothtool.sim.linalg.pcg import filtered_pcg, make_preconditioner

MAX_HALVINGS = 30  # down to 2⁻³⁰: a descent direction always decreases E for a small enough step
REACHED = 1e-9  # m: moving pins and animated colliders this close to their goal have reached it
# Eisenstat–Walker forcing terms, choice 2, at most EW_MAX: a looser PCG (0.5) stops after
# a few iterations with a Newton step far too short, which the stopping test then takes for
# convergence (measured with bench_accuracy's scenes: stiff cloth locks, the plate's error
# grows 12 %); 0.15 was as accurate as 0.1 there and cheaper on the 64×64 sheet
EW_GAMMA, EW_MAX = 0.9, 0.15
SDIRK_GAMMA = 1.0 - np.sqrt(0.5)  # Alexander's SDIRK2: L-stable, exact for free fall
# SDIRK2's first stage enters the second's inertia target with its error amplified by
# 2(1 − γ)/γ ≈ 4.8: it is solved to a tenth of newton_tolerance (the 1e7 N/m plate at one step
# per frame: 0.160 m from its tightly solved step at the full tolerance, 0.118 m at a tenth)
SDIRK_FIRST_TOL = 0.1
# solver.stiffness_continuation: each level's membrane this much softer than the next one's.
# 12×12 sheet of 1e6 N/m hanging from two corners, h = 1 s, 6 steps: Newton alone stops at its
# cap in every solve (0.99 m short of the converged swing); 4 levels of 10 converge every
# solve, 5 levels of 10 every solve at 1e7 N/m too; levels of 30 or 100 left the first steps'
# stiffer solves at the cap
CONTINUATION_RATIO = 10.0
# solver.stiffness_continuation: auto: as many levels as bring the stage's stiffness-to-inertia
# ratio k·ĥ²/m (the stiffest membrane k, the free vertices' mean mass m) to at most this.
# 12×12 sheets at h = 1 s after 20 stalled steps (ĥ = 2h/3: 3.2e8 at 1e6 N/m, 3.2e9 at 1e7):
# 1e4 converged every solve of both (4 steps); 1e5 left SDIRK2's first stage capped in each
CONTINUATION_TARGET = 1e4
# solver.continuation_after: the share of a solve's steps bound by the stiffness (velocity
# correction within solver.newton_tolerance, decrement not) that marks a stall of the
# linearisation. Unconverged after 20 steps: the stiff sheet 13–19 such steps, the crumpled
# start 0–5, the turning sphere 0–5 (whose solves the continuation does not help: as many at
# the cap, twice the Newton steps); the line search's shortened steps did not tell them apart
# (6–12 against 0–4 and 0–8)
STALLED = 0.5


def eisenstat_walker(g_norm, g_prev, previous, floor):
    """PCG tolerance of the next Newton step (Eisenstat & Walker 1996, choice 2):
    η = γ(‖g_k‖/‖g_{k−1}‖)², at least γη_{k−1}² when that exceeds 0.1, within [floor, EW_MAX]."""
    eta = EW_GAMMA * (g_norm / g_prev) ** 2 if g_prev > 0.0 else EW_MAX
    safeguard = EW_GAMMA * previous * previous
    if safeguard > 0.1:
        eta = max(eta, safeguard)
    return min(EW_MAX, max(floor, eta))


def _filtered(g, kind, constrained):
    """S g (the gradient on the unconstrained directions), a copy when it differs from g."""
    if constrained:
        g = g.copy()
        apply_filter(g, kind)
    return g


class NewtonIntegrator(Integrator):
    """Newton + filtered PCG on the incremental potential, a list of terms
    (:mod:`clothtool.sim.solve.potential`).

    A subclass names its energy (``energy_class``, see :mod:`clothtool.sim.energies.energy`) and
    whether it uses ``solver.preconditioner`` (``multigrid``; otherwise block Jacobi) and
    ``solver.stiffness_continuation`` (``continuation``; otherwise Newton alone).
    """

    multigrid = False
    continuation = False

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        self.bdf2 = solver.integrator == "bdf2"
        n = model.n_vertices
        pattern = self.elastic.pattern
        self.matrix = BlockMatrix(pattern)
        self._grad = np.zeros((n, 3))
        self._free_mass = float(np.sum(model.mass[model.free]))
        # a garment being sewn: no first cut (the stitches, not the guess, drive its steps;
        # capped at 10–30 iterations the benchmark garment's seams closed curled and stuck)
        self.sewing = model.stitches is not None
        # solver.stiffness_continuation: auto: k the stiffest membrane (stretch or shear, N/m),
        # m the free vertices' mean mass (kg), fixed for the run
        self._stiffest = max(float(model.tri_stretch[:, :2].max()), float(model.tri_shear.max()))
        self._mean_free_mass = self._free_mass / max(int(np.count_nonzero(model.free)), 1)
        self.preconditioner = make_preconditioner(
            solver.preconditioner if self.multigrid else "jacobi", pattern, model.faces,
            self._stiffest * h * h / self._mean_free_mass)
        self.terms = self._terms(model, solver, h, pattern)

    def _terms(self, model, solver, h, pattern):
        """The incremental potential: elastic first (it starts the sums), then inertia and
        gravity, damping (frozen Rayleigh, per-panel, dissipation potentials), moving pins,
        barrier contact and friction."""
        terms = [Elastic(self.elastic), Inertia(model.mass, model.gravity)]
        if model.damping > 0 and model.strain_damping is None:
            # frozen βK(x_n); per-panel damping (materials): the terms with stiffness × β_e
            panel = (FemElastic(model, model.damping_terms, model.damping_constant)
                     if model.damping_terms is not None else None)
            terms.insert(1, RayleighDamping(self.elastic, BlockMatrix(pattern), model.damping,
                                            panel))
        if model.strain_damping is not None:
            # damping_model: strain: the dissipation potential of the strains' change, with
            # the triangle or edge membrane in the same pass (the elastic term then leaves it out)
            membrane = next((t for t in model.terms if isinstance(t, (Membrane, EdgeMembrane))),
                            None)
            if membrane is not None:
                rest = [t for t in model.terms if t is not membrane]
                terms[0] = Elastic(FemElastic(model, rest, model.constant_hessian))
            terms.append(Dissipation(StrainDissipation(model, membrane)))
        if len(model.moving_pinned):
            terms.append(MovingPins())
        if model.contact is not None:  # mesh colliders and self-collision
            contact = BarrierContact(model.contact, model.mass, model.free, h,
                                     max(model.tri_stretch[:, :2].max(), model.tri_shear.max()),
                                     solver.friction_velocity, solver.overshoot_bound,
                                     solver.slow_slip_bound)
            contact.check_initial(model.mesh.positions)
            terms.append(Contact(contact))
        return terms

    @property
    def contact(self):
        """The run's :class:`BarrierContact` (None without barrier contact)."""
        return next((t.contact for t in self.terms if isinstance(t, Contact)), None)

    def potential(self, x):
        """E(x) of the last stage begun (:meth:`begin`)."""
        return sum(term.energy(x) for term in self.terms)

    def along(self, x, dx):
        """s ↦ E(x + s dx), for the line search."""
        lines = [term.along(x, dx) for term in self.terms]
        return lambda s: sum(line(s) for line in lines)

    def _line_search(self, x, dx, energy_x, start):
        """The first step s = start, start/2, … (at most ``MAX_HALVINGS`` halvings) with
        E(x + s dx) ≤ E(x) = energy_x; 0 when there is none."""
        energy = self.along(x, dx)
        s = start
        for _ in range(MAX_HALVINGS):
            if energy(s) <= energy_x:
                return s
            s *= 0.5
        return 0.0

    def stage(self, state, duration, h_eff, base, target, past):
        """The stage from ``state`` over ``duration`` with v = (x − base)/ĥ and inertia
        target x̃ = ``target``; Newton's start: x_n with contact (collision-free, PCG guess
        x̃ − x_n) or with one Newton step (the PCG guess h v_n: exactly Baraff–Witkin's
        linearised step), else x̃ (the motion without forces, the PCG guess ĥ²g)."""
        model = self.model
        moving = model.moving_pinned
        goal = model.pin_goal(state.time + duration) if len(moving) else None
        stage = Stage(state, duration, h_eff, base, target, past, moving, goal)
        stage.from_state = (self.solver.newton_iterations == 1
                            or any(t.starts_at_state for t in self.terms))
        if self.solver.newton_iterations == 1:
            stage.start, stage.guess = state.x.copy(), duration * state.v
        elif stage.from_state:
            stage.start, stage.guess = state.x.copy(), target - state.x
        else:
            stage.start = target.copy()
            stage.guess = np.empty_like(target)
            stage.guess[:] = (h_eff * h_eff) * model.gravity
        if model.has_pins:
            stage.start[model.pinned] = state.x[model.pinned]
            stage.guess[model.pinned] = 0.0
        return stage

    def discretisation(self, state):
        """The step's stage: backward Euler (ĥ, b, x̃) = (h, x_n, x_n + h v_n); BDF2 with
        its history (2h/3, (4x_n − x_{n−1})/3, b + ĥ(4v_n − v_{n−1})/3)."""
        h = self.h
        if self.bdf2:
            h_eff = 2.0 * h / 3.0
            base = (4.0 * state.x - state.x_prev) / 3.0
            target = base + h_eff * ((4.0 * state.v - state.v_prev) / 3.0)
            return self.stage(state, h, h_eff, base, target,
                              ((4.0 / 3.0, state.x), (-1.0 / 3.0, state.x_prev)))
        return self.stage(state, h, h, state.x, state.x + h * state.v, ((1.0, state.x),))

    def first_step(self, state, report):
        """BDF2's first step, which has no past: Alexander's two-stage SDIRK2 (L-stable,
        stiffly accurate, second order; Alexander 1977, "Diagonally implicit Runge–Kutta
        methods for stiff ODEs"), γ = 1 − 1/√2. Stage 1 is backward Euler over γh: X, V =
        (X − x_n)/(γh), A = (V − v_n)/(γh); stage 2 minimises with the same ĥ = γh, b = x_n +
        (1 − γ)h V, x̃ = b + ĥ(v_n + (1 − γ)h A), whose strains' past is x_n and X in the same
        proportion. Exact for free fall (x_n + h v_n + ½h²g at its end). Returns the last
        stage and its solution."""
        h, x_n, v_n = self.h, state.x, state.v
        h_eff = SDIRK_GAMMA * h
        first = self.stage(state, h_eff, h_eff, x_n, x_n + h_eff * v_n, ((1.0, x_n),))
        x1 = self.minimise(first, report, SDIRK_FIRST_TOL * self.solver.newton_tolerance)
        v1 = (x1 - x_n) / h_eff
        a1 = (v1 - v_n) / h_eff
        rest = (1.0 - SDIRK_GAMMA) * h
        base = x_n + rest * v1
        c = rest / h_eff
        second = self.stage(state, h, h_eff, base, base + h_eff * (v_n + rest * a1),
                            ((1.0 - c, x_n), (c, x1)))
        return second, self.minimise(second, report)

    def step(self, state):
        """Advance state by h in place (BDF2's first step by :meth:`first_step`); returns a
        :class:`~clothtool.sim.solve.integrator.StepReport`."""
        report = StepReport()
        if self.bdf2 and state.x_prev is None:
            stage, x = self.first_step(state, report)
        else:
            stage = self.discretisation(state)
            x = self.minimise(stage, report)
        for term in self.terms:
            term.finish(x, report)
        state.x_prev, state.v_prev = state.x, state.v
        state.v = (x - stage.base) / stage.h_eff
        state.x = x
        state.time += self.h
        model = self.model
        if model.has_colliders:
            resolve_collisions(state.x, state.v, model.free, model.spheres, model.planes,
                               model.collision_margin)
        return report

    def _behind(self, x):
        """How far (m) prescribed motion (moving pins, animated colliders) is from the end of
        the stage."""
        return max((term.behind(x) for term in self.terms), default=0.0)

    def minimise(self, stage, report, tol=None):
        """Newton's minimisation of the stage's incremental potential Σ_k E_k (see the
        module docstring) to ``tol`` (default ``solver.newton_tolerance``): its solution x;
        the counts go into ``report``. With ``solver.stiffness_continuation`` n (``auto``:
        :meth:`continuation_levels`), the membrane 10ⁿ, …, 10× softer first, each solve from
        the last's solution; with ``solver.continuation_after`` k too, only when Newton alone
        has stalled in its first k steps (unconverged, ``STALLED`` of them bound by the
        stiffness), again from the stage's start; otherwise Newton goes on alone up to
        ``solver.newton_iterations``."""
        for term in self.terms:
            term.begin(stage)
        x, guess = stage.start, stage.guess
        levels, after = self.solver.stiffness_continuation, self.solver.continuation_after
        if not self.continuation:
            levels = 0
        if levels == "auto":
            levels = self.continuation_levels(stage.h_eff)
        if levels and after:
            x, converged, stalled = self._newton(stage, x.copy(), guess.copy(), report, tol,
                                                 min(after, self.solver.newton_iterations))
            rest = self.solver.newton_iterations - after
            if not converged and stalled < STALLED * after and rest > 0:
                x, converged, _ = self._newton(stage, x, np.zeros_like(guess), report, tol, rest)
            if converged or stalled < STALLED * after:
                report.capped += not converged
                return x
            x, guess = stage.start, stage.guess
        try:
            for level in range(levels, 0, -1):
                for term in self.terms:
                    term.soften(CONTINUATION_RATIO ** -level)
                x, converged, _ = self._newton(stage, x, guess, report, tol)
                report.capped += not converged
                guess = np.zeros_like(guess)
        finally:
            if levels:
                for term in self.terms:
                    term.soften(1.0)
        x, converged, _ = self._newton(stage, x, guess, report, tol)
        report.capped += not converged
        return x

    def continuation_levels(self, h_eff):
        """``solver.stiffness_continuation: auto``: the fewest levels n ≥ 0 with
        k·ĥ²/(m·10ⁿ) ≤ ``CONTINUATION_TARGET``, k the stiffest membrane (stretch or shear, N/m),
        m the free vertices' mean mass: Newton's stall on near-inextensible cloth grows with
        the membrane's stiffness over the inertia M/ĥ² it is solved against."""
        ratio = self._stiffest * h_eff * h_eff / self._mean_free_mass
        return max(0, int(np.ceil(np.log10(ratio / CONTINUATION_TARGET))))

    def _newton(self, stage, x, dx, report, tol, cap=None):
        """Newton from x (its first PCG from the guess dx) on the terms begun on ``stage``, at
        most ``cap`` steps (default ``solver.newton_iterations``; prescribed motion short of
        its goal gets three times that many more): (x, converged, the number of its steps
        bound by the stiffness: a full step's velocity correction max|Δx|/h within
        ``solver.newton_tolerance``, its decrement not)."""
        solver, terms, matrix = self.solver, self.terms, self.matrix
        h_eff = stage.h_eff
        constraints = ConstraintFilter(self.model.kind, self.model.has_pins)
        self.preconditioner.update(x, constraints)
        tol, grad = solver.newton_tolerance if tol is None else tol, self._grad
        forcing, g_prev, step, cut, shortened = solver.tolerance, 0.0, 1.0, False, False
        if solver.first_forcing > 0.0 and stage.from_state and solver.newton_iterations > 1:
            forcing = max(solver.tolerance, solver.first_forcing)
        line_search = solver.line_search or any(t.needs_line_search for t in terms)
        # prescribed motion still short of its goal gets 3 × newton_iterations more steps
        converged, cap = False, solver.newton_iterations if cap is None else cap
        stalled = 0  # stiffness-bound steps
        for it in range(cap + 3 * solver.newton_iterations):
            if it >= cap and self._behind(x) <= REACHED:
                converged = False
                break
            energy = sum(term.assemble(x, grad, matrix) for term in terms)
            free_grad = _filtered(grad, constraints.kind, constraints.active)
            g_norm = float(np.sqrt(np.sum(free_grad * free_grad)))
            if it > 0:
                # PCG guess: what the line search left of the last step; after a step that CCD
                # cut short, zero: the barrier it ran into has changed the Hessian by up to
                # 1e22·m/ĥ², and the old direction (into the barrier) still met the loose
                # forcing term with no PCG iteration, so Newton repeated it until it gave up
                dx = np.zeros_like(dx) if cut else (1.0 - step) * dx
                forcing = eisenstat_walker(g_norm, g_prev, forcing, solver.tolerance)
                if shortened and solver.short_step_forcing:
                    # the line search kept the fraction ``step`` of the last direction, and
                    # the gradient's ratio says what that fraction gained, not how good the
                    # direction was: at the forcing's cap Newton took the same loose
                    # direction again and at stick–slip crawled to its cap of steps (the 15°
                    # cloth incline with slow_slip_bound braked, under whichever
                    # preconditioner and tolerance led a step there): ask that fraction of it
                    forcing = max(solver.tolerance, forcing * step)
            # solver.forcing_from_second: a stage from the state (contact) starts the ratios at
            # its second iterate: x_n is where collision-freedom puts Newton, not a step of its
            # minimisation (there BDF2's velocity turns every friction slip, and the first
            # ratio set a 3× longer solve)
            skip = it == 0 and stage.from_state and solver.forcing_from_second
            g_prev = 0.0 if skip else g_norm
            prescribed = self._behind(x) > REACHED  # moves with this step
            rhs = -grad
            if it > 0 and float(np.sum(rhs * dx)) < 0.0:
                # the rest of the last step climbs the new potential (after a re-lag of the
                # friction, say): a loose PCG from it could stop on an ascent direction
                dx[:] = 0.0
            if prescribed:
                for term in terms:
                    term.prescribe(x, dx, rhs)
            operator = next((t.operator for t in terms if t.operator is not None), None)
            # solver.first_cut_iterations: a first solve whose guess already runs into a
            # surface proposes a motion that CCD cuts at the first contact; its PCG stops early
            limit = solver.max_iterations
            if (it == 0 and solver.first_cut_iterations and stage.from_state and not prescribed
                    and not self.sewing and solver.newton_iterations > 1
                    and any(t.cuts(x, dx) for t in terms)):
                limit = min(limit, solver.first_cut_iterations)
            # prescribed motion still short of its goal puts the barrier's coupling −H_cX ΔX
            # (up to 1e22·m/ĥ² an entry) into the right-hand side, and one PCG iteration
            # that resolves that part alone meets a loose relative tolerance: the cloth
            # hardly moved, CCD cut every step and the collider never arrived (a capsule
            # through a hanging sheet, damping_model: strain); such steps solve to the floor
            cg_its, res = filtered_pcg(matrix, rhs, dx, constraints,
                                       solver.tolerance if prescribed else forcing,
                                       limit, self.preconditioner, operator)
            report.newton_iterations += 1
            report.cg_iterations += cg_its
            report.residual = max(report.residual, res)
            if not np.all(np.isfinite(dx)):
                raise NumericalError("the linear solve produced non-finite values")
            step = min((term.max_step(x, dx) for term in terms), default=1.0)
            cut = step < 1.0
            shortened = False
            if line_search and not prescribed:
                cut_to, step = step, self._line_search(x, dx, energy, step)
                shortened = step < cut_to
            if step > 0.0:
                x += step * dx
            for term in terms:
                term.advance(x, dx, step)
            moved = float(np.max(np.abs(step * dx))) / self.h
            # converged when a full Newton step is small, in velocity and in its decrement
            # Δxᵀ H Δx = −∇E·Δx; a step the line search shortened is small because the model
            # was poor there, not because x is near the minimum; then each term's own test
            slow = tol * tol * self._free_mass  # the decrement of a converged step, at most
            decrement = -float(np.sum(grad * dx))
            converged = step == 0.0 or (step == 1.0 and moved <= tol and decrement <= slow)
            if solver.friction_velocity_test and not converged and any(t.lagged() for t in terms):
                # IPC's test (Li et al. 2020): the whole proposal max‖Δx‖/h within the
                # tolerance, cut or not, its decrement not asked: at stick–slip the stick
                # stiffness 2μλ/(ĥε_v) gives a tiny Δx a large decrement, and the twist's
                # steps ran to their cap within tolerance in velocity
                converged = float(np.max(np.abs(dx))) / self.h <= tol
            # stiffness-bound: its velocities already small, its decrement not (at the solver's
            # tolerance: SDIRK2's first stage asks for a tenth of it)
            small = solver.newton_tolerance
            stalled += (float(np.max(np.abs(dx))) <= small * self.h
                        and decrement > small * small * self._free_mass)
            if converged and step > 0.0:
                converged = max(term.settled(free_grad, h_eff) for term in terms) <= tol
            # converged: done unless re-lagging lagged terms (friction) changes their force
            if (converged and self._behind(x) <= REACHED
                    and all(term.relag(x) <= tol for term in terms)):
                break
        else:
            converged = False
        behind = self._behind(x)
        if behind > REACHED:
            raise NumericalError(
                f"a moving pin or collider could not reach its position without crossing the "
                f"cloth (still {behind:.3g} m away after {report.newton_iterations} Newton steps)")
        return x, converged, stalled
