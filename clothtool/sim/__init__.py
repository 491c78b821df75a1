"""Implicit cloth simulation (Baraff–Witkin 1998 in the finite-element form of Kim 2020).

Modules, one idea each:

- ``config``: YAML → validated dataclasses.
- ``mesh``, ``pins``: the rest mesh (grid or PLY) and named pin sets.
- ``model``: what does not change during a run (rest data, masses, energies, pins, colliders).
- ``state``: positions, velocities, time.
- ``membrane``, ``bending``: per-element energies, gradients and PSD Hessians (numba).
- ``blocksparse``: the block-CSR 3×3 matrix and the filtered block-Jacobi PCG.
- ``integrator``: implicit Euler as minimisation of the incremental potential.
- ``collide``: planes and spheres.
- ``output``: PLY frames and ``stats.csv``.
- ``api``: :func:`simulate`, the entry point under ``clothtool simulate``.
"""
