"""The 3D (Kabsch) variant: one-ring tables, eigen-solver, vertex rotations, face F3, dihedral change."""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from conftest import grid
from scipy.spatial.transform import Rotation

from clothtool.analysis.deformation2d import analyze_pair
from clothtool.analysis.dihedral import dihedral_change
from clothtool.analysis.face3d import face_gradients3
from clothtool.analysis.kabsch import (
    AMBIGUOUS,
    DEF_DEGENERATE,
    NONFINITE,
    REF_DEGENERATE,
    horn_matrix,
    vertex_rotations,
)
from clothtool.analysis.symeig import adjugate_eigenvector4, jacobi_eigvals_batch
from clothtool.geometry import hinges, one_ring

HYP = settings(deadline=None, max_examples=60, suppress_health_check=[HealthCheck.too_slow])


def curved_patch(nx=7, ny=6):
    x, faces = grid(nx, ny)
    x[:, 2] = 0.3 * np.sin(2.0 * x[:, 0]) * np.cos(1.5 * x[:, 1]) + 0.2 * x[:, 0] ** 2
    return x, faces


def tables(x, faces):
    offsets, neighbours = one_ring(faces, len(x))
    return offsets, neighbours


def tangent_stretches(x_ref, x_def, tri):
    """Principal stretches of the 2D analysis (tangent-frame edge matrices), written out with numpy."""
    def edge_matrix(x):
        e1, e2 = x[tri[1]] - x[tri[0]], x[tri[2]] - x[tri[0]]
        t1 = e1 / np.linalg.norm(e1)
        n = np.cross(e1, e2)
        n /= np.linalg.norm(n)
        t2 = np.cross(n, t1)
        return np.array([[t1 @ e1, t1 @ e2], [t2 @ e1, t2 @ e2]])

    F = edge_matrix(x_def) @ np.linalg.inv(edge_matrix(x_ref))
    return np.linalg.svd(F, compute_uv=False)


def in_plane_stretches(x, faces, stretch3, directions3):
    """The two stretches of F3 whose directions lie in the reference triangle's plane (the third,
    along the normal, must be 1), in descending order."""
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    normal_k = np.argmax(np.abs(np.einsum("mkj,mj->mk", directions3, n)), axis=1)
    rows = np.arange(len(faces))
    np.testing.assert_allclose(np.abs(np.einsum("mj,mj->m", directions3[rows, normal_k], n)), 1.0, atol=1e-9)
    np.testing.assert_allclose(stretch3[rows, normal_k], 1.0, atol=1e-12)
    keep = np.ones_like(stretch3, bool)
    keep[rows, normal_k] = False
    return stretch3[keep].reshape(-1, 2)


rotations = st.integers(0, 2**32 - 1).map(lambda s: Rotation.random(random_state=s).as_matrix())
translations = st.tuples(*[st.floats(-10, 10)] * 3).map(np.array)


# ---------------------------------------------------------------- eigen-solver


EPS = 2.0**-53  # unit roundoff


