"""``analyze`` on tetrahedral sequences, end to end: every input format gives the same result,
the reference modes, the options that do not apply, bad sequences, and info / export / plot /
merge / XDMF on a tetrahedral result."""

import os

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import TET_VARIANTS, tet_grid, write_tet_file, write_tetgen
from test_results import arrays, read_ply_faces, read_xdmf, vtk_to_numpy

import clothtool
from clothtool.analysis.tet import TET_FIELDS, analyze_tet_pair
from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.io.ply import read_ply

X, TETS = tet_grid(3, np.random.default_rng(11))
X = np.round(X * 1024) / 1024  # exact in every format
FRAMES = 4
TRIANGLES = np.array([[0, 1, 2]])


def frame(k):
    """Frame k: stretched by 1 + 0.1k along x and sheared, exact in every format."""
    A = np.array([[1 + 0.1 * k, 0.05 * k, 0], [0, 1, 0], [0, 0, 1 - 0.05 * k]])
    return np.round(X @ A.T * 1024) / 1024


def make_sequence(folder, variant="vtu", frames=FRAMES, triangles=None):
    folder.mkdir(parents=True, exist_ok=True)
    return [write_tet_file(folder / f"f{k}", frame(k), TETS, variant, triangles=triangles)
            for k in range(frames)]


@pytest.fixture(scope="module")
def formats(tmp_path_factory):
    """One result per input format (all frames from the same arrays)."""
    tmp = tmp_path_factory.mktemp("tet_formats")
    out = {}
    for variant in TET_VARIANTS:
        extra = None if variant in ("msh41", "msh41_ascii", "tetgen") else TRIANGLES
        make_sequence(tmp / variant, variant, triangles=extra)
        out[variant] = tmp / f"{variant}.h5"
        clothtool.analyze_sequence(tmp / variant, out[variant], dtype="float64")
    return out


def test_every_format_gives_the_same_result(formats):
    expected = [analyze_tet_pair(frame(k), frame(k + 1), TETS) for k in range(FRAMES - 1)]
    for variant, path in formats.items():
        with h5py.File(path) as f:
            np.testing.assert_array_equal(f["mesh/tets"][:], TETS)
            np.testing.assert_array_equal(f["mesh/vertices"][:], X)
            np.testing.assert_array_equal(f["pairs"][:], [[k, k + 1] for k in range(FRAMES - 1)])
            assert "faces" not in f["mesh"] and "face" not in f
            assert set(f["tet"]) == set(TET_FIELDS)
            assert f.attrs["ignored_cells"] == (0 if variant.startswith(("msh41", "tetgen")) else 1)
            for name in TET_FIELDS:
                assert f[f"tet/{name}"].chunks[0] == 1
                for p in range(FRAMES - 1):
                    np.testing.assert_array_equal(f[f"tet/{name}"][p], expected[p][name],
                                                  err_msg=f"{variant} {name}")
            np.testing.assert_array_equal(f["frame_vertices"][:], [frame(k) for k in range(FRAMES)])


@pytest.mark.parametrize("reference", ["first", "mesh"])
def test_reference_modes(tmp_path, reference):
    make_sequence(tmp_path / "seq")
    rest = write_tet_file(tmp_path / "rest", X * 0.5, TETS, "vtk")
    ref = str(rest) if reference == "mesh" else reference
    out = tmp_path / "out.h5"
    summary = clothtool.analyze_sequence(tmp_path / "seq", out, reference=ref, dtype="float64",
                                         fields="stretch,volume_ratio")
    assert summary.tets == len(TETS) and summary.triangles == 0
    base = X * 0.5 if reference == "mesh" else frame(0)
    with h5py.File(out) as f:
        pairs = f["pairs"][:]
        assert set(f["tet"]) == {"stretch", "volume_ratio"}
        np.testing.assert_array_equal(f["mesh/vertices"][:], base)
        for p, (r, d) in enumerate(pairs):
            assert r == (-1 if reference == "mesh" else 0)
            want = analyze_tet_pair(base, frame(d), TETS)
            np.testing.assert_array_equal(f["tet/volume_ratio"][p], want["volume_ratio"])
            np.testing.assert_array_equal(f["tet/stretch"][p], want["stretch"])
    assert len(pairs) == (FRAMES if reference == "mesh" else FRAMES - 1)


