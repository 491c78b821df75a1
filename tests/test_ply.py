"""The PLY reader and writer: every flavour, polygons, extra properties, face-block reuse."""

import numpy as np
import pytest
from conftest import grid

from clothtool.analysis.deformation2d import analyze_pair
from clothtool.io.frames import discover_frames, natural_key
from clothtool.io.ply import parse_ply, read_ply, write_ply


def ply_bytes(vertices, faces, fmt="binary_little_endian", coord="float", extra=True,
              count_type="uchar", index_type="int"):
    """Build a PLY file by hand (independently of our writer)."""
    order = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": None}[fmt]
    ctype = {"float": "f4", "double": "f8"}[coord]
    props = [("x", ctype), ("y", ctype), ("z", ctype)]
    if extra:
        props += [("nx", "f4"), ("ny", "f4"), ("nz", "f4"), ("red", "u1"), ("green", "u1"),
                  ("blue", "u1"), ("s", "f4"), ("t", "f4")]
    names = {"f4": "float", "f8": "double", "u1": "uchar"}
    head = ["ply", f"format {fmt} 1.0", "comment made by a test", f"element vertex {len(vertices)}"]
    head += [f"property {names[t]} {n}" for n, t in props]
    head += [f"element face {len(faces)}", f"property list {count_type} {index_type} vertex_indices",
             "end_header"]
    n = len(vertices)
    cols = {"x": vertices[:, 0], "y": vertices[:, 1], "z": vertices[:, 2], "nx": np.zeros(n),
            "ny": np.zeros(n), "nz": np.ones(n), "red": np.arange(n) % 256, "green": np.zeros(n),
            "blue": np.zeros(n), "s": vertices[:, 0], "t": vertices[:, 1]}
    out = ("\n".join(head) + "\n").encode()
    if order is None:
        lines = [" ".join(repr(float(cols[p][i])) if t != "u1" else str(int(cols[p][i]))
                          for p, t in props) for i in range(n)]
        lines += [" ".join(map(str, [len(f), *f])) for f in faces]
        return out + ("\n".join(lines) + "\n").encode()
    rec = np.empty(n, [(p, order + t) for p, t in props])
    for p, _ in props:
        rec[p] = cols[p]
    out += rec.tobytes()
    cdt = {"uchar": "u1", "int": "i4", "ushort": "u2"}[count_type]
    idt = {"int": "i4", "uint": "u4", "int16": "i2"}[index_type]
    for f in faces:
        out += np.array([len(f)], order + cdt).tobytes() + np.array(f, order + idt).tobytes()
    return out


FLAVOURS = [(fmt, coord) for fmt in ("ascii", "binary_little_endian", "binary_big_endian")
            for coord in ("float", "double")]


@pytest.mark.parametrize("fmt,coord", FLAVOURS)
def test_every_flavour_reads_the_same_mesh(fmt, coord):
    vertices, faces = grid(5, 4)
    vertices = (vertices + [0.125, -3.5, 0.25]).astype(np.float32).astype(np.float64)
    mesh = parse_ply(ply_bytes(vertices, faces, fmt, coord))
    np.testing.assert_array_equal(mesh.vertices, vertices)
    np.testing.assert_array_equal(mesh.faces, faces)
    np.testing.assert_array_equal(mesh.uv, vertices[:, :2])
    assert set(mesh.vertex_properties) == {"nx", "ny", "nz", "red", "green", "blue", "s", "t"}


def test_every_flavour_gives_identical_analysis():
    vertices, faces = grid(6, 5)
    moved = vertices @ np.array([[1.2, 0.3, 0], [0, 0.9, 0], [0.1, 0, 1]]).T
    vertices = vertices.astype(np.float32).astype(np.float64)
    moved = moved.astype(np.float32).astype(np.float64)
    results = []
    for fmt, coord in FLAVOURS:
        a = parse_ply(ply_bytes(vertices, faces, fmt, coord))
        b = parse_ply(ply_bytes(moved, faces, fmt, coord))
        results.append(analyze_pair(a.vertices, b.vertices, a.faces))
    for r in results[1:]:
        for name in r:
            np.testing.assert_array_equal(r[name], results[0][name])


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_polygons_are_fan_triangulated_with_source_map(fmt):
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0],
                         [3, 0.5, 0]], float)
    faces = [[0, 1, 2, 3], [1, 4, 5, 6, 2], [4, 6, 5]]
    mesh = parse_ply(ply_bytes(vertices, faces, fmt, extra=False))
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 6], [1, 6, 2], [4, 6, 5]]
    assert mesh.face_source.tolist() == [0, 0, 1, 1, 1, 2]