def jacobi_eigenvalue_bound(fro, n, sweeps):
    """How far each sorted Jacobi eigenvalue can be from the exact one (Weyl): the off-diagonal
    part E left at the stop, ‖E‖₂ ≤ ‖E‖_F = √(2·off) ≤ √2·2⁻⁵³‖A‖_F (the stopping test
    off ≤ 2⁻¹⁰⁶‖A‖_F²), plus the rounding of the sweeps·n(n−1)/2 rotations, each an exact
    rotation of a matrix within 12ε‖A‖_F of the one it rotates (6ε per side; Higham,
    *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Lemma 19.8)."""
    return fro * (np.sqrt(2.0) * EPS + 12.0 * EPS * sweeps * (n * (n - 1) // 2))


def adjugate_angle_bound(others, lam, error, m, gap):
    """sin of the angle between the adjugate eigenvector of the simple eigenvalue λ_i and the
    exact one, λ = ``lam`` its computed value within ``error`` of it, ``others`` the other
    three exact eigenvalues (within ``error`` too), m = max|A − λI|, ``gap`` ≤ min|λ_j − λ|.

    - Davis–Kahan (residual form; Parlett, *The Symmetric Eigenvalue Problem*, Thm 11.7.1):
      sin θ ≤ ‖(A − λI)c‖/(‖c‖·gap). The exact column c of adj(B), B = A − λI, has
      B c = det(B) e_col and ‖c‖ ≥ Π_(j≠i)|λ_j − λ|·|v_i[col]|, so ‖Bc‖/‖c‖ ≤ |λ_i − λ|/|v_i[col]|;
      the column of the largest diagonal cofactor has v_i[col]² ≥ 1/5 (≥ 1/4 up to the terms
      bounded here), hence the constant √5. Rounding B's diagonal perturbs A by 4εm (2-norm).
    - The cofactors' own rounding: each 3×3 minor is 6 triple products summed, off by at most
      γ₅·6m³ ≈ 30εm³, so ‖Δc‖ ≤ 60εm³ and the angle ≤ √5·60εm³/Π_(j≠i)|λ_j − λ|. Next to a
      near-double eigenvalue this term, not Davis–Kahan's, is the larger: the adjugate vector
      is not as accurate as an accumulated Jacobi vector there.
    """
    product = np.prod(np.abs(others - lam) - error)
    return np.sqrt(5.0) * ((error + 4.0 * EPS * m) / gap + 60.0 * EPS * m**3 / product) + 3.0 * EPS


@HYP
@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 4]), st.integers(1, 9))
@example(seed=141514766, n=4, batch=5)  # λ = 1 next to a double 0.99966: 2.5e-11 off
def test_jacobi_eigenvalues_match_numpy(seed, n, batch):
    """Random spectra over six decades, with repeated and opposite eigenvalues mixed in; and the
    adjugate eigenvector of each simple eigenvalue of the 4×4 ones. Against numpy's eigh, whose
    own errors are taken as LAPACK's backward-stable bounds with p(n) = n: n·ε‖A‖_F for an
    eigenvalue, n·ε‖A‖_F/gap for the angle of a vector."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(batch, n, n)))
    lam = rng.normal(size=(batch, n)) * 10.0 ** rng.uniform(-3, 3, size=(batch, 1))
    lam[::2, 1] = lam[::2, 0]
    lam[1::3, 2] = -lam[1::3, 0]
    A = np.einsum("bij,bj,bkj->bik", q, lam, q)
    A = 0.5 * (A + np.swapaxes(A, 1, 2))
    a = A.transpose(1, 2, 0).copy()
    sweeps = jacobi_eigvals_batch(a)
    assert sweeps < 10
    for k in range(batch):
        fro = np.linalg.norm(A[k])
        reference = n * EPS * fro  # numpy's own error
        error = jacobi_eigenvalue_bound(fro, n, sweeps) + reference
        values = np.sort(np.diag(a[:, :, k]))
        w, v = np.linalg.eigh(A[k])
        np.testing.assert_allclose(values, w, rtol=0, atol=error)
        if n == 4:
            for i in range(4):
                others = np.delete(w, i)
                gap = np.abs(others - values[i]).min() - error
                if gap > 1e-6 * np.abs(w).max():
                    x = np.empty(4)
                    adjugate_eigenvector4(A.transpose(1, 2, 0).copy(), k, values[i], np.empty((4, 4)), x)
                    sin = np.linalg.norm(x - (x @ v[:, i]) * v[:, i])
                    m = np.abs(A[k] - values[i] * np.eye(4)).max()
                    assert sin <= adjugate_angle_bound(others, values[i], error, m, gap) \
                        + reference / gap


@HYP
@given(st.integers(0, 2**32 - 1), st.sampled_from(["random", "half_turn", "identity"]))
def test_adjugate_eigenvector_of_horn_matrices(seed, case):
    """Top eigenvector of Horn's N(H) from adj(N − λI), with λ from eigenvalue-only Jacobi, against
    numpy; half turns have w = 0 (the first adjugate column vanishes), near-identity w ≈ 1."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(8, 3))
    axis = rng.normal(size=3)
    R = {"random": Rotation.random(random_state=rng).as_matrix(),
         "half_turn": Rotation.from_rotvec(np.pi * axis / np.linalg.norm(axis)).as_matrix(),
         "identity": np.eye(3)}[case]
    q = (p + (0.1 if case == "random" else 0.0) * rng.normal(size=p.shape)) @ R.T
    a = np.empty((4, 4, 1))
    horn_matrix((p - p.mean(0)).T @ (q - q.mean(0)), 1.0, a, 0)
    N = a[:, :, 0].copy()
    sweeps = jacobi_eigvals_batch(a)
    lam = np.diag(a[:, :, 0]).max()
    x, b = np.empty(4), np.empty((4, 4))
    adjugate_eigenvector4(N[:, :, None].copy(), 0, lam, b, x)
    w, v = np.linalg.eigh(N)
    fro = np.linalg.norm(N)
    error = jacobi_eigenvalue_bound(fro, 4, sweeps) + 4 * EPS * fro  # ours and numpy's
    np.testing.assert_allclose(lam, w[-1], rtol=0, atol=error)
    gap = w[-1] - w[-2] - error
    m = np.abs(N - lam * np.eye(4)).max()
    sin = np.linalg.norm(x - (x @ v[:, -1]) * v[:, -1])
    assert sin <= adjugate_angle_bound(w[:-1], lam, error, m, gap) + 4 * EPS * fro / gap
    # the norm: 4 squares summed (γ₄), a square root, a division, 4 products; then numpy's norm
    np.testing.assert_allclose(np.linalg.norm(x), 1.0, rtol=0, atol=8 * EPS)


