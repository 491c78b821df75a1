"""Every field of the registry end to end: analyze_pair (or analyze_tet_pair), analyze_sequence,
its dataset, its /summary columns and its XDMF attribute; and a summary that follows the
registry for a field it has not seen."""

import re

import h5py
import numpy as np
import pytest
from conftest import grid, tet_grid

import clothtool
from clothtool.analysis.deformation2d import analyze_pair
from clothtool.analysis.output.summary import pair_summary
from clothtool.analysis.tet import analyze_tet_pair
from clothtool.fields import FIELDS_2D, FIELDS_TET, NAMES_2D, REGISTRY, Field
from clothtool.io.ply import write_ply
from clothtool.io.result import (COLUMNS, FLAG_BITS, PERCENTILES, TET_COLUMNS, TET_FLAG_BITS,
                                 summary_columns)

XDMF_GROUPS = ("face", "tet", "vertex")  # edges have no cell topology in the XDMF


def frames(n_frames=3):
    x, faces = grid(6, 5)
    x = x + [0.0, 0.0, 0.01] * np.sin(3 * x[:, :1])  # not flat, so the 3D variant has rings
    rng = np.random.default_rng(7)
    out = [x]
    for k in range(1, n_frames):
        stretch = np.diag([1 + 0.1 * k, 1 - 0.05 * k, 1 + 0.02 * k])
        out.append(x @ stretch.T + 0.01 * rng.normal(size=x.shape))
    return out, faces


def tet_frames(n_frames=3):
    x, tets = tet_grid(2, np.random.default_rng(3))
    rng = np.random.default_rng(8)
    return [x + 0.05 * k * rng.normal(size=x.shape) for k in range(n_frames)], tets


@pytest.fixture(scope="module")
def sheet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheet")
    xs, faces = frames()
    for k, x in enumerate(xs):
        write_ply(folder / f"f{k}.ply", x, faces)
    return folder, xs, faces


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    import meshio

    folder = tmp_path_factory.mktemp("block")
    xs, tets = tet_frames()
    for k, x in enumerate(xs):
        meshio.write(folder / f"f{k}.vtk", meshio.Mesh(x, [("tetra", tets)]))
    return folder, xs, tets


def xdmf_attributes(path):
    """{(short name, center)} of the first grid's attributes in the XDMF beside ``path``."""
    text = path.with_suffix(".xdmf").read_text()
    first = text.split("</Grid>")[0]
    return set(re.findall(r'<Attribute Name="([^"]+)" AttributeType="[^"]+" Center="([^"]+)"', first))


def check_summary(h5, columns, registry_fields, flag_bits, pair_values):
    """The /summary of ``h5`` has ``columns``, and row p is pair_summary of ``pair_values[p]``."""
    group = h5["summary"]
    assert list(group.attrs["columns"]) == list(columns)
    for p, values in enumerate(pair_values):
        expected = pair_summary(values, registry_fields, flag_bits)
        for name, value in expected.items():
            np.testing.assert_allclose(group[name][p], value, rtol=1e-12, equal_nan=True)


@pytest.mark.parametrize("f", [f for f in REGISTRY if f.kernel == "2d"], ids=lambda f: f.key)
def test_every_2d_field(tmp_path, sheet, f):
    folder, xs, faces = sheet
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(folder, out, fields=f.name, dtype="float64",
                               vertex_average=f.name if f.averageable else None)
    pairs = [analyze_pair(xs[k], xs[k + 1], faces, fields=NAMES_2D) for k in range(len(xs) - 1)]
    with h5py.File(out, "r") as h5:
        assert set(h5["face"]) == {f.name}  # only what was asked for is stored
        stored = h5["face"][f.name]
        assert stored.shape == (len(pairs), len(faces), *f.shape)
        for p, values in enumerate(pairs):
            assert values[f.name].shape == (len(faces), *f.shape)
            np.testing.assert_allclose(stored[p], values[f.name], rtol=1e-12, atol=1e-15,
                                       equal_nan=True)
        check_summary(h5, COLUMNS, FIELDS_2D, FLAG_BITS, pairs)
        if f.averageable:
            assert h5["vertex"][f"{f.name}_avg"].shape == (len(pairs), len(xs[0]), *f.shape)
    attributes = xdmf_attributes(out)
    assert (f.name, "Cell") in attributes
    assert ((f"{f.name}_avg", "Node") in attributes) == f.averageable


