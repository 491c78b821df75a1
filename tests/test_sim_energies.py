"""Energies of the simulator: finite-difference checks, PSD projections, bending calibration."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from clothtool.geometry import dihedral_angle, dihedral_angle_gradient, hinges
from clothtool.sim.energies.bending import (dihedral_element, dihedral_total_energy, quadratic_element,
                                   quadratic_weights)
from clothtool.sim.model.config import GridSpec
from clothtool.sim.energies.membrane import membrane_element, membrane_energy
from clothtool.sim.model.mesh import grid_mesh

FD_STEP = 1e-6
FD_TOL = 1e-5


def central_difference(fun, x):
    """∂fun/∂x by central differences; fun returns a scalar or an array."""
    cols = []
    for a in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[a] += FD_STEP
        xm[a] -= FD_STEP
        cols.append((np.asarray(fun(xp)) - np.asarray(fun(xm))) / (2 * FD_STEP))
    return np.stack(cols, axis=-1)


def rel_error(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def stretch_of(ks):
    """The kernels' (k_u, k_v, b_u, b_v) from one isotropic stiffness, or the four values."""
    return np.array([ks, ks, 1.0, 1.0] if np.isscalar(ks) else ks, dtype=np.float64)


def membrane(x, dr_inv, area, ks, kh, project=False):
    g, h = np.zeros(9), np.zeros((9, 9))
    e = membrane_element(x[0:3], x[3:6], x[6:9], dr_inv, area, stretch_of(ks), kh, project, g, h,
                         np.zeros((6, 6)))
    return e, g, h


def dihedral(x, rest, coef, project=False):
    g, h = np.zeros(12), np.zeros((12, 12))
    e = dihedral_element(x[0:3], x[3:6], x[6:9], x[9:12], rest, coef, project, g, h)
    return e, g, h


def random_triangle(rng):
    """Rest edge matrix with bounded conditioning and a deformed triangle around it."""
    while True:
        dm = rng.normal(size=(2, 2))
        if abs(np.linalg.det(dm)) > 0.3:
            break
    x = rng.normal(size=9)
    return x, np.linalg.inv(dm), 0.5 * abs(np.linalg.det(dm))


def random_hinge(rng):
    """A hinge with well-shaped triangles at a random fold angle in (−2.5, 2.5) rad."""
    xi, xj = np.zeros(3), np.array([1.0, 0.0, 0.0])
    angle_k, angle_l = rng.uniform(0.2, 2.5), rng.uniform(-2.5, -0.2)
    xk = np.array([rng.uniform(0.1, 0.9), np.cos(angle_k), np.sin(angle_k)])
    xl = np.array([rng.uniform(0.1, 0.9), np.cos(angle_l), np.sin(angle_l)])
    # a random rigid motion so that no coordinate is special
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return np.concatenate([q @ p + 0.3 for p in (xi, xj, xk, xl)])


@pytest.mark.parametrize("ks", [3.0, (3.0, 30.0, 1.1, 0.9), (0.0, 5.0, 1.0, 1.3)],
                         ids=["isotropic", "warp-weft", "weft-only"])
@pytest.mark.parametrize("seed", range(5))
def test_membrane_gradient_and_hessian_match_finite_differences(seed, ks):
    rng = np.random.default_rng(seed)
    x, dr_inv, area = random_triangle(rng)
    kh = 2.0
    _, g, h = membrane(x, dr_inv, area, ks, kh)
    st_ = stretch_of(ks)
    assert rel_error(g, central_difference(lambda y: membrane_energy(y[0:3], y[3:6], y[6:9], dr_inv, area, st_, kh), x)) < FD_TOL
    assert rel_error(h, central_difference(lambda y: membrane(y, dr_inv, area, ks, kh)[1], x)) < FD_TOL


def test_anisotropic_membrane_density_known_answer():
    """x0 = 0, D_r = I, A = 1: f0 = x1, f1 = x2, so Ψ = k_u/2 (‖x1‖ − b_u)² + k_v/2 (‖x2‖ − b_v)²
    + k_h/2 (x1·x2)²; zero at F = R diag(b_u, b_v)."""
    ks = (4.0, 40.0, 1.1, 0.95)
    x1, x2 = np.array([1.5, 0.0, 0.0]), np.array([0.3, 0.0, 2.0])
    e, _, _ = membrane(np.concatenate([np.zeros(3), x1, x2]), np.eye(2), 1.0, ks, 3.0)
    expected = 2.0 * (1.5 - 1.1) ** 2 + 20.0 * (np.sqrt(4.09) - 0.95) ** 2 + 1.5 * 0.45 ** 2
    assert e == pytest.approx(expected, rel=1e-14)
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    rest = np.concatenate([np.zeros(3), q @ [1.1, 0, 0], q @ [0, 0.95, 0]])
    e, g, _ = membrane(rest, np.eye(2), 1.0, ks, 3.0)
    assert e == pytest.approx(0.0, abs=1e-28) and np.abs(g).max() < 1e-14


