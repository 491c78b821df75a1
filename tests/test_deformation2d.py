"""Known-answer and property tests of the per-triangle 2D kernel."""

import numpy as np
import pytest
from conftest import grid, irregular_patch, random_rotation, tangent_basis
from hypothesis import given, settings
from hypothesis import strategies as st

from clothtool.analysis.deformation2d import DEGENERATE_TOL, FIELDS, analyze_pair


def expected_C(vertices, faces, A):
    """Right Cauchy–Green tensor of the linear map A, in each reference tangent frame."""
    T = tangent_basis(vertices, faces)
    return T @ (A.T @ A) @ np.transpose(T, (0, 2, 1))


@pytest.mark.parametrize("seed", range(5))
def test_patch_test_random_affine_maps(seed):
    rng = np.random.default_rng(seed)
    vertices, faces = irregular_patch(rng)
    A = rng.normal(size=(3, 3)) + 2 * np.eye(3)
    b = rng.normal(size=3)
    r = analyze_pair(vertices, vertices @ A.T + b, faces)
    C = expected_C(vertices, faces, A)
    np.testing.assert_allclose(r["C"], C, atol=1e-10)
    np.testing.assert_allclose(r["strain"], 0.5 * (C - np.eye(2)), atol=1e-10)
    mu = np.linalg.eigvalsh(C)[:, ::-1]
    np.testing.assert_allclose(r["stretch"], np.sqrt(mu), atol=1e-10)
    np.testing.assert_allclose(r["area_ratio"], np.sqrt(np.linalg.det(C)), atol=1e-10)
    # every triangle of the patch sees the same map: one C in world coordinates
    T = tangent_basis(vertices, faces)
    world = np.transpose(T, (0, 2, 1)) @ r["C"] @ T
    np.testing.assert_allclose(world, np.broadcast_to(world[0], world.shape), atol=1e-10)
    assert not r["flags"].any()


@pytest.mark.parametrize("angle", [0.3, np.pi / 2, np.pi, -np.pi])
def test_rigid_motions_including_half_turns(rng, angle):
    vertices, faces = irregular_patch(rng)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    Q = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    r = analyze_pair(vertices, vertices @ Q.T + [5.0, -2.0, 1.0], faces)
    np.testing.assert_allclose(r["stretch"], 1.0, atol=1e-12)
    np.testing.assert_allclose(r["strain"], 0.0, atol=1e-12)
    np.testing.assert_allclose(r["area_ratio"], 1.0, atol=1e-12)
    np.testing.assert_allclose(r["U"], np.broadcast_to(np.eye(2), r["U"].shape), atol=1e-12)


def test_flat_sheet_turned_over_is_rigid(rng):
    vertices, faces = irregular_patch(rng)
    flipped = vertices * [1.0, -1.0, -1.0]  # 180° about x: the sheet shows its back
    r = analyze_pair(vertices, flipped, faces)
    np.testing.assert_allclose(r["stretch"], 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r["R"]), 1.0, atol=1e-12)


@pytest.mark.parametrize("lam", [0.5, 1.0, 1.7])
def test_uniaxial_stretch(lam):
    vertices, faces = grid(6, 5)
    r = analyze_pair(vertices, vertices * [lam, 1.0, 1.0], faces)
    expect = np.sort([lam, 1.0])[::-1]
    np.testing.assert_allclose(r["stretch"], np.broadcast_to(expect, r["stretch"].shape), atol=1e-12)
    np.testing.assert_allclose(r["area_ratio"], lam, atol=1e-12)
    if lam != 1.0:  # the direction of the stretch λ is x (sign free)
        k = 0 if lam > 1 else 1
        np.testing.assert_allclose(np.abs(r["directions"][:, k]),
                                   np.broadcast_to([1.0, 0, 0], (len(faces), 3)), atol=1e-12)


@pytest.mark.parametrize("gamma", [0.1, 0.5, 2.0])
def test_simple_shear(gamma):
    vertices, faces = grid(5, 5)
    sheared = vertices.copy()
    sheared[:, 0] += gamma * vertices[:, 1]
    r = analyze_pair(vertices, sheared, faces)
    root = np.sqrt(1 + gamma ** 2 / 4)
    np.testing.assert_allclose(r["stretch"][:, 0], root + gamma / 2, atol=1e-12)
    np.testing.assert_allclose(r["stretch"][:, 1], root - gamma / 2, atol=1e-12)
    np.testing.assert_allclose(r["area_ratio"], 1.0, atol=1e-12)
    E_xy = np.array([[0, gamma / 2], [gamma / 2, gamma ** 2 / 2]])
    T = tangent_basis(vertices, faces)[:, :, :2]
    np.testing.assert_allclose(r["strain"], T @ E_xy @ np.transpose(T, (0, 2, 1)), atol=1e-12)


