"""The edge-based smoothed membrane (material.membrane_model: edge)."""

import numpy as np
import pytest
from conftest import random_rotation
from smoothed_membranes import edge_system, flat, random_sheets, sheet

from clothtool.sim.energies.membrane import membrane_gradient, membrane_total_energy
from clothtool.sim.energies.membrane_edge import edge_cells, edge_parts, unfolded_frames
from clothtool.sim.energies.terms import EdgeMembrane, Membrane
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.config import load_config
from clothtool.sim.textile import disc


@random_sheets(6)
def test_never_above_the_triangles_energy(seed, kind):
    """Ψ is convex in C, so the smoothed metric stores at most the triangles' energy (Jensen),
    less where neighbouring triangles strain differently (a crumpled sheet)."""
    uv, faces, dr_inv, area, stretch, shear = sheet(kind)
    system = edge_system(uv, faces, dr_inv, area, stretch, shear)
    rng = np.random.default_rng(seed)
    x = flat(uv) + 0.002 * rng.standard_normal((len(uv), 3))
    triangles = membrane_total_energy(x, faces, dr_inv, area, stretch, shear)
    assert 0.0 < system.energy(x) < triangles


def test_cells_are_the_edges_and_share_out_the_area():
    uv, faces, dr_inv, area, stretch, shear = sheet("delaunay")
    cells = edge_cells(faces)
    turn, weight, cell_area, mat_stretch, mat_shear = edge_parts(area, stretch, shear, cells)
    pairs = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2), axis=2)
    edges = np.unique(pairs.reshape(-1, 2), axis=0)
    assert len(cell_area) == len(edges)
    assert cell_area.sum() == pytest.approx(area.sum(), rel=1e-14)
    for c in range(len(cell_area)):
        mine = cells == c
        assert mine.sum() in (1, 2) and len(np.unique(pairs[mine], axis=0)) == 1  # one edge
        assert weight[mine].sum() == pytest.approx(1.0, rel=1e-14)
        assert cell_area[c] == pytest.approx(area[np.flatnonzero(mine.any(axis=1))].sum() / 3)
    assert np.array_equal(turn, np.broadcast_to(np.eye(2), turn.shape))
    assert np.allclose(mat_stretch, stretch[0]) and np.allclose(mat_shear, 50.0)


def test_the_hessian_is_exact_on_one_triangle_and_along_affine_motions():
    """The majorised Gauss–Newton part is exact on cells of one triangle (a lone triangle:
    three such cells), and, at an affine map (every triangle the same F), along any affine
    motion (every triangle the same change of F: equality in Jensen's inequality)."""
    def second_derivative(system, x, d, h=1e-6):
        return (system.assemble(x + h * d, False)[1]
                - system.assemble(x - h * d, False)[1]).ravel() @ d.ravel() / (2 * h)

    rng = np.random.default_rng(4)
    uv = np.array([[0.0, 0.0], [0.011, 0.001], [0.003, 0.009]])
    faces = np.array([[0, 1, 2]])
    p = uv[faces]
    dr = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)
    one = edge_system(uv, faces, np.linalg.inv(dr), 0.5 * np.abs(np.linalg.det(dr)),
                      np.array([[5000.0, 3000.0, 0.9, 1.0]]), np.array([50.0]))
    x = flat(uv) + 0.002 * rng.standard_normal((3, 3))
    k = one.dense(one.assemble(x, False)[2])
    exact = np.zeros((9, 9))
    for i in range(9):
        d = np.zeros(9)
        d[i] = 1e-7
        exact[:, i] = (one.assemble(x + d.reshape(3, 3), False)[1]
                       - one.assemble(x - d.reshape(3, 3), False)[1]).ravel() / 2e-7
    assert np.abs(k - exact).max() <= 1e-6 * np.abs(exact).max()
    uv, faces, dr_inv, area, stretch, shear = sheet("delaunay", stretch=(5000.0, 3000.0, 0.9, 1.0))
    system = edge_system(uv, faces, dr_inv, area, stretch, shear)
    a = np.eye(3, 2) + 0.1 * rng.standard_normal((3, 2))
    x = uv @ a.T
    k = system.dense(system.assemble(x, False)[2])
    for _ in range(3):
        d = uv @ rng.standard_normal((3, 2)).T
        assert d.ravel() @ k @ d.ravel() == pytest.approx(second_derivative(system, x, d),
                                                          rel=1e-6)
    d = rng.standard_normal(x.shape)  # not affine: the majorant is strictly above
    assert d.ravel() @ k @ d.ravel() > 1.01 * second_derivative(system, x, d)


