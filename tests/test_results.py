"""Results people can use: XDMF for ParaView (loaded with VTK's own reader), the stored
summary and `clothtool info`, coloured PLY export, per-vertex averages."""

import csv
import io

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import grid

import clothtool
from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.io.ply import read_ply, write_ply
from clothtool.results.colormap import VIRIDIS_ANCHORS, colorize, viridis
from clothtool.results.merge import merge_results
from clothtool.analysis.output.summary import COLUMNS, PERCENTILES, TOL
from clothtool.vertex_average import VertexAverager

FRAMES = 6


def make_sheet_sequence(folder, frames=FRAMES, nx=7, ny=5):
    """A sheet stretched along x on its left half and bent up on its right half, more in each
    frame, so that the fields differ between triangles and pairs. Returns (positions, faces)."""
    vertices, faces = grid(nx, ny)
    folder.mkdir()
    out = []
    for k in range(frames):
        x = vertices.copy()
        left = x[:, 0] < 0.5
        x[left, 0] *= 1 + 0.05 * k
        x[~left, 0] = 0.5 * (1 + 0.05 * k) + (vertices[~left, 0] - 0.5) * (1 - 0.02 * k)
        x[~left, 2] = 0.1 * k * (vertices[~left, 0] - 0.5) ** 2
        write_ply(folder / f"f{k}.ply", x, faces,
                  vertex_properties={"s": vertices[:, 0], "t": vertices[:, 1]})
        out.append(x)
    return out, faces


@pytest.fixture
def sheet(tmp_path):
    xs, faces = make_sheet_sequence(tmp_path / "seq")
    return tmp_path, xs, faces


def read_xdmf(path):
    """(time steps, reader, captured messages) of VTK's XDMF reader on ``path``."""
    vtk = pytest.importorskip("vtk")
    log = vtk.vtkStringOutputWindow()
    vtk.vtkOutputWindow.SetInstance(log)
    reader = vtk.vtkXdmfReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    times = reader.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    return times, reader, log


def vtk_to_numpy(array):
    from vtk.util.numpy_support import vtk_to_numpy as convert

    return convert(array)


def arrays(data):
    return {data.GetArrayName(i): vtk_to_numpy(data.GetArray(i)) for i in range(data.GetNumberOfArrays())}


@pytest.mark.parametrize("reference", ["previous", "uv"])
def test_xdmf_loads_in_vtk(sheet, reference):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, reference=reference,
                               vertex_average="stretch,area_ratio")
    times, reader, log = read_xdmf(tmp / "out.xdmf")
    deformed = list(range(1, FRAMES)) if reference == "previous" else list(range(FRAMES))
    assert list(times) == deformed  # one time step per pair, at its deformed frame
    with h5py.File(out) as f:
        for p, t in enumerate(times):
            reader.UpdateTimeStep(t)
            grid_ = reader.GetOutputDataObject(0)
            assert grid_.GetNumberOfCells() == len(faces)
            assert grid_.GetNumberOfPoints() == len(xs[0])
            points = arrays(grid_.GetPointData())
            np.testing.assert_allclose(vtk_to_numpy(grid_.GetPoints().GetData()), xs[int(t)],
                                       rtol=1e-6, atol=1e-7)
            cells = arrays(grid_.GetCellData())
            assert set(cells) == set(f["face"])
            for name, values in cells.items():
                stored = f["face"][name][p]
                assert values.shape == (len(faces), *((int(np.prod(stored.shape[1:])),)
                                                      if stored.ndim > 1 else ()))
                np.testing.assert_array_equal(values.reshape(stored.shape), stored)
            assert set(points) == {"stretch_avg", "area_ratio_avg"}
            np.testing.assert_array_equal(points["stretch_avg"], f["vertex/stretch_avg"][p])
            connectivity = vtk_to_numpy(grid_.GetCells().GetConnectivityArray())
            np.testing.assert_array_equal(connectivity.reshape(-1, 3), faces)
    assert "ERR" not in log.GetOutput() and "rror" not in log.GetOutput()


