"""The OBJ reader, OBJ sequences end to end, and per-corner uv (PLY ``texcoord``, OBJ ``vt``)
with ``--reference uv`` on a seam mesh of two panels with known stretches."""

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import grid

import clothtool
from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.io.obj import parse_obj, read_obj
from clothtool.io.ply import parse_ply, read_ply, write_ply

SQUARE = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def fmt(x):
    return repr(float(x))


def write_obj(path, vertices, faces, corner_uv=None, extra=b""):
    """OBJ text of a triangle mesh; with ``corner_uv`` (M, 3, 2) one vt per corner (a/b)."""
    lines = [b"# written by the test", b"o cloth", b"mtllib cloth.mtl"]
    lines += [("v " + " ".join(map(fmt, v))).encode() for v in vertices]
    if corner_uv is not None:
        lines += [("vt " + " ".join(map(fmt, t))).encode() for t in corner_uv.reshape(-1, 2)]
    lines += [b"usemtl cloth", b"s 1"]
    for k, f in enumerate(faces):
        if corner_uv is None:
            lines.append(("f " + " ".join(str(i + 1) for i in f)).encode())
        else:
            lines.append(("f " + " ".join(f"{i + 1}/{3 * k + j + 1}" for j, i in enumerate(f))).encode())
    path.write_bytes(b"\n".join(lines) + b"\n" + extra)


def ply_with_texcoord(vertices, faces, corner_uv, binary=True, vertex_uv=None, float_type="double"):
    """A PLY with a per-corner ``texcoord`` face list (MeshLab writes it as float)."""
    head = ["ply", "format " + ("binary_little_endian" if binary else "ascii") + " 1.0",
            f"element vertex {len(vertices)}", "property double x", "property double y",
            "property double z"]
    if vertex_uv is not None:
        head += ["property double s", "property double t"]
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices",
             f"property list uchar {float_type} texcoord", "end_header"]
    vcols = vertices if vertex_uv is None else np.column_stack([vertices, vertex_uv])
    tdt = "<f4" if float_type == "float" else "<f8"
    tc = corner_uv.reshape(len(faces), -1).astype(tdt)
    out = ("\n".join(head) + "\n").encode()
    if binary:
        out += np.ascontiguousarray(vcols, "<f8").tobytes()
        rec = np.empty(len(faces), [("n", "u1"), ("i", "<i4", (3,)), ("m", "u1"), ("t", tdt, (6,))])
        rec["n"], rec["i"], rec["m"], rec["t"] = 3, faces, 6, tc
        return out + rec.tobytes()
    body = [" ".join(map(fmt, row)) for row in vcols]
    body += ["3 " + " ".join(map(str, f)) + " 6 " + " ".join(map(fmt, t)) for f, t in zip(faces, tc)]
    return out + ("\n".join(body) + "\n").encode()


# ------------------------------------------------------------------ the reader


@pytest.mark.parametrize("corners", ["1 2 3 4", "1/1 2/2 3/3 4/4", "1//1 2//1 3//1 4//1",
                                     "1/1/1 2/2/1 3/3/1 4/4/1", "-4/-4/-1 -3/-3/-1 -2/-2/-1 -1/-1/-1",
                                     "-4 -3 -2 -1", "1/-4 2/-3 3/-2 4/-1"])
def test_corner_forms_and_negative_indices(corners):
    data = SQUARE + b"vt 0 0\nvt 0.5 0\nvt 0.5 0.5\nvt 0 0.5\nvn 0 0 1\nf " + corners.encode() + b"\n"
    mesh = parse_obj(data, "sq.obj")
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert mesh.face_source.tolist() == [0, 0]
    assert mesh.vertices.dtype == np.float64 and mesh.vertices[2].tolist() == [1, 1, 0]
    if "/" in corners and "//" not in corners:
        assert mesh.corner_uv.tolist() == [[[0, 0], [0.5, 0], [0.5, 0.5]], [[0, 0], [0.5, 0.5], [0, 0.5]]]
    else:
        assert mesh.corner_uv is None


def test_relative_indices_count_from_the_line():
    """-1 is the last vertex defined before the face line, not the last of the file."""
    data = SQUARE[:16] + b"v 1 1 0\nf -3 -2 -1\nv 0 1 0\nv 5 5 5\nf -4 -3 -1\n"
    mesh = parse_obj(data, "rel.obj")
    assert mesh.faces.tolist() == [[0, 1, 2], [1, 2, 4]]