def test_cli_known_answer_float32(tmp_path):
    """Uniform stretch sequence: λ and J exactly as constructed; summary and describe agree."""
    folder = tmp_path / "seq"
    folder.mkdir()
    for k in range(3):
        write_tetgen(folder / f"s{k}.node", X * [1.0, 1.0, 1 + 0.25 * k],
                     TETS if k == 0 else None, ele_path=folder / "shared.ele")
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(main, ["analyze", str(folder), "-o", str(out), "--reference",
                                       "first"])
    assert result.exit_code == 0, result.output
    assert f"2 pairs of 3 frames, {len(TETS)} tetrahedra" in result.output
    assert "largest λ1 1.5000" in result.output
    with h5py.File(out) as f:
        assert f["tet/F"].dtype == np.float32 and f["tet/flags"].dtype == np.uint8
        np.testing.assert_allclose(f["tet/stretch"][1], np.broadcast_to([1.5, 1, 1], (len(TETS), 3)),
                                   atol=1e-6)
        np.testing.assert_allclose(f["tet/volume_ratio"][0], 1.25, atol=1e-6)
        np.testing.assert_allclose(f["summary/volume_ratio_p50"][:], [1.25, 1.5], atol=1e-6)
        np.testing.assert_allclose(f["summary/lambda3_p50"][:], [1.0, 1.0], atol=1e-6)
        assert list(f["summary/inverted"][:]) == [0, 0]


def test_inverted_and_degenerate_tets_are_counted(tmp_path):
    folder = tmp_path / "seq"
    make_sequence(folder, frames=2)
    y = frame(1)
    y[TETS[0, 3]] = 2 * y[TETS[0, :3]].mean(0) - y[TETS[0, 3]]  # through its face: inverted
    write_tet_file(folder / "f1", y, TETS, "vtu")
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(folder, out)
    with h5py.File(out) as f:
        flags = f["tet/flags"][0]
        assert flags[0] & 16 and f["tet/stretch"][0, 0, 2] < 0
        assert f["summary/inverted"][0] == np.count_nonzero(flags & 16) >= 1
        assert f["summary/flagged"][0] == np.count_nonzero(flags)


@pytest.mark.parametrize("options,message", [
    (["--kabsch"], "--kabsch: the 3D variant is for triangle meshes"),
    (["--reference", "uv"], "--reference uv: tetrahedral meshes have no texture coordinates"),
    (["--vertex-average", "stretch"], "--vertex-average stretch: only for triangle meshes"),
    (["--fields", "area_ratio"], "--fields: unknown field 'area_ratio' for tetrahedra"),
    (["--reference", "nowhere.vtu"], "--reference: 'nowhere.vtu' is not previous"),
])
def test_options_that_do_not_apply(tmp_path, options, message):
    """One line each, named as the CLI spells the option (the library says kabsch=True …)."""
    make_sequence(tmp_path / "seq", frames=2)
    result = CliRunner().invoke(main, ["analyze", str(tmp_path / "seq"), "-o",
                                       str(tmp_path / "out.h5"), *options])
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert sorted(os.listdir(tmp_path)) == ["seq"]


def _different_tets(folder):
    paths = make_sequence(folder)
    write_tet_file(folder / "f2", frame(2), TETS[::-1], "vtu")
    return None, [f"{paths[2]}: tetrahedra differ from those of {paths[0]}"]


def _fewer_vertices(folder):
    paths = make_sequence(folder)
    keep = TETS.max(1) < len(X) - 1
    write_tet_file(folder / "f3", frame(3)[:-1], TETS[keep], "vtu")
    return None, [f"{paths[3]}: {len(X) - 1} vertices, but {paths[0]} has {len(X)}"]


def _broken_frame(folder):
    paths = make_sequence(folder)
    paths[1].write_bytes(paths[1].read_bytes()[:300])
    return None, [f"{paths[1]}: cannot read as VTK XML"]


def _no_tets(folder):
    import meshio

    folder.mkdir()
    for k in range(2):
        meshio.write(folder / f"f{k}.vtk", meshio.Mesh(X, [("triangle", TRIANGLES)]))
    return None, [f"{folder / 'f0.vtk'}: no tetrahedra in the file (cells: 1 triangle)"]


def _mixed_formats(folder):
    make_sequence(folder, frames=2)
    write_tet_file(folder / "g", X, TETS, "msh22")
    return None, [f"{folder}: folder holds both .vtu and .msh files (", "g.msh)"]


def _ply_among_tets(folder):
    from clothtool.io.ply import write_ply

    paths = make_sequence(folder, frames=2)
    write_ply(folder / "f1.ply", X, TETS[:, :3])
    return [paths[0], folder / "f1.ply"], ["the frames are both .ply and .vtu files (f1.ply, f0.vtu)"]


@pytest.mark.parametrize("case", [_different_tets, _fewer_vertices, _broken_frame, _no_tets,
                                  _mixed_formats, _ply_among_tets])
