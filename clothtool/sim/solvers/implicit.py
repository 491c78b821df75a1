"""``implicit``: Baraff–Witkin implicit Euler on the finite-element cloth (the default).

The incremental potential of :mod:`clothtool.sim.solve.newton` with the finite-element
energy of :mod:`clothtool.sim.energies.energy` (Kim 2020 membrane, dihedral or quadratic
bending), barrier contact with friction for every collider and self-collision
(:mod:`clothtool.sim.solve.contact`), and the ``solver.preconditioner`` of the PCG (multigrid by default).
"""

from clothtool.sim.energies.energy import FemElastic
from clothtool.sim.solve.newton import NewtonIntegrator


class ImplicitEuler(NewtonIntegrator):
    energy_class = FemElastic
    multigrid = True
    continuation = True
