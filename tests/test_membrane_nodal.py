"""The node-based smoothed membrane (material.membrane_model: nodal)."""

import numpy as np
import pytest
from conftest import random_rotation
from smoothed_membranes import flat, sheet

from clothtool.sim.model.config import load_config
from clothtool.sim.model.builder import build_model
from clothtool.sim.energies.membrane import membrane_total_energy
from clothtool.sim.energies.membrane_nodal import nodal_operator
from clothtool.sim.energies.terms import NodalMembrane
from clothtool.sim.textile import disc


def test_cells_share_out_the_area_and_stencils_are_the_rings():
    uv, faces, dr_inv, area, stretch, shear = sheet("delaunay")
    (ptr, index, tri_ptr, tri, weight, local, cell, mat_stretch,
     mat_shear) = nodal_operator(faces, dr_inv, area, len(uv), stretch, shear)
    assert cell.sum() == pytest.approx(area.sum(), rel=1e-14)
    for v in range(len(uv)):
        around = np.flatnonzero(np.any(faces == v, axis=1))
        assert np.array_equal(index[ptr[v]:ptr[v + 1]], np.unique(faces[around]))
        assert np.array_equal(np.sort(tri[tri_ptr[v]:tri_ptr[v + 1]]), around)
        assert weight[tri_ptr[v]:tri_ptr[v + 1]].sum() == pytest.approx(1.0, rel=1e-14)
        stencil = index[ptr[v]:ptr[v + 1]]
        assert np.array_equal(stencil[local[tri_ptr[v]:tri_ptr[v + 1]]],
                              faces[tri[tri_ptr[v]:tri_ptr[v + 1]]])
    assert np.allclose(mat_stretch, stretch[0]) and np.allclose(mat_shear, 50.0)


def test_the_config_key_selects_the_term(tmp_path):
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}},
                       "material": {"membrane_model": "nodal"}})
    model = build_model(cfg)
    assert isinstance(model.terms[0], NodalMembrane)  # the stretch; the shear per triangle
    assert np.all(model.terms[0].operator[-1] == 0.0) and np.all(model.terms[1].stretch[:, :2] == 0)
    x = model.mesh.positions * np.array([1.01, 1.0, 1.0])
    x[:, 1] += 0.01 * x[:, 0]  # sheared too
    assert model.terms[0].energy(x) + model.terms[1].energy(x) == pytest.approx(
        membrane_total_energy(x, model.faces, model.dr_inv, model.area, model.tri_stretch,
                              model.tri_shear), rel=1e-10)


def test_a_mesh_resting_curved_without_uv_keeps_the_triangle_membrane(tmp_path):
    """Its triangles' frames are each their own (no pattern): no cell can average them."""
    from clothtool.io.ply import write_ply
    from clothtool.sim.energies.terms import Membrane

    uv, faces = disc(0.03, 0.01, "grid")
    path = tmp_path / "curved.ply"
    write_ply(path, np.concatenate([uv, 10 * (uv[:, :1] ** 2)], axis=1), faces)
    cfg = load_config({"mesh": {"ply": str(path)}, "material": {"membrane_model": "nodal"}})
    terms = build_model(cfg).terms
    assert not any(isinstance(t, NodalMembrane) for t in terms)
    assert next(t for t in terms if isinstance(t, Membrane)).stretch[0, 0] == 5000.0


def test_a_flat_mesh_without_uv_is_its_own_pattern(tmp_path):
    """A PLY without uv that rests flat (tilted out of every coordinate plane): the nodal
    membrane on its own plane's coordinates; stretched by 1 % along any direction of that
    plane it stores ½k(0.01)² per area (patch test), nothing when turned rigidly."""
    from clothtool.io.ply import write_ply

    uv, faces = disc(0.03, 0.01, "delaunay", seed=4)
    turn = random_rotation(np.random.default_rng(0))
    x0 = flat(uv) @ turn.T + [0.3, -0.2, 0.1]
    write_ply(tmp_path / "tilted.ply", x0, faces)
    model = build_model(load_config({"mesh": {"ply": str(tmp_path / "tilted.ply")},
                                     "material": {"membrane_model": "nodal", "shear": 0.0}}))
    nodal = next(t for t in model.terms if isinstance(t, NodalMembrane))
    assert nodal.energy(x0 @ random_rotation(np.random.default_rng(1)).T) == pytest.approx(
        0.0, abs=1e-20)
    d = turn[:, 0] * np.cos(0.7) + turn[:, 1] * np.sin(0.7)  # a direction in the plane
    x = x0 + 0.01 * np.outer((x0 - x0.mean(axis=0)) @ d, d)
    # its warp and weft (the plane's principal axes) lengthen by √(1 + 0.0201 c²) − 1, c the
    # cosine of each with d: whichever they are, the two add up to the same energy
    energy = nodal.energy(x) / model.area.sum()
    c = np.abs(np.linalg.svd(x0 - x0.mean(axis=0), full_matrices=False)[2][:2] @ d)
    expected = 0.5 * 5000.0 * sum((np.sqrt(1 + 0.0201 * ci * ci) - 1) ** 2 for ci in c)
    assert energy == pytest.approx(expected, rel=1e-6)


def test_a_garments_panels_have_a_cell_each_at_their_seam(tmp_path):
    """Two panels welded along a seam, each with its own pattern (one turned a quarter): a
    seam vertex has a cell in each panel, so each panel's metric is its own; stretching both
    panels 1 % along their own warp stores the triangle membrane's energy (an affine map of
    each pattern), and folding the garment along the seam stores nothing."""
    from garment_meshes import stretched_and_folded, welded_pair_model

    model, seam = welded_pair_model(tmp_path, {"membrane_model": "nodal"})
    nodal = next(t for t in model.terms if isinstance(t, NodalMembrane))
    cells = nodal.operator[6]  # the cell areas
    assert len(cells) == model.n_vertices + len(seam)
    assert cells.sum() == pytest.approx(model.area.sum(), rel=1e-12)
    # the left panel (x < 0) stretched 1 % along its warp, x; the right one as it rests
    left, stretched, folded = stretched_and_folded(model.mesh.positions)
    assert nodal.energy(folded) == pytest.approx(0.0, abs=1e-18)
    left_faces = np.all(left[model.faces] | np.isin(model.faces, seam), axis=1)
    expected = 0.5 * 5000.0 * 0.01 ** 2 * model.area[left_faces].sum()
    assert nodal.energy(stretched) == pytest.approx(expected, rel=1e-6)


def test_other_methods_than_implicit_keep_the_triangle_membrane():
    cfg = load_config({"mesh": {"grid": {"nx": 4, "ny": 4}}, "solver": {"method": "vbd"},
                       "material": {"membrane_model": "nodal"}})
    assert not any(isinstance(t, NodalMembrane) for t in build_model(cfg).terms)
