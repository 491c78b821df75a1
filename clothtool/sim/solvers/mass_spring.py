"""``mass-spring``: implicit Euler on the spring network, Newton + filtered PCG.

The incremental potential is the implicit solver's (see
:mod:`clothtool.sim.solve.newton`) with the spring energy of
:mod:`clothtool.sim.energies.springs` in place of the finite-element membrane
and dihedral bending:

    E(x) = 1/(2h²)‖x − x_n − h v_n‖²_M − Σ m g·x + Σ_e ½k_e(‖x_i − x_j‖ − L_e)² + ½(x − x_n)ᵀD(x − x_n)

with D = (β/h) K(x_n) (β = ``material.damping``). The spring Hessian
k[d̂d̂ᵀ + (1 − L/‖d‖)(I − d̂d̂ᵀ)] is indefinite when a spring is compressed
(‖d‖ < L); as in the course notes the negative term is dropped, which keeps
every Newton system positive definite (the Newton direction is then a descent
direction, and the line search never has to halve for indefiniteness).

The Newton loop is ``implicit``'s (:mod:`clothtool.sim.solve.newton`), with the same
parameters (``newton_iterations``, ``newton_tolerance``, ``line_search``,
``tolerance`` and ``max_iterations``); the PCG is block-Jacobi preconditioned and
colliders project vertices out after the step (no contact constraints, no friction).

Known limits: a spring network is a coarser material model than the membrane
(stretch and shear couple through the diagonals, bend springs resist bending only
to second order), so it converges to a slightly different shape than
``implicit``; the difference does not vanish with the step.
"""

from clothtool.sim.energies.energy import SpringElastic
from clothtool.sim.solve.newton import NewtonIntegrator


class MassSpringImplicit(NewtonIntegrator):
    energy_class = SpringElastic