def test_isometric_bend_onto_cylinder_is_chord_over_arc():
    h, radius = 0.05, 0.2
    vertices, faces = grid(21, 4, width=20 * h, height=3 * h)
    u = vertices[:, 0]
    bent = np.stack([radius * np.sin(u / radius), vertices[:, 1], radius * (1 - np.cos(u / radius))], 1)
    r = analyze_pair(vertices, bent, faces)
    chord_over_arc = np.sin(h / (2 * radius)) / (h / (2 * radius))
    np.testing.assert_allclose(r["stretch"][:, 0], 1.0, atol=1e-12)
    np.testing.assert_allclose(r["stretch"][:, 1], chord_over_arc, atol=1e-12)
    np.testing.assert_allclose(r["area_ratio"], chord_over_arc, atol=1e-12)


def test_baraff_witkin_uv_example():
    """uv (0,0),(1,0),(0,1); positions (0,0,1),(1,1,1),(0,2,1) → C = [[2,2],[2,4]] (seed notes 002)."""
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    x = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 2.0, 1.0]])
    faces = np.array([[0, 1, 2]])
    r = analyze_pair(None, x, faces, uv=uv)
    np.testing.assert_allclose(r["C"][0], [[2.0, 2.0], [2.0, 4.0]], atol=1e-14)
    # columns of F have the lengths ‖w_u‖ = √2, ‖w_v‖ = 2 of the notes
    np.testing.assert_allclose(np.linalg.norm(r["F"][0], axis=0), [np.sqrt(2), 2.0], atol=1e-14)
    np.testing.assert_allclose(r["directions"][0, :, 2], 0.0)  # directions are (u, v, 0)
    assert r["flags"][0] == 0
    r2 = analyze_pair(None, x, faces, uv=uv, uv_scale=2.0)
    np.testing.assert_allclose(r2["C"][0], np.array([[2.0, 2.0], [2.0, 4.0]]) / 4, atol=1e-14)


def test_uv_flipped_triangle_is_flagged_not_nan():
    uv = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]])  # clockwise in uv
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    r = analyze_pair(None, x, np.array([[0, 1, 2]]), uv=uv)
    assert r["flags"][0] == 8
    np.testing.assert_allclose(r["stretch"][0], [1.0, 1.0], atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r["R"][0]), -1.0, atol=1e-14)  # a reflection
    np.testing.assert_allclose(r["R"][0] @ r["U"][0], r["F"][0], atol=1e-14)


DEGENERATE = {
    "needle": [[0, 0, 0], [1, 0, 0], [1, 1e-9, 0]],
    "cap": [[0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0]],
    "coincident": [[0, 0, 0], [0, 0, 0], [0, 0, 0]],
    "collinear": [[0, 0, 0], [1, 1, 1], [2, 2, 2]],
}
GOOD = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


@pytest.mark.parametrize("shape", DEGENERATE)
def test_degenerate_triangles_are_flagged_nan(shape):
    bad = np.array(DEGENERATE[shape], float)
    good = np.array(GOOD, float)
    faces = np.array([[0, 1, 2]])
    for ref, dfm, bit in [(bad, good, 1), (good, bad, 2)]:
        r = analyze_pair(ref, dfm, faces)
        assert r["flags"][0] == bit
        for name in FIELDS:
            if name != "flags":
                assert np.isnan(r[name]).all(), name


def test_degenerate_tolerance_boundary():
    """A height of 10× the tolerance (relative to the longest edge) is still analysed."""
    ok = np.array([[0, 0, 0], [1, 0, 0], [0.5, 10 * DEGENERATE_TOL, 0]])
    r = analyze_pair(ok, ok * [1.0, 2.0, 1.0], np.array([[0, 1, 2]]))
    assert r["flags"][0] == 0
    np.testing.assert_allclose(r["area_ratio"][0], 2.0, rtol=1e-6)