def test_polygons_fan_triangulated_with_face_source():
    data = (SQUARE + b"v 2 0 0\nv 2 1 0\nv 3 0 0\nv 3 1 0\nv 4 0 0\n"
            b"f 1 2 3 4\nf 2 5 6 3\nf 5 7 9 8 6\nf 1 2 4\n")
    mesh = parse_obj(data, "poly.obj")
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2],
                                   [4, 6, 8], [4, 8, 7], [4, 7, 5], [0, 1, 3]]
    assert mesh.face_source.tolist() == [0, 0, 1, 1, 2, 2, 2, 3]
    pent = parse_obj(SQUARE + b"v 0.5 1.5 0\nf 1 2 3 5 4\nf 1 2 3 5 4\n", "pent.obj")
    assert pent.faces.tolist() == [[0, 1, 2], [0, 2, 4], [0, 4, 3]] * 2
    assert pent.face_source.tolist() == [0, 0, 0, 1, 1, 1]


def test_w_colours_and_ignored_statements():
    data = (b"# comment\nmtllib a.mtl\no piece\ng front back\ns off\nusemtl red\n"
            b"v 0 0 0 1.0\nv 1 0 0 0.5 0.1 0.2\nv 1 1 0 1 0 0 1\n\nv 0 1 0 0.25 0.5 0.75\r\n"
            b"vn 0 0 1\nvp 0.5\nl 1 2\ns 1\nf 1//1 2//1 3//1\r\nf 1 3 4 # a comment\n")
    mesh = parse_obj(data, "misc.obj")
    assert mesh.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert mesh.corner_uv is None and mesh.uv is None


def test_fast_and_per_line_paths_agree(tmp_path):
    vertices, faces = grid(7, 5)
    uv = np.random.default_rng(3).random((len(faces), 3, 2))
    write_obj(tmp_path / "a.obj", vertices, faces, uv)
    fast = read_obj(tmp_path / "a.obj")
    text = (tmp_path / "a.obj").read_bytes()
    slow = parse_obj(text.replace(b"\nv ", b"\n  v "), "indented.obj")  # the per-line path
    for mesh in (fast, slow):
        np.testing.assert_array_equal(mesh.vertices, vertices)
        np.testing.assert_array_equal(mesh.faces, faces)
        np.testing.assert_array_equal(mesh.corner_uv, uv)


# ------------------------------------------------------------------ PLY per-corner texcoord


@pytest.mark.parametrize("binary", [True, False])
def test_ply_per_corner_texcoord(binary):
    vertices, faces = grid(4, 3)
    corner_uv = (np.arange(len(faces) * 6).reshape(-1, 3, 2) / 8.0)  # exact in float32
    mesh = parse_ply(ply_with_texcoord(vertices, faces, corner_uv, binary, float_type="float"), "tc.ply")
    np.testing.assert_array_equal(mesh.faces, faces)
    assert mesh.corner_uv.dtype == np.float64 and mesh.corner_uv.shape == (len(faces), 3, 2)
    np.testing.assert_array_equal(mesh.corner_uv, corner_uv)
    assert not mesh.corner_uv_missing.any()


def test_ply_texcoord_of_a_quad_follows_the_fan():
    data = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            b"property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
            b"4 0 1 2 3 8 0 0 0.5 0 0.5 0.5 0 0.5\n")
    mesh = parse_ply(data, "quad.ply")
    assert mesh.corner_uv.tolist() == [[[0, 0], [0.5, 0], [0.5, 0.5]], [[0, 0], [0.5, 0.5], [0, 0.5]]]
    with pytest.raises(InputError, match=r"quad.ply: face 0 has 6 texcoord values for 4 corners"):
        parse_ply(data.replace(b"8 0 0 0.5 0 0.5 0.5 0 0.5", b"6 0 0 0.5 0 0.5 0.5"), "quad.ply")


# ------------------------------------------------------------------ sequences


def frames(tmp_path, n=3):
    """Vertex positions of a sequence (a stretching, bending sheet) and its faces and uv."""
    vertices, faces = grid(6, 5)
    out = []
    for k in range(n):
        x = vertices * [1 + 0.1 * k, 1 - 0.05 * k, 1]
        x[:, 2] = 0.1 * k * np.sin(3 * vertices[:, 0])
        out.append(x)
    corner_uv = vertices[faces][:, :, :2] * 0.5
    return out, faces, corner_uv


