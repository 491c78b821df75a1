"""The strain dissipation potential Φ (clothtool.sim.energies.dissipation): finite-difference checks
of its gradient and Hessian (stretch, shear, bending), its known values, zero for rigid
motions, and the crumpled start it was built for."""

import numpy as np
import pytest
import scipy.sparse as sps
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.errors import InputError
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.config import load_config
from clothtool.sim.energies.dissipation import (StrainDissipation, dissipation_element,
                                                dissipation_energy, strain_measures)
from clothtool.geometry import dihedral_angles
from clothtool.sim.energies.bending import dihedral_element, dihedral_total_energy
from clothtool.sim.linalg.blocks import BlockMatrix
from clothtool.sim.energies.membrane import max_principal_stretch
from clothtool.sim.energies.terms import EdgeMembrane, Membrane
from clothtool.sim.solvers.compare import run_in_memory

DR_INV = np.linalg.inv(np.array([[0.1, 0.03], [0.0, 0.08]]))  # a rest triangle, uv edges
AREA = 0.5 * 0.1 * 0.08
COEF = np.array([300.0, 120.0, 40.0])
STEP = 1e-6


def element(x, length, exact=True):
    g, h = np.empty(9), np.empty((9, 9))
    e = dissipation_element(x[0], x[1], x[2], DR_INV, AREA, COEF, length, exact, g, h)
    return e, g, h


def fd_check(x, length):
    """Central differences of Φ (against the gradient) and of the gradient (against the
    exact Hessian)."""
    _, g, h = element(x, length)
    fd_g, fd_h = np.empty(9), np.empty((9, 9))
    for i in range(9):
        d = np.zeros(9)
        d[i] = STEP
        xp, xm = (x.ravel() + d).reshape(3, 3), (x.ravel() - d).reshape(3, 3)
        fd_g[i] = (element(xp, length)[0] - element(xm, length)[0]) / (2 * STEP)
        fd_h[:, i] = (element(xp, length)[1] - element(xm, length)[1]) / (2 * STEP)
    scale = max(np.abs(g).max(), 1e-3)
    np.testing.assert_allclose(g, fd_g, atol=1e-6 * scale)
    np.testing.assert_allclose(h, fd_h, atol=1e-5 * max(np.abs(h).max(), 1.0))


def triangle(rng):
    return np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.03, 0.08, 0.0]]) + rng.normal(0, 0.03, (3, 3))


def test_gradient_and_hessian_match_finite_differences():
    rng = np.random.default_rng(1)
    for _ in range(20):
        fd_check(triangle(rng), np.append(rng.uniform(0.5, 1.5, 2), rng.uniform(-0.5, 0.5)))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.3, 2.0), st.floats(0.3, 2.0),
       st.floats(-0.8, 0.8))
def test_gradient_and_hessian_match_finite_differences_on_random_triangles(seed, l0, l1, s):
    fd_check(triangle(np.random.default_rng(seed)), np.array([l0, l1, s]))


def test_projected_hessian_is_psd_and_exact_where_both_fibres_are_longer_than_the_base():
    rng = np.random.default_rng(2)
    for _ in range(20):
        x = triangle(rng)
        base = np.append(rng.uniform(0.5, 1.5, 2), rng.uniform(-0.5, 0.5))
        _, _, proj = element(x, base, exact=False)
        assert np.linalg.eigvalsh(proj).min() >= -1e-9 * np.abs(proj).max()
    x = triangle(rng)
    measures = strain_measures(x, np.array([[0, 1, 2]]), DR_INV[None], np.empty((1, 3)))[0]
    # ‖f‖ > ‖f(b)‖ in both columns: c > 0, nothing clamped; the shear at its base: no H₆ part
    shorter = measures * [0.8, 0.8, 1.0]
    np.testing.assert_allclose(element(x, shorter, exact=False)[2], element(x, shorter)[2],
                               atol=1e-9 * np.abs(element(x, shorter)[2]).max())


