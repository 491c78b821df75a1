"""The linear algebra of the Newton step, apart from what it solves.

- :mod:`~clothtool.sim.linalg.filter`: Baraff–Witkin's constraint filter (free, pinned);
- :mod:`~clothtool.sim.linalg.blocks`: block-CSR matrices of 3×3 blocks, their assembly
  and product, and the constraint filter's per-vertex data;
- :mod:`~clothtool.sim.linalg.pairs`: contact's pair operator, applied matrix-free;
- :mod:`~clothtool.sim.linalg.multigrid`: the aggregation multigrid of translations
  (``solver.preconditioner: multigrid``);
- the mode multigrid (``amg``) in named pieces: :mod:`~clothtool.sim.linalg.aggregation`
  (aggregates and coarse patterns, shared with ``multigrid``), :mod:`~clothtool.sim.linalg.modes`
  (each aggregate's rigid motions and in-plane shears: the prolongators),
  :mod:`~clothtool.sim.linalg.galerkin` (Pᵀ A P), :mod:`~clothtool.sim.linalg.relaxation`
  (block Gauss–Seidel, block inverses, dense Cholesky) and
  :mod:`~clothtool.sim.linalg.multilevel` (the levels and the cycle);
- :mod:`~clothtool.sim.linalg.pcg`: filtered PCG, block Jacobi and the choice between the
  preconditioners (``hybrid``: ``amg`` or ``multigrid`` by each solve's tolerance).

``blocks``, ``filter``, ``pairs`` and ``aggregation`` import nothing of the others; ``pcg``
imports the preconditioners.
"""