def analyze(args):
    result = CliRunner().invoke(main, ["analyze", *map(str, args), "-q"])
    return result


def all_datasets(path):
    out = {}
    with h5py.File(path) as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if hasattr(obj, "shape") else None)
    return out


@pytest.mark.parametrize("reference", ["previous", "uv"])
def test_obj_and_ply_copies_give_identical_results(tmp_path, reference):
    """The same arrays written as OBJ (vt per corner) and as PLY (texcoord per corner)."""
    xs, faces, corner_uv = frames(tmp_path)
    (tmp_path / "obj").mkdir()
    (tmp_path / "ply").mkdir()
    for k, x in enumerate(xs):
        write_obj(tmp_path / "obj" / f"f{k}.obj", x, faces, corner_uv)
        (tmp_path / "ply" / f"f{k}.ply").write_bytes(ply_with_texcoord(x, faces, corner_uv))
    for kind in ("obj", "ply"):
        result = analyze([tmp_path / kind, "-o", tmp_path / f"{kind}.h5", "--reference", reference])
        assert result.exit_code == 0, result.output
    a, b = all_datasets(tmp_path / "obj.h5"), all_datasets(tmp_path / "ply.h5")
    assert set(a) == set(b) and "face/stretch" in a
    assert ("mesh/corner_uv" in a) == (reference == "uv")
    for name in a:
        if name == "frames":  # the file names: f0.obj vs f0.ply
            assert [p.decode().replace(".obj", ".ply").replace("/obj/", "/ply/") for p in a[name]] \
                == [p.decode() for p in b[name]]
            continue
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_obj_sequence_through_the_library_and_an_obj_reference(tmp_path):
    vertices, faces = grid(6, 5)
    xs = [vertices * [1 + 0.1 * k, 1, 1] for k in range(3)]  # stretched along x by 1, 1.1, 1.2
    folder = tmp_path / "seq"
    folder.mkdir()
    for k, x in enumerate(xs):
        write_obj(folder / f"f{k}.obj", x, faces)
    write_obj(tmp_path / "rest.obj", xs[0], faces)
    summary = clothtool.analyze_sequence(folder, tmp_path / "a.h5", reference=str(tmp_path / "rest.obj"))
    assert summary.frames == 3 and summary.pairs == 3
    with h5py.File(tmp_path / "a.h5") as f:
        stretch = f["face/stretch"][:]
    np.testing.assert_allclose(stretch[0], 1.0, atol=1e-6)  # frame 0 against itself
    np.testing.assert_allclose(stretch[1], [[1.1, 1.0]] * len(faces), rtol=1e-6)
    np.testing.assert_allclose(stretch[2], [[1.2, 1.0]] * len(faces), rtol=1e-6)


def test_mixed_formats_in_a_folder(tmp_path):
    xs, faces, _ = frames(tmp_path, 2)
    write_obj(tmp_path / "f0.obj", xs[0], faces)
    write_ply(tmp_path / "f1.ply", xs[1], faces)
    result = CliRunner().invoke(main, ["analyze", str(tmp_path), "-o", str(tmp_path / "o.h5")])
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "both .ply and .obj" in result.stderr
    assert not (tmp_path / "o.h5").exists()


# ------------------------------------------------------------------ the seam


