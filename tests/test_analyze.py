"""End to end: clothtool analyze on PLY sequences made here, through the library and the CLI."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import grid

import clothtool
from clothtool.cli import main
from clothtool.io.ply import write_ply


def make_sequence(folder, frames=5, nx=6, ny=5, uv=True):
    """A sheet stretched a little more in every frame; returns the positions."""
    vertices, faces = grid(nx, ny)
    folder.mkdir(exist_ok=True)
    out = []
    for k in range(frames):
        x = vertices * [1 + 0.1 * k, 1.0, 1.0] + [0, 0, 0.01 * k]
        props = {"s": vertices[:, 0], "t": vertices[:, 1]} if uv else None
        write_ply(folder / f"frame_{k}.ply", x, faces, vertex_properties=props)
        out.append(x)
    return out, faces


@pytest.mark.parametrize("reference,pairs", [
    ("previous", [(0, 1), (1, 2), (2, 3), (3, 4)]),
    ("first", [(0, 1), (0, 2), (0, 3), (0, 4)]),
    ("uv", [(-1, 0), (-1, 1), (-1, 2), (-1, 3), (-1, 4)]),
])
def test_layout_and_values(tmp_path, reference, pairs):
    xs, faces = make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    summary = clothtool.analyze_sequence(tmp_path / "seq", out, reference=reference, dtype="float64")
    assert summary.pairs == len(pairs)
    with h5py.File(out) as f:
        assert f.attrs["reference"] == reference
        assert f.attrs["clothtool_version"] == clothtool.__version__
        assert "created" in f.attrs and "command" in f.attrs
        np.testing.assert_array_equal(f["pairs"][:], pairs)
        np.testing.assert_array_equal(f["mesh/faces"][:], faces)
        np.testing.assert_array_equal(f["mesh/vertices"][:], xs[0])
        assert [s.decode() for s in f["frames"][:]] == [str(tmp_path / "seq" / f"frame_{k}.ply")
                                                         for k in range(5)]
        assert f["face/F"].shape == (len(pairs), len(faces), 2, 2)
        assert f["face/directions"].shape == (len(pairs), len(faces), 2, 3)
        assert f["face/flags"].dtype == np.uint8
        assert f["face/stretch"].chunks[0] == 1  # one pair per chunk row
        for p, (r, d) in enumerate(pairs):
            # frame k is the flat grid stretched by 1 + 0.1k along x (and lifted): a uniaxial
            # stretch s along x with λ2 = 1 (the uv rest shape is the unstretched grid)
            s = (1 + 0.1 * d) / (1 + 0.1 * max(r, 0))
            face = {name: f["face"][name][p] for name in f["face"]}
            np.testing.assert_allclose(face["stretch"], np.broadcast_to([s, 1.0], (len(faces), 2)),
                                       rtol=1e-12)
            np.testing.assert_allclose(face["area_ratio"], s, rtol=1e-12)
            np.testing.assert_array_equal(face["flags"], 0)
            if s > 1:  # (at s = 1 every direction is principal)
                np.testing.assert_allclose(np.abs(face["directions"][:, 0]),
                                           [[1, 0, 0]] * len(faces), atol=1e-12)
            np.testing.assert_allclose(np.linalg.det(face["F"]), s, rtol=1e-12)
            np.testing.assert_allclose(np.trace(face["C"], axis1=1, axis2=2), s * s + 1, rtol=1e-12)
            np.testing.assert_allclose(np.trace(face["strain"], axis1=1, axis2=2), (s * s - 1) / 2,
                                       atol=1e-12)
            np.testing.assert_allclose(np.trace(face["U"], axis1=1, axis2=2), s + 1, rtol=1e-12)
            np.testing.assert_allclose(face["R"] @ face["U"], face["F"], atol=1e-12)


def test_fields_and_dtype(tmp_path):
    make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out, fields="stretch,area_ratio")
    with h5py.File(out) as f:
        assert set(f["face"]) == {"stretch", "area_ratio"}  # absent, not zero-filled
        assert f["face/stretch"].dtype == np.float32
        np.testing.assert_allclose(f["face/stretch"][0][:, 0], 1.1, rtol=1e-6)


def test_reference_mesh_path(tmp_path):
    xs, faces = make_sequence(tmp_path / "seq")
    rest = tmp_path / "rest.ply"
    write_ply(rest, xs[0] * 0.5, faces)
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out, reference=str(rest), fields=["area_ratio"])
    with h5py.File(out) as f:
        np.testing.assert_array_equal(f["pairs"][:, 0], -1)
        np.testing.assert_allclose(f["mesh/vertices"][:], xs[0] * 0.5)
        np.testing.assert_allclose(f["face/area_ratio"][0], 4.0, rtol=1e-6)


def test_gzip_compression_gives_the_same_data(tmp_path):
    make_sequence(tmp_path / "seq")
    clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "a.h5")
    clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "b.h5", compression="gzip=6")
    with h5py.File(tmp_path / "a.h5") as a, h5py.File(tmp_path / "b.h5") as b:
        assert b["face/F"].compression == "gzip"
        for name in a["face"]:
            np.testing.assert_array_equal(a["face"][name][:], b["face"][name][:])


def test_cli_prints_summary_and_writes(tmp_path):
    make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(main, ["analyze", str(tmp_path / "seq"), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "4 pairs of 5 frames" in result.output
    assert out.exists()
    assert not [p for p in os.listdir(tmp_path) if ".tmp" in p]


@pytest.mark.parametrize("args,culprit", [
    (["--reference", "nowhere"], "nowhere"),
    (["--fields", "stretch,bogus"], "bogus"),
    (["--dtype", "int8"], "int8"),
    (["--compression", "zstd"], "zstd"),
])
def test_cli_bad_options_are_one_line_errors(tmp_path, args, culprit):
    make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(main, ["analyze", str(tmp_path / "seq"), "-o", str(out), *args])
    assert result.exit_code == 2
    assert culprit in result.output
    assert "Traceback" not in result.output
    assert not out.exists()


def test_failure_keeps_existing_output(tmp_path):
    xs, faces = make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out)
    before = out.read_bytes()
    write_ply(tmp_path / "seq" / "frame_5.ply", xs[0][:-1], faces[:3])  # wrong vertex count
    with pytest.raises(clothtool.InputError, match="frame_5.ply"):
        clothtool.analyze_sequence(tmp_path / "seq", out)
    assert out.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["out.h5", "out.xdmf", "seq"]


def test_uv_reference_without_texture_coordinates(tmp_path):
    make_sequence(tmp_path / "seq", uv=False)
    with pytest.raises(clothtool.InputError, match="texture coordinates"):
        clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "o.h5", reference="uv")


def test_help_is_fast_and_does_not_import_numba():
    code = ("import sys; from clothtool.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "assert not {'numba', 'h5py', 'meshio'} & set(sys.modules), 'heavy import'")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    help_text = subprocess.run([sys.executable, "-m", "clothtool.cli", "analyze", "--help"],
                               capture_output=True, text=True, check=True).stdout
    assert "Examples" in help_text and "Exit codes" in help_text