def test_non_finite_input_is_flagged():
    x = np.array(GOOD, float)
    y = x.copy()
    y[1, 2] = np.nan
    faces = np.array([[0, 1, 2]])
    assert analyze_pair(x, y, faces)["flags"][0] == 4
    assert analyze_pair(y, x, faces)["flags"][0] == 4
    y[1, 2] = np.inf
    assert np.isnan(analyze_pair(x, y, faces)["stretch"]).all()


def test_only_requested_fields_are_returned(rng):
    vertices, faces = irregular_patch(rng)
    r = analyze_pair(vertices, vertices * 1.1, faces, fields=("stretch", "area_ratio"))
    assert set(r) == {"stretch", "area_ratio"}
    np.testing.assert_allclose(r["stretch"], 1.1, atol=1e-12)


def test_cross_check_against_numpy_svd(rng):
    """Random meshes with random deformations: every field against an SVD reference."""
    n = 400
    vertices = rng.normal(size=(n, 3))
    faces = np.array([rng.choice(n, 3, replace=False) for _ in range(2000)])
    deformed = vertices + 0.3 * rng.normal(size=(n, 3))
    r = analyze_pair(vertices, deformed, faces)
    T0 = tangent_basis(vertices, faces)
    T1 = tangent_basis(deformed, faces)

    def edges(x):
        return np.stack([x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]], axis=2)

    F = (T1 @ edges(deformed)) @ np.linalg.inv(T0 @ edges(vertices))
    W, S, Vt = np.linalg.svd(F)
    np.testing.assert_allclose(r["F"], F, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r["stretch"], S, rtol=1e-9)
    np.testing.assert_allclose(r["R"], W @ Vt, atol=1e-9)
    np.testing.assert_allclose(r["U"], np.transpose(Vt, (0, 2, 1)) @ (S[:, :, None] * Vt), atol=1e-9)
    d_ref = np.einsum("mkj,mjc->mkc", Vt, T0)  # principal directions in 3D, sign free
    dots = np.abs(np.einsum("mkc,mkc->mk", d_ref, r["directions"]))
    well_separated = (S[:, 0] - S[:, 1]) > 1e-6 * S[:, 0]
    np.testing.assert_allclose(dots[well_separated], 1.0, atol=1e-8)


finite = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(finite, min_size=9, max_size=9), st.lists(finite, min_size=9, max_size=9),
       st.lists(finite, min_size=4, max_size=4))
def test_properties_on_random_triangles(ref, dfm, quat):
    ref = np.array(ref).reshape(3, 3) + np.eye(3)
    dfm = np.array(dfm).reshape(3, 3) + np.eye(3)
    faces = np.array([[0, 1, 2]])
    r = analyze_pair(ref, dfm, faces)
    if r["flags"][0]:
        assert np.isnan(r["stretch"]).all()
        return
    lam = r["stretch"][0]
    assert lam[0] >= lam[1] >= 0
    F = r["F"][0]
    np.testing.assert_allclose(r["area_ratio"][0], np.linalg.det(F), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r["area_ratio"][0], lam[0] * lam[1], rtol=1e-9, atol=1e-12)
    area = lambda x: 0.5 * np.linalg.norm(np.cross(x[1] - x[0], x[2] - x[0]))  # noqa: E731
    np.testing.assert_allclose(r["area_ratio"][0], area(dfm) / area(ref), rtol=1e-7)
    np.testing.assert_allclose(r["R"][0] @ r["U"][0], F, atol=1e-9 * max(1.0, np.abs(F).max()))
    # rotation invariance: turning the deformed triangle rigidly changes nothing
    q = np.array(quat) + [1.0, 0, 0, 0]
    q /= np.linalg.norm(q)
    w, x, y, z = q
    Q = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    r2 = analyze_pair(ref, dfm @ Q.T + 3.0, faces)
    scale = max(1.0, lam[0])
    np.testing.assert_allclose(r2["stretch"], r["stretch"], atol=1e-9 * scale)
    np.testing.assert_allclose(r2["C"], r["C"], atol=1e-9 * scale ** 2)


def test_rotation_invariance_of_the_reference_too(rng):
    vertices, faces = irregular_patch(rng)
    deformed = vertices @ (np.eye(3) + 0.2 * rng.normal(size=(3, 3))).T
    Q = random_rotation(rng)
    a = analyze_pair(vertices, deformed, faces)
    b = analyze_pair(vertices @ Q.T, deformed, faces)
    np.testing.assert_allclose(a["stretch"], b["stretch"], atol=1e-12)
    np.testing.assert_allclose(a["C"], b["C"], atol=1e-12)


