"""What both smoothed membranes (``material.membrane_model: nodal`` and ``edge``) must do:
forces and Hessians that match finite differences, a PSD projection, the patch test, rigid
motions and folds along mesh lines that store nothing."""

import numpy as np
import pytest
from conftest import random_rotation
from hypothesis import given, settings
from hypothesis import strategies as st
from smoothed_membranes import (KINDS, STRETCH, SYSTEMS, boundary_vertices, flat, random_sheets,
                                sheet_system)

from clothtool.sim.energies.membrane import membrane_total_energy

MEMBRANES = pytest.mark.parametrize("membrane", sorted(SYSTEMS))


@MEMBRANES
@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31), kind=st.sampled_from(KINDS),
       rest=st.sampled_from([1.0, 0.9]))
def test_gradient_and_hessian_match_finite_differences(membrane, seed, kind, rest):
    """Central differences of W (gradient) and of ∇W (the unprojected Hessian), stretch and
    shear, in compression (rest factor 0.9 less than the stretch) and tension: nodal's
    Hessian is exact, edge's majorises it (K − ∇²W PSD: its Gauss–Newton part per triangle,
    by Jensen over each cell)."""
    (uv, *_), system = sheet_system(membrane, kind, stretch=(5000.0, 3000.0, rest, 1.0))
    rng = np.random.default_rng(seed)
    x = flat(uv) @ np.diag([1.05, 0.97, 1.0]).T + 0.002 * rng.standard_normal((len(uv), 3))
    x[:, 1] += 0.05 * x[:, 0]  # sheared
    energy, grad, values = system.assemble(x, False)
    assert energy == pytest.approx(system.energy(x), rel=1e-14)
    h = 1e-7
    num_grad = np.zeros_like(x)
    num_hess = np.zeros((x.size, x.size))
    for i in range(len(x)):
        for p in range(3):
            up, down = x.copy(), x.copy()
            up[i, p] += h
            down[i, p] -= h
            num_grad[i, p] = (system.energy(up) - system.energy(down)) / (2 * h)
            num_hess[:, 3 * i + p] = ((system.assemble(up, False)[1]
                                       - system.assemble(down, False)[1]) / (2 * h)).ravel()
    assert np.abs(num_grad - grad).max() <= 1e-7 * np.abs(grad).max()
    if membrane == "nodal":
        assert np.abs(num_hess - system.dense(values)).max() <= 1e-6 * np.abs(num_hess).max()
    else:
        excess = system.dense(values) - 0.5 * (num_hess + num_hess.T)
        assert np.linalg.eigvalsh(excess).min() >= -1e-6 * np.abs(num_hess).max()


@MEMBRANES
@random_sheets(6)
def test_projected_hessian_is_psd(membrane, seed, kind):
    (uv, *_), system = sheet_system(membrane, kind)
    rng = np.random.default_rng(seed)
    x = flat(uv) @ np.diag([0.9, 1.1, 1.0]).T + 0.003 * rng.standard_normal((len(uv), 3))
    k = system.dense(system.assemble(x, True)[2])
    assert np.linalg.eigvalsh(k).min() >= -1e-9 * np.abs(k).max()


@MEMBRANES
@random_sheets(10)
def test_patch_test_an_affine_map_stores_the_constant_strain_energy(membrane, seed, kind):
    """x = A u + c: every cell's metric is AᵀA, so W = A_total Ψ(A), the triangles' energy,
    and the interior vertices feel no force."""
    (uv, faces, dr_inv, area, stretch, shear), system = sheet_system(membrane, kind)
    rng = np.random.default_rng(seed)
    a = np.eye(3, 2) + 0.2 * rng.standard_normal((3, 2))
    x = uv @ a.T + rng.standard_normal(3)
    energy, grad, _ = system.assemble(x, True)
    f0, f1 = a[:, 0], a[:, 1]
    psi = (0.5 * 5000.0 * (np.linalg.norm(f0) - 1.0) ** 2
           + 0.5 * 3000.0 * (np.linalg.norm(f1) - 1.0) ** 2 + 0.5 * 50.0 * (f0 @ f1) ** 2)
    assert energy == pytest.approx(area.sum() * psi, rel=1e-10)
    assert energy == pytest.approx(membrane_total_energy(x, faces, dr_inv, area, stretch, shear),
                                   rel=1e-10)
    boundary = boundary_vertices(faces, len(uv))
    assert np.abs(grad[~boundary]).max() <= 1e-9 * np.abs(grad).max()
    assert np.abs(grad.sum(axis=0)).max() <= 1e-9 * np.abs(grad).max()


@MEMBRANES
@random_sheets(10)
def test_rigid_motions_change_neither_energy_nor_force_magnitudes(membrane, seed, kind):
    (uv, *_), system = sheet_system(membrane, kind)
    rng = np.random.default_rng(seed)
    x = flat(uv) + 0.002 * rng.standard_normal((len(uv), 3))
    rot = random_rotation(rng)
    energy, grad, _ = system.assemble(x, True)
    moved, moved_grad, _ = system.assemble(x @ rot.T + rng.standard_normal(3), True)
    assert moved == pytest.approx(energy, rel=1e-10)
    assert np.abs(moved_grad - grad @ rot.T).max() <= 1e-9 * np.abs(grad).max()
    rest = system.assemble(flat(uv) @ rot.T, True)
    assert rest[0] == pytest.approx(0.0, abs=1e-18) and np.abs(rest[1]).max() < 1e-12


@MEMBRANES
@pytest.mark.parametrize("angle", [10.0, 60.0, 120.0])
def test_a_sheet_folded_along_a_mesh_line_stores_nothing(membrane, angle):
    """Every triangle moves rigidly, so every C_t and every cell's metric is I (an average of
    F would be shorter along the fold)."""
    from clothtool.sim.textile import _criss_cross

    uv, faces = _criss_cross(np.linspace(-0.03, 0.03, 7), np.linspace(-0.02, 0.02, 5))
    p = uv[faces]
    dr = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    area = 0.5 * np.abs(np.linalg.det(dr))
    system = SYSTEMS[membrane](uv, faces, np.linalg.inv(dr), area,
                               np.tile(STRETCH, (len(faces), 1)), np.full(len(faces), 50.0))
    t = np.radians(angle)
    x = flat(uv)
    right = uv[:, 0] > 1e-12
    x[right, 0] = uv[right, 0] * np.cos(t)
    x[right, 2] = uv[right, 0] * np.sin(t)
    energy, grad, _ = system.assemble(x, True)
    assert energy == pytest.approx(0.0, abs=1e-20) and np.abs(grad).max() < 1e-12
