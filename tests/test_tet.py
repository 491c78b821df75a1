"""Known-answer and property tests of the per-tetrahedron kernel."""

import numpy as np
import pytest
from conftest import random_rotation, tet_grid
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import polar

from clothtool.analysis.tet import (DEGENERATE_TOL, FLAG_INVERTED, KernelPlan, allocate_rest,
                                    analyze_tet_pair, rest_from_positions,
                                    tet_fields_and_next_rest)

FLOATS = ("F", "C", "U", "R", "strain", "stretch", "directions", "volume_ratio")
REGULAR = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])  # det D > 0


def check_polar(r, atol=1e-10):
    """R·U = F, R a proper rotation, U symmetric with eigenvalues λ, λ1 ≥ λ2 ≥ |λ3|."""
    F, R, U, lam = r["F"], r["R"], r["U"], r["stretch"]
    np.testing.assert_allclose(R @ U, F, atol=atol)
    np.testing.assert_allclose(np.transpose(R, (0, 2, 1)) @ R,
                               np.broadcast_to(np.eye(3), R.shape), atol=atol)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=atol)
    np.testing.assert_allclose(U, np.transpose(U, (0, 2, 1)), atol=atol)
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(U), axis=1), np.sort(lam, axis=1),
                               atol=atol)
    assert (lam[:, 0] >= lam[:, 1]).all() and (lam[:, 1] >= np.abs(lam[:, 2])).all()
    V = r["directions"]  # rows: unit eigenvectors of U for λk
    np.testing.assert_allclose(np.linalg.norm(V, axis=2), 1.0, atol=atol)
    np.testing.assert_allclose(np.einsum("mij,mkj->mki", U, V), lam[:, :, None] * V, atol=atol)


@pytest.mark.parametrize("seed", range(4))
def test_affine_maps(seed):
    rng = np.random.default_rng(seed)
    x, tets = tet_grid(4, rng)
    A = rng.normal(size=(3, 3)) + 2.5 * np.eye(3)
    assert np.linalg.det(A) > 0
    r = analyze_tet_pair(x, x @ A.T + rng.normal(size=3), tets)
    m = len(tets)
    np.testing.assert_allclose(r["F"], np.broadcast_to(A, (m, 3, 3)), atol=1e-10)
    np.testing.assert_allclose(r["C"], np.broadcast_to(A.T @ A, (m, 3, 3)), atol=1e-10)
    np.testing.assert_allclose(r["strain"], np.broadcast_to(0.5 * (A.T @ A - np.eye(3)), (m, 3, 3)),
                               atol=1e-10)
    W, S, Vt = np.linalg.svd(A)
    np.testing.assert_allclose(r["stretch"], np.broadcast_to(S, (m, 3)), atol=1e-10)
    np.testing.assert_allclose(r["volume_ratio"], np.linalg.det(A), atol=1e-10)
    rotation, stretch = polar(A)
    np.testing.assert_allclose(r["R"], np.broadcast_to(rotation, (m, 3, 3)), atol=1e-10)
    np.testing.assert_allclose(r["U"], np.broadcast_to(stretch, (m, 3, 3)), atol=1e-10)
    # directions: the right singular vectors, up to sign
    np.testing.assert_allclose(np.abs(np.einsum("mkj,kj->mk", r["directions"], Vt)), 1.0, atol=1e-9)
    check_polar(r)
    assert not r["flags"].any()


