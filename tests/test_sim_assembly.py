"""Finite-difference checks of the assembled gradients and Hessians the solvers call.

The per-element kernels are checked in test_sim_energies; here the mesh-level
kernels that the Newton loop and the explicit method actually call are differentiated
numerically on small meshes: ``membrane_assemble`` and ``dihedral_assemble`` (through
:class:`FemElastic`), ``spring_assemble`` (through :class:`SpringElastic`), the
explicit method's ``elastic_forces``, and the incremental potential a converged Newton
step minimises. Hessians are compared where the PSD projection is the identity
(stretched membranes without shear, or in a pure stretch; hinges at their rest angle;
stretched springs); elsewhere the assembled matrix is checked to be symmetric PSD.
"""

import numpy as np
import pytest

from clothtool.geometry import dihedral_angles
from clothtool.sim.linalg.blocks import BlockMatrix
from clothtool.sim.model.config import load_config
from clothtool.sim.energies.energy import FemElastic, SpringElastic
from clothtool.sim.model.methods import make_integrator
from clothtool.sim.model.builder import build_model
from clothtool.sim.solve.potential import RayleighDamping
from clothtool.sim.solvers.explicit import elastic_forces

STEP = 1e-6


def model_of(nx=5, plane="xz", **material):
    mat = {"stretch": 300.0, "shear": 40.0, "bend": 1e-2, "damping": 0.0, **material}
    return build_model(load_config({"mesh": {"grid": {"nx": nx, "ny": nx, "plane": plane}},
                                    "material": mat, "scene": {"pins": ["top_corners"]}}))


def fd_gradient(fun, x):
    """∂fun/∂x (fun: (N, 3) → scalar or array) by central differences, as (N, 3, ...)."""
    out = []
    for i in range(x.shape[0]):
        for p in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, p] += STEP
            xm[i, p] -= STEP
            out.append((np.asarray(fun(xp)) - np.asarray(fun(xm))) / (2 * STEP))
    return np.stack(out)


def dense(matrix):
    return matrix.to_scipy().toarray()


def assembled(energy, x):
    grad = np.zeros_like(x)
    matrix = BlockMatrix(energy.pattern)
    total = energy.assemble(x, grad, matrix.values)
    return total, grad, matrix


def gradient_of(energy):
    def grad(y):
        return assembled(energy, y)[1].ravel()
    return grad


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


WARP_WEFT = {"stretch": [300.0, 3000.0], "rest_stretch": [1.1, 0.9]}


@pytest.mark.parametrize("material", [{}, WARP_WEFT], ids=["isotropic", "warp-weft"])
def test_fem_gradient_is_the_derivative_of_the_energy(material):
    model = model_of(**material)
    rng = np.random.default_rng(0)
    x = model.mesh.rest3d + 0.05 * rng.normal(size=model.mesh.rest3d.shape)
    energy = FemElastic(model)
    total, grad, _ = assembled(energy, x)
    assert total == pytest.approx(energy.energy(x), rel=1e-12)
    assert rel(grad.ravel(), fd_gradient(energy.energy, x)) < 1e-6


@pytest.mark.parametrize("material", [{}, WARP_WEFT], ids=["isotropic", "warp-weft"])
def test_stretched_membrane_hessian_is_the_derivative_of_its_gradient(material):
    """Every column of F longer than its rest factor b and no shear: the projection clamps
    nothing."""
    model = model_of(shear=0.0, bend=0.0, **material)
    rng = np.random.default_rng(1)
    x = 1.3 * model.mesh.rest3d + 0.002 * rng.normal(size=model.mesh.rest3d.shape)
    energy = FemElastic(model)
    _, _, matrix = assembled(energy, x)
    assert rel(dense(matrix), fd_gradient(gradient_of(energy), x)) < 1e-6


@pytest.mark.parametrize("material", [{}, WARP_WEFT], ids=["isotropic", "warp-weft"])
def test_pure_stretch_membrane_hessian_with_shear_is_the_derivative_of_its_gradient(material):
    """F = R diag(1.2, 1.1) everywhere: f0·f1 = 0, so the shear projection clamps nothing."""
    model = model_of(bend=0.0, **material)
    q, _ = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 3)))
    x = (model.mesh.rest3d * [1.2, 1.0, 1.1]) @ q.T
    energy = FemElastic(model)
    _, _, matrix = assembled(energy, x)
    assert rel(dense(matrix), fd_gradient(gradient_of(energy), x)) < 1e-6


