"""clothtool analyze --kabsch end to end: datasets, --fields, --dtype, references, the CLI."""

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import grid
from scipy.spatial.transform import Rotation

import clothtool
from clothtool.analysis.dihedral import dihedral_change
from clothtool.analysis.face3d import face_gradients3
from clothtool.analysis.kabsch import vertex_rotations
from clothtool.geometry import hinges, one_ring
from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.io.ply import write_ply
from clothtool.results.merge import merge_results

N_FRAMES = 4


def make_sequence(folder, nx=7, ny=6):
    """A sheet that bends more and turns about z from frame to frame; uv = the flat grid."""
    flat, faces = grid(nx, ny)
    folder.mkdir(exist_ok=True)
    xs = []
    for k in range(N_FRAMES):
        x = flat.copy()
        x[:, 2] = 0.2 * k * np.sin(2.0 * flat[:, 0])
        x = x @ Rotation.from_rotvec([0, 0, 0.3 * k]).as_matrix().T
        write_ply(folder / f"f{k}.ply", x, faces, vertex_properties={"s": flat[:, 0], "t": flat[:, 1]})
        xs.append(x)
    return xs, flat, faces


def expected(x_ref, x_def, faces):
    offsets, neighbours = one_ring(faces, len(x_ref))
    hinge, _ = hinges(faces, len(x_ref))
    edges, opposite = hinge[:, :2], hinge[:, 2:]
    rotation, angle, residual, vflags = vertex_rotations(x_ref, x_def, offsets, neighbours)
    F3, R3, U3, stretch3, directions3, _ = face_gradients3(x_ref, x_def, faces)
    change, eflags = dihedral_change(x_ref, x_def, edges, opposite)
    return {"vertex/rotation": rotation, "vertex/angle": angle, "vertex/residual": residual,
            "vertex/flags": vflags, "face/F3": F3, "face/R3": R3, "face/U3": U3,
            "face/stretch3": stretch3, "face/directions3": directions3,
            "edge/dihedral_change": change, "edge/flags": eflags}


@pytest.mark.parametrize("reference", ["previous", "first", "uv"])
def test_layout_and_values(tmp_path, reference):
    xs, flat, faces = make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out, reference=reference, dtype="float64", kabsch=True)
    hinge, _ = hinges(faces, len(flat))
    edges, opposite = hinge[:, :2], hinge[:, 2:]
    with h5py.File(out) as f:
        pairs = f["pairs"][:]
        np.testing.assert_array_equal(f["mesh/edges"][:], edges)
        np.testing.assert_array_equal(f["mesh/edge_opposite"][:], opposite)
        assert set(f["vertex"]) == {"rotation", "angle", "residual", "flags"}
        assert set(f["edge"]) == {"dihedral_change", "flags"}
        assert {"F3", "R3", "U3", "stretch3", "directions3", "stretch", "flags"} <= set(f["face"])
        for name, value in expected(xs[0], xs[1], faces).items():
            assert f[name].shape == (len(pairs), *value.shape)
            assert f[name].chunks[0] == 1
            assert f[name].dtype == (np.uint8 if name.endswith("flags") else np.float64)
        for p, (r, d) in enumerate(pairs):
            x_ref = np.column_stack([flat[:, :2], np.zeros(len(flat))]) if r < 0 else xs[r]
            for name, value in expected(x_ref, xs[d], faces).items():
                np.testing.assert_array_equal(f[name][p], value, err_msg=name)
        np.testing.assert_array_equal(f["face/flags"][:] & 7, 0)
    xdmf = (tmp_path / "out.xdmf").read_text()
    assert "/vertex/rotation" in xdmf and "/face/F3" in xdmf and "/edge/" not in xdmf
    if reference == "uv":  # frame k against the flat uv sheet: the turn 0.3·k about z dominates
        with h5py.File(out) as f:
            assert np.all(f["vertex/angle"][0] < 1e-12) and np.all(f["vertex/angle"][3] > 0.8)


