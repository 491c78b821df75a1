"""The methods behind ``solver.method``, one module each, sharing the Model, the State and
the :class:`~clothtool.sim.solve.integrator.Integrator` protocol; the registry that names
them is :mod:`clothtool.sim.model.methods`. ``constraints`` holds the PBD, XPBD and Projective
Dynamics kernels on the spring network (:mod:`clothtool.sim.energies.springs`), ``compare`` runs
configs in memory for the benchmarks and tests."""
