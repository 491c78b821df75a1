"""``projective``: Projective Dynamics (Bouaziz et al. 2014; Liu et al. 2013 for springs).

Each spring's energy is written as ½k_e‖A_e x − p_e‖² minimised over p_e on the
set of vectors of length L_e (A_e x = x_i − x_j), which equals ½k_e(‖x_i − x_j‖ − L_e)².
A step alternates ``iterations`` times, starting from the inertial target
y = x_n + h v_n + h² g:

- local step (numba): p_e = L_e (x_i − x_j)/‖x_i − x_j‖ for every spring;
- global step: solve (M/h² + (1 + β/h) L) x = M y/h² + Σ k_e A_eᵀ p_e + (β/h) L x_n
  for the free vertices, where L = Σ k_e A_eᵀA_e is the stiffness-weighted graph
  Laplacian (the same for x, y, z) and β = ``material.damping``.

The system matrix does not depend on x, so it is built and factorised once
(scipy.sparse.linalg.splu, on the free vertices only; pinned vertices move to the
right-hand side) and each iteration costs one back-substitution with three
right-hand sides. Every iteration decreases the implicit-Euler incremental
potential of the spring energy, and the fixed point is ``mass-spring``'s step.

Damping uses the constant L in place of the tangent stiffness K(x_n), so it
acts along the spring directions at rest; it is not the same damping as
``implicit``'s. Known limits: the local–global iteration converges linearly and
slowly for stiff materials (the first few iterations remove most of the error,
the rest crawls: few iterations make the cloth look softer); a change of step
size or of the pins needs a new factorisation (done at construction).
"""

import numpy as np
import scipy.sparse as sps
from scipy.sparse.linalg import splu

from clothtool.sim.energies.energy import SpringElastic
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.solvers.constraints import pd_local_rhs


class ProjectiveDynamics(Integrator):
    energy_class = SpringElastic

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        sp = self.springs = model.springs
        n = model.n_vertices
        rows = np.concatenate([sp.i, sp.j, sp.i, sp.j])
        cols = np.concatenate([sp.i, sp.j, sp.j, sp.i])
        vals = np.concatenate([sp.k, sp.k, -sp.k, -sp.k])
        self.laplacian = sps.csr_matrix((vals, (rows, cols)), shape=(n, n))
        beta = model.damping / h
        system = sps.diags(model.mass / (h * h)) + (1.0 + beta) * self.laplacian
        self.free_idx = np.flatnonzero(model.free)
        system = system.tocsr()
        s_ff = system[self.free_idx][:, self.free_idx].tocsc()
        self.lu = splu(s_ff)
        self._s_fp = system[self.free_idx][:, model.pinned].tocsr() if model.has_pins else None
        self._rhs = np.zeros((n, 3))

    def step(self, state):
        model, h, sp = self.model, self.h, self.springs
        y = self._inertial_target(state)
        base = self._mass3 * y / (h * h)
        if model.damping > 0.0:
            base += (model.damping / h) * (self.laplacian @ state.x)
        x = y.copy()
        free = self.free_idx
        rhs = self._rhs
        pin_rhs = self._s_fp @ state.x[model.pinned] if self._s_fp is not None else None
        for _ in range(self.solver.iterations):
            rhs[:] = base
            pd_local_rhs(x, sp.i, sp.j, sp.rest, sp.k, rhs)
            rhs_f = rhs[free]
            if pin_rhs is not None:
                rhs_f -= pin_rhs
            x[free] = self.lu.solve(rhs_f)
        self._finish(state, x)
        return StepReport(sweeps=self.solver.iterations)