def test_fields_select_3d_datasets(tmp_path):
    make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(tmp_path / "seq", out, fields="stretch,angle,dihedral_change", kabsch=True)
    with h5py.File(out) as f:
        assert set(f["face"]) == {"stretch"}
        assert set(f["vertex"]) == {"angle"}
        assert set(f["edge"]) == {"dihedral_change"}
        assert "edges" in f["mesh"]
        assert f["vertex/angle"].dtype == np.float32
        assert f["vertex/angle"].chunks[0] == 1

    clothtool.analyze_sequence(tmp_path / "seq", out, fields="F3", kabsch=True)
    with h5py.File(out) as f:
        assert set(f["face"]) == {"F3"} and "vertex" not in f and "edge" not in f
        assert "edges" not in f["mesh"]

    clothtool.analyze_sequence(tmp_path / "seq", out, fields="flags", kabsch=True)
    with h5py.File(out) as f:
        assert set(f["face"]) == {"flags"} and set(f["vertex"]) == {"flags"} and set(f["edge"]) == {"flags"}


def test_merge_of_kabsch_slices_equals_single_run(tmp_path):
    make_sequence(tmp_path / "seq")
    clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "all.h5", kabsch=True)
    for k, part in enumerate(("0:1", "1:3")):
        clothtool.analyze_sequence(tmp_path / "seq", tmp_path / f"part{k}.h5", kabsch=True, pairs=part)
    merge_results([tmp_path / "part1.h5", tmp_path / "part0.h5"], tmp_path / "merged.h5")
    with h5py.File(tmp_path / "all.h5") as a, h5py.File(tmp_path / "merged.h5") as b:
        for name in ("vertex/rotation", "vertex/flags", "face/R3", "edge/dihedral_change", "mesh/edges"):
            np.testing.assert_array_equal(a[name][:], b[name][:], err_msg=name)


def test_3d_fields_need_kabsch(tmp_path):
    make_sequence(tmp_path / "seq")
    with pytest.raises(InputError, match="kabsch=True"):
        clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "out.h5", fields="rotation")
    clothtool.analyze_sequence(tmp_path / "seq", tmp_path / "out.h5")
    with h5py.File(tmp_path / "out.h5") as f:
        assert "vertex" not in f and "edge" not in f and "F3" not in f["face"]


def test_cli_kabsch(tmp_path):
    make_sequence(tmp_path / "seq")
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(main, ["analyze", str(tmp_path / "seq"), "-o", str(out), "--kabsch"])
    assert result.exit_code == 0, result.output
    assert "largest vertex rotation" in result.output and "flagged vertex-pairs" in result.output
    with h5py.File(out) as f:
        assert 0.3 <= f["vertex/angle"][:].max() < 0.6  # the turn of 0.3 plus some bending
    result = CliRunner().invoke(main, ["analyze", str(tmp_path / "seq"), "-o", str(out),
                                       "--fields", "residual"])
    assert result.exit_code == 2 and "--kabsch" in result.output


def test_mesh_without_interior_edges(tmp_path):
    """A lone triangle: /edge datasets of length 0, vertex rotations of a scaled triangle = I."""
    folder = tmp_path / "tri"
    folder.mkdir()
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    for k in range(3):
        write_ply(folder / f"f{k}.ply", x * (1 + 0.1 * k), np.array([[0, 1, 2]]))
    clothtool.analyze_sequence(folder, tmp_path / "out.h5", kabsch=True, dtype="float64")
    with h5py.File(tmp_path / "out.h5") as f:
        assert f["edge/dihedral_change"].shape == (2, 0) and f["mesh/edges"].shape == (0, 2)
        np.testing.assert_allclose(f["vertex/rotation"][:], np.broadcast_to(np.eye(3), (2, 3, 3, 3)), atol=1e-15)