def test_the_config_key_selects_the_term():
    """One term, stretch and shear: at an affine map the triangles' energy."""
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}},
                       "material": {"membrane_model": "edge", "stretch": [5000.0, 3000.0]}})
    model = build_model(cfg)
    assert isinstance(model.terms[0], EdgeMembrane)
    assert not any(isinstance(t, Membrane) for t in model.terms)
    x = model.mesh.positions * np.array([1.01, 1.0, 1.0])
    x[:, 1] += 0.01 * x[:, 0]  # sheared too
    assert model.terms[0].energy(x) == pytest.approx(
        membrane_total_energy(x, model.faces, model.dr_inv, model.area, model.tri_stretch,
                              model.tri_shear), rel=1e-10)
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}}, "solver": {"method": "vbd"},
                       "material": {"membrane_model": "edge"}})
    assert not any(isinstance(t, EdgeMembrane) for t in build_model(cfg).terms)


def curved_disc(tmp_path, flip=0):
    """A PLY without uv resting curved (a paraboloid cap), ``flip`` triangles turned the other
    way round: (model, rest positions)."""
    from clothtool.io.ply import write_ply

    uv, faces = disc(0.03, 0.008, "delaunay", seed=5)
    faces = faces.copy()
    faces[:flip] = faces[:flip, ::-1]
    x0 = np.concatenate([uv, 8.0 * (uv ** 2).sum(axis=1, keepdims=True)], axis=1)
    write_ply(tmp_path / "cap.ply", x0, faces)
    model = build_model(load_config({"mesh": {"ply": str(tmp_path / "cap.ply")},
                                     "material": {"membrane_model": "edge"}}))
    return model, x0


@pytest.mark.parametrize("flip", [0, 9])
def test_a_mesh_resting_curved_without_uv_unfolds_each_edge(tmp_path, flip):
    """No pattern: each edge's second triangle is unfolded onto the first. At rest and turned
    rigidly nothing is stored; the cap stretched 1 % about its centre stores the triangles'
    energy and feels their forces (an isotropic stretch reads alike in every frame); its
    triangles turned the other way round (mirrored frames) change nothing."""
    model, x0 = curved_disc(tmp_path, flip)
    term = next(t for t in model.terms if isinstance(t, EdgeMembrane))
    rot = random_rotation(np.random.default_rng(2))
    assert term.energy(x0) == pytest.approx(0.0, abs=1e-20)
    assert term.energy(x0 @ rot.T + 0.1) == pytest.approx(0.0, abs=1e-20)
    grown = 1.01 * x0
    triangles = membrane_total_energy(grown, model.faces, model.dr_inv, model.area,
                                      model.tri_stretch, model.tri_shear)
    assert term.energy(grown) == pytest.approx(triangles, rel=1e-9)
    assert triangles == pytest.approx(0.5 * 5000.0 * 2 * 0.01 ** 2 * model.area.sum(), rel=1e-9)
    grad, expected = np.zeros_like(x0), np.zeros_like(x0)
    term.bind(model.pattern)
    term.assemble(grown, grad, model.pattern.zeros())
    membrane_gradient(grown, model.faces, model.dr_inv, model.area, model.tri_stretch,
                      model.tri_shear, expected)
    assert np.abs(grad - expected).max() <= 1e-9 * np.abs(expected).max()


def test_unfolded_frames_lay_each_edges_triangles_side_by_side():
    """Unfolded, an edge's two triangles share the edge's vector and lie on its two sides."""
    from clothtool.geometry import tangent_edge_matrices

    uv, faces = disc(0.03, 0.008, "delaunay", seed=5)
    x0 = np.concatenate([uv, 8.0 * (uv ** 2).sum(axis=1, keepdims=True)], axis=1)
    dr, _ = tangent_edge_matrices(x0, faces, 1e-12)
    cells = edge_cells(faces)
    q = unfolded_frames(faces, dr, cells)
    p = np.zeros((len(faces), 3, 2))
    p[:, 1], p[:, 2] = dr[:, :, 0], dr[:, :, 1]
    turned = np.einsum("tkij,tcj->tkci", q, p)  # every triangle in each of its edges' frames
    flat_cells = cells.ravel()
    for c in np.unique(flat_cells):
        entries = np.flatnonzero(flat_cells == c)
        if len(entries) < 2:
            continue
        (t1, k1), (t2, k2) = divmod(entries[0], 3), divmod(entries[1], 3)
        a, b = turned[t1, k1], turned[t2, k2]
        i1, j1 = k1, (k1 + 1) % 3
        j2 = list(faces[t2]).index(faces[t1, i1])
        i2 = list(faces[t2]).index(faces[t1, j1])
        assert np.allclose(a[j1] - a[i1], b[i2] - b[j2], atol=1e-14)
        e = a[j1] - a[i1]
        side = [e[0] * (pt - a[i1])[1] - e[1] * (pt - a[i1])[0]
                for pt in (a[3 - i1 - j1], b[3 - i2 - j2] - b[j2] + a[i1])]
        assert side[0] * side[1] < 0.0