@pytest.mark.parametrize("membrane", ["triangle", "nodal", "edge"])
def test_the_exact_membrane_hessian_is_the_derivative_of_its_gradient_anywhere(membrane):
    """With the projection off (statics' ``exact_hessian``) on a compressed, sheared sheet:
    the derivative of the gradient (edge: at or above it, its Gauss–Newton part majorised
    per triangle), indefinite; with it back on, PSD again."""
    model = model_of(bend=0.0, membrane_model=membrane, **WARP_WEFT)
    rng = np.random.default_rng(4)
    x = 0.8 * model.mesh.rest3d + 0.05 * rng.normal(size=model.mesh.rest3d.shape)
    energy = FemElastic(model)
    energy.project(False)
    exact = dense(assembled(energy, x)[2])
    fd = fd_gradient(gradient_of(energy), x)
    if membrane == "edge":
        excess = np.linalg.eigvalsh(exact - 0.5 * (fd + fd.T))
        assert excess.min() > -1e-6 * np.abs(fd).max() and excess.max() > 1e-2 * np.abs(fd).max()
    else:
        assert rel(exact, fd) < 1e-6
    assert np.linalg.eigvalsh(exact).min() < -1e-3 * np.abs(exact).max()
    energy.project(True)
    k = dense(assembled(energy, x)[2])
    assert np.linalg.eigvalsh(k).min() > -1e-9 * np.abs(k).max()


def test_membrane_and_bending_hessian_is_symmetric_psd_anywhere():
    model = model_of()
    x = model.mesh.rest3d + 0.1 * np.random.default_rng(3).normal(size=model.mesh.rest3d.shape)
    k = dense(assembled(FemElastic(model), x)[2])
    np.testing.assert_allclose(k, k.T, atol=1e-10 * np.abs(k).max())
    assert np.linalg.eigvalsh(k).min() > -1e-9 * np.abs(k).max()


def test_bending_hessian_at_the_rest_angles_is_the_derivative_of_its_gradient():
    """At θ = θ̄ the Gauss–Newton Hessian 2c∇θ∇θᵀ is the exact one."""
    model = model_of(stretch=0.0, shear=0.0, bend_model="dihedral")
    x = model.mesh.rest3d + 0.05 * np.random.default_rng(4).normal(size=model.mesh.rest3d.shape)
    model.hinge_rest_angle[:] = dihedral_angles(x, model.hinge)
    energy = FemElastic(model)
    total, grad, matrix = assembled(energy, x)
    assert total == 0.0 and not grad.any()
    fd = fd_gradient(gradient_of(energy), x)
    assert np.abs(fd).max() > 1e-3  # bending is stiff there, not a zero comparison
    assert rel(dense(matrix), fd) < 1e-6


def test_bending_gradient_away_from_rest_is_the_derivative_of_the_energy():
    model = model_of(stretch=0.0, shear=0.0)
    x = model.mesh.rest3d + 0.05 * np.random.default_rng(5).normal(size=model.mesh.rest3d.shape)
    energy = FemElastic(model)
    _, grad, _ = assembled(energy, x)
    assert rel(grad.ravel(), fd_gradient(energy.energy, x)) < 1e-6


@pytest.mark.parametrize("stretched", [False, True])
def test_spring_gradient_and_hessian(stretched):
    model = model_of()
    rng = np.random.default_rng(6)
    rest = model.mesh.rest3d
    x = (1.2 * rest + 0.002 * rng.normal(size=rest.shape) if stretched
         else rest + 0.05 * rng.normal(size=rest.shape))
    energy = SpringElastic(model)
    total, grad, matrix = assembled(energy, x)
    assert total == pytest.approx(energy.energy(x), rel=1e-12)
    assert rel(grad.ravel(), fd_gradient(energy.energy, x)) < 1e-6
    k = dense(matrix)
    if stretched:  # every spring longer than its rest length: the PSD clamp is inactive
        assert rel(k, fd_gradient(gradient_of(energy), x)) < 1e-6
    else:
        assert np.linalg.eigvalsh(k).min() > -1e-9 * np.abs(k).max()