# ---------------------------------------------------------------- vertex rotations


@HYP
@given(rotations, translations)
def test_rigid_motion_of_a_curved_patch_is_recovered(R, b):
    x, faces = curved_patch()
    y = x @ R.T + b
    rotation, angle, residual, flags = vertex_rotations(x, y, *tables(x, faces))
    assert not flags.any()
    np.testing.assert_allclose(rotation, np.broadcast_to(R, rotation.shape), atol=1e-9)
    np.testing.assert_allclose(angle, np.linalg.norm(Rotation.from_matrix(R).as_rotvec()), atol=1e-9)
    assert residual.max() < 1e-12


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (1, 1, 0), (3, -2, 0)])
def test_flat_sheet_turned_over_is_a_proper_half_turn(axis):
    """A planar ring admits a perfect reflection too (H has rank 2); the result must be the rotation."""
    x, faces = grid(6, 5)
    R = Rotation.from_rotvec(np.pi * np.array(axis) / np.linalg.norm(axis)).as_matrix()
    rotation, angle, residual, flags = vertex_rotations(x, x @ R.T + [0, 0, 2.0], *tables(x, faces))
    assert not flags.any()
    np.testing.assert_allclose(np.linalg.det(rotation), 1.0, atol=1e-12)
    np.testing.assert_allclose(rotation, np.broadcast_to(R, rotation.shape), atol=1e-12)
    np.testing.assert_allclose(angle, np.pi, atol=1e-12)
    assert residual.max() < 1e-14


def test_isometric_bend_onto_a_cylinder():
    """A flat strip wrapped onto a cylinder of radius r: the triangles hardly stretch (chords are
    shorter than arcs by h²/24r²), the ring of a vertex at arc length s turns by s/r about the axis, and the
    bending leaves a residual no rotation explains."""
    r, h = 1.0, 0.05
    x, faces = grid(41, 5, width=2.0, height=0.2)
    x[:, 0] -= 1.0  # arc length s ∈ [−1, 1]
    s = x[:, 0].copy()
    y = np.stack([r * np.sin(s / r), x[:, 1], r * (1 - np.cos(s / r))], axis=1)

    F3, R3, U3, stretch3, directions3, fflags = face_gradients3(x, y, faces)
    assert not fflags.any()
    np.testing.assert_allclose(stretch3, 1.0, atol=h**2 / (4 * r**2))
    stretch2 = in_plane_stretches(x, faces, stretch3, directions3)
    for t in range(0, len(faces), 7):
        np.testing.assert_allclose(stretch2[t], tangent_stretches(x, y, faces[t]), rtol=1e-12)

    offsets, neighbours = tables(x, faces)
    rotation, angle, residual, flags = vertex_rotations(x, y, offsets, neighbours)
    assert not flags.any()
    interior = np.diff(offsets) == 6  # full, point-symmetric rings
    np.testing.assert_allclose(angle[interior], np.abs(s[interior]) / r, atol=h**2)
    np.testing.assert_allclose(angle, np.abs(s) / r, atol=h / r)  # boundary rings are lopsided
    axes = Rotation.from_matrix(rotation[interior & (np.abs(s) > 0.1)]).as_rotvec()
    np.testing.assert_allclose(axes / np.linalg.norm(axes, axis=1)[:, None] * np.sign(axes[:, 1:2]),
                               np.broadcast_to([0, 1, 0], axes.shape), atol=h**2)
    assert residual.min() > 0 and residual[interior].min() > 0.1 * h**2 / r