def test_a_garments_panels_have_a_cell_each_at_their_seam(tmp_path):
    """Two panels welded along a seam, each with its own pattern (one turned a quarter): a
    seam edge has a cell in each panel; stretching the left panel 1 % along its warp stores
    the triangle membrane's energy, and folding the garment along the seam stores nothing."""
    from garment_meshes import stretched_and_folded, welded_pair_model

    model, seam = welded_pair_model(tmp_path, {"membrane_model": "edge"})
    term = next(t for t in model.terms if isinstance(t, EdgeMembrane))
    cells = term.cell_area
    edges = np.unique(np.sort(np.stack([model.faces, np.roll(model.faces, -1, axis=1)], axis=2),
                              axis=2).reshape(-1, 2), axis=0)
    assert len(cells) == len(edges) + len(seam) - 1
    assert cells.sum() == pytest.approx(model.area.sum(), rel=1e-12)
    _, stretched, folded = stretched_and_folded(model.mesh.positions)
    assert term.energy(folded) == pytest.approx(0.0, abs=1e-18)
    assert term.energy(stretched) == pytest.approx(
        membrane_total_energy(stretched, model.faces, model.dr_inv, model.area,
                              model.tri_stretch, model.tri_shear), rel=1e-6)


def test_a_pinned_sheet_hangs_to_rest(tmp_path):
    """A sheet hung by two corners, simulated with the edge membrane: pins held, stretch
    bounded, the solve converging (the same scene as the triangle membrane's)."""
    from clothtool.sim.model.methods import make_integrator

    for model_name in ("triangle", "edge"):
        cfg = load_config({"mesh": {"grid": {"nx": 8, "ny": 8, "width": 0.3, "height": 0.3,
                                             "plane": "xz"}},
                           "material": {"membrane_model": model_name},
                           "scene": {"gravity": [0, 0, -9.81], "pins": ["top_corners"]}})
        model = build_model(cfg)
        integrator = make_integrator(model, cfg.solver, 1.0 / 30)
        state = model.initial_state()
        for _ in range(15):
            integrator.step(state)
        assert np.array_equal(state.x[model.pinned], model.mesh.positions[model.pinned])
        assert integrator.max_stretch(state) < 1.05
        assert np.isfinite(state.x).all() and state.x[:, 2].min() < -0.05


@random_sheets(4)
def test_with_its_exact_remainder_the_hessian_is_the_finite_differences(seed, kind):
    """The assembled unprojected Hessian plus :meth:`EdgeMembrane.exact_remainder` (the flap
    pairs' Gauss–Newton coupling less the majorant) is the central differences of ∇W; the
    remainder is negative semidefinite (Jensen, cell by cell)."""
    uv, faces, dr_inv, area, stretch, shear = sheet(kind, stretch=(5000.0, 3000.0, 0.9, 1.0))
    system = edge_system(uv, faces, dr_inv, area, stretch, shear)
    rng = np.random.default_rng(seed)
    x = flat(uv) + 0.002 * rng.standard_normal((len(uv), 3))
    k = system.dense(system.assemble(x, False)[2])
    remainder = system.term.exact_remainder(x).toarray()
    exact = np.zeros_like(k)
    for i in range(x.size):
        d = np.zeros(x.size)
        d[i] = 1e-7
        exact[:, i] = (system.assemble(x + d.reshape(x.shape), False)[1]
                       - system.assemble(x - d.reshape(x.shape), False)[1]).ravel() / 2e-7
    assert np.abs(k + remainder - exact).max() <= 1e-6 * np.abs(exact).max()
    assert np.linalg.eigvalsh(remainder).max() <= 1e-9 * np.abs(remainder).max()
    assert np.abs(remainder).max() > 1e-3 * np.abs(exact).max()