@pytest.mark.parametrize("f", [f for f in REGISTRY if f.kernel not in ("2d", "tet")],
                         ids=lambda f: f.key)
def test_every_3d_variant_field(tmp_path, sheet, f):
    folder, xs, faces = sheet
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(folder, out, fields=f.name, kabsch=True, dtype="float64")
    with h5py.File(out, "r") as h5:
        stored = h5[f.key]
        assert stored.shape[0] == len(xs) - 1 and stored.shape[2:] == f.shape
        counts = {"face": len(faces), "vertex": len(xs[0])}
        if f.group in counts:
            assert stored.shape[1] == counts[f.group]
        assert np.isfinite(stored[...]).any() or f.integer
        check_summary(h5, COLUMNS, FIELDS_2D, FLAG_BITS,
                      [analyze_pair(xs[k], xs[k + 1], faces, fields=NAMES_2D)
                       for k in range(len(xs) - 1)])
    center = {"face": "Cell", "vertex": "Node"}.get(f.group)
    assert ((f.name, center) in xdmf_attributes(out)) == (f.group in XDMF_GROUPS)


@pytest.mark.parametrize("f", FIELDS_TET, ids=lambda f: f.key)
def test_every_tet_field(tmp_path, block, f):
    folder, xs, tets = block
    out = tmp_path / "out.h5"
    clothtool.analyze_sequence(folder, out, fields=f.name, dtype="float64")
    pairs = [analyze_tet_pair(xs[k], xs[k + 1], tets) for k in range(len(xs) - 1)]
    with h5py.File(out, "r") as h5:
        assert set(h5["tet"]) == {f.name}
        stored = h5["tet"][f.name]
        assert stored.shape == (len(pairs), len(tets), *f.shape)
        for p, values in enumerate(pairs):
            np.testing.assert_allclose(stored[p], values[f.name], rtol=1e-12, atol=1e-15,
                                       equal_nan=True)
        check_summary(h5, TET_COLUMNS, FIELDS_TET, TET_FLAG_BITS, pairs)
    assert (f.name, "Cell") in xdmf_attributes(out)


def test_the_summary_follows_the_registry():
    """A field that declares summary quantities gets its own columns, labelled by its
    quantities wherever it stands in the registry; each column is the percentile of the
    right component, and the flagged elements are left out."""
    bits = (("bad", 1),)
    registry = (Field("twist", "face", (2,), "2d", "", summary=("twist_a", "twist_b")),
                Field("stretch", "face", (2,), "2d", "", summary=("lambda1", "lambda2")),
                Field("flags", "face", (), "2d", "", integer=True, summary=("flags",)))
    columns, ints = summary_columns(registry, bits)
    assert columns == ("pair", "reference", "deformed",
                       *(f"{q}_p{p}" for q in ("twist_a", "twist_b", "lambda1", "lambda2")
                         for p in PERCENTILES),
                       "compressed", "stretched", "flagged", "bad")
    assert ints == {"pair", "reference", "deformed", "flagged", "bad"}
    rng = np.random.default_rng(1)
    twist = rng.normal(size=(1000, 2)) + [10.0, -10.0]
    stretch = 1 + 0.1 * rng.normal(size=(1000, 2))
    flags = np.zeros(1000, np.uint8)
    flags[:7] = 1
    twist[:7], stretch[:7] = np.nan, np.nan
    row = pair_summary({"twist": twist, "stretch": stretch, "flags": flags}, registry, bits)
    assert set(row) == set(columns) - {"pair", "reference", "deformed"}
    for name, values in (("twist_a", twist[7:, 0]), ("twist_b", twist[7:, 1]),
                         ("lambda1", stretch[7:, 0]), ("lambda2", stretch[7:, 1])):
        for p in PERCENTILES:
            assert row[f"{name}_p{p}"] == pytest.approx(np.percentile(values, p), rel=1e-12)
    assert row["flagged"] == row["bad"] == 7
    assert row["stretched"] == pytest.approx(np.mean(stretch[7:, 0] > 1 + 1e-5))


def test_each_summary_quantity_names_one_component():
    for f in REGISTRY:
        if f.summary and not f.integer:
            assert len(f.summary) == f.size, f.key