@pytest.mark.parametrize("stretch", [(1.5, 1.0), (1.2, 1.2), (0.8, 1.3)])
def test_thickness_is_the_incompressible_third_stretch(stretch):
    """Stretching a unit right triangle by (sx, sy): λ3 = 1/(sx·sy)."""
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    r = analyze_pair(x, x * [*stretch, 1.0], np.array([[0, 1, 2]]), fields="thickness,flags")
    assert set(r) == {"thickness", "flags"}
    np.testing.assert_allclose(r["thickness"][0], 1.0 / (stretch[0] * stretch[1]), rtol=1e-14)


# ------------------------------------------------------------------ the extended strain measures
UNIT = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)  # D_r = I: F is the map of the xy plane


def _extended(F2):
    """The extended fields of the unit triangle deformed by the in-plane 2×2 map F2."""
    y = UNIT.copy()
    y[:, :2] = UNIT[:, :2] @ np.asarray(F2, float).T
    return analyze_pair(UNIT, y, np.array([[0, 1, 2]]), fields="extended")


def _closed_forms(lam1, lam2):
    e1, e2 = np.log(lam1), np.log(lam2)
    return {"principal_strain": [(lam1**2 - 1) / 2, (lam2**2 - 1) / 2],
            "max_shear": (lam1**2 - lam2**2) / 4,
            "von_mises": np.sqrt(2 / 3 * (e1**2 + e2**2 + (e1 + e2) ** 2)),
            "thickness": 1 / (lam1 * lam2)}


@pytest.mark.parametrize("s", [1.5, 0.7])
def test_uniaxial_stretch_closed_forms(s):
    r = _extended([[s, 0], [0, 1]])
    for name, value in _closed_forms(max(s, 1.0), min(s, 1.0)).items():
        np.testing.assert_allclose(r[name][0], value, rtol=1e-13, atol=1e-15, err_msg=name)
    np.testing.assert_allclose(r["almansi"][0], np.diag([(1 - 1 / s**2) / 2, 0]), atol=1e-15)
    np.testing.assert_allclose(r["hencky"][0], np.diag([np.log(s), 0]), atol=1e-15)
    np.testing.assert_allclose(r["engineering"][0], np.diag([s - 1, 0]), atol=1e-15)
    np.testing.assert_allclose(r["von_mises"][0], 2 / np.sqrt(3) * abs(np.log(s)), rtol=1e-13)
    np.testing.assert_allclose(r["max_shear"][0], abs(s**2 - 1) / 4, rtol=1e-13)
    np.testing.assert_allclose(r["thickness"][0], 1 / s, rtol=1e-14)
    major = 0 if s > 1 else 1  # the x axis is the direction of λ1 when stretched, λ2 when compressed
    np.testing.assert_allclose(np.abs(r["directions_deformed"][0][major]), [1, 0, 0], atol=1e-15)


@pytest.mark.parametrize("s", [1.3, 0.8])
def test_equibiaxial_stretch_closed_forms(s):
    r = _extended([[s, 0], [0, s]])
    for name, value in _closed_forms(s, s).items():
        np.testing.assert_allclose(r[name][0], value, rtol=1e-13, atol=1e-15, err_msg=name)
    np.testing.assert_allclose(r["von_mises"][0], 2 * abs(np.log(s)), rtol=1e-13)
    np.testing.assert_allclose(r["thickness"][0], 1 / s**2, rtol=1e-14)
    np.testing.assert_allclose(r["almansi"][0], (1 - 1 / s**2) / 2 * np.eye(2), atol=1e-15)
    np.testing.assert_allclose(r["hencky"][0], np.log(s) * np.eye(2), atol=1e-15)
    np.testing.assert_allclose(r["engineering"][0], (s - 1) * np.eye(2), atol=1e-15)
    assert r["max_shear"][0] == 0.0


