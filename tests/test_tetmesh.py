"""Reading tetrahedral meshes: every format from the same arrays gives the same mesh and the
same analysis; bad files give one-line InputErrors naming the file."""

import numpy as np
import pytest
from conftest import TET_VARIANTS, tet_grid, write_tet_file, write_tetgen

from clothtool.analysis.tet import analyze_tet_pair
from clothtool.errors import InputError
from clothtool.io.tetmesh import TetFrameReader, read_tet_mesh

X, TETS = tet_grid(3, np.random.default_rng(7))
X = np.round(X * 1024) / 1024  # exact in every format (ascii VTU keeps 12 digits)
TRIANGLES = np.array([[0, 1, 2], [1, 2, 3]])
A = np.array([[1.2, 0.1, 0.0], [0.0, 0.9, 0.2], [0.1, 0.0, 1.1]])
Y = np.round(X @ A.T * 1024) / 1024


@pytest.mark.parametrize("variant", sorted(TET_VARIANTS))
def test_every_format_reads_the_same_mesh_and_analysis(tmp_path, variant):
    extra = None if variant in ("msh41", "msh41_ascii", "tetgen") else TRIANGLES
    p0 = write_tet_file(tmp_path / "f0", X, TETS, variant, triangles=extra)
    p1 = write_tet_file(tmp_path / "f1", Y, TETS, variant, triangles=extra)
    m0, m1 = read_tet_mesh(p0), read_tet_mesh(p1)
    np.testing.assert_array_equal(m0.vertices, X)
    np.testing.assert_array_equal(m0.tets, TETS)
    assert m0.vertices.dtype == np.float64 and m0.tets.dtype == np.int64
    assert m0.other_cells == (0 if extra is None else len(TRIANGLES))
    ours = analyze_tet_pair(m0.vertices, m1.vertices, m0.tets)
    expected = analyze_tet_pair(X, Y, TETS)
    for name, values in expected.items():
        np.testing.assert_array_equal(ours[name], values, err_msg=name)


def test_tetgen_shared_ele_one_based_and_reused(tmp_path):
    write_tetgen(tmp_path / "a_1.node", X, TETS, base=1, ele_path=tmp_path / "mesh.ele")
    write_tetgen(tmp_path / "a_2.node", X * 2, base=1)
    reader = TetFrameReader([tmp_path / "a_1.node", tmp_path / "a_2.node"])
    np.testing.assert_array_equal(reader.tets, TETS)
    second = reader.mesh(1)
    assert second.tets is reader.tets  # the shared .ele is parsed once
    np.testing.assert_array_equal(second.vertices, X * 2)


def test_tetgen_ten_node_tets_and_attributes(tmp_path):
    node = tmp_path / "q.node"
    lines = [f"{len(X)} 3 1 1"] + [f"{i} {p[0]!r} {p[1]!r} {p[2]!r} 7.5 1"
                                   for i, p in enumerate(X.tolist())]
    node.write_text("\n".join(lines) + "\n")
    mid = np.zeros((len(TETS), 6), np.int64)  # the six edge nodes (any indices here)
    rows = [f"{len(TETS)} 10 1"] + [f"{i} " + " ".join(map(str, [*t, *m])) + " 3"
                                   for i, (t, m) in enumerate(zip(TETS.tolist(), mid.tolist()))]
    (tmp_path / "q.ele").write_text("\n".join(rows) + "\n")
    mesh = read_tet_mesh(node)
    np.testing.assert_array_equal(mesh.tets, TETS)
    np.testing.assert_array_equal(mesh.vertices, X)


def test_frames_must_match_the_first(tmp_path):
    p0 = write_tet_file(tmp_path / "f0", X, TETS, "vtu")
    p1 = write_tet_file(tmp_path / "f1", X[:-1], TETS[TETS.max(1) < len(X) - 1], "vtu")
    p2 = write_tet_file(tmp_path / "f2", X, TETS[::-1], "vtu")
    reader = TetFrameReader([p0, p1, p2])
    with pytest.raises(InputError, match=f"{p1}: {len(X) - 1} vertices, but {p0} has"):
        reader.positions(1)
    with pytest.raises(InputError, match=f"{p2}: tetrahedra differ from those of {p0}"):
        reader.positions(2)


def _vtu_without_tets(path):
    import meshio

    meshio.write(path, meshio.Mesh(X, [("triangle", TRIANGLES)]))


BROKEN = {
    "no_tets.vtu": (_vtu_without_tets, "no tetrahedra in the file (cells: 2 triangle)"),
    "garbage.vtu": (lambda p: p.write_bytes(b"\x00\x01 not xml"), "cannot read as VTK XML"),
    "empty.vtk": (lambda p: p.write_bytes(b""), "cannot read as legacy VTK"),
    "garbage.msh": (lambda p: p.write_text("$MeshFormat\n9.9 0 8\n$EndMeshFormat\n"),
                    "cannot read as Gmsh"),
    "truncated.vtu": (lambda p: p.write_bytes(write_tet_file(p.with_name("t"), X, TETS, "vtu")
                                              .read_bytes()[:700]), "cannot read as VTK XML"),
    "empty.node": (lambda p: p.write_text("# nothing\n"), "empty .node file"),
    "short.node": (lambda p: (write_tetgen(p, X, TETS), p.write_text(p.read_text()[:200])),
                   "the point list has"),
    "bad_header.node": (lambda p: (write_tetgen(p, X, TETS), p.write_text("5 2 0 0\n")),
                        "is not N 3 ATTRIBUTES 0|1"),
    "word.node": (lambda p: (write_tetgen(p, X, TETS), p.write_text(
        p.read_text().replace(" ", " x", 1).replace("\n0 ", "\n0 x", 1))), "not a number"),
    "out_of_range.node": (lambda p: (write_tetgen(p, X, TETS), p.with_suffix(".ele").write_text(
        "1 4 0\n0 0 1 2 999\n")), "index 999 is outside 0..63"),
    "fractional.node": (lambda p: (write_tetgen(p, X, TETS), p.with_suffix(".ele").write_text(
        "1 4 0\n0 0 1 2 3.5\n")), "non-integer index"),
    "numbering.node": (lambda p: p.write_text("2 3 0 0\n0 0 0 0\n5 1 1 1\n"),
                       "not numbered consecutively"),
    "lonely.node": (lambda p: write_tetgen(p, X), "no lonely.ele and no other .ele"),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_files_raise_one_line_input_errors(tmp_path, name):
    make, message = BROKEN[name]
    path = tmp_path / name
    make(path)
    with pytest.raises(InputError) as info:
        read_tet_mesh(path)
    text = str(info.value)
    assert text.startswith((f"{path}: ", f"{path.with_suffix('.ele')}: ")) and "\n" not in text
    assert message in text


def test_several_ele_files_and_no_own(tmp_path):
    write_tetgen(tmp_path / "f.node", X)
    for name in ("a.ele", "b.ele"):
        (tmp_path / name).write_text("1 4 0\n0 0 1 2 3\n")
    with pytest.raises(InputError, match="several .ele files beside it"):
        read_tet_mesh(tmp_path / "f.node")


def test_folder_and_missing_file(tmp_path):
    (tmp_path / "d.vtu").mkdir()
    with pytest.raises(InputError, match="d.vtu: is a folder"):
        read_tet_mesh(tmp_path / "d.vtu")
    with pytest.raises(InputError, match="nope.msh: no such file"):
        read_tet_mesh(tmp_path / "nope.msh")
