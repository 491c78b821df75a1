"""Results opened by real ParaView: ``pvpython`` (a subprocess) opens the XDMF of each kind of
result with ``OpenDataFile`` (ParaView's choice of reader) and with each of its XDMF readers,
and every time step's points, cells and arrays are compared with the HDF5 file; one step is
rendered to a PNG that must not be blank.

Needs ParaView's ``pvpython`` on PATH (or in $PVPYTHON) and, to render without a display,
``xvfb-run``; without them the test is skipped. Debian/Ubuntu: ``apt-get install
--no-install-recommends paraview python3-paraview xvfb xauth``.
"""

import json
import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest
from conftest import grid, tet_grid, write_tet_file

import clothtool
from clothtool.io.ply import write_ply
from clothtool.results.merge import merge_results

FRAMES = 5
INSTALL = ("needs ParaView's pvpython{} (Debian/Ubuntu: apt-get install --no-install-recommends "
           "paraview python3-paraview xvfb xauth; or set PVPYTHON to pvpython's path)")

# Run by pvpython: argv = a JSON file of jobs [{"xdmf", "reader", "out"}] and a PNG path (or -).
# Writes, per job, the arrays of every step to job["out"] (.npz) and prints one JSON line.
PROBE = r'''
import json, sys
import numpy as np
from paraview import servermanager, simple
from paraview.vtk.util.numpy_support import vtk_to_numpy

jobs, png = json.load(open(sys.argv[1])), sys.argv[2] if sys.argv[2] != "-" else None
READERS = {"XDMFReader": "FileNames", "Xdmf3ReaderS": "FileName", "Xdmf3ReaderT": "FileName"}
results = []
for job in jobs:
    if job["reader"] == "OpenDataFile":
        source = simple.OpenDataFile(job["xdmf"])
    else:
        source = getattr(simple, job["reader"])(**{READERS[job["reader"]]: [job["xdmf"]]})
    times = [float(t) for t in source.TimestepValues]
    steps, saved = [], {}
    for k, t in enumerate(times):
        source.UpdatePipeline(t)
        data = servermanager.Fetch(source)
        blocks = 0
        while data.IsA("vtkMultiBlockDataSet"):
            blocks += 1
            data = data.GetBlock(0)
        step = {"time": t, "class": data.GetClassName(), "blocks": blocks,
                "points": data.GetNumberOfPoints(), "cells": data.GetNumberOfCells(),
                "cell_types": sorted({data.GetCellType(i) for i in range(data.GetNumberOfCells())}),
                "cell": {}, "point": {}}
        if data.GetNumberOfPoints():
            saved[f"{k}/points"] = vtk_to_numpy(data.GetPoints().GetData()).copy()
        if data.GetNumberOfCells():
            saved[f"{k}/connectivity"] = vtk_to_numpy(data.GetCells().GetConnectivityArray()).copy()
        for kind, arrays in (("cell", data.GetCellData()), ("point", data.GetPointData())):
            for i in range(arrays.GetNumberOfArrays()):
                array = arrays.GetArray(i)
                step[kind][array.GetName()] = array.GetNumberOfComponents()
                saved[f"{k}/{kind}/{array.GetName()}"] = vtk_to_numpy(array).copy()
        steps.append(step)
    np.savez(job["out"], **saved)
    results.append({"reader": source.GetXMLName(), "times": times, "steps": steps})
    if png and steps and steps[-1]["points"]:
        view = simple.CreateRenderView()
        view.ViewSize = [640, 480]
        view.OrientationAxesVisibility = 0
        view.ViewTime = times[-1]
        display = simple.Show(source, view)
        simple.ColorBy(display, ("CELLS", "area_ratio"))
        display.RescaleTransferFunctionToDataRange(True)
        simple.ResetCamera(view)
        simple.SaveScreenshot(png, view, ImageResolution=[640, 480])
        png = None
print("PROBE " + json.dumps({"version": servermanager.vtkSMProxyManager.GetParaViewSourceVersion(), "results": results}))
'''


def pvpython():
    """The command that runs a pvpython script: pvpython, under xvfb-run without a display
    (Debian's ParaView renders through X even offscreen)."""
    found = os.environ.get("PVPYTHON") or shutil.which("pvpython")
    if not found:
        pytest.skip(INSTALL.format(""))
    if os.environ.get("DISPLAY"):
        return [found, "--force-offscreen-rendering"]
    if not shutil.which("xvfb-run"):
        pytest.skip(INSTALL.format(" and, without a display, xvfb-run"))
    return ["xvfb-run", "--auto-servernum", found, "--force-offscreen-rendering"]


def run_paraview(tmp_path, jobs, png=None):
    """Run :data:`PROBE` on ``jobs`` [(xdmf, reader)], rendering the last step of the first
    one to ``png`` if given; returns (ParaView's version,
    [(result, arrays)] in the order of ``jobs``)."""
    script, spec = tmp_path / "probe.py", tmp_path / "jobs.json"
    script.write_text(PROBE)
    listed = [{"xdmf": str(x), "reader": r, "out": str(tmp_path / f"job{k}.npz")}
              for k, (x, r) in enumerate(jobs)]
    spec.write_text(json.dumps(listed))
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    proc = subprocess.run([*pvpython(), str(script), str(spec), str(png or "-")],
                          capture_output=True, text=True, timeout=600, env=env)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("PROBE ")]
    assert proc.returncode == 0 and lines, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = json.loads(lines[-1][len("PROBE "):])
    return out["version"], [(result, np.load(job["out"]))
                            for result, job in zip(out["results"], listed)]