@HYP
@given(st.integers(0, 2**32 - 1), st.integers(3, 12), st.floats(0, 0.3))
def test_agrees_with_scipy_align_vectors_on_random_rings(seed, n_ring, noise):
    """One vertex (index 0) with a ring of n_ring neighbours, deformed by a rotation, a random
    linear map near the identity and noise; compared with scipy's SVD-based alignment."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n_ring + 1, 3))
    if seed % 3 == 0:
        x[:, 2] = 0.0  # planar rings: rank-2 covariance
    R = Rotation.random(random_state=rng).as_matrix()
    A = np.eye(3) + noise * rng.normal(size=(3, 3))
    y = (x @ A.T) @ R.T + noise * rng.normal(size=x.shape)
    offsets = np.array([0, n_ring] + [n_ring] * n_ring)
    neighbours = np.arange(1, n_ring + 1)
    p, q = x - x.mean(0), y - y.mean(0)
    sv = np.linalg.svd(p.T @ q, compute_uv=False)
    d = np.sign(np.linalg.det(p.T @ q))
    assume(sv[1] + d * sv[2] > 1e-3 * sv[0])  # a well-determined rotation
    rotation, angle, residual, flags = vertex_rotations(x, y, offsets, neighbours)
    expected, rssd = Rotation.align_vectors(q, p)
    assert flags[0] == 0
    np.testing.assert_allclose(rotation[0], expected.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(angle[0], expected.magnitude(), atol=1e-9)
    # scipy's rssd comes from √(Σ‖p‖² + Σ‖q‖² − 2 tr RH) and cancels; ours is summed directly
    np.testing.assert_allclose(residual[0], rssd / np.sqrt(n_ring + 1), rtol=1e-7, atol=1e-7 * np.abs(p).max())
    np.testing.assert_allclose(residual[0], np.sqrt(np.mean(np.sum((p @ rotation[0].T - q) ** 2, 1))),
                               rtol=1e-9, atol=1e-14 * np.abs(p).max())


def star(points):
    """Vertex 0 with all the other points as its one-ring."""
    n = len(points) - 1
    return np.array([0, n] + [n] * n), np.arange(1, n + 1)


@pytest.mark.parametrize("case, bit", [
    ("coincident_deformed", DEF_DEGENERATE),
    ("collinear_reference", REF_DEGENERATE),
    ("collinear_deformed", DEF_DEGENERATE),
    ("nearly_collinear_reference", REF_DEGENERATE),
    ("isolated_vertex", REF_DEGENERATE | DEF_DEGENERATE),
    ("non_finite", NONFINITE),
    ("point_reflection", AMBIGUOUS),
])
def test_degenerate_rings_are_flagged_and_nan(case, bit):
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.3]], float)
    y = x @ Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix().T
    offsets, neighbours = star(x)
    if case == "coincident_deformed":
        y[:] = [1.0, 2.0, 3.0]
    elif case == "collinear_reference":
        x = np.outer(np.arange(5.0), [1.0, 2.0, -1.0])
    elif case == "collinear_deformed":
        y = np.outer(np.arange(5.0), [1.0, 2.0, -1.0]) + 7.0
    elif case == "nearly_collinear_reference":
        x = np.outer(np.arange(5.0), [1.0, 2.0, -1.0])
        x[2, 0] += 1e-8
    elif case == "isolated_vertex":
        offsets, neighbours = np.array([0, 0, 0, 0, 0, 0]), np.array([], np.int64)
    elif case == "non_finite":
        y[3, 1] = np.nan
    elif case == "point_reflection":  # octahedron → −octahedron: every half-turn fits equally well
        x = np.concatenate([[[0, 0, 0]], np.eye(3), -np.eye(3)])
        y = -x
        offsets, neighbours = star(x)
    rotation, angle, residual, flags = vertex_rotations(x, y, offsets, neighbours)
    assert flags[0] == bit
    assert np.isnan(rotation[0]).all() and np.isnan(angle[0]) and np.isnan(residual[0])


def test_slightly_noncollinear_ring_is_not_flagged():
    x = np.outer(np.arange(5.0), [1.0, 2.0, -1.0])
    x[2] += [1e-2, -1e-2, 0]  # rms width / length ≈ 2e-3, above RING_TOL
    R = Rotation.from_rotvec([0.4, -0.1, 0.2]).as_matrix()
    rotation, angle, residual, flags = vertex_rotations(x, x @ R.T, *star(x))
    assert flags[0] == 0
    np.testing.assert_allclose(rotation[0], R, atol=1e-9)


# ---------------------------------------------------------------- face F3


@HYP
@given(st.integers(0, 2**32 - 1))
def test_face_F3_reproduces_an_affine_map_on_the_tangent_plane(seed):
    rng = np.random.default_rng(seed)
    x, faces = curved_patch(4, 4)
    A = rng.normal(size=(3, 3)) + 2.0 * np.eye(3)
    assume(abs(np.linalg.det(A)) > 0.1)
    y = x @ A.T + rng.normal(size=3)
    F3, R3, U3, stretch3, directions3, flags = face_gradients3(x, y, faces)
    assert not flags.any()
    e = np.stack([x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]], axis=2)  # (M,3,2)
    n = np.cross(e[..., 0], e[..., 1])
    n /= np.linalg.norm(n, axis=1)[:, None]
    ed = A @ e
    nd = np.cross(ed[..., 0], ed[..., 1])
    nd /= np.linalg.norm(nd, axis=1)[:, None]
    np.testing.assert_allclose(F3 @ e, ed, atol=1e-12 * np.abs(ed).max())
    np.testing.assert_allclose(np.einsum("mij,mj->mi", F3, n), nd, atol=1e-12)
    np.testing.assert_allclose(R3 @ np.swapaxes(R3, 1, 2), np.broadcast_to(np.eye(3), R3.shape), atol=1e-13)
    np.testing.assert_allclose(np.linalg.det(R3), 1.0, atol=1e-13)
    np.testing.assert_allclose(U3, np.swapaxes(U3, 1, 2), atol=0)
    np.testing.assert_allclose(R3 @ U3, F3, atol=1e-12 * np.abs(F3).max())
    assert np.all(np.diff(stretch3, axis=1) <= 0) and np.all(stretch3 > 0)
    np.testing.assert_allclose(np.einsum("mij,mkj->mki", U3, directions3), stretch3[..., None] * directions3,
                               atol=1e-12 * stretch3.max())
    np.testing.assert_allclose(directions3 @ np.swapaxes(directions3, 1, 2),
                               np.broadcast_to(np.eye(3), R3.shape), atol=1e-13)
    stretch2 = in_plane_stretches(x, faces, stretch3, directions3)
    for t in range(len(faces)):
        np.testing.assert_allclose(stretch2[t], tangent_stretches(x, y, faces[t]), rtol=1e-12)


@HYP
@given(rotations, translations)
def test_face_F3_of_a_rigid_motion_is_the_rotation(R, b):
    x, faces = curved_patch(4, 4)
    F3, R3, U3, stretch3, directions3, flags = face_gradients3(x, x @ R.T + b, faces)
    assert not flags.any()
    for field in (F3, R3):
        np.testing.assert_allclose(field, np.broadcast_to(R, field.shape), atol=1e-12)
    np.testing.assert_allclose(U3, np.broadcast_to(np.eye(3), U3.shape), atol=1e-12)
    np.testing.assert_allclose(stretch3, 1.0, atol=1e-12)


@pytest.mark.parametrize("tri, bit", [
    ([[0, 0, 0], [1, 0, 0], [2, 1e-12, 0]], REF_DEGENERATE),  # needle
    ([[0, 0, 0], [1, 0, 0], [0.5, 1e-12, 0]], REF_DEGENERATE),  # cap
    ([[0, 0, 0], [1, 0, 0], [1, 0, 0]], REF_DEGENERATE),  # two corners coincide
])
def test_face_degenerate_triangles_are_flagged(tri, bit):
    x = np.array(tri, float)
    good = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 1]], float)
    faces = np.array([[0, 1, 2]])
    *fields, flags = face_gradients3(x, good, faces)
    assert flags[0] == REF_DEGENERATE and all(np.isnan(f).all() for f in fields)
    *fields, flags = face_gradients3(good, x, faces)
    assert flags[0] == DEF_DEGENERATE and all(np.isnan(f).all() for f in fields)
    bad = good.copy()
    bad[1, 2] = np.inf
    *fields, flags = face_gradients3(good, bad, faces)
    assert flags[0] == NONFINITE and all(np.isnan(f).all() for f in fields)
    *_, flags = face_gradients3(good, good + [[0, 0, 0], [0, 0, 0], [1e-6, 0, 0]], faces)
    assert flags[0] == 0


def test_face_F3_agrees_with_the_2D_analysis(rng):
    """In-plane stretches of F3 = the 2D kernel's λ1, λ2; flags = its bits 0–2, NaN alike."""
    x, faces = curved_patch(8, 7)
    y = x @ (np.eye(3) + 0.3 * rng.normal(size=(3, 3))).T + 0.02 * rng.normal(size=x.shape)
    y[5] = y[4] + 1e-12 * (y[6] - y[4])  # squashes the triangles around vertex 5 into needles
    x[20] = x[21]  # reference triangles with two corners in one place
    y[30, 1] = np.inf
    F3, R3, U3, stretch3, directions3, flags = face_gradients3(x, y, faces)
    two_d = analyze_pair(x, y, faces, fields=("stretch", "flags"))
    np.testing.assert_array_equal(flags, two_d["flags"] & 7)
    assert {1, 2, 4} <= set(flags)
    ok = flags == 0
    assert np.isnan(F3[~ok]).all() and np.isnan(stretch3[~ok]).all() and not np.isnan(F3[ok]).any()
    np.testing.assert_allclose(in_plane_stretches(x, faces[ok], stretch3[ok], directions3[ok]),
                               two_d["stretch"][ok], rtol=1e-11)