@pytest.mark.parametrize("gamma", [0.2, 0.6, 2.0])
def test_simple_shear_closed_forms(gamma):
    """F = [[1, γ], [0, 1]]: λ = √(1 + γ²/4) ± γ/2, λ1λ2 = 1."""
    r = _extended([[1, gamma], [0, 1]])
    root = np.sqrt(1 + gamma**2 / 4)
    lam1, lam2 = root + gamma / 2, root - gamma / 2
    for name, value in _closed_forms(lam1, lam2).items():
        np.testing.assert_allclose(r[name][0], value, rtol=1e-13, atol=1e-15, err_msg=name)
    np.testing.assert_allclose(r["max_shear"][0], gamma * root / 2, rtol=1e-13)
    np.testing.assert_allclose(r["von_mises"][0], 2 / np.sqrt(3) * np.log(lam1), rtol=1e-13)
    np.testing.assert_allclose(r["thickness"][0], 1.0, rtol=1e-14)
    # B = F·Fᵀ = [[1 + γ², γ], [γ, 1]], B⁻¹ = [[1, −γ], [−γ, 1 + γ²]]
    np.testing.assert_allclose(r["almansi"][0], [[0, gamma / 2], [gamma / 2, -gamma**2 / 2]],
                               atol=1e-14)
    # U = [[2, γ], [γ, 2 + γ²]]/√(4 + γ²)
    U = np.array([[2, gamma], [gamma, 2 + gamma**2]]) / np.sqrt(4 + gamma**2)
    np.testing.assert_allclose(r["engineering"][0], U - np.eye(2), atol=1e-14)
    np.testing.assert_allclose(np.linalg.eigvalsh(r["hencky"][0]), [np.log(lam2), np.log(lam1)],
                               atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-0.6, 0.6), min_size=9, max_size=9),
       st.floats(0, 2 * np.pi), st.floats(-0.99, 0.99))
def test_extended_measures_properties(noise, angle, tilt):
    """On random triangles: hencky has eigenvalues ln λ, almansi = F⁻ᵀ E F⁻¹, engineering = U − I,
    principal strains are the eigenvalues of E, directions_deformed are unit, in the deformed
    plane and = F·vk/λk; a rigid motion of the same triangle has zero strain in every measure."""
    x = np.array([[0, 0, 0], [1, 0, 0], [0.3, 1, 0]]) + 0.2 * np.reshape(noise, (3, 3))
    y = x @ np.diag([1.4, 0.8, 1.1]) + np.reshape(noise, (3, 3))[::-1] * 0.3
    faces = np.array([[0, 1, 2]])
    r = analyze_pair(x, y, faces, fields="extended,F,strain,U,stretch,directions")
    if r["flags"][0]:
        return
    F, E, lam = r["F"][0], r["strain"][0], r["stretch"][0]
    np.testing.assert_allclose(np.linalg.eigvalsh(r["hencky"][0]), np.log(lam[::-1]), atol=1e-9)
    Finv = np.linalg.inv(F)
    np.testing.assert_allclose(r["almansi"][0], Finv.T @ E @ Finv, atol=1e-9)
    np.testing.assert_allclose(r["engineering"][0], r["U"][0] - np.eye(2), atol=1e-12)
    np.testing.assert_allclose(np.sort(r["principal_strain"][0]), np.linalg.eigvalsh(E), atol=1e-9)
    assert r["von_mises"][0] >= 0 and r["max_shear"][0] >= 0
    d = r["directions_deformed"][0]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
    normal = np.cross(y[1] - y[0], y[2] - y[0])
    np.testing.assert_allclose(d @ normal / np.linalg.norm(normal), 0.0, atol=1e-12)
    # F·vk/λk in 3D: push the reference direction (3D) through the affine map of the triangle
    A = np.linalg.lstsq(np.stack([x[1] - x[0], x[2] - x[0]]), np.stack([y[1] - y[0], y[2] - y[0]]),
                        rcond=None)[0]
    for k in range(2):
        pushed = r["directions"][0][k] @ A / lam[k]
        np.testing.assert_allclose(abs(pushed @ d[k]), 1.0, rtol=1e-9)
    c, s = np.cos(angle), np.sin(angle)
    Q = np.array([[c, -s * tilt, 0], [s, c * tilt, 0], [0, 0, 1]])
    Q, _ = np.linalg.qr(Q)
    rigid = analyze_pair(x, x @ Q.T + 3.0, faces, fields="extended")
    for name in ("almansi", "hencky", "engineering", "principal_strain", "max_shear", "von_mises"):
        np.testing.assert_allclose(rigid[name][0], 0.0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(rigid["thickness"][0], 1.0, rtol=1e-12)


def test_extended_fields_are_nan_on_degenerate_triangles():
    bad = np.array(DEGENERATE["needle"], float)
    r = analyze_pair(UNIT, bad, np.array([[0, 1, 2]]), fields="extended")
    for name, value in r.items():
        if name != "flags":
            assert np.isnan(value).all(), name
