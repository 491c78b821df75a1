"""The shared geometry: tangent-frame edge matrices, hinges and one-rings, against brute force."""

import numpy as np
import pytest
from conftest import grid, random_rotation, tangent_basis

from clothtool.geometry import (DEGENERATE, DEGENERATE_TOL, NONFINITE, dihedral_angles, hinges,
                                one_ring, tangent_edge_matrices)


def curved_patch(nx=5, ny=4):
    x, faces = grid(nx, ny)
    x[:, 2] = 0.3 * np.sin(2 * x[:, 0]) * np.cos(x[:, 1])
    return x, faces


def test_edge_matrix_is_the_edges_in_the_tangent_frame(rng):
    x, faces = curved_patch(6, 5)
    x = x @ random_rotation(rng).T
    d, status = tangent_edge_matrices(x, faces, DEGENERATE_TOL)
    assert not status.any()
    basis = tangent_basis(x, faces)
    e = np.stack([x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]], axis=2)
    np.testing.assert_allclose(d, np.einsum("mij,mjk->mik", basis, e), atol=1e-14)
    assert np.all(d[:, 1, 0] == 0) and np.all(d[:, 0, 0] > 0) and np.all(d[:, 1, 1] > 0)


def test_edge_matrix_status_of_needles_and_non_finite_corners():
    x = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0], [0.5, 1e-7, 0], [np.nan, 0, 0]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])
    d, status = tangent_edge_matrices(x, faces, DEGENERATE_TOL)
    assert list(status) == [DEGENERATE, 0, NONFINITE]
    assert d[1, 1, 1] == pytest.approx(1e-7, rel=1e-6) and not d[[0, 2]].any()


def test_one_ring_matches_a_brute_force_table():
    x, faces = curved_patch(5, 4)
    faces = np.concatenate([faces, [[0, 1, 1]]])  # a degenerate face adds no self-neighbour
    n = len(x) + 1  # the last vertex is on no face
    offsets, neighbours = one_ring(faces, n)
    expected = [set() for _ in range(n)]
    for f in faces:
        for a in f:
            expected[a] |= {b for b in f if b != a}
    assert offsets.shape == (n + 1,) and offsets[0] == 0 and offsets[-1] == len(neighbours)
    for i in range(n):
        assert list(neighbours[offsets[i]:offsets[i + 1]]) == sorted(expected[i])


def test_hinges_have_two_faces_and_carry_the_orientation():
    x, faces = grid(5, 4)
    faces[3] = faces[3][::-1]  # one inconsistently oriented face
    hinge, hinge_faces = hinges(faces, len(x))
    count = {}
    for m, f in enumerate(faces):
        for k in range(3):
            key = tuple(sorted((f[k], f[(k + 1) % 3])))
            count[key] = count.get(key, []) + [m]
    interior = sorted(k for k, v in count.items() if len(v) == 2)
    assert [tuple(h[:2]) for h in hinge] == interior
    cyclic = {tuple(np.roll(f, s)) for f in faces for s in range(3)}
    for (i, j, k0, k1), (f0, f1) in zip(hinge, hinge_faces):
        assert {f0, f1} == set(count[(i, j)])
        assert set(faces[f0]) == {i, j, k0} and set(faces[f1]) == {i, j, k1}
        runs_forward = [(i, j, int(np.setdiff1d(faces[f], [i, j])[0])) in cyclic for f in (f0, f1)]
        if any(runs_forward):
            assert (i, j, k0) in cyclic
    assert len(hinge) == 4 * 2 + 3 * 3 + 4 * 3  # interior horizontal + vertical + diagonal edges


def test_dihedral_angle_of_a_fold_along_a_grid_line():
    """A flat grid folded by α along the line x = 0.5: the hinges on that line turn by ±α,
    the others stay flat."""
    x, faces = grid(3, 3)
    alpha = 0.7
    right = x[:, 0] > 0.5
    x[right, 2] = (x[right, 0] - 0.5) * np.sin(alpha)
    x[right, 0] = 0.5 + (x[right, 0] - 0.5) * np.cos(alpha)
    hinge, _ = hinges(faces, len(x))
    theta = dihedral_angles(x, hinge)
    on_fold = np.isclose(x[hinge[:, 0], 0], 0.5) & np.isclose(x[hinge[:, 1], 0], 0.5)
    np.testing.assert_allclose(np.abs(theta[on_fold]), alpha, rtol=1e-12)
    np.testing.assert_allclose(theta[~on_fold], 0.0, atol=1e-14)
    assert on_fold.sum() == 2
