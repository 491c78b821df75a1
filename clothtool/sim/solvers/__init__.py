"""Solver alternatives behind ``solver.method``, sharing the Model and the State.

=============  ==================================================================
method         what it is
=============  ==================================================================
implicit       Baraff–Witkin implicit Euler, Newton + filtered PCG (the default;
               :mod:`clothtool.sim.integrator`)
mass-spring    implicit Euler on a spring network, PSD-clamped spring Hessians
pbd            Position Based Dynamics, Gauss–Seidel or Jacobi, strain limiting
xpbd           extended PBD: compliant constraints, same springs as mass-spring
projective     Projective Dynamics: constant prefactored matrix, local projections
explicit       symplectic Euler with (automatic) internal steps, the baseline
=============  ==================================================================

Every solver has ``step(state)`` (advance by h in place, returns a
:class:`~clothtool.sim.integrator.StepReport`), ``energies(state)`` and
``max_stretch(state)``. See ``docs/solvers.md`` for the choice between them.
"""


def make_integrator(model, solver, h):
    """The integrator for ``solver.method`` (a :class:`~clothtool.sim.config.Solver`)."""
    method = solver.method
    if method == "implicit":
        from clothtool.sim.integrator import ImplicitEuler
        return ImplicitEuler(model, solver, h)
    if method == "mass-spring":
        from clothtool.sim.solvers.mass_spring import MassSpringImplicit
        return MassSpringImplicit(model, solver, h)
    if method == "pbd":
        from clothtool.sim.solvers.pbd import PositionBased
        return PositionBased(model, solver, h)
    if method == "xpbd":
        from clothtool.sim.solvers.xpbd import ExtendedPositionBased
        return ExtendedPositionBased(model, solver, h)
    if method == "projective":
        from clothtool.sim.solvers.projective import ProjectiveDynamics
        return ProjectiveDynamics(model, solver, h)
    if method == "explicit":
        from clothtool.sim.solvers.explicit import SymplecticEuler
        return SymplecticEuler(model, solver, h)
    raise ValueError(f"unknown solver.method {method!r}")