def test_zero_at_the_base_and_for_every_rigid_motion_of_it():
    """Φ measures strain change only: zero, with zero gradient, at b and at any rotation
    and translation of b; ½ A k (λ − 1)² ‖f(b)‖² for a stretch by λ along the warp,
    ½ A (k_v (√(1 + γ²) − 1)² + k_h γ²) for a shear f1 = γ f0 + ŷ."""
    rng = np.random.default_rng(3)
    base = triangle(rng)
    length = strain_measures(base, np.array([[0, 1, 2]]), DR_INV[None], np.empty((1, 3)))[0]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    for x in (base, base @ q.T + [0.3, -1.0, 2.0]):
        e, g, _ = element(x, length)
        assert abs(e) < 1e-20 and np.abs(g).max() < 1e-9
    rest = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.03, 0.08, 0.0]])
    stretched = rest * [1.2, 1.0, 1.0]  # f0 = 1.2 x̂, f1 = ŷ: only the warp column changes
    e = element(stretched, np.array([1.0, 1.0, 0.0]))[0]
    assert e == pytest.approx(0.5 * AREA * COEF[0] * 0.2**2, rel=1e-12)
    sheared = rest + np.outer(rest[:, 1], [0.25, 0.0, 0.0])  # x += γ y: f0 = x̂, f1 = γx̂ + ŷ
    e = element(sheared, np.array([1.0, 1.0, 0.0]))[0]
    weft = np.sqrt(1 + 0.25**2) - 1.0  # ‖f1‖ grows too
    assert e == pytest.approx(0.5 * AREA * (COEF[1] * weft**2 + COEF[2] * 0.25**2), rel=1e-12)


def test_first_order_it_is_the_frozen_stretch_damping():
    """For x = b + δ, Φ = ½ δᵀ H(b) δ + O(δ³) with H(b) = A (k f̂f̂ᵀ + k_h ggᵀ) through ∂F/∂x."""
    rng = np.random.default_rng(4)
    base = triangle(rng)
    length = strain_measures(base, np.array([[0, 1, 2]]), DR_INV[None], np.empty((1, 3)))[0]
    _, _, h = element(base, length)
    delta = rng.normal(size=9)
    for eps in (1e-3, 1e-4):
        d = eps * delta
        quadratic = 0.5 * d @ h @ d
        assert element(base + d.reshape(3, 3), length)[0] == pytest.approx(quadratic, rel=20 * eps)


def assert_gradient_is_central_differences(term, x, grad):
    """``grad`` against central differences of ``term.energy`` at ``x`` (steps of 1e-7)."""
    fd = np.empty(x.size)
    for i in range(x.size):
        d = np.zeros(x.size)
        d[i] = 1e-7
        fd[i] = (term.energy(x + d.reshape(x.shape)) - term.energy(x - d.reshape(x.shape))) / 2e-7
    np.testing.assert_allclose(grad.ravel(), fd, atol=1e-6 * np.abs(fd).max())


def test_the_mesh_kernels_sum_the_elements_and_hinges():
    """Triangles (stretch, shear) and hinges (bending, the dihedral kernel with c → βc/ĥ and
    θ̄ → Θ): energy, gradient against central differences, projected Hessian blocks."""
    cfg = load_config({"mesh": {"grid": {"nx": 5, "ny": 4, "plane": "xz"}},
                       "material": {"damping_model": "strain", "damping": 0.02, "stretch": [800.0, 500.0], "shear": 60.0,
                                    "bend": 1e-3, "bend_model": "dihedral"}})
    model = build_model(cfg)
    rng = np.random.default_rng(5)
    base = model.mesh.positions + rng.normal(0, 0.02, model.mesh.positions.shape)
    x = base + rng.normal(0, 0.02, base.shape)
    term = StrainDissipation(model)
    term.begin(((1.0, base),), 0.01)
    np.testing.assert_allclose(model.strain_damping, 0.02 * np.array([[800.0, 500.0, 60.0]]).repeat(
        len(model.faces), axis=0))
    np.testing.assert_allclose(model.bend_damping, 0.02 * model.hinge_coef)
    np.testing.assert_allclose(term.angle, dihedral_angles(base, model.hinge))
    matrix = BlockMatrix(model.pattern)
    grad = np.zeros_like(x)
    total = term.assemble(x, grad, matrix.values)
    assert total == pytest.approx(term.energy(x), rel=1e-12)
    bending = dihedral_total_energy(x, model.hinge, term.angle, term.bend_coef)
    assert bending > 0.0
    assert total == pytest.approx(dissipation_energy(x, model.faces, model.dr_inv, model.area,
                                                     term.coef, term.base) + bending, rel=1e-12)
    assert_gradient_is_central_differences(term, x, grad)
    g, h = np.empty(9), np.empty((9, 9))
    dense = np.zeros((x.size, x.size))
    for t, f in enumerate(model.faces):
        dissipation_element(x[f[0]], x[f[1]], x[f[2]], model.dr_inv[t], model.area[t],
                            term.coef[t], term.base[t], False, g, h)
        idx = np.concatenate([3 * f[a] + np.arange(3) for a in range(3)])
        dense[np.ix_(idx, idx)] += h
    g, h = np.empty(12), np.empty((12, 12))
    for e, hinge in enumerate(model.hinge):
        dihedral_element(*x[hinge], term.angle[e], term.bend_coef[e], True, g, h)
        idx = np.concatenate([3 * v + np.arange(3) for v in hinge])
        dense[np.ix_(idx, idx)] += h
    v = rng.normal(size=x.shape)
    np.testing.assert_allclose(matrix.multiply(v, np.empty_like(v)).ravel(), dense @ v.ravel(),
                               atol=1e-9 * np.abs(dense).max())