# ---------------------------------------------------------------- dihedral change


@HYP
@given(rotations, translations)
def test_dihedral_change_is_zero_for_rigid_motions(R, b):
    x, faces = curved_patch()
    hinge, _ = hinges(faces, len(x))
    edges, opposite = hinge[:, :2], hinge[:, 2:]
    change, flags = dihedral_change(x, x @ R.T + b, edges, opposite)
    assert not flags.any()
    np.testing.assert_allclose(change, 0.0, atol=1e-12)


@pytest.mark.parametrize("fold", [0.3, -1.2, 2.5, -3.0])
def test_dihedral_change_equals_the_fold_angle(fold):
    """A flat grid folded along the line x = 0.5 about the y axis; positive folds bend the sheet
    away from its normal (+z)."""
    x, faces = grid(5, 4)
    x[:, 0] -= 0.5
    right = x[:, 0] > 1e-9
    y = x.copy()
    y[right] = x[right] @ Rotation.from_rotvec([0, fold, 0]).as_matrix().T
    hinge, _ = hinges(faces, len(x))
    edges, opposite = hinge[:, :2], hinge[:, 2:]
    change, flags = dihedral_change(x, y, edges, opposite)
    assert not flags.any()
    on_fold = np.all(np.abs(x[edges, 0]) < 1e-9, axis=1)
    assert on_fold.sum() == 3
    np.testing.assert_allclose(change[on_fold], fold, atol=1e-12)
    np.testing.assert_allclose(change[~on_fold], 0.0, atol=1e-12)
    back, _ = dihedral_change(y, x, edges, opposite)
    np.testing.assert_allclose(back[on_fold], -fold, atol=1e-12)


def test_dihedral_change_flags_degenerate_neighbours():
    x = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0]], float)
    edges, opposite = np.array([[0, 1]]), np.array([[2, 3]])
    y = x.copy()
    y[3] = [0.5, 0, 0]  # the second triangle collapses onto the edge
    change, flags = dihedral_change(x, y, edges, opposite)
    assert flags[0] == DEF_DEGENERATE and np.isnan(change[0])
    change, flags = dihedral_change(y, x, edges, opposite)
    assert flags[0] == REF_DEGENERATE and np.isnan(change[0])
    for v in range(4):  # a non-finite coordinate at any of the four corners
        y = x.copy()
        y[v, 1] = np.nan
        change, flags = dihedral_change(x, y, edges, opposite)
        assert flags[0] == NONFINITE and np.isnan(change[0])
