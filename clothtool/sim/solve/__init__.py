"""How one state becomes the next: the integrator protocol and the Newton loop.

- :mod:`~clothtool.sim.solve.integrator`: the protocol every method implements, the step report;
- :mod:`~clothtool.sim.solve.potential`: the terms of the incremental potential (inertia,
  elastic, damping, dissipation, moving pins, contact), each with its energy, gradient,
  Hessian and largest safe step;
- :mod:`~clothtool.sim.solve.newton`: the Newton loop that sums them (line search, filtered
  PCG) for the implicit method;
- :mod:`~clothtool.sim.solve.contact`: its barrier contact and friction term;
- :mod:`~clothtool.sim.solve.statics`: the static equilibrium (a cantilever's rest shape).

The solve imports the model, the energies and the linear algebra; only the methods
(:mod:`clothtool.sim.solvers`) import it.
"""
