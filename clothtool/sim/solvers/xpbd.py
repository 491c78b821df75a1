"""``xpbd``: extended Position Based Dynamics (Macklin, Müller & Chentanez 2016).

Each spring is a compliant constraint C = ‖x_i − x_j‖ − L_e with compliance
α_e = 1/k_e (the spring network's stiffness, so XPBD has the same material as
``mass-spring``). Per step: predict x = x_n + h v_n + h² g, λ = 0, then
``iterations`` Gauss–Seidel sweeps (alternating forward and backward) of

    Δλ = (−C − α̃λ − γ ∇C·(x − x_n)) / ((1 + γ) ∇C M⁻¹ ∇Cᵀ + α̃),   x += M⁻¹∇Cᵀ Δλ

with α̃ = α/h² and, for stiffness-proportional damping β = ``material.damping``,
γ = α̃ β h (0 without damping: the term is skipped). Its fixed point is the
implicit Euler step of the spring energy, so with enough iterations XPBD
converges to ``mass-spring``'s answer; with few iterations the cloth is softer
than the material (the residual acts as extra compliance) but stays stable.
Sub-stepping (``substeps``) with few iterations is usually the cheaper way to
accuracy (Macklin et al. 2019, "Small steps").

Parameters: ``iterations``, ``substeps``. Known limits: Gauss–Seidel order
dependence; stiff springs converge slowly at large steps (α̃ → 0 is hard PBD);
collisions are the post-step projection shared with the other solvers.
"""

import numpy as np

from clothtool.sim.energies.energy import SpringElastic
from clothtool.sim.solve.integrator import Integrator, StepReport
from clothtool.sim.solvers.constraints import xpbd_sweep


class ExtendedPositionBased(Integrator):
    energy_class = SpringElastic

    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        sp = self.springs = model.springs
        self.alpha_tilde = 1.0 / (sp.k * h * h)
        self.gamma = self.alpha_tilde * model.damping * h  # zeros without damping
        self.inv_mass = self._inverse_mass()
        self._lam = np.zeros(len(sp))

    def step(self, state):
        sp = self.springs
        x_n = state.x
        x = self._inertial_target(state)
        lam = self._lam
        lam[:] = 0.0
        for it in range(self.solver.iterations):
            xpbd_sweep(x, x_n, sp.i, sp.j, sp.rest, self.alpha_tilde, self.gamma, self.inv_mass, lam,
                       it % 2 == 1)
        self._finish(state, x)
        return StepReport(sweeps=self.solver.iterations)