@pytest.mark.parametrize("angle", [0.0, 0.4, np.pi / 2, np.pi, -np.pi])
def test_rigid_motions(rng, angle):
    x, tets = tet_grid(3, rng)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    Q = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    r = analyze_tet_pair(x, x @ Q.T + [3.0, -1.0, 2.0], tets)
    m = len(tets)
    np.testing.assert_allclose(r["stretch"], 1.0, atol=1e-12)
    np.testing.assert_allclose(r["strain"], 0.0, atol=1e-12)
    np.testing.assert_allclose(r["volume_ratio"], 1.0, atol=1e-12)
    np.testing.assert_allclose(r["R"], np.broadcast_to(Q, (m, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(r["U"], np.broadcast_to(np.eye(3), (m, 3, 3)), atol=1e-12)
    assert not r["flags"].any()


def test_inverted_mesh_mirror(rng):
    """A mirror image: every tetrahedron inverted, |λ| = singular values, λ3 < 0, R proper."""
    x, tets = tet_grid(3, rng)
    A = np.diag([1.3, 0.9, -0.7]) @ random_rotation(rng)
    r = analyze_tet_pair(x, x @ A.T, tets)
    S = np.linalg.svd(A, compute_uv=False)
    np.testing.assert_allclose(r["stretch"], np.broadcast_to(S * [1, 1, -1], r["stretch"].shape),
                               atol=1e-10)
    np.testing.assert_allclose(r["volume_ratio"], np.linalg.det(A), atol=1e-10)
    assert (r["flags"] == FLAG_INVERTED).all()
    check_polar(r)


def test_one_tet_pushed_through_its_face():
    """Corner 4 moved through the face (1, 2, 3): the tetrahedron is inverted, not degenerate."""
    deformed = REGULAR.copy()
    deformed[3] = [1.0, 1.0, -1.0]  # the face's plane is x + y − z = 1; corner 4 was at −3, now 3
    r = analyze_tet_pair(REGULAR, deformed, [[0, 1, 2, 3]])
    assert r["volume_ratio"][0] < 0
    assert r["stretch"][0, 2] < 0 < r["stretch"][0, 1]
    assert r["flags"][0] == FLAG_INVERTED
    np.testing.assert_allclose(np.linalg.det(r["R"][0]), 1.0, atol=1e-12)
    check_polar(r)


def flat_tet(h):
    """A 'sliver' of longest edge 2 whose fourth corner is ``h`` above the plane of the others."""
    return np.array([[0.0, 0, 0], [2, 0, 0], [1, 1.5, 0], [1, 0.5, h]])


def tol_height():
    """The height h at which flat_tet(h) is exactly at the threshold: |det D| = 3h, L = 2."""
    return DEGENERATE_TOL * 8 / 3


@pytest.mark.parametrize("shape", ["sliver", "needle", "cap", "coincident"])
def test_degenerate_reference_and_deformed(shape):
    x = {"sliver": flat_tet(0.1 * tol_height()),
         "needle": np.array([[0.0, 0, 0], [1, 0, 0], [2, 1e-9, 0], [3, 0, 1e-9]]),
         "cap": np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0], [0.5, 0.5, 1e-9]]),
         "coincident": np.array([[0.0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 1]])}[shape]
    good = REGULAR
    both = np.concatenate([good, x + 5.0])
    tets = [[0, 1, 2, 3], [4, 5, 6, 7]]
    r = analyze_tet_pair(both, np.concatenate([good, good + 5.0]), tets)
    assert list(r["flags"]) == [0, 1]
    for name in FLOATS:
        assert np.isnan(r[name][1]).all() and np.isfinite(r[name][0]).all(), name
    r = analyze_tet_pair(np.concatenate([good, good + 5.0]), both, tets)
    assert list(r["flags"]) == [0, 2]
    assert np.isnan(r["stretch"][1]).all() and np.isnan(r["F"][1]).all()


def test_degenerate_threshold():
    """10× below the tolerance: flagged (the stretched copy too); 10× above: analysed, and
    accurately (a thin tetrahedron is fine)."""
    thin = flat_tet(10 * tol_height())
    thinner = flat_tet(0.1 * tol_height())
    A = np.diag([1.1, 0.9, 1.2])
    for x, flag in ((thin, 0), (thinner, 3)):
        r = analyze_tet_pair(x, x @ A.T, [[0, 1, 2, 3]])
        assert r["flags"][0] == flag
        if flag == 0:
            np.testing.assert_allclose(r["F"][0], A, atol=1e-6)
            np.testing.assert_allclose(r["volume_ratio"][0], np.linalg.det(A), rtol=1e-6)


