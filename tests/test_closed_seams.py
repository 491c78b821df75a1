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


def test_a_garment_sewn_in_the_file_runs_closed_and_crosses_nothing(tmp_path):
    from clothtool.contact.broadphase import mesh_edges
    from clothtool.contact.intersect import has_intersections

    ipctk = pytest.importorskip("ipctk")
    path, a, b, x0 = closed_obj(tmp_path)
    out = tmp_path / "out"
    lines = []
    result = clothtool.simulate(hanging(path, x0), output_dir=out, progress=False,
                                log=lines.append)
    assert lines == result.notes and len(lines) == 1
    assert "welded the closed seam left–right at the start: 7 vertex pairs, 0.3 m" in lines[0]
    merge = np.arange(len(x0))
    merge[b] = a
    crossings = ipc = 0
    for k in range(16):
        frame = read_ply(out / f"frame_{k:05d}.ply")
        x = frame.vertices
        assert x.shape == x0.shape  # the file's vertices, the welded pairs at one position
        assert np.array_equal(x[a], x[b])  # the seam stays closed
        f = merge[frame.faces]
        crossings += bool(has_intersections(x, f, np.zeros(len(x), bool)))
        ipc += bool(ipctk.has_intersections(ipctk.CollisionMesh(x, mesh_edges(f), f), x))
    assert crossings == 0 and ipc == 0
    assert np.ptp(x[:, 2]) > 0.01  # it moved out of its plane: the seam bends


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
