"""Implicit cloth simulation (Baraff–Witkin 1998 in the finite-element form of Kim 2020).

Modules, one idea each:

- ``config``: YAML → validated dataclasses, every section and key declared; ``schema``: the
  toolkit they are declared with.
- ``mesh``, ``pins``: the rest mesh (grid or PLY) and named pin sets.
- ``model``: what does not change during a run (rest data, masses, energies, pins, colliders,
  the spring network).
- ``state``: what does (positions, velocities, time, contact memory).
- ``integrator``: the protocol every method implements, and the step report.
- ``methods``: the registry of methods (name → class, supported features).
- ``membrane``, ``bending``, ``springs``: energies, gradients and PSD Hessians (numba).
- ``energy``: the elastic energies the methods integrate (finite elements, springs).
- ``newton``: the one Newton loop (incremental potential, line search, filtered PCG).
- ``filter``: Baraff–Witkin's constraint filter (free, pinned, sliding vertices).
- ``linalg``: the block-CSR 3×3 matrix, the filtered PCG and its preconditioners (block
  Jacobi, aggregation multigrid).
- ``collide``: planes and spheres (contact constraints, friction, projection).
- ``solvers``: one module per method (implicit, mass-spring, PBD, XPBD, projective, explicit,
  VBD), above everything else in ``sim``.
- ``output``: PLY frames and ``stats.csv``.
- ``api``: :func:`simulate`, the entry point under ``clothtool simulate``.
"""