def test_xdmf_only_requested_fields(sheet):
    tmp, xs, faces = sheet
    clothtool.analyze_sequence(tmp / "seq", tmp / "out.h5", fields="area_ratio", reference="first")
    times, reader, _ = read_xdmf(tmp / "out.xdmf")
    reader.UpdateTimeStep(times[-1])
    grid_ = reader.GetOutputDataObject(0)
    assert list(arrays(grid_.GetCellData())) == ["area_ratio"]
    assert grid_.GetPointData().GetNumberOfArrays() == 0


def test_failed_analysis_leaves_no_xdmf(sheet):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out)
    before = (out.read_bytes(), (tmp / "out.xdmf").read_bytes())
    write_ply(tmp / "seq" / "f3.ply", xs[3][:-1], faces[:4])  # wrong vertex count mid-sequence
    with pytest.raises(InputError, match="f3.ply"):
        clothtool.analyze_sequence(tmp / "seq", out)
    assert (out.read_bytes(), (tmp / "out.xdmf").read_bytes()) == before
    with pytest.raises(InputError):
        clothtool.analyze_sequence(tmp / "seq", tmp / "new.h5")
    assert sorted(p.name for p in tmp.iterdir()) == ["out.h5", "out.xdmf", "seq"]


def test_frame_vertices(sheet):
    tmp, xs, faces = sheet
    clothtool.analyze_sequence(tmp / "seq", tmp / "out.h5", dtype="float64")
    with h5py.File(tmp / "out.h5") as f:
        assert f["frame_vertices"].shape == (FRAMES, len(xs[0]), 3)
        assert f["frame_vertices"].chunks[0] == 1
        np.testing.assert_array_equal(f["frame_vertices"][:], np.array(xs))


def test_summary_matches_fields(sheet):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, reference="first", fields="stretch,area_ratio")
    with h5py.File(out) as f:
        s, j = f["face/stretch"][:].astype(float), f["face/area_ratio"][:].astype(float)
        summary = {name: f["summary"][name][:] for name in COLUMNS}
        assert list(f["summary"].attrs["columns"]) == list(COLUMNS)
        for q in PERCENTILES:  # the names of results before the area_ratio_* columns
            np.testing.assert_array_equal(f["summary"][f"J_p{q}"][:], summary[f"area_ratio_p{q}"])
    for p in range(FRAMES - 1):
        assert summary["pair"][p] == p and summary["deformed"][p] == p + 1
        for k, q in enumerate(PERCENTILES):
            assert summary[f"lambda1_p{q}"][p] == pytest.approx(np.percentile(s[p, :, 0], q))
            assert summary[f"lambda2_p{q}"][p] == pytest.approx(np.percentile(s[p, :, 1], q))
            assert summary[f"area_ratio_p{q}"][p] == pytest.approx(np.percentile(j[p], q))
        assert summary["compressed"][p] == pytest.approx(np.mean(s[p, :, 1] < 1 - TOL))
        assert summary["stretched"][p] == pytest.approx(np.mean(s[p, :, 0] > 1 + TOL))
    # left half stretched (λ1 = 1 + 0.05k), right half compressed along x: both kinds present
    assert 0.3 < summary["stretched"][-1] < 1 and 0.3 < summary["compressed"][-1] < 1
    assert summary["flagged"].sum() == 0


def test_summary_counts_flags(tmp_path):
    vertices, faces = grid(4, 3)
    (tmp_path / "seq").mkdir()
    write_ply(tmp_path / "seq" / "a.ply", vertices, faces)
    squashed = vertices.copy()
    squashed[faces[0]] = squashed[faces[0][0]]  # triangle 0 collapses to a point
    write_ply(tmp_path / "seq" / "b.ply", squashed, faces)
    clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "out.h5", fields="F")
    with h5py.File(tmp_path / "out.h5") as f:
        assert "stretch" not in f["face"]  # the summary is computed even when not stored
        flagged = f["summary/flagged"][0]
        assert flagged == f["summary/deformed_degenerate"][0] >= 1
        assert np.isfinite(f["summary/lambda1_p50"][0])