def rigid_turn(angle=0.7, axis=(0.3, 1.0, -0.2)):
    axis = np.asarray(axis) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


@pytest.mark.parametrize("membrane_model", ["triangle", "edge"])
def test_with_the_membrane_in_one_pass_it_is_the_sum_of_the_two(membrane_model):
    """StrainDissipation(model, membrane) is W_membrane + Φ: energy, gradient and matrix
    blocks those of the membrane term (triangles or edges) and the dissipation assembled
    apart (rounding)."""
    cfg = load_config({"mesh": {"grid": {"nx": 7, "ny": 5, "plane": "xz"}},
                       "material": {"damping_model": "strain", "damping": 0.03,
                                    "stretch": [900.0, 400.0], "rest_stretch": [1.05, 0.97],
                                    "shear": 70.0, "bend": 1e-3,
                                    "membrane_model": membrane_model}})
    model = build_model(cfg)
    membrane = next(t for t in model.terms if isinstance(t, (Membrane, EdgeMembrane)))
    rng = np.random.default_rng(6)
    base = model.mesh.positions + rng.normal(0, 0.02, model.mesh.positions.shape)
    x = base + rng.normal(0, 0.02, base.shape)
    fused, apart = StrainDissipation(model, membrane), StrainDissipation(model)
    for term in (fused, apart):
        term.begin(((4 / 3, base), (-1 / 3, model.mesh.positions)), 0.02)
    one, two = BlockMatrix(model.pattern), BlockMatrix(model.pattern)
    g1, g2 = np.zeros_like(x), np.zeros_like(x)
    e1 = fused.assemble(x, g1, one.values)
    e2 = apart.assemble(x, g2, two.values) + membrane.assemble(x, g2, two.values)
    assert e1 == pytest.approx(e2, rel=1e-12)
    assert fused.energy(x) == pytest.approx(e2, rel=1e-12)
    np.testing.assert_allclose(g1, g2, atol=1e-12 * np.abs(g2).max())
    np.testing.assert_allclose(one.values, two.values, atol=1e-12 * np.abs(two.values).max())


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(10.0, 1e5), st.floats(10.0, 1e5),
       st.floats(0.8, 1.2), st.floats(0.8, 1.2), st.floats(0.0, 1e4),
       st.lists(st.floats(0.0, 1e3), min_size=3, max_size=3))
def test_one_pass_is_the_membrane_and_the_dissipation_on_random_triangles(seed, k_u, k_v, b_u,
                                                                         b_v, shear, coef):
    """strain_assemble on one triangle: the membrane element's energy, gradient and projected
    Hessian plus the dissipation element's (projected), whatever the material and shape."""
    from clothtool.sim.energies.dissipation import NO_EDGES, strain_assemble
    from clothtool.sim.energies.membrane import membrane_element
    from clothtool.sim.linalg.blocks import BlockPattern

    rng = np.random.default_rng(seed)
    x, base = triangle(rng), np.append(rng.uniform(0.5, 1.5, 2), rng.uniform(-0.5, 0.5))
    stretch, coef = np.array([[k_u, k_v, b_u, b_v]]), np.array([coef])
    faces = np.array([[0, 1, 2]])
    pattern = BlockPattern(3, faces)
    matrix = BlockMatrix(pattern)
    grad = np.zeros((3, 3))
    w, phi = strain_assemble(x, faces, DR_INV[None], np.array([AREA]), stretch,
                             np.array([shear]), *NO_EDGES, coef, base[None],
                             pattern.slots(faces), grad, matrix.values)
    g1, h1, g2, h2 = np.empty(9), np.empty((9, 9)), np.empty(9), np.empty((9, 9))
    w1 = membrane_element(x[0], x[1], x[2], DR_INV, AREA, stretch[0], shear, True, g1, h1,
                          np.empty((6, 6)))
    phi2 = dissipation_element(x[0], x[1], x[2], DR_INV, AREA, coef[0], base, False, g2, h2)
    assert w == pytest.approx(w1, rel=1e-12, abs=1e-300)
    assert phi == pytest.approx(phi2, rel=1e-12, abs=1e-300)
    scale = max(np.abs(g1 + g2).max(), 1e-300)
    np.testing.assert_allclose(grad.ravel(), g1 + g2, atol=1e-12 * scale)
    dense = np.zeros((9, 9))
    v = np.eye(9)
    for i in range(9):
        dense[:, i] = matrix.multiply(v[i].reshape(3, 3), np.empty((3, 3))).ravel()
    np.testing.assert_allclose(dense, h1 + h2, atol=1e-12 * max(np.abs(h1 + h2).max(), 1e-300))


