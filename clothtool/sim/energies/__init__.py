"""The energies of the cloth: each a pure numba kernel with its gradient and PSD Hessian.

- :mod:`~clothtool.sim.energies.membrane`: the triangle membrane (Baraff–Witkin stretch and
  shear in the finite-element form of Kim 2020); :mod:`~clothtool.sim.energies.membrane_nodal`
  its nodally smoothed variant;
- :mod:`~clothtool.sim.energies.bending`: dihedral and quadratic bending;
  :mod:`~clothtool.sim.energies.plate`: the plate (Hessian) bending;
- :mod:`~clothtool.sim.energies.springs`: the spring network of the position-based methods;
- :mod:`~clothtool.sim.energies.dissipation`: the dissipation potential of the strain rate;
- :mod:`~clothtool.sim.energies.terms`: the ``Term`` protocol every elastic energy follows;
  :mod:`~clothtool.sim.energies.energy`: the elastic energy the methods integrate.

Energies import only :mod:`clothtool.sim.linalg` below them.
"""
