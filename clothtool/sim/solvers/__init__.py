"""The methods behind ``solver.method``, one module each, sharing the Model, the State and
the :class:`~clothtool.sim.integrator.Integrator` protocol; the registry that names
them is :mod:`clothtool.sim.methods`. ``springs`` holds the spring network and its
kernels, ``compare`` runs configs in memory for the benchmarks and tests."""