def test_a_rigid_rotation_feels_no_damping_force():
    """A bent, sheared, stretched sheet turned rigidly (and moved) from its base: Φ and its
    force are zero, for every part with the hinge bending (the frozen βK form resists the
    same motion)."""
    cfg = load_config({"mesh": {"grid": {"nx": 6, "ny": 6, "plane": "xz"}},
                       "material": {"damping_model": "strain", "damping": 0.05, "shear": 80.0,
                                    "bend": 1e-3, "bend_model": "dihedral"}})
    model = build_model(cfg)
    rng = np.random.default_rng(11)
    base = model.mesh.positions + rng.normal(0, 0.03, model.mesh.positions.shape)
    term = StrainDissipation(model)
    term.begin(((1.0, base),), 1 / 30)
    x = base @ rigid_turn().T + [0.2, -0.5, 1.0]
    grad = np.zeros_like(x)
    matrix = BlockMatrix(model.pattern)
    assert abs(term.assemble(x, grad, matrix.values)) < 1e-18
    assert np.abs(grad).max() < 1e-10
    # the same motion as frozen damping's force βK(b)(x − b)/ĥ: not zero
    frozen = BlockMatrix(model.pattern)
    from clothtool.sim.energies.energy import FemElastic
    FemElastic(model).assemble(base, np.zeros_like(base), frozen.values)
    assert np.abs(frozen.multiply(x - base, np.empty_like(x))).max() > 1e-3


def test_the_plates_damping_is_its_own_matrix_and_turns_with_its_force():
    """With the plate (``bend_model: hessian``), bending's Φ is 1/(2ĥ) Σ_c (x − b)_cᵀ β k_b Q
    (x − b)_c on the plate's own blocks (no hinges in the matrix). Its strain, the Hessian of
    x over the pattern, is linear in x: a rigid turn R of the base feels
    (β/ĥ) k_b Q b (Rᵀ − I), the plate's force at b turned less itself, which is zero for a
    flat sheet and has no part of second order in the turn (frozen βK has one: the membrane's
    stretch along the old fibres)."""
    cfg = load_config({"mesh": {"grid": {"nx": 6, "ny": 6, "plane": "xz"}},
                       "material": {"damping_model": "strain", "damping": 0.05, "shear": 80.0,
                                    "bend": 1e-3}})
    model = build_model(cfg)
    assert model.bend_damping is None and model.plate_damping is not None
    frozen = build_model(load_config({"mesh": {"grid": {"nx": 6, "ny": 6, "plane": "xz"}},
                                      "material": {"damping_model": "frozen", "bend": 1e-3}}))
    assert len(model.pattern.col) == len(frozen.pattern.col)
    ptr, col, val = model.plate_damping
    np.testing.assert_allclose(val, 0.05 * model.plate[2])
    q = sps.csr_matrix((val, col, ptr))
    rng = np.random.default_rng(13)
    turn, move = rigid_turn(), np.array([0.2, -0.5, 1.0])
    for base, bent in ((model.mesh.positions, False),
                       (model.mesh.positions + rng.normal(0, 0.03, model.mesh.positions.shape), True)):
        term = StrainDissipation(model)
        term.begin(((1.0, base),), 1 / 30)
        x = base @ turn.T + move
        grad = np.zeros_like(x)
        total = term.assemble(x, grad, BlockMatrix(model.pattern).values)
        assert total == pytest.approx(term.energy(x), rel=1e-12)
        expected = 30 * (q @ base) @ (turn.T - np.eye(3))
        # Q's rows sum to zero within its pruning (1e-10 of an entry): the translation
        scale = 30 * np.abs(val).max() * np.abs(x).max()
        np.testing.assert_allclose(grad, expected, atol=1e-9 * scale)
        assert (np.abs(grad).max() > 1e-3 * scale) == bent
    # the plate's Φ against central differences, its Hessian blocks against Q/ĥ
    x = model.mesh.positions + rng.normal(0, 0.03, model.mesh.positions.shape)
    term = StrainDissipation(model)
    term.begin(((4 / 3, base), (-1 / 3, model.mesh.positions)), 0.02)
    np.testing.assert_allclose(term.plate_base, 4 / 3 * base - model.mesh.positions / 3)
    grad = np.zeros_like(x)
    matrix = BlockMatrix(model.pattern)
    term.assemble(x, grad, matrix.values)
    assert_gradient_is_central_differences(term, x, grad)
    v = rng.normal(size=x.shape)
    triangles = BlockMatrix(model.pattern)
    from clothtool.sim.energies.dissipation import NO_EDGES, strain_assemble
    strain_assemble(x, model.faces, model.dr_inv, model.area, np.zeros((0, 4)), np.zeros(0),
                    *NO_EDGES, term.coef, term.base, model.tri_slots, np.zeros_like(x),
                    triangles.values)
    np.testing.assert_allclose(matrix.multiply(v, np.empty_like(v)) - triangles.multiply(v, np.empty_like(v)),
                               (q @ v) / 0.02, atol=1e-9 * np.abs(q @ v).max() / 0.02)