def test_info_and_csv(sheet):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out)
    runner = CliRunner()
    result = runner.invoke(main, ["info", str(out)])
    assert result.exit_code == 0, result.output
    assert "reference: previous" in result.output and f"frames:    {FRAMES}" in result.output
    assert f"pairs:     {FRAMES - 1} (all)" in result.output
    result = runner.invoke(main, ["info", str(out), "--csv"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO(result.output)))
    assert len(rows) == FRAMES - 1 and list(rows[0]) == list(COLUMNS)
    with h5py.File(out) as f:
        for name in COLUMNS:
            np.testing.assert_array_equal([float(r[name]) for r in rows], f["summary"][name][:])
    result = runner.invoke(main, ["info", str(tmp / "seq" / "f0.ply")])
    assert result.exit_code == 2 and "f0.ply: not an HDF5 file" in result.output


def test_colormap_matches_matplotlib():
    cm = pytest.importorskip("matplotlib").colormaps["viridis"]
    t = np.linspace(0, 1, 256)
    assert np.abs(viridis(t) - cm(t)[:, :3]).max() < 6 / 255
    rgb = colorize(np.array([0.0, 2.0, np.nan, -5.0, 9.0]), 0.0, 2.0)
    np.testing.assert_array_equal(rgb[0], np.round(VIRIDIS_ANCHORS[0] * 255))
    np.testing.assert_array_equal(rgb[1], np.round(VIRIDIS_ANCHORS[-1] * 255))
    np.testing.assert_array_equal(rgb[2], [128, 128, 128])
    np.testing.assert_array_equal(rgb[3:], rgb[:2])  # clipped


def test_export_round_trip(sheet):
    trimesh = pytest.importorskip("trimesh")
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, dtype="float64")
    ply = tmp / "colored.ply"
    result = CliRunner().invoke(main, ["export", str(out), "--pair", "3", "--field", "stretch",
                                       "-o", str(ply)])
    assert result.exit_code == 0, result.output
    with h5py.File(out) as f:
        lam1 = f["face/stretch"][3][:, 0]
    mesh = read_ply(ply)
    np.testing.assert_array_equal(mesh.vertices, xs[4])  # deformed frame of pair (3, 4)
    np.testing.assert_array_equal(mesh.faces, faces)
    face = read_ply_faces(ply)
    np.testing.assert_allclose(face["stretch_0"], lam1, rtol=1e-7)
    rgb = np.stack([face["red"], face["green"], face["blue"]], axis=1)
    np.testing.assert_array_equal(rgb, colorize(lam1, lam1.min(), lam1.max()))
    np.testing.assert_array_equal(rgb[np.argmin(lam1)], np.round(VIRIDIS_ANCHORS[0] * 255))
    loaded = trimesh.load(ply, process=False)
    np.testing.assert_allclose(loaded.vertices, xs[4])
    np.testing.assert_array_equal(loaded.faces, faces)
    np.testing.assert_array_equal(loaded.metadata["_ply_raw"]["face"]["data"]["red"], rgb[:, 0])
    assert loaded.visual.vertex_colors.shape == (len(xs[4]), 4)  # for Blender

    flat = tmp / "flat.ply"
    CliRunner().invoke(main, ["export", str(out), "--pair", "3", "--component", "1",
                              "--range", "0.9:1.1", "--no-vertex-colors", "-o", str(flat)])
    loaded = trimesh.load(flat, process=False)
    with h5py.File(out) as f:
        lam2 = f["face/stretch"][3][:, 1]
    np.testing.assert_array_equal(loaded.visual.face_colors[:, :3], colorize(lam2, 0.9, 1.1))


def read_ply_faces(path):
    """The face records of a binary PLY written by clothtool (to check its extra properties)."""
    mesh = read_ply(path)
    header = mesh.header
    data = path.read_bytes()[header.size:]
    vertex_bytes = header.element("vertex").count * header.element("vertex").scalar_dtype("<").itemsize
    dtype = np.dtype([("n", "u1"), ("idx", "<i4", (3,))]
                     + [(p.name, "<" + p.dtype) for p in header.element("face").properties[1:]])
    return np.frombuffer(data[vertex_bytes:], dtype)