def readers(tmp_path):
    """The XDMF readers of this ParaView (``OpenDataFile`` first: the one it picks)."""
    script = tmp_path / "readers.py"
    script.write_text("from paraview import simple\n"
                      "print('READERS', *[r for r in ('XDMFReader', 'Xdmf3ReaderS', "
                      "'Xdmf3ReaderT') if hasattr(simple, r)])\n")
    out = subprocess.run([*pvpython(), str(script)],
                         capture_output=True, text=True, timeout=300,
                         env=dict(os.environ, QT_QPA_PLATFORM="offscreen")).stdout
    line = [x for x in out.splitlines() if x.startswith("READERS")][-1]
    return ["OpenDataFile", *line.split()[1:]]


def make_sequence(folder):
    """A sheet stretched along x on its left half and bent up on its right half, more in each
    frame, with texture coordinates (for --reference uv)."""
    vertices, faces = grid(6, 4)
    folder.mkdir()
    for k in range(FRAMES):
        x = vertices.copy()
        left = x[:, 0] < 0.5
        x[left, 0] *= 1 + 0.05 * k
        x[~left, 2] = 0.1 * k * (vertices[~left, 0] - 0.5) ** 2
        write_ply(folder / f"f{k}.ply", x, faces,
                  vertex_properties={"s": vertices[:, 0], "t": vertices[:, 1]})


def make_results(tmp_path):
    """{kind: result path} of every kind of result."""
    seq = tmp_path / "seq"
    make_sequence(seq)
    run = clothtool.analyze_sequence
    kinds = {"2d": {}, "kabsch": {"kabsch": True, "reference": "first"},
             "uv": {"reference": "uv"}, "vertex_average": {"vertex_average": "stretch,area_ratio"},
             "slice": {"pairs": "1:3", "kabsch": True}}
    out = {}
    for kind, options in kinds.items():
        out[kind] = tmp_path / f"{kind}.h5"
        run(seq, out[kind], **options)
    for cut in ("0:2", "2:4"):
        run(seq, tmp_path / f"part{cut[0]}.h5", pairs=cut, vertex_average="stretch")
    out["merged"] = tmp_path / "merged.h5"
    merge_results([tmp_path / "part2.h5", tmp_path / "part0.h5"], out["merged"])
    x, tets = tet_grid(2, np.random.default_rng(0))
    (tmp_path / "tets").mkdir()
    for k in range(FRAMES):
        write_tet_file(tmp_path / "tets" / f"f{k}", x * [1 + 0.05 * k, 1, 1], tets, "vtu")
    out["tet"] = tmp_path / "tet.h5"
    run(tmp_path / "tets", out["tet"])
    return out


def check_against_hdf5(h5_path, result, arrays):
    """Every step of ``result`` (what ParaView loaded) equals the HDF5 result."""
    with h5py.File(h5_path) as f:
        pairs = f["pairs"][:]
        cells, group, corners, vtk_type = (("tets", "tet", 4, 10) if "tets" in f["mesh"]
                                           else ("faces", "face", 3, 5))  # VTK_TETRA, _TRIANGLE
        faces, positions = f[f"mesh/{cells}"][:], f["frame_vertices"]
        assert result["times"] == [float(d) for d in pairs[:, 1]]
        cell_fields = {name: f[group][name] for name in f[group]}
        point_fields = {name: f["vertex"][name] for name in f.get("vertex", {})
                        if f["vertex"][name].shape[1] == positions.shape[1]}
        assert cell_fields and len(result["steps"]) == len(pairs)
        for p, step in enumerate(result["steps"]):
            assert (step["points"], step["cells"]) == (positions.shape[1], len(faces))
            assert step["cell_types"] == [vtk_type]
            np.testing.assert_array_equal(arrays[f"{p}/points"], positions[pairs[p, 1]])
            np.testing.assert_array_equal(arrays[f"{p}/connectivity"].reshape(-1, corners), faces)
            for kind, fields in (("cell", cell_fields), ("point", point_fields)):
                assert set(step[kind]) == set(fields), (kind, p)
                for name, ds in fields.items():
                    stored = ds[p]
                    k = int(np.prod(stored.shape[1:], dtype=np.int64))
                    assert step[kind][name] == k, (kind, name)
                    got = arrays[f"{p}/{kind}/{name}"]
                    assert got.dtype == stored.dtype, name
                    np.testing.assert_array_equal(got.reshape(stored.shape), stored, err_msg=name)


def test_paraview_opens_every_kind_of_result(tmp_path, capsys):
    pvpython()
    results = make_results(tmp_path)
    names = readers(tmp_path)
    assert "XDMFReader" in names and "Xdmf3ReaderS" in names, names
    jobs = [(path.with_suffix(".xdmf"), reader) for path in results.values() for reader in names]
    png = tmp_path / "render.png"
    version, loaded = run_paraview(tmp_path, jobs, png)
    with capsys.disabled():
        print(f"\n{version}: {len(results)} kinds of result x readers {', '.join(names)}")
    assert version.startswith("paraview")
    chosen = set()
    for (xdmf, reader), (result, arrays) in zip(jobs, loaded):
        if reader == "OpenDataFile":
            chosen.add(result["reader"])
        else:
            assert result["reader"] == reader.replace("XDMFReader", "XdmfReader")
        check_against_hdf5(xdmf.with_suffix(".h5"), result, arrays)
    assert chosen and chosen <= {"Xdmf3ReaderS", "Xdmf3ReaderT", "XdmfReader"}
    plt = pytest.importorskip("matplotlib.pyplot")
    image = plt.imread(png)
    assert image.shape[:2] == (480, 640)
    rgb = image[..., :3]
    background = np.all(np.abs(rgb - rgb[0, 0]) < 0.02, axis=-1)  # the corner's colour
    assert 0.05 < 1 - background.mean() < 0.95  # the sheet covers part of the view
    assert rgb[~background].std(axis=0).max() > 0.05  # in several colours (area_ratio differs)
