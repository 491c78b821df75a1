"""``explicit``: symplectic (semi-implicit) Euler, the baseline.

Same material as ``implicit`` (finite-element Baraff–Witkin membrane, dihedral
or quadratic bending, stiffness-proportional damping), integrated by

    v ← v + h M⁻¹ (−∇W(x) − β K(x) v + M g),   x ← x + h v

on the free vertices. Only gradients are needed; the damping force −βKv is a
product with the element Hessians, computed element by element without
assembling a matrix, and only when ``material.damping`` > 0.

Stability needs h below the critical step h_c = (2/ω)(√(1 + ζ²) − ζ), ω the
highest natural frequency and ζ = βω/2. With ``cfl`` > 0 (default 0.5) each
solver step is split into ⌈h/(cfl·h_c)⌉ internal steps, with ω² bounded by the
Gershgorin bound of M⁻¹K at rest (times 1.5 for stretched states); with
``cfl: 0`` the step is exactly 1/(fps · substeps) and may blow up.

Known limits: the critical step shrinks like the mesh spacing (∝ 1/√k_stretch)
and, with damping, like 1/(β ω²) — stiff or damped cloth needs thousands of
steps per frame (the stats' ``newton_iterations`` column counts internal steps).
"""

import math

import numpy as np
from numba import njit

from clothtool.sim.bending import dihedral_angle_gradient, dihedral_assemble, quadratic_gradient
from clothtool.sim.collide import resolve_collisions
from clothtool.sim.integrator import fem_elastic_energy
from clothtool.sim.membrane import EPS, _deformation, membrane_assemble, membrane_element
from clothtool.sim.solvers.base import SolverBase, StepReport
from clothtool.vec3 import add, dot, load, scale

STRETCH_MARGIN = 1.5


@njit(cache=True)
def membrane_gradient(x, faces, dinv, area, k_stretch, k_shear, grad):
    """Adds ∇W_membrane to grad (N, 3); no Hessian."""
    for t in range(faces.shape[0]):
        f0, f1, alpha, beta = _deformation(load(x, faces[t, 0]), load(x, faces[t, 1]),
                                           load(x, faces[t, 2]), dinv[t])
        n0 = max(np.sqrt(dot(f0, f0)), EPS)
        n1 = max(np.sqrt(dot(f1, f1)), EPS)
        s = dot(f0, f1)
        g0 = add(scale(k_stretch * (n0 - 1.0) / n0, f0), scale(k_shear * s, f1))
        g1 = add(scale(k_stretch * (n1 - 1.0) / n1, f1), scale(k_shear * s, f0))
        a = area[t]
        for v in range(3):
            vi = faces[t, v]
            for p in range(3):
                grad[vi, p] += a * (alpha[v] * g0[p] + beta[v] * g1[p])


@njit(cache=True)
def membrane_hessian_product(x, faces, dinv, area, k_stretch, k_shear, scale_by, v, out):
    """out += scale_by · K_membrane(x) v, element by element (projected Hessians)."""
    g = np.empty(9)
    hess = np.empty((9, 9))
    work = np.empty((6, 6))
    for t in range(faces.shape[0]):
        membrane_element(load(x, faces[t, 0]), load(x, faces[t, 1]), load(x, faces[t, 2]),
                         dinv[t], area[t], k_stretch, k_shear, True, g, hess, work)
        for a in range(3):
            ia = faces[t, a]
            for p in range(3):
                acc = 0.0
                for b in range(3):
                    ib = faces[t, b]
                    for q in range(3):
                        acc += hess[3 * a + p, 3 * b + q] * v[ib, q]
                out[ia, p] += scale_by * acc


@njit(cache=True)
def dihedral_gradient(x, hinge, theta_rest, coef, grad, v, damp, out):
    """Adds ∇W_bend to grad; with damp > 0 also damp · 2c ∇θ(∇θ·v) (Gauss–Newton K v) to out."""
    g = np.empty(12)
    for h in range(hinge.shape[0]):
        theta = dihedral_angle_gradient(load(x, hinge[h, 0]), load(x, hinge[h, 1]),
                                        load(x, hinge[h, 2]), load(x, hinge[h, 3]), g)
        c2 = 2.0 * coef[h]
        delta = theta - theta_rest[h]
        if delta != delta:  # degenerate hinge: no bending there
            continue
        gv = 0.0
        if damp > 0.0:
            for a in range(4):
                for p in range(3):
                    gv += g[3 * a + p] * v[hinge[h, a], p]
        for a in range(4):
            i = hinge[h, a]
            for p in range(3):
                grad[i, p] += c2 * delta * g[3 * a + p]
                if damp > 0.0:
                    out[i, p] += damp * c2 * gv * g[3 * a + p]