@pytest.mark.parametrize("seed", range(5))
def test_dihedral_gradient_and_hessian_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = random_hinge(rng)
    rest, coef = 0.4, 1.7
    e, g, h = dihedral(x, rest, coef)
    assert e > 0
    assert rel_error(g, central_difference(lambda y: dihedral(y, rest, coef)[0], x)) < FD_TOL
    assert rel_error(h, central_difference(lambda y: dihedral(y, rest, coef)[1], x)) < FD_TOL
    np.testing.assert_allclose(h, h.T, atol=1e-10 * np.abs(h).max())


def test_quadratic_bending_gradient_matches_finite_differences():
    rng = np.random.default_rng(7)
    w, coef = rng.normal(size=4), 0.8
    x = rng.normal(size=12)

    def energy(y, grad=None):
        return quadratic_element(y[0:3], y[3:6], y[6:9], y[9:12], w, coef,
                                 np.zeros(12) if grad is None else grad)

    g = np.zeros(12)
    energy(x, g)
    assert rel_error(g, central_difference(energy, x)) < FD_TOL


def test_dihedral_angle_sign_and_value():
    xi, xj = np.zeros(3), np.array([1.0, 0, 0])
    xk = np.array([0.5, 1.0, 0])
    flat_l = np.array([0.5, -1.0, 0])
    assert dihedral_angle(np.array([xi, xj, xk, flat_l]), np.arange(4)) == pytest.approx(0.0, abs=1e-15)
    folded = np.array([0.5, -np.cos(0.3), np.sin(0.3)])  # l lifted by 0.3 rad
    assert abs(dihedral_angle(np.array([xi, xj, xk, folded]), np.arange(4))) == pytest.approx(0.3, rel=1e-12)


def test_quadratic_model_is_the_linearisation_of_the_dihedral_model():
    """Near the flat state both models agree to second order in the fold."""
    mesh = grid_mesh(GridSpec(nx=5, ny=5, width=1.0, height=1.0, plane="xy"))
    hinge, _ = hinges(mesh.faces, 25)
    w = quadratic_weights(mesh.rest3d, hinge)
    rng = np.random.default_rng(3)
    bump = mesh.rest3d.copy()
    bump[:, 2] = 1e-4 * rng.normal(size=25)
    coef = np.ones(len(hinge))
    quad = sum(quadratic_element(*(bump[v] for v in hinge[h]), w[h], 1.0, np.zeros(12))
               for h in range(len(hinge)))
    dihedral_e = dihedral_total_energy(bump, hinge, np.zeros(len(hinge)), coef)
    assert quad == pytest.approx(dihedral_e, rel=1e-4)


@pytest.mark.parametrize("axis", [0, 1])
def test_dihedral_bending_of_a_cylinder_is_the_continuum_energy(axis):
    """A grid rolled onto a cylinder of curvature κ stores ≈ k_b κ²/2 · area (interior rows)."""
    n, kb, radius = 41, 2e-3, 0.8
    mesh = grid_mesh(GridSpec(nx=n, ny=n, width=1.0, height=1.0, plane="xy"))
    hinge, faces_of = hinges(mesh.faces, n * n)
    area = np.full(len(mesh.faces), 0.5 / (n - 1) ** 2)
    r = mesh.rest3d
    edge2 = np.sum((r[hinge[:, 1]] - r[hinge[:, 0]]) ** 2, axis=1)
    coef = kb * edge2 / (2 * area[faces_of].sum(axis=1))
    # roll along the other axis: arc length s → (R sin(s/R), R(1 − cos(s/R)))
    s = r[:, 1 - axis]
    rolled = r.copy()
    rolled[:, 1 - axis] = radius * np.sin(s / radius)
    rolled[:, 2] = radius * (1 - np.cos(s / radius))
    energy = dihedral_total_energy(rolled, hinge, np.zeros(len(hinge)), coef)
    # hinges bend on the n − 2 interior grid lines; each strip is one spacing wide
    bent_area = 1.0 * (n - 2) / (n - 1)
    assert energy == pytest.approx(0.5 * kb / radius**2 * bent_area, rel=1e-3)