@pytest.mark.parametrize("bend_model", ["hessian", "dihedral", "quadratic"])
def test_explicit_forces_are_the_gradient_plus_damping_times_the_hessian(bend_model):
    model = model_of(damping=0.03, bend_model=bend_model)
    rng = np.random.default_rng(7)
    x = model.mesh.rest3d + 0.03 * rng.normal(size=model.mesh.rest3d.shape)
    v = rng.normal(size=x.shape)
    energy = FemElastic(model)
    still = elastic_forces(model, x, np.zeros_like(x), np.empty_like(x)).copy()
    assert rel(still.ravel(), fd_gradient(energy.energy, x)) < 1e-6
    moving = elastic_forces(model, x, v, np.empty_like(x))
    _, _, matrix = assembled(energy, x)
    kv = matrix.multiply(v, np.empty_like(v))
    np.testing.assert_allclose(moving - still, model.damping * kv, rtol=1e-9,
                               atol=1e-12 * np.abs(kv).max())


@pytest.mark.parametrize("integrator", ["euler", "bdf2"])
@pytest.mark.parametrize("method, damping_model", [("implicit", "strain"), ("implicit", "frozen"),
                                                   ("mass-spring", "frozen")])
def test_a_converged_newton_step_is_a_stationary_point_of_the_incremental_potential(
        method, damping_model, integrator):
    """The gradient the loop builds (inertia, gravity, elasticity, damping) is the
    derivative of the potential it line-searches: a converged step zeroes it."""
    cfg = load_config({"mesh": {"grid": {"nx": 5, "ny": 5, "plane": "xz"}},
                       "material": {"stretch": 300.0, "shear": 40.0, "bend": 1e-2,
                                    "damping": 0.02, "damping_model": damping_model},
                       "scene": {"pins": ["top_corners"]},
                       "solver": {"method": method, "integrator": integrator,
                                  "newton_iterations": 40, "newton_tolerance": 1e-12,
                                  "tolerance": 1e-12, "max_iterations": 2000}})
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    state.v[model.free] = np.random.default_rng(8).normal(0, 0.3, (int(model.free.sum()), 3))
    integ.step(state)  # a history for BDF2
    stage = integ.discretisation(state)
    h_eff, base = stage.h_eff, stage.base
    assert h_eff == pytest.approx(cfg.step * (2 / 3 if integrator == "bdf2" else 1))
    start = state.x.copy()
    integ.step(state)

    def potential(y):  # of the stage just minimised
        return integ.potential(y)

    grad = fd_gradient(potential, state.x).reshape(-1, 3)
    scale = np.abs(fd_gradient(potential, start + 0.01)).max()
    assert np.abs(grad[model.free]).max() < 1e-5 * scale
    np.testing.assert_allclose(state.v, (state.x - base) / h_eff, rtol=1e-12)


def test_the_line_search_potential_is_the_incremental_potential():
    """The line search evaluates E along the Newton direction with the frozen damping term
    in closed form; it must be the same E."""
    cfg = load_config({"mesh": {"grid": {"nx": 5, "ny": 5, "plane": "xz"}},
                       "material": {"damping": 0.05, "damping_model": "frozen"},
                       "scene": {"pins": ["top_corners"]}})
    model = build_model(cfg)
    integ = make_integrator(model, cfg.solver, cfg.step)
    state = model.initial_state()
    rng = np.random.default_rng(9)
    state.v[model.free] = rng.normal(0, 0.3, (int(model.free.sum()), 3))
    integ.step(state)
    integ.step(state)  # leaves this step's damping matrix D in the integrator
    damping = next(t for t in integ.terms if isinstance(t, RayleighDamping))
    base = damping.base
    x = state.x + 0.01 * rng.normal(size=state.x.shape)
    damping.matrix.multiply(x - base, damping._damped)
    dx = 0.02 * rng.normal(size=x.shape)
    energy = integ.along(x, dx)
    for s in (0.0, 0.25, 1.0):
        y = x + s * dx
        assert energy(s) == pytest.approx(integ.potential(y), rel=1e-12)
    # the damping term is really there: without it the two differ
    d = damping.matrix.multiply(x + dx - base, np.empty_like(x))
    assert 0.5 * np.sum((x + dx - base) * d) > 1e-6 * abs(integ.potential(x + dx))
