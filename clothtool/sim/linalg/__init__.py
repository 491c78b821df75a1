"""The linear algebra of the Newton step, apart from what it solves.

- :mod:`~clothtool.sim.linalg.filter`: Baraff–Witkin's constraint filter (free, pinned);
- :mod:`~clothtool.sim.linalg.blocks`: block-CSR matrices of 3×3 blocks, their assembly
  and product, and the constraint filter's per-vertex data;
- :mod:`~clothtool.sim.linalg.multigrid`: the aggregation multigrid preconditioner;
- :mod:`~clothtool.sim.linalg.pcg`: filtered PCG, block Jacobi and the choice between the
  preconditioners.

``blocks`` imports neither of the others, ``multigrid`` only ``blocks``, and ``pcg`` both.
"""