@njit(cache=True)
def quadratic_product(hinge, w, coef, damp, v, out):
    """out += damp · 2c w(wᵀv) (the constant quadratic-bending Hessian times v)."""
    for h in range(hinge.shape[0]):
        for p in range(3):
            wv = 0.0
            for a in range(4):
                wv += w[h, a] * v[hinge[h, a], p]
            for a in range(4):
                out[hinge[h, a], p] += damp * 2.0 * coef[h] * w[h, a] * wv


@njit(cache=True)
def symplectic_update(x, v, force, inv_mass, gravity, h, free):
    for i in range(x.shape[0]):
        if not free[i]:
            continue
        for p in range(3):
            v[i, p] += h * (gravity[p] - inv_mass[i] * force[i, p])
            x[i, p] += h * v[i, p]


def critical_step(model):
    """Estimated largest stable symplectic-Euler step h_c of a model (s); inf without elasticity."""
    rest = model.mesh.rest3d
    n = model.n_vertices
    grad = np.zeros((n, 3))
    values = model.pattern.zeros()
    if model.constant_hessian is not None:
        values += model.constant_hessian
    if model.has_membrane:
        membrane_assemble(rest, model.faces, model.dinv, model.area, model.k_stretch,
                          model.k_shear, model.tri_slots, grad, values)
    if model.bend_model == "dihedral":
        dihedral_assemble(rest, model.hinge, model.hinge_rest_angle, model.hinge_coef,
                          model.hinge_slots, grad, values)
    p = model.pattern
    row_abs = np.abs(values).sum(axis=2)  # (nnzb, 3): Σ_q |K_pq| per block row
    rows = np.add.reduceat(row_abs, p.row_ptr[:-1], axis=0) if p.nnzb else np.zeros((n, 3))
    bound = rows.max(axis=1) / model.mass
    bound = bound[model.free] if model.has_pins else bound
    omega2 = STRETCH_MARGIN * float(bound.max()) if len(bound) else 0.0
    if omega2 <= 0.0:
        return math.inf
    omega = math.sqrt(omega2)
    zeta = 0.5 * model.damping * omega
    return 2.0 / omega * (math.sqrt(1.0 + zeta * zeta) - zeta)


class SymplecticEuler(SolverBase):
    def __init__(self, model, solver, h):
        super().__init__(model, solver, h)
        self.h_critical = critical_step(model)
        if solver.cfl > 0 and math.isfinite(self.h_critical):
            self.internal = max(1, math.ceil(h / (solver.cfl * self.h_critical)))
        else:
            self.internal = 1
        self.dt = h / self.internal
        n = model.n_vertices
        self._force = np.zeros((n, 3))
        self._inv_mass = 1.0 / model.mass

    def elastic_energy(self, x):
        return fem_elastic_energy(self.model, x)

    def _forces(self, x, v):
        """force = ∇W(x) + β K(x) v (the sign convention of a gradient)."""
        model, f = self.model, self._force
        beta = model.damping
        f[:] = 0.0
        if model.has_membrane:
            membrane_gradient(x, model.faces, model.dinv, model.area, model.k_stretch,
                              model.k_shear, f)
            if beta > 0.0:
                membrane_hessian_product(x, model.faces, model.dinv, model.area, model.k_stretch,
                                         model.k_shear, beta, v, f)
        if model.bend_model == "dihedral":
            dihedral_gradient(x, model.hinge, model.hinge_rest_angle, model.hinge_coef, f, v, beta, f)
        elif model.bend_model == "quadratic":
            quadratic_gradient(x, model.hinge, model.hinge_weights, model.hinge_coef, f)
            if beta > 0.0:
                quadratic_product(model.hinge, model.hinge_weights, model.hinge_coef, beta, v, f)
        return f

    def step(self, state):
        model = self.model
        x = state.x.copy()
        v = state.v.copy()
        for _ in range(self.internal):
            force = self._forces(x, v)
            symplectic_update(x, v, force, self._inv_mass, model.gravity, self.dt, model.free)
            if model.has_colliders:
                resolve_collisions(x, v, model.free, model.spheres, model.planes,
                               model.collision_margin)
        state.x = x
        state.v = v
        state.time += self.h
        return StepReport(newton_iterations=self.internal)