def test_export_errors(sheet):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, fields="stretch")
    runner = CliRunner()
    for args, message in [(["--pair", "9"], "--pair 9: not in "),
                          (["--field", "F"], "--field: 'F' is not in "),
                          (["--component", "2"], "--component 2"),
                          (["--range", "2:1"], "--range 2:1")]:
        result = runner.invoke(main, ["export", str(out), "-o", str(tmp / "x.ply"), *args])
        assert result.exit_code == 2 and message in result.output, result.output
    assert not (tmp / "x.ply").exists()


def test_vertex_average_is_area_weighted_and_nan_aware():
    vertices, faces = grid(3, 3)
    values = np.arange(len(faces), dtype=float)
    areas = np.linspace(1, 2, len(faces))
    values[2] = np.nan
    got = VertexAverager(faces, len(vertices))(values, areas)
    for v in range(len(vertices)):
        ts = [t for t in range(len(faces)) if v in faces[t] and np.isfinite(values[t])]
        expect = np.dot(areas[ts], values[ts]) / areas[ts].sum() if ts else np.nan
        np.testing.assert_allclose(got[v], expect)
    lonely = VertexAverager(np.array([[0, 1, 2]]), 4)(np.array([[1.0, 2.0]]), np.array([0.5]))
    np.testing.assert_array_equal(lonely[:3], [[1.0, 2.0]] * 3)
    assert np.isnan(lonely[3]).all()  # a vertex without triangles


def test_vertex_average_dataset(sheet):
    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, reference="first", fields="area_ratio",
                               vertex_average="area_ratio,stretch", dtype="float64")
    with h5py.File(out) as f:
        assert set(f["vertex"]) == {"area_ratio_avg", "stretch_avg"}
        assert "stretch" not in f["face"]
        j = f["face/area_ratio"][2]
        rest = 0.5 * np.linalg.norm(np.cross(xs[0][faces[:, 1]] - xs[0][faces[:, 0]],
                                             xs[0][faces[:, 2]] - xs[0][faces[:, 0]]), axis=1)
        np.testing.assert_allclose(f["vertex/area_ratio_avg"][2],
                                   VertexAverager(faces, len(xs[0]))(j, rest), rtol=1e-12)
    with pytest.raises(InputError, match="vertex_average=: no vertex average of 'directions'"):
        clothtool.analyze_sequence(tmp / "seq", tmp / "x.h5", vertex_average="directions")


def assert_same_result(a, b):
    """Every dataset of ``a`` and ``b`` equal (values, dtype, chunks); root attributes equal
    apart from provenance."""
    with h5py.File(a) as fa, h5py.File(b) as fb:
        names = []
        fa.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        other = []
        fb.visititems(lambda n, o: other.append(n) if isinstance(o, h5py.Dataset) else None)
        assert sorted(names) == sorted(other)
        for name in names:
            assert fa[name].dtype == fb[name].dtype, name
            assert fa[name].chunks == fb[name].chunks, name
            np.testing.assert_array_equal(fa[name][()], fb[name][()], err_msg=name)
        provenance = {"command", "created", "merged_commands"}
        keys = set(fa.attrs) - provenance
        assert keys == set(fb.attrs) - provenance
        for key in keys:
            assert np.array_equal(fa.attrs[key], fb.attrs[key]), key
        assert dict(fa["summary"].attrs).keys() == dict(fb["summary"].attrs).keys()