def test_uniform_quads_take_the_fast_path():
    vertices = np.random.default_rng(0).random((6, 3))
    mesh = parse_ply(ply_bytes(vertices, [[0, 1, 2, 3], [2, 3, 4, 5]], extra=False))
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [2, 3, 4], [2, 4, 5]]
    assert mesh.face_source.tolist() == [0, 0, 1, 1]


@pytest.mark.parametrize("count_type,index_type", [("uchar", "uint"), ("ushort", "int16"),
                                                   ("int", "int")])
def test_list_types(count_type, index_type):
    vertices, faces = grid(3, 3)
    mesh = parse_ply(ply_bytes(vertices, faces, count_type=count_type, index_type=index_type))
    np.testing.assert_array_equal(mesh.faces, faces)


@pytest.mark.parametrize("binary", [True, False])
def test_writer_round_trip(tmp_path, binary):
    rng = np.random.default_rng(3)
    vertices, faces = grid(4, 4)
    vertices = rng.random(vertices.shape)
    uv = rng.random((len(vertices), 2)).astype(np.float32)
    colours = rng.integers(0, 255, (len(faces), 3)).astype(np.uint8)
    path = tmp_path / "m.ply"
    write_ply(path, vertices, faces, vertex_properties={"s": uv[:, 0], "t": uv[:, 1]},
              face_properties={"red": colours[:, 0], "green": colours[:, 1], "blue": colours[:, 2]},
              binary=binary)
    mesh = read_ply(path)
    np.testing.assert_array_equal(mesh.vertices, vertices)  # double coordinates, exact
    np.testing.assert_array_equal(mesh.faces, faces)
    np.testing.assert_array_equal(mesh.uv, uv.astype(np.float64))
    assert not list(tmp_path.glob(".*tmp*"))


def test_writer_output_matches_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    vertices, faces = grid(5, 3)
    path = tmp_path / "m.ply"
    write_ply(path, vertices.astype(np.float32), faces)
    t = trimesh.load(path, process=False)
    np.testing.assert_array_equal(np.asarray(t.faces), faces)
    np.testing.assert_allclose(np.asarray(t.vertices), vertices, atol=1e-7)


def test_identical_face_block_is_not_parsed_again(tmp_path):
    vertices, faces = grid(4, 4)
    for name in ("a", "b"):
        write_ply(tmp_path / f"{name}.ply", vertices + (name == "b"), faces)
    first = read_ply(tmp_path / "a.ply")
    second = read_ply(tmp_path / "b.ply", reuse=first)
    assert second.faces is first.faces  # taken, not parsed
    np.testing.assert_array_equal(second.vertices, vertices + 1)
    write_ply(tmp_path / "c.ply", vertices, faces[::-1])
    third = read_ply(tmp_path / "c.ply", reuse=first)
    assert third.faces is not first.faces
    np.testing.assert_array_equal(third.faces, faces[::-1])


def test_vertex_order_is_never_changed():
    """Duplicate and unreferenced vertices survive: vertex order is the correspondence."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [5, 5, 5]], float)
    mesh = parse_ply(ply_bytes(vertices, [[0, 1, 2], [3, 1, 2]], extra=False))
    np.testing.assert_array_equal(mesh.vertices, vertices)


def test_natural_order(tmp_path):
    names = ["f10.ply", "f2.ply", "f1.ply", "F3.ply", "notes.txt"]
    for n in names:
        (tmp_path / n).write_bytes(b"")
    found = [p.split("/")[-1] for p in discover_frames(tmp_path)]
    assert found == ["f1.ply", "f2.ply", "F3.ply", "f10.ply"]
    assert [p.split("/")[-1] for p in discover_frames(str(tmp_path / "f*.ply"))] == \
        ["f1.ply", "f2.ply", "f10.ply"]
    explicit = [str(tmp_path / "f10.ply"), str(tmp_path / "f1.ply")]
    assert discover_frames(explicit) == explicit
    assert sorted(["a_2_b10", "a_2_b9", "a_10_b1"], key=natural_key) == ["a_2_b9", "a_2_b10", "a_10_b1"]
