"""How one state becomes the next: the integrator protocol and the Newton loop.

- :mod:`~clothtool.sim.solve.integrator`: the protocol every method implements, the step report;
- :mod:`~clothtool.sim.solve.newton`: the incremental potential's Newton loop (line search,
  filtered PCG) of the implicit method;
- :mod:`~clothtool.sim.solve.contact`: its barrier contact and friction term;
- :mod:`~clothtool.sim.solve.statics`: the static equilibrium (a cantilever's rest shape).

The solve imports the model, the energies and the linear algebra; only the methods
(:mod:`clothtool.sim.solvers`) import it.
"""