@pytest.mark.parametrize("reference", ["previous", "first", "uv"])
def test_merge_of_slices_equals_single_run(sheet, reference):
    tmp, xs, faces = sheet
    options = dict(reference=reference, vertex_average="stretch", compression="gzip")
    clothtool.analyze_sequence(tmp / "seq", tmp / "all.h5", **options)
    n_pairs = FRAMES if reference == "uv" else FRAMES - 1
    cuts = [(0, 2), (2, 3), (3, 100)]  # the last STOP is past the end: clipped
    for k, cut in enumerate(cuts):
        clothtool.analyze_sequence(tmp / "seq", tmp / f"part{k}.h5", pairs=cut, **options)
    with h5py.File(tmp / "part1.h5") as f:
        assert f.attrs["pair_offset"] == 2 and f.attrs["pairs_total"] == n_pairs
        assert len(f["pairs"]) == 1 and f["summary/pair"][0] == 2
    result = CliRunner().invoke(main, ["merge", str(tmp / "part2.h5"), str(tmp / "part0.h5"),
                                       str(tmp / "part1.h5"), "-o", str(tmp / "merged.h5")])
    assert result.exit_code == 0, result.output
    assert f"pairs 0:{n_pairs} from 3 parts" in result.output
    assert_same_result(tmp / "all.h5", tmp / "merged.h5")
    with h5py.File(tmp / "merged.h5") as f:
        assert len(f.attrs["merged_commands"]) == 3
    times, _, _ = read_xdmf(tmp / "merged.xdmf")
    assert len(times) == n_pairs
    # merging in stages gives the same
    merge_results([tmp / "part1.h5", tmp / "part0.h5"], tmp / "m01.h5", allow_partial=True)
    merge_results([tmp / "m01.h5", tmp / "part2.h5"], tmp / "staged.h5")
    assert_same_result(tmp / "all.h5", tmp / "staged.h5")
    with h5py.File(tmp / "staged.h5") as f:
        assert len(f.attrs["merged_commands"]) == 3


def test_merge_rejects_gaps_overlaps_and_strangers(sheet):
    tmp, xs, faces = sheet
    run = clothtool.analyze_sequence
    run(tmp / "seq", tmp / "a.h5", pairs="0:2")
    run(tmp / "seq", tmp / "b.h5", pairs="1:5")
    run(tmp / "seq", tmp / "c.h5", pairs="3:5")
    run(tmp / "seq", tmp / "d.h5", pairs="2:5", fields="stretch")
    run(tmp / "seq", tmp / "e.h5", pairs="2:5", reference="first")
    runner = CliRunner()
    for parts, message in [("ab", "b.h5: pairs 1:5 overlap"), ("ac", "pairs 2:3 are missing"),
                           ("ad", "datasets differ"), ("ae", "attribute reference='first'")]:
        result = runner.invoke(main, ["merge", *(str(tmp / f"{p}.h5") for p in parts),
                                      "-o", str(tmp / "m.h5")])
        assert result.exit_code == 2 and message in result.output, result.output
        assert not (tmp / "m.h5").exists() and not (tmp / "m.xdmf").exists()


def test_merge_refuses_a_missing_last_or_first_part_unless_allow_partial(sheet):
    """A Slurm array whose last task failed: the parts cover 0:3 of the 5 pairs."""
    tmp, xs, faces = sheet
    n_pairs = FRAMES - 1
    for k, cut in enumerate(["0:2", "2:3", f"3:{n_pairs}"]):
        clothtool.analyze_sequence(tmp / "seq", tmp / f"p{k}.h5", pairs=cut)
    runner = CliRunner()
    for parts, message in [("01", f"pairs 3:{n_pairs} of the analysis' {n_pairs} are in no part"),
                           ("12", f"pairs 0:2 of the analysis' {n_pairs}"),
                           ("1", f"pairs 0:2 and 3:{n_pairs} of the analysis' {n_pairs}")]:
        result = runner.invoke(main, ["merge", *(str(tmp / f"p{p}.h5") for p in parts),
                                      "-o", str(tmp / "m.h5")])
        assert result.exit_code == 2 and message in result.stderr, result.output
        assert result.stderr.count("\n") == 1 and "--allow-partial" in result.stderr
        assert not (tmp / "m.h5").exists() and not (tmp / "m.xdmf").exists()
        with pytest.raises(InputError, match="are in no part"):
            merge_results([tmp / f"p{p}.h5" for p in parts], tmp / "m.h5")
    result = runner.invoke(main, ["merge", str(tmp / "p1.h5"), str(tmp / "p0.h5"), "-o",
                                  str(tmp / "m.h5"), "--allow-partial"])
    assert result.exit_code == 0, result.output
    assert "pairs 0:3 from 2 parts" in result.output
    with h5py.File(tmp / "m.h5") as f:
        assert len(f["pairs"]) == 3 and f.attrs["pairs_total"] == n_pairs
        assert f.attrs["pair_offset"] == 0
    assert merge_results([tmp / "p2.h5", tmp / "p1.h5"], tmp / "m12.h5", allow_partial=True) == (2, n_pairs - 2)
    assert merge_results([tmp / f"p{k}.h5" for k in range(3)], tmp / "all.h5") == (0, n_pairs)