def test_nonfinite_input_flags_only_touching_tets(rng):
    x, tets = tet_grid(2, rng)
    y = x * 1.1
    y[0] = [np.nan, 0, 0]
    x[-1, 2] = np.inf
    r = analyze_tet_pair(x, y, tets)
    touching = (tets == 0).any(1) | (tets == len(x) - 1).any(1)
    assert touching.any() and not touching.all()
    assert (r["flags"][touching] == 4).all() and (r["flags"][~touching] == 0).all()
    assert np.isnan(r["stretch"][touching]).all()
    np.testing.assert_allclose(r["stretch"][~touching], 1.1, atol=1e-12)


def test_only_requested_fields_and_same_values(rng):
    x, tets = tet_grid(2, rng)
    y = x @ (np.eye(3) + 0.2 * rng.normal(size=(3, 3))).T
    full = analyze_tet_pair(x, y, tets)
    for fields in (("volume_ratio",), ("stretch", "flags"), ("R",), ("directions", "C")):
        part = analyze_tet_pair(x, y, tets, fields=fields)
        assert set(part) == set(fields)
        for name in fields:
            np.testing.assert_array_equal(part[name], full[name])


def test_float32_storage_and_next_rest(rng):
    x, tets = tet_grid(2, rng)
    y = x @ (np.eye(3) + 0.2 * rng.normal(size=(3, 3))).T
    r64 = analyze_tet_pair(x, y, tets)
    r32 = analyze_tet_pair(x, y, tets, dtype=np.float32)
    for name in FLOATS:
        assert r32[name].dtype == np.float32
        np.testing.assert_allclose(r32[name], r64[name], rtol=1e-6, atol=1e-6)
    # the rest data of the deformed frame, computed in the same pass, equals a fresh computation
    plan = KernelPlan(len(tets), ("stretch",))
    out, out_flags, views = plan.allocate(np.float64)
    nxt = allocate_rest(len(tets))
    tet_fields_and_next_rest(y, tets, *rest_from_positions(x, tets), DEGENERATE_TOL, plan.starts,
                             plan.needs, out, out_flags, *nxt)
    np.testing.assert_array_equal(views["stretch"], r64["stretch"])
    fresh = rest_from_positions(y, tets)
    np.testing.assert_array_equal(nxt[0], fresh[0])
    np.testing.assert_array_equal(nxt[1], fresh[1])


matrices = st.lists(st.floats(-3, 3, allow_nan=False), min_size=9, max_size=9).map(
    lambda v: np.array(v).reshape(3, 3))


def svd_reference(A):
    """λ with the Irving sign from numpy's SVD: (σ1, σ2, sgn(det A)·σ3)."""
    S = np.linalg.svd(A, compute_uv=False)
    return S * [1.0, 1.0, np.sign(np.linalg.det(A))]


@settings(max_examples=300, deadline=None)
@given(matrices)
def test_polar_properties_against_numpy_svd(A):
    S = np.linalg.svd(A, compute_uv=False)
    if S[2] < 1e-3 * max(S[0], 1.0):  # near singular: a degenerate deformed tetrahedron
        return
    r = analyze_tet_pair(REGULAR, REGULAR @ A.T, [[0, 1, 2, 3]])
    assert r["flags"][0] == (FLAG_INVERTED if np.linalg.det(A) < 0 else 0)
    np.testing.assert_allclose(r["F"][0], A, atol=1e-12)
    np.testing.assert_allclose(r["stretch"][0], svd_reference(A), atol=1e-10)
    np.testing.assert_allclose(r["volume_ratio"][0], np.linalg.det(A), atol=1e-10)
    check_polar(r, atol=1e-9)