# ---------------------------------------------------------------------------- PSD projections

vec9 = arrays(np.float64, 9, elements=st.floats(-2, 2, allow_nan=False))


@settings(max_examples=200, deadline=None)
@given(x=vec9, dm=arrays(np.float64, 4, elements=st.floats(-2, 2)))
def test_projected_membrane_hessian_is_psd(x, dm):
    dm = dm.reshape(2, 2)
    if abs(np.linalg.det(dm)) < 0.2:
        dm = dm + np.eye(2)
        if abs(np.linalg.det(dm)) < 0.2:
            return
    _, _, h = membrane(x, np.linalg.inv(dm), 0.7, 5.0, 3.0, project=True)
    assert np.allclose(h, h.T, atol=1e-12 * max(1.0, np.abs(h).max()))
    assert np.linalg.eigvalsh(h).min() >= -1e-9 * max(1.0, np.abs(h).max())


@settings(max_examples=100, deadline=None)
@given(f=arrays(np.float64, 6, elements=st.floats(-2, 2, allow_nan=False)),
       k=st.floats(0.01, 10), term=st.sampled_from(["stretch", "shear"]),
       warp_weft=st.tuples(st.floats(0.0, 10), st.floats(0.5, 1.5), st.floats(0.5, 1.5)))
def test_projection_is_the_eigenvalue_clamp_of_the_F_space_hessian(f, k, term, warp_weft):
    """With x0 = 0, D_r = I, A = 1 the (x1, x2) block of the element Hessian is ∂²Ψ/∂F²,
    so each term's projected block must equal V max(Λ, 0) Vᵀ of its exact one
    (the terms are projected one by one, as in Kim 2020); the stretch term with its own
    k_v and rest factors b_u, b_v (eigenvalues k along f̂, k(1 − b/‖f‖) across)."""
    k_v, b_u, b_v = warp_weft
    ks, kh = ((k, k_v, b_u, b_v), 0.0) if term == "stretch" else (0.0, k)
    x = np.concatenate([np.zeros(3), f])
    _, _, exact = membrane(x, np.eye(2), 1.0, ks, kh)
    _, _, proj = membrane(x, np.eye(2), 1.0, ks, kh, project=True)
    lam, vec = np.linalg.eigh(exact[3:, 3:])
    clamped = (vec * np.maximum(lam, 0)) @ vec.T
    np.testing.assert_allclose(proj[3:, 3:], clamped, atol=1e-8 * max(1.0, np.abs(exact).max()))


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_bending_gauss_newton_hessian_is_psd(seed):
    x = random_hinge(np.random.default_rng(seed))
    _, _, h = dihedral(x, 0.2, 1.3, project=True)
    assert np.linalg.eigvalsh(h).min() >= -1e-10 * np.abs(h).max()


@pytest.mark.parametrize("hinge", [
    [[0, 0, 0], [1, 0, 0], [0.5, 0, 0], [0.5, -1, 0.2]],   # triangle (i, j, k) collapsed onto the edge
    [[0, 0, 0], [0, 0, 0], [0.5, 1, 0], [0.5, -1, 0.2]],   # zero-length edge
])
def test_degenerate_hinge_bends_nothing(hinge):
    x = np.array(hinge, float)
    g = np.ones(12)
    assert np.isnan(dihedral_angle(x, np.arange(4)))
    coef, rest = np.array([1.0]), np.array([0.0])
    assert dihedral_total_energy(x, np.array([[0, 1, 2, 3]]), rest, coef) == 0.0
    assert np.isnan(dihedral_angle_gradient(x[0], x[1], x[2], x[3], g))
    assert not g.any()


@pytest.mark.parametrize("height, bends", [(0.5e-4, False), (2e-4, True)])
def test_sliver_hinges_bend_nothing(height, bends):
    """A hinge triangle lower than THIN = 1e-4 of its shared edge adds no energy or force."""
    from clothtool.sim.energies.bending import dihedral_assemble

    x = np.array([[0, 0, 0], [1, 0, 0], [0.5, height, 0], [0.5, -0.6, 0.3]], dtype=float)
    hinge = np.array([[0, 1, 2, 3]])
    grad = np.zeros((4, 3))
    values = np.zeros((16, 3, 3))
    energy = dihedral_assemble(x, hinge, np.zeros(1), np.ones(1), np.arange(16)[None], grad,
                               values)
    assert energy == dihedral_total_energy(x, hinge, np.zeros(1), np.ones(1))
    assert (energy > 0.1) == bends and grad.any() == bends and values.any() == bends
