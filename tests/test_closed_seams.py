"""Garments whose seams are closed in the file (each panel with its own vertices along a seam,
at the same positions, as pattern software exports a sewn garment): the coincident boundary
vertices of different panels are welded at the start; the run crosses nothing (ours and
ipctk, the welded seam merged) and the seam stays closed; a crossing start is still refused,
and a weld tolerance that would weld a panel to itself is a one-line error."""

import subprocess
import sys

import numpy as np
import pytest

import clothtool
from clothtool.errors import InputError
from clothtool.io.ply import read_ply
from clothtool.sim.model.builder import build_model
from clothtool.sim.model.config import load_config

from garment_meshes import apart_pair, write_obj


def closed_obj(tmp_path, fold=False):
    """Two 0.2 × 0.3 m panels side by side in the xy plane, their facing edges' 7 vertices at
    the same positions; ``fold``: the right panel also turned through the left one."""
    x, lf, rf, luv, ruv, a, b = apart_pair(gap=0.0)
    if fold:
        n = len(x) // 2
        x[n:] = np.column_stack([np.full(n, -0.1), x[n:, 1], x[n:, 0] - 0.1])
        x[b] = x[a]
    return write_obj(tmp_path / "closed.obj", x, [("left", lf, luv), ("right", rf, ruv)]), a, b, x


def hanging(path, x, frames=15, **mesh):
    top = np.flatnonzero(np.isclose(x[:, 1], x[:, 1].max()) & (np.abs(x[:, 0]) > 0.15))
    return {"mesh": {"obj": str(path), **mesh}, "material": {"damping": 0.05},
            "scene": {"pins": [int(v) for v in top], "gravity": [0, -9.81, 0.5],
                      "self_collision": {"thickness": 0.002}},
            "time": {"fps": 30, "frames": frames}, "output": {"format": ["ply", "obj"]}}


def crossing_frames(out, frames, a, b, x0):
    """(frames crossing by ours, by ipctk), the welded pairs merged; asserts every frame keeps
    the file's vertices with the seam a–b closed (0 m)."""
    from clothtool.contact.broadphase import mesh_edges
    from clothtool.contact.intersect import has_intersections

    ipctk = pytest.importorskip("ipctk")
    merge = np.arange(len(x0))
    merge[b] = a
    crossings = ipc = 0
    for k in range(frames + 1):
        frame = read_ply(out / f"frame_{k:05d}.ply")
        x = frame.vertices
        assert x.shape == x0.shape  # the file's vertices, the welded pairs at one position
        assert np.array_equal(x[a], x[b])  # the seam stays closed
        f = merge[frame.faces]
        crossings += bool(has_intersections(x, f, np.zeros(len(x), bool)))
        ipc += bool(ipctk.has_intersections(ipctk.CollisionMesh(x, mesh_edges(f), f), x))
    return crossings, ipc


def test_a_garment_sewn_in_the_file_runs_closed_and_crosses_nothing(tmp_path):
    path, a, b, x0 = closed_obj(tmp_path)
    out = tmp_path / "out"
    lines = []
    result = clothtool.simulate(hanging(path, x0), output_dir=out, progress=False,
                                log=lines.append)
    assert lines == result.notes and len(lines) == 1
    assert "welded the closed seam left–right at the start: 7 vertex pairs, 0.3 m" in lines[0]
    assert crossing_frames(out, 15, a, b, x0) == (0, 0)
    x = read_ply(out / "frame_00015.ply").vertices
    assert np.ptp(x[:, 2]) > 0.01  # it moved out of its plane: the seam bends


def test_a_seam_listed_and_closed_in_the_file_is_satisfied(tmp_path):
    """One config for the sewing run and the exported garment: the seam listed in mesh.seams
    is closed in the file, so the log says so (one line per seam) and the run goes on."""
    path, a, b, x0 = closed_obj(tmp_path)
    out = tmp_path / "out"
    seams = [{"a": a.tolist(), "b": b.tolist()}]
    result = clothtool.simulate(hanging(path, x0, seams=seams), output_dir=out, progress=False)
    assert len(result.notes) == 2
    assert "welded the closed seam left–right at the start" in result.notes[0]
    assert result.notes[1] == ("mesh.seams[0]: already closed in the file, all 7 vertex pairs "
                               "welded at the start: nothing to sew")
    assert crossing_frames(out, 15, a, b, x0) == (0, 0)


