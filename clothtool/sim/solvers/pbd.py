"""``pbd``: Position Based Dynamics (Müller et al. 2007) on the spring network.

Each step predicts p = x_n + h v_n + h² g, then runs ``iterations`` sweeps that
project every distance constraint C = ‖p_i − p_j‖ − L_e with inverse-mass
weights, and sets v = (p − x_n)/h. Pinned vertices have inverse mass 0.

Variants (``pbd_variant``):

- ``gauss-seidel``: constraints one after the other, each seeing the previous
  corrections, alternating forward and backward sweeps (symmetric Gauss–Seidel;
  converges faster; the result depends on the order);
- ``jacobi``: all constraints from the same positions, vertex i moving by
  Σ corrections / (n_i + α) with α = ``relaxation`` (course notes); order-free
  and parallel-friendly, but slower to converge;
- ``hierarchical``: Müller's hierarchical PBD (2008): before the Gauss–Seidel sweeps on
  the mesh, ``iterations`` sweeps on each coarser level of a particle hierarchy
  (:mod:`clothtool.sim.solvers.hierarchy`), coarsest first, whose constraints only resist
  stretching (full stiffness); after each level its left-out particles follow their
  parents. A stretch wave crosses a coarse level in a few sweeps, so a fine sheet
  stretches far less at the same number of sweeps.

Stiffness: ``pbd_stiffness`` s ∈ (0, 1] for every edge constraint (stretch and
shear edges alike, as in Müller's triangulated cloth: PBD has no physical shear
modulus), s · k_bend/k_stretch for the bend springs, each corrected per iteration as
k' = 1 − (1 − k)^(1/iterations) so that the effective stiffness does not grow
with the iteration count (Müller 2007, §3.3).

Strain limiting (``strain_limit`` ε > 0): after each sweep, every edge
spring (not the bend springs) is projected into [(1 − ε)L, (1 + ε)L] at full stiffness, so a soft PBD
cloth (s < 1) still never stretches more than ε.

Known limits: not physically parameterised — the apparent stiffness depends on
the step and the iteration count, and with too few iterations the cloth is
stretchy (the error against a converged solution does not vanish as h → 0 at a
fixed iteration count); ``material.damping`` is ignored (PBD is dissipative by
itself); collisions are the same post-step projection as the implicit solver's.
"""

import numpy as np

from clothtool.sim.energies.energy import SpringElastic
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.solvers.hierarchy import build_levels, coarse_masses, prolong
from clothtool.sim.solvers.constraints import (pbd_gauss_seidel, pbd_jacobi,
                                           strain_limit_pass)


class PositionBased(Integrator):
    energy_class = SpringElastic

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        sp = self.springs = model.springs
        k = np.full(len(sp), solver.pbd_stiffness)
        if sp.n_bend:  # bend springs: as much softer than the edges as in the material
            edge_k = sp.k[:len(sp) - sp.n_bend]
            stretch_k = edge_k[sp.structural[:len(edge_k)]]
            ratio = sp.k[len(sp) - sp.n_bend:] / (np.median(stretch_k) if len(stretch_k)
                                                  else edge_k.max())
            k[len(sp) - sp.n_bend:] *= np.minimum(ratio, 1.0)
        self.stiff = 1.0 - (1.0 - k) ** (1.0 / solver.iterations)
        self.inv_mass = self._inverse_mass()
        self.jacobi = solver.pbd_variant == "jacobi"
        if self.jacobi:
            self._delta = np.zeros((model.n_vertices, 3))
            self._count = np.zeros(model.n_vertices)
        eps = solver.strain_limit
        self.limit = (1.0 - eps, 1.0 + eps) if eps > 0 else None
        self.edge = np.ones(len(sp), np.bool_)
        if sp.n_bend:
            self.edge[-sp.n_bend:] = False
        self.levels = []  # hierarchical: (level, its inverse masses), finest first
        if solver.pbd_variant == "hierarchical":
            edges = len(sp) - sp.n_bend
            _, _, b_u, b_v = model.stretch  # the rest state F = diag(b_u, b_v), as the springs'
            rest = model.mesh.rest3d * [b_u, b_v, b_u]
            levels = build_levels(rest, sp.i[:edges], sp.j[:edges],
                                  np.flatnonzero(self.inv_mass == 0.0))
            for lev, mass in zip(levels, coarse_masses(model.mass, levels)):
                w = np.zeros(model.n_vertices)
                w[lev.particles] = 1.0 / mass[lev.particles]
                w[self.inv_mass == 0.0] = 0.0  # pinned particles stay pinned on every level
                self.levels.append((lev, w))

    def step(self, state):
        sp, solver = self.springs, self.solver
        p = self._inertial_target(state)
        if self.levels:
            start = p.copy()
            for lev, inv_mass in reversed(self.levels):  # coarsest first; unilateral
                for _ in range(solver.iterations):
                    strain_limit_pass(p, lev.i, lev.j, lev.rest, lev.limited, inv_mass, 0.0, 1.0)
                prolong(p, start, lev.fine, lev.parent_ptr, lev.parent, lev.weight,
                        self.inv_mass)
        for it in range(solver.iterations):
            if self.jacobi:
                pbd_jacobi(p, sp.i, sp.j, sp.rest, self.stiff, self.inv_mass, solver.relaxation,
                           self._delta, self._count)
            else:
                pbd_gauss_seidel(p, sp.i, sp.j, sp.rest, self.stiff, self.inv_mass, it % 2 == 1)
            if self.limit is not None:
                strain_limit_pass(p, sp.i, sp.j, sp.rest, self.edge, self.inv_mass, *self.limit)
        self._finish(state, p)
        return StepReport(sweeps=solver.iterations * (1 + len(self.levels)))
