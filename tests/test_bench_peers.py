"""The peers benchmark (``benchmarks/bench_peers.py``): its table, its skip path without the
peers, its geometry, and, where bpy is installed in ``.venv-bpy`` (or $BPY_PYTHON), Blender's
cloth on a tiny sheet through ``benchmarks/peer_blender.py``."""

import csv

import numpy as np
import pytest

from benchmarks import bench_peers
from benchmarks.bench_peers import (BLENDER_INSTALL, COLUMNS, HERE, crossing_frames, ratios,
                                    run_peer, sag, scene, scene_rows, uv_sphere, write_tables)


def test_the_table_names_a_missing_peer_with_its_install_line(tmp_path):
    rows = ratios([
        {"scene": "sheet", "simulator": "clothtool (defaults)", "CPU s": 2.0},
        {"scene": "sheet", "simulator": "Blender cloth (defaults)", "CPU s": 5.0},
        {"scene": "twist", "simulator": "clothtool (sample_data/twist.yaml)", "CPU s": 4.0},
        {"scene": "twist", "simulator": "NVIDIA Newton VBD",
         "note": "not installed: pip install x"},
    ])
    assert rows[0]["× ours"] == 1.0 and rows[1]["× ours"] == 2.5
    assert "× ours" not in rows[3]
    text = write_tables(rows, tmp_path)
    assert (tmp_path / "peers.md").read_text() == text
    assert "| twist | NVIDIA Newton VBD |" in text and "not installed: pip install x" in text
    with open(tmp_path / "peers.csv") as fh:
        read = list(csv.DictReader(fh))
    assert list(read[0]) == COLUMNS
    assert [r["simulator"] for r in read] == [r["simulator"] for r in rows]
    assert float(read[1]["× ours"]) == 2.5


def test_a_peer_not_installed_is_none(monkeypatch, tmp_path):
    monkeypatch.setenv("BPY_PYTHON", str(tmp_path / "no" / "python"))
    assert bench_peers.peer_python("BPY_PYTHON", ".venv-bpy") is None


def test_without_blender_the_sheet_gives_ours_its_converged_run_and_the_skip_row(tmp_path):
    rows = scene_rows("sheet", tmp_path, None, n=5, frames=2)
    assert [r["simulator"] for r in rows] == [
        "clothtool (defaults)", "Blender cloth", "clothtool, BDF2 ×4 solved tightly (converged)",
        "clothtool, BDF2 ×2 solved tightly"]
    assert rows[1]["note"] == f"not installed: {BLENDER_INSTALL}"
    assert rows[0]["crossing frames (ipctk)"] == "0/3"
    assert rows[0]["steps/frame"] == 1.0 and rows[0]["CPU s"] > 0.0
    # two frames of free fall from rest: the sheet sags, and the converged run against itself is 0
    assert 0.0 < rows[0]["sag m"] < 0.5 * 9.81 * (2 / 30) ** 2 * 1.5
    assert rows[2]["sag − converged mm"] == 0.0 and rows[2]["max distance to converged mm"] == 0.0


def test_scene_meshes_are_ours_vertex_for_vertex():
    """The peer's vertices and pins are our grid's (plane xy, vertex j·n + i, top corners)."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config

    for name in ("sheet", "drop"):
        config, arrays = scene(name, n=6, frames=1)
        model = build_model(load_config(config))
        np.testing.assert_allclose(arrays["vertices"], model.mesh.positions, atol=1e-12)
        np.testing.assert_array_equal(arrays["faces"], model.faces)
        np.testing.assert_array_equal(np.sort(model.pinned), arrays["pins"])
        quads = arrays["quads"]
        assert len(quads) == 25 and set(np.unique(quads)) == set(range(36))
    assert scene("sheet", n=6, frames=1)[1]["pins"].tolist() == [30, 35]


def test_the_uv_sphere_is_closed_and_on_the_sphere():
    centre = np.array([0.1, -0.2, 0.3])
    vertices, faces = uv_sphere(centre, 0.25, segments=8, rings=6)
    assert len(vertices) == 8 * 5 + 2 and len(faces) == 2 * 8 * 5
    np.testing.assert_allclose(np.linalg.norm(vertices - centre, axis=1), 0.25, rtol=1e-14)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert np.all(count == 2)  # closed, every edge between two triangles
    # V − E + F = 2, and every triangle faces outwards (its normal along the centre's ray)
    assert len(vertices) - len(count) + len(faces) == 2
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3 - centre) > 0)


def test_crossing_frames_counts_the_frames_with_crossing_triangles():
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    apart = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]], float)
    through = apart.copy()
    through[3:] = [[0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.8, 0.8, 0.0]]  # pierces the first
    assert crossing_frames(np.stack([apart, through, apart]), faces) == 1
    sphere = uv_sphere(np.zeros(3), 0.1, segments=8, rings=6)
    assert crossing_frames(apart[None], faces, sphere) == 1  # the first triangle cuts the sphere
    assert crossing_frames(apart[None] + 1.0, faces, sphere) == 0


def test_sag_is_the_pins_height_over_the_mean_height():
    x = np.zeros((2, 4, 3))
    x[-1, :, 2] = [0.0, -1.0, -2.0, 0.0]
    assert sag(x, np.array([0, 3])) == 0.75


def test_blender_holds_a_tiny_sheet_at_two_corners(tmp_path):
    python = bench_peers.peer_python("BPY_PYTHON", ".venv-bpy")
    if python is None:
        pytest.skip(f"needs Blender 5 as the bpy module: {BLENDER_INSTALL} (or set BPY_PYTHON)")
    _, arrays = scene("sheet", n=6, frames=4)
    out = run_peer(python, HERE / "peer_blender.py", arrays, tmp_path)
    x = out["positions"]
    assert x.shape == (5, 36, 3) and int(out["quality"]) == 5 and float(out["cpu"]) > 0.0
    np.testing.assert_allclose(x[0], arrays["vertices"], atol=1e-6)  # frame 1: the rest state
    np.testing.assert_allclose(x[:, arrays["pins"]], x[:1, arrays["pins"]].repeat(5, 0), atol=1e-6)
    # the free corners fall, and no faster than free fall over the 4 frames (float32 positions)
    free = np.setdiff1d(np.arange(36), arrays["pins"])
    drop = x[0, free, 2] - x[-1, free, 2]
    assert np.all(drop[-1:] > 0.0) and drop.max() <= 0.5 * 9.81 * (4 / 30) ** 2 + 1e-6
