"""Implicit cloth simulation (Baraff–Witkin 1998 in the finite-element form of Kim 2020).

Rooms, from the top floor down (no import goes up a floor):

- ``api``: :func:`simulate`, the entry point under ``clothtool simulate``; ``output``: PLY, OBJ
  and MDD frames and ``stats.csv``; ``scene``: the colliders as a picture sees them;
  ``textile``: the textile lab's tests (cantilever, hanging strip) as runs;
- ``solvers``: one module per method (implicit, mass-spring, PBD, XPBD, projective, explicit,
  VBD);
- ``solve``: the integrator protocol, the incremental potential's terms, the Newton loop
  that sums them, its contact term, statics;
- ``model``: the config and its schema, the builder, the Model and the State, mesh, pins,
  seams, attachments, colliders and their motion, the contact data;
- ``energies``: membrane, bending, plate, springs, dissipation (numba kernels);
- ``linalg``: the block-CSR 3×3 matrix, the constraint filter, filtered PCG and its
  preconditioners (block Jacobi, aggregation multigrid).
"""