def test_bdf2_and_the_second_stage_measure_rates_from_a_combination_of_strains():
    """The base strains are Σ w_i m(x_i) over the past (BDF2: 4/3 and −1/3), not the
    strains of the combined positions."""
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4, "plane": "xz"}},
                       "material": {"damping_model": "strain", "damping": 0.05, "bend": 1e-3,
                                    "bend_model": "dihedral"}})
    model = build_model(cfg)
    rng = np.random.default_rng(12)
    a = model.mesh.positions + rng.normal(0, 0.03, model.mesh.positions.shape)
    b = model.mesh.positions + rng.normal(0, 0.03, model.mesh.positions.shape)
    term = StrainDissipation(model)
    term.begin(((4 / 3, a), (-1 / 3, b)), 0.02)
    m = lambda y: strain_measures(y, model.faces, model.dr_inv, np.empty((len(model.faces), 3)))
    np.testing.assert_allclose(term.base, np.maximum(4 / 3 * m(a) - m(b) / 3, [0, 0, -np.inf]))
    np.testing.assert_allclose(term.angle, 4 / 3 * dihedral_angles(a, model.hinge)
                               - dihedral_angles(b, model.hinge) / 3)
    np.testing.assert_allclose(term.coef, model.strain_damping / 0.02)


@pytest.mark.parametrize("substeps", [1, 16])
def test_a_crumpled_sheet_relaxes_by_frame_8_at_one_step_per_frame(substeps):
    """A 16×16 sheet released from random displacements of up to 0.6 cell (folded and
    inverted triangles, fibres stretched up to 2.7×), with ``damping_model: strain`` (stretch,
    shear and bending): the largest principal stretch is at most 1.1 by frame 8,
    at one step per frame (1.066) as at 16 (with the damping frozen at the start of the
    step, 1.29 at one step per frame)."""
    def crumple(model, state):
        state.x += np.random.default_rng(0).uniform(-0.6, 0.6, state.x.shape) / 15

    cfg = load_config({"mesh": {"grid": {"nx": 16, "ny": 16, "plane": "xz"}},
                       "material": {"damping_model": "strain"},
                       "solver": {"substeps": substeps}, "time": {"fps": 30, "frames": 8}})
    model = build_model(cfg)
    run = run_in_memory(cfg, (0, 8), warmup=False, initial=crumple)
    assert run.ok, run.blew_up
    assert max_principal_stretch(run.positions[0], model.faces, model.dr_inv) > 2.5
    assert max_principal_stretch(run.positions[8], model.faces, model.dr_inv) <= 1.1


def test_strain_damping_is_the_implicit_methods_alone():
    base = {"mesh": {"grid": {"nx": 4, "ny": 4}}}
    assert build_model(load_config(base)).strain_damping is not None  # the default
    frozen = {**base, "material": {"damping_model": "frozen"}}
    assert build_model(load_config(frozen)).strain_damping is None
    undamped = {**base, "material": {"damping": 0.0}}
    assert build_model(load_config(undamped)).strain_damping is None
    strain = {**base, "material": {"damping_model": "strain"}}
    for method in ("explicit", "vbd", "mass-spring"):
        # these methods damp with their own βK, the default strain damping notwithstanding
        assert build_model(load_config({**base, "solver": {"method": method}})).strain_damping is None
        with pytest.raises(InputError, match=rf"solver.method: '{method}' does not support "
                                             r"material.damping_model: strain"):
            load_config({**strain, "solver": {"method": method}})