def test_bad_sequences_fail_with_one_line_and_write_nothing(tmp_path, case):
    inputs, expected = case(tmp_path / "seq")
    inputs = [str(p) for p in inputs or [tmp_path / "seq"]]
    out = tmp_path / "out" / "out.h5"
    out.parent.mkdir()
    result = CliRunner().invoke(main, ["analyze", *inputs, "-o", str(out)])
    assert result.exit_code == 2, result.output
    message = result.stderr
    assert message.startswith("clothtool: error: ") and message.count("\n") == 1, message
    for text in expected:
        assert text in message, message
    assert os.listdir(out.parent) == []
    with pytest.raises(InputError):
        clothtool.analyze_sequence(inputs, out)


def test_info_export_plot_merge_and_xdmf(tmp_path):
    pytest.importorskip("matplotlib")
    make_sequence(tmp_path / "seq", triangles=TRIANGLES)
    out = tmp_path / "all.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out)
    runner = CliRunner()
    info = runner.invoke(main, ["info", str(out)])
    assert info.exit_code == 0, info.output
    assert f"{len(TETS)} tetrahedra (1 other cells ignored)" in info.output
    assert "λ3 p50" in info.output and "inverted" in info.output
    csv = runner.invoke(main, ["info", str(out), "--csv"]).output.splitlines()
    assert "lambda3_p50" in csv[0].split(",") and len(csv) == FRAMES
    # export: the boundary surface, each triangle with its tetrahedron's value
    ply = tmp_path / "j.ply"
    result = runner.invoke(main, ["export", str(out), "--pair", "1", "--field", "volume_ratio",
                                  "-o", str(ply)])
    assert result.exit_code == 0, result.output
    mesh = read_ply(ply)
    with h5py.File(out) as f:
        J = f["tet/volume_ratio"][1]
        np.testing.assert_array_equal(mesh.vertices, f["frame_vertices"][2])
    n = 3  # tet_grid(3): 6 sides × 3² squares × 2 triangles on the boundary
    assert len(mesh.faces) == 6 * n * n * 2
    owner = {tuple(sorted(f)): k for k, t in enumerate(TETS.tolist())
             for f in ([t[0], t[1], t[2]], [t[0], t[1], t[3]], [t[0], t[2], t[3]], [t[1], t[2], t[3]])}
    expected = J[[owner[tuple(sorted(f))] for f in mesh.faces.tolist()]]
    np.testing.assert_array_equal(read_ply_faces(ply)["volume_ratio"], expected)
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))  # outward: the enclosed volume
    d = frame(2)[TETS[:, :3]] - frame(2)[TETS[:, 3:]]
    np.testing.assert_allclose(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6,
                               np.linalg.det(d).sum() / 6, rtol=1e-6)
    result = runner.invoke(main, ["plot", str(out), "-o", str(tmp_path / "p.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "p.png").stat().st_size > 10000
    # merge of slices equals one run
    for k, cut in enumerate(["0:1", "1:"]):
        clothtool.analyze_sequence(tmp_path / "seq", tmp_path / f"part{k}.h5", pairs=cut)
    result = runner.invoke(main, ["merge", str(tmp_path / "part1.h5"), str(tmp_path / "part0.h5"),
                                  "-o", str(tmp_path / "merged.h5")])
    assert result.exit_code == 0, result.output
    with h5py.File(out) as a, h5py.File(tmp_path / "merged.h5") as b:
        for name in [*(f"tet/{n}" for n in a["tet"]), "mesh/tets", "frame_vertices",
                     "summary/volume_ratio_p50", "summary/lambda3_p5"]:
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)
    # ParaView's reader sees tetrahedra with the /tet fields as cell data
    times, reader, log = read_xdmf(tmp_path / "all.xdmf")
    assert list(times) == list(range(1, FRAMES))
    with h5py.File(out) as f:
        for p, t in enumerate(times):
            reader.UpdateTimeStep(t)
            grid = reader.GetOutputDataObject(0)
            assert grid.GetNumberOfCells() == len(TETS)
            assert {grid.GetCellType(i) for i in range(len(TETS))} == {10}  # VTK_TETRA
            connectivity = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
            np.testing.assert_array_equal(connectivity.reshape(-1, 4), TETS)
            np.testing.assert_allclose(vtk_to_numpy(grid.GetPoints().GetData()), frame(int(t)),
                                       rtol=1e-6)
            cells = arrays(grid.GetCellData())
            assert set(cells) == set(f["tet"])
            for name, values in cells.items():
                stored = f["tet"][name][p]
                np.testing.assert_array_equal(values.reshape(stored.shape), stored)
    assert "rror" not in log.GetOutput()