def test_a_seam_closed_at_its_ends_sews_the_rest(tmp_path):
    """Only the seam's end pairs coincide in the file (its middle 4 mm open): those two are
    welded at the start, the other five sewn, and the seam closes."""
    x, lf, rf, luv, ruv, a, b = apart_pair(gap=0.0)
    x[b[1:-1], 0] += 0.004
    path = write_obj(tmp_path / "ends.obj", x, [("left", lf, luv), ("right", rf, ruv)])
    cfg = hanging(path, x, frames=20, seams=[{"a": a.tolist(), "b": b.tolist()}],
                  sewing={"time": 0.5})
    result = clothtool.simulate(cfg, output_dir=tmp_path / "out", progress=False)
    assert "mesh.seams[0]: already closed in the file, 2 of its 7 vertex pairs welded at the " \
           "start, the others sewn" in result.notes
    assert any("sewn and welded at frame" in line for line in result.notes)
    last = read_ply(tmp_path / "out" / "frame_00020.ply").vertices
    assert np.abs(last[a] - last[b]).max() == 0.0


def test_weld_closed_off_refuses_the_overlap(tmp_path):
    path, a, b, x0 = closed_obj(tmp_path)
    cfg = hanging(path, x0, weld_closed=False, seams=[{"a": a.tolist(), "b": b.tolist()}])
    with pytest.raises(InputError, match=r"closed\.obj: the panels overlap at the start"):
        build_model(load_config(cfg))
    model = build_model(load_config(hanging(path, x0)))
    assert model.n_vertices == len(x0) - len(a)
    assert np.array_equal(model.file_vertex[a], model.file_vertex[b])


def test_a_crossing_start_is_still_refused_naming_the_pair(tmp_path):
    path, a, b, x0 = closed_obj(tmp_path, fold=True)
    with pytest.raises(InputError, match=r"closed\.obj: the panels overlap at the start: "
                                         r"triangle \d+ crosses triangle \d+"):
        build_model(load_config(hanging(path, x0)))


def test_a_tolerance_that_welds_a_panel_to_itself_is_one_line_and_writes_nothing(tmp_path):
    path, a, b, x0 = closed_obj(tmp_path)
    out = tmp_path / "out"
    config = tmp_path / "scene.yaml"
    import yaml

    config.write_text(yaml.safe_dump(hanging(path, x0, weld_tolerance=0.06)))
    proc = subprocess.run([sys.executable, "-c", "from clothtool.cli import run; run()",
                           "simulate", str(config), "-o", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1
    assert "mesh.weld_tolerance: 0.06 m would weld vertices" in proc.stderr
    assert "of one panel (left), 0.05 m apart" in proc.stderr
    assert not out.exists()


def test_the_rim_is_shown_apart_without_the_kd_tree_only_when_the_kd_tree_finds_no_pair():
    """weld_closed_seams skips scipy's KD-tree when a sweep along the widest axis shows no two
    rim vertices within the tolerance: on random point sets, flat ones and ones with a near
    pair planted, that never happens where the KD-tree finds a pair, and a single sheet's
    rim (no pair) is shown apart; a pair just inside the tolerance is not."""
    from scipy.spatial import cKDTree

    from clothtool.sim.model.seams import _apart

    rng = np.random.default_rng(0)
    shown = 0
    for _ in range(1000):
        n = int(rng.integers(2, 60))
        pts = rng.normal(size=(n, 3)) * rng.choice([1e-3, 1.0, 100.0])
        if rng.random() < 0.5:
            pts[:, rng.integers(3)] = rng.normal()
        if rng.random() < 0.3:
            pts[rng.integers(n)] = pts[rng.integers(n)] + 1e-5 * rng.normal(size=3)
        tol = float(rng.choice([1e-6, 1e-4, 1e-2, 0.5]))
        apart = _apart(pts, tol)
        assert not (apart and len(cKDTree(pts).query_pairs(tol)))
        shown += apart
    assert shown > 300
    u, v = np.meshgrid(np.linspace(0, 1, 33), np.linspace(0, 1, 33))
    sheet = np.column_stack([u.ravel(), np.zeros(u.size), v.ravel()])
    rim = sheet[(u.ravel() % 1 == 0) | (v.ravel() % 1 == 0)]
    assert _apart(rim, 1e-4)
    assert not _apart(np.array([[0.0, 0.0, 0.0], [0.0, 1e-4 * (1 - 1e-9), 0.0]]), 1e-4)
