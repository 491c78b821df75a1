"""Implicit cloth simulation (Baraff–Witkin 1998 in the finite-element form of Kim 2020).

Modules, one idea each:

- ``config``: YAML → validated dataclasses.
- ``mesh``, ``pins``: the rest mesh (grid or PLY) and named pin sets.
- ``model``: what does not change during a run (rest data, masses, energies, pins, colliders).
- ``state``: positions, velocities, time.
- ``membrane``, ``bending``: per-element energies, gradients and PSD Hessians (numba).
- ``vec3``: tuple 3-vectors and 3×3 inverses for allocation-free kernels.
- ``filter``: Baraff–Witkin's constraint filter (free, pinned, sliding vertices).
- ``blocksparse``: the block-CSR 3×3 matrix and the filtered PCG.
- ``multigrid``: the aggregation multigrid preconditioner.
- ``integrator``: implicit Euler as minimisation of the incremental potential.
- ``collide``: planes and spheres (contact constraints, friction, projection).
- ``solvers``: the other methods (mass-spring, PBD, XPBD, projective, explicit).
- ``output``: PLY frames and ``stats.csv``.
- ``api``: :func:`simulate`, the entry point under ``clothtool simulate``.
"""