def seam_mesh():
    """Two panels joined along a seam (shared vertices). Panel A is 1.2 × its uv width along u,
    panel B 0.8 ×; their uv lie apart in the atlas, so a seam vertex has two uv.
    Returns vertices, faces, per-corner uv, panel of each triangle, per-vertex uv (A's at the seam)."""
    na, nb, ny = 4, 5, 4
    ua, ub, v = np.linspace(0, 1, na), np.linspace(0, 1, nb), np.linspace(0, 1, ny)
    xs = np.concatenate([1.2 * ua, 1.2 + 0.8 * ub[1:]])  # the seam column is shared
    uv_a = ua
    uv_b = 2.0 + ub  # panel B's uv, offset in the atlas
    nx = len(xs)
    X, Y = np.meshgrid(xs, v)
    vertices = np.stack([X.ravel(), Y.ravel(), 0.1 * Y.ravel()], axis=1)
    faces, panel, corner_uv = [], [], []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            in_b = i >= na - 1
            for tri in ([a, a + 1, a + nx + 1], [a, a + nx + 1, a + nx]):
                faces.append(tri)
                panel.append(in_b)
                col = [t % nx for t in tri]
                row = [t // nx for t in tri]
                u = [uv_b[c - (na - 1)] if in_b else uv_a[c] for c in col]
                corner_uv.append([[u[q], v[row[q]]] for q in range(3)])
    vertex_uv = np.stack([np.concatenate([uv_a, uv_b[1:]])[np.arange(len(vertices)) % nx],
                          v[np.arange(len(vertices)) // nx]], axis=1)
    # the z tilt: y runs along the sheet's length √(1 + 0.01) per uv unit; undo it
    vertices[:, 1] /= np.sqrt(1.01)
    vertices[:, 2] /= np.sqrt(1.01)
    return vertices, np.array(faces), np.array(corner_uv), np.array(panel), vertex_uv


@pytest.mark.parametrize("kind", ["obj", "ply"])
def test_seam_panels_get_their_own_stretch(tmp_path, kind):
    vertices, faces, corner_uv, panel, vertex_uv = seam_mesh()
    frame = tmp_path / f"seam.{kind}"
    if kind == "obj":
        write_obj(frame, vertices, faces, corner_uv)
    else:
        frame.write_bytes(ply_with_texcoord(vertices, faces, corner_uv))
    result = analyze([frame, "-o", tmp_path / "seam.h5", "--reference", "uv", "--dtype", "float64"])
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "seam.h5") as f:
        stretch = f["face/stretch"][0]
        np.testing.assert_array_equal(f["mesh/corner_uv"][:], corner_uv)
        assert "mesh/uv" not in f
    np.testing.assert_allclose(stretch[~panel], [[1.2, 1.0]] * int((~panel).sum()), rtol=0, atol=1e-12)
    np.testing.assert_allclose(stretch[panel], [[1.0, 0.8]] * int(panel.sum()), rtol=0, atol=1e-12)

    # per-vertex uv cannot: a seam vertex has A's uv, so B's triangles along the seam are wrong
    write_ply(tmp_path / "pv.ply", vertices, faces,
              vertex_properties={"s": vertex_uv[:, 0], "t": vertex_uv[:, 1]})
    result = analyze([tmp_path / "pv.ply", "-o", tmp_path / "pv.h5", "--reference", "uv",
                      "--dtype", "float64"])
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "pv.h5") as f:
        per_vertex = f["face/stretch"][0]
        assert f["mesh/uv"].shape == (len(vertices), 2) and "mesh/corner_uv" not in f
    seam_b = panel & np.isin(faces, np.flatnonzero(np.isclose(vertices[:, 0], 1.2))).any(axis=1)
    assert seam_b.any()
    assert np.abs(per_vertex[seam_b] - [1.0, 0.8]).max() > 0.1
    np.testing.assert_allclose(per_vertex[panel & ~seam_b], stretch[panel & ~seam_b], atol=1e-12)


def test_per_corner_uv_wins_over_per_vertex_uv(tmp_path):
    vertices, faces, corner_uv, panel, vertex_uv = seam_mesh()
    (tmp_path / "both.ply").write_bytes(ply_with_texcoord(vertices, faces, corner_uv,
                                                          vertex_uv=vertex_uv))
    mesh = read_ply(tmp_path / "both.ply")
    assert mesh.uv is not None and mesh.corner_uv is not None
    result = analyze([tmp_path / "both.ply", "-o", tmp_path / "b.h5", "--reference", "uv"])
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "b.h5") as f:
        np.testing.assert_allclose(f["face/stretch"][0][panel], [[1.0, 0.8]] * int(panel.sum()),
                                   atol=1e-6)


def test_kabsch_with_uv_seam_fails_and_without_seam_works(tmp_path):
    vertices, faces, corner_uv, panel, _ = seam_mesh()
    write_obj(tmp_path / "seam.obj", vertices, faces, corner_uv)
    result = analyze([tmp_path / "seam.obj", "-o", tmp_path / "k.h5", "--reference", "uv", "--kabsch"])
    assert result.exit_code == 2 and "uv seam" in result.stderr and "seam.obj: line " in result.stderr
    assert not (tmp_path / "k.h5").exists()
    plain = vertices[faces][:, :, :2]  # one uv per vertex, written per corner
    write_obj(tmp_path / "plain.obj", vertices, faces, plain)
    result = analyze([tmp_path / "plain.obj", "-o", tmp_path / "k.h5", "--reference", "uv", "--kabsch"])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("body, message", [
    (b"vt 0 0 0 0\nf 1 2 3\n", "line 5: texture coordinate has 4 numbers"),
    (b"vt\nf 1 2 3\n", "line 5: texture coordinate has 0 numbers"),
    (b"f 1 2 3 4 5\n", "line 5: vertex index 5 is out of range (the file has 4 vertices)"),
    (b"f 1/1 2/2 3/3\n", "line 5: texture index 1 is out of range (the file has 0 texture"),
    (b"f 1//2 2//2 3//2\nvn 0 0 1\n", "line 5: normal index 2 is out of range"),
    (b"f 1/1/1/1 2 3\n", "line 5: bad face corner '1/1/1/1'"),
    (b"f 1 2 x\n", "line 5: index 'x' is not an integer"),
    (b"f 1 2 3\nf 1\n", "line 6: face has 1 corners"),
])
def test_errors_name_the_line(body, message):
    with pytest.raises(InputError, match="^bad.obj: " + message.replace("(", r"\(").replace(")", r"\)")):
        parse_obj(SQUARE + body, "bad.obj")


def _same_mesh(a, b):
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
    assert np.array_equal(a.face_source, b.face_source)
    assert np.array_equal(a.source_lines, b.source_lines)
    for x, y in ((a.corner_uv, b.corner_uv), (a.corner_uv_missing, b.corner_uv_missing)):
        assert (x is None) == (y is None) and (x is None or np.array_equal(x, y, equal_nan=True))


REUSE_BODIES = {
    "triangles": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n",
    "uv and a quad": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
                     b"f 1/1 2/2 4/4 3/3\n",
    "relative indices": b"o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//1 -2//1 -1//1\n",
    "uv on some corners": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                          b"f 1/1 2/2 3/3\nf 2 4 3\n",
}


@pytest.mark.parametrize("body", REUSE_BODIES.values(), ids=REUSE_BODIES)
def test_faces_of_a_sequence_are_parsed_once(body):
    """A frame that ends with the first frame's face block after as many v, vt and vn lines
    takes its faces without parsing them, and reads as a fresh parse does; moved vertices and
    texture positions are read anew."""
    first = parse_obj(body, "f0.obj")
    assert first.face_block and body.endswith(first.face_block)
    moved = body.replace(b"v 1 0 0", b"v 1.5 0.25 0").replace(b"vt 1 0", b"vt 0.5 0.5")
    later = parse_obj(moved, "f1.obj", reuse=first)
    assert later.faces is first.faces  # taken over, not parsed
    _same_mesh(later, parse_obj(moved, "f1.obj"))
    assert later.vertices[1].tolist() == [1.5, 0.25, 0.0]


@pytest.mark.parametrize("change", [
    lambda b: b + b"f 1 2 3\n",  # another face
    lambda b: b.replace(b"v 0 0 0\n", b"v 0 0 0\nv 9 9 9\n", 1),  # the indices mean other vertices
    lambda b: b.replace(b"f ", b"# c\nf ", 1),  # the face lines are no longer the last lines
    lambda b: b + b"# end\n",
    lambda b: b"vt 0 0\n" + b,  # one more texture coordinate
])
def test_faces_are_parsed_again_when_they_may_differ(change):
    body = REUSE_BODIES["relative indices"]
    first = parse_obj(body, "f0.obj")
    other = change(body)
    _same_mesh(parse_obj(other, "f1.obj", reuse=first), parse_obj(other, "f1.obj"))


def test_a_reused_face_block_still_checks_the_head():
    first = parse_obj(REUSE_BODIES["triangles"], "f0.obj")
    bad = REUSE_BODIES["triangles"].replace(b"v 1 1 0", b"v 1 x 0")
    with pytest.raises(InputError, match="f1.obj: line 4: 'x' is not a number"):
        parse_obj(bad, "f1.obj", reuse=first)
    with pytest.raises(InputError, match="line 1: unknown statement 'q'"):
        parse_obj(b"q\n" + REUSE_BODIES["triangles"], "f1.obj", reuse=first)