def test_pairs_option_errors(sheet):
    tmp, xs, faces = sheet
    for spec, message in [("3", "not START:STOP"), ("9:12", "no pairs in this slice"),
                          ("2:2", "no pairs"), ("a:b", "not START:STOP")]:
        with pytest.raises(InputError, match=message):
            clothtool.analyze_sequence(tmp / "seq", tmp / "x.h5", pairs=spec)


@pytest.mark.parametrize("extra", [[], ["--pair", "1", "--field", "stretch_avg"]])
def test_plot_writes_a_png_that_is_not_blank(sheet, extra):
    plt = pytest.importorskip("matplotlib.pyplot")
    tmp, xs, faces = sheet
    clothtool.analyze_sequence(tmp / "seq", tmp / "out.h5", reference="first",
                               vertex_average="stretch")
    png = tmp / "fig.png"
    result = CliRunner().invoke(main, ["plot", str(tmp / "out.h5"), "-o", str(png), *extra])
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = plt.imread(png)
    assert image.shape[0] > 500 and image.shape[1] > 500
    assert image[..., :3].std() > 0.05  # not blank
    # the mesh panel (bottom right) holds viridis colours: purple-blue and yellow-green
    quarter = image[image.shape[0] // 2:, image.shape[1] // 2:, :3].reshape(-1, 3)
    assert (np.abs(quarter - viridis(0.0)).max(axis=1) < 0.08).any()
    assert (np.abs(quarter - viridis(1.0)).max(axis=1) < 0.08).any()


def test_plot_without_matplotlib_is_one_line(sheet, monkeypatch):
    tmp, xs, faces = sheet
    clothtool.analyze_sequence(tmp / "seq", tmp / "out.h5", fields="stretch")
    monkeypatch.setitem(__import__("sys").modules, "matplotlib", None)
    result = CliRunner().invoke(main, ["plot", str(tmp / "out.h5"), "-o", str(tmp / "f.png")])
    assert result.exit_code == 2
    assert result.output.strip() == ("clothtool: error: clothtool plot needs matplotlib: "
                                     "pip install 'clothtool[plot]'")


def test_xdmf_is_generic_over_face_and_vertex_datasets(sheet):
    """Datasets the 3D variant adds (3×3 rotations, scalars, uint8 flags, per-edge values) are
    picked up by shape: per-face and per-vertex ones become cell and point data."""
    from clothtool.io.xdmf import write_xdmf

    tmp, xs, faces = sheet
    out = tmp / "out.h5"
    clothtool.analyze_sequence(tmp / "seq", out, fields="area_ratio")
    rng = np.random.default_rng(1)
    p, n, m = FRAMES - 1, len(xs[0]), len(faces)
    added = {"vertex/rotation": rng.random((p, n, 3, 3)), "vertex/angle": rng.random((p, n)),
             "vertex/flags": rng.integers(0, 16, (p, n)).astype(np.uint8),
             "vertex/axis": rng.random((p, n, 3)).astype(np.float32),
             "face/F3": rng.random((p, m, 3, 3)).astype(np.float32),
             "edge/dihedral_change": rng.random((p, 40))}
    with h5py.File(out, "a") as f:
        for name, value in added.items():
            f.create_dataset(name, data=value, chunks=(1, *value.shape[1:]))
    write_xdmf(out)
    times, reader, log = read_xdmf(tmp / "out.xdmf")
    reader.UpdateTimeStep(times[2])
    grid_ = reader.GetOutputDataObject(0)
    cells, points = arrays(grid_.GetCellData()), arrays(grid_.GetPointData())
    assert set(cells) == {"area_ratio", "F3"} and set(points) == {"rotation", "angle", "flags", "axis"}
    for name, value in added.items():
        group, short = name.split("/")
        if group != "edge":
            got = (cells if group == "face" else points)[short]
            np.testing.assert_array_equal(got.reshape(value[2].shape), value[2])
    assert grid_.GetPointData().GetArray("rotation").GetNumberOfComponents() == 9
    assert "rror" not in log.GetOutput()
