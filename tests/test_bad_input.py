"""Bad input through the CLI: a corpus of broken files, sequences, options and
output paths, each built here. Every case must give its exit code, one line on stderr
naming the culprit, no traceback, and leave nothing behind: no new output, no temporary
file, and an existing output byte-identical."""

import os
import tracemalloc
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import grid

from clothtool.cli import main
from clothtool.errors import InputError
from clothtool.io.frames import read_mesh
from clothtool.io.ply import read_ply, write_ply

VERTICES, FACES = grid(4, 3)  # 12 vertices, 12 triangles
PREVIOUS = b"a previous result that a failed run must not touch"
PEAK_BYTES = 64 << 20  # a bad file fails before its declared counts are allocated


@dataclass
class Case:
    inputs: list  # FRAMES arguments
    culprit: str  # must appear in the message
    options: list = field(default_factory=list)
    code: int = 2
    output: Path | None = None  # default: tmp/out/out.h5
    patch: dict = field(default_factory=dict)  # "module.attr" → replacement, for faults
    also: str = ""  # a second name the message must contain
    broken_file: Path | None = None  # the broken PLY file, for the library check


CASES = {}


def case(builder):
    CASES[builder.__name__] = builder
    return builder


def sequence(tmp, frames=3, uv=True, name="seq"):
    """A small valid sequence; returns the folder."""
    folder = tmp / name
    folder.mkdir(exist_ok=True)
    props = {"s": VERTICES[:, 0], "t": VERTICES[:, 1]} if uv else None
    for k in range(frames):
        write_ply(folder / f"frame_{k}.ply", VERTICES * [1 + 0.1 * k, 1, 1], FACES,
                  vertex_properties=props)
    return folder


def header(fmt="binary_little_endian", n_vertices=4, n_faces=2, count="uchar", index="int",
           vertex_props="xyz", extra=()):
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {n_vertices}"]
    lines += [f"property float {p}" for p in vertex_props]
    if n_faces is not None:
        lines += [f"element face {n_faces}", f"property list {count} {index} vertex_indices"]
    lines += list(extra) + ["end_header"]
    return ("\n".join(lines) + "\n").encode("ascii")


QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "<f4")


def binary(faces, count="<u1", index="<i4", n_faces=None, **kw):
    """A binary little-endian PLY of QUAD with ``faces`` (lists of indices)."""
    body = QUAD.tobytes()
    for f in faces:
        body += np.array([len(f)], count).tobytes() + np.array(f, index).tobytes()
    names = {"<u1": "uchar", "<i4": "int", "<u4": "uint"}
    return header(n_faces=len(faces) if n_faces is None else n_faces, count=names[count],
                  index=names[index], **kw) + body


def ascii_ply(vertex_lines, face_lines, **kw):
    kw.setdefault("n_vertices", len(vertex_lines))
    kw.setdefault("n_faces", len(face_lines))
    return header("ascii", **kw) + ("\n".join(vertex_lines + face_lines) + "\n").encode("ascii")


GOOD_ASCII_VERTICES = ["0 0 0", "1 0 0", "1 1 0", "0 1 0"]


def broken_frame(tmp, data, name="frame_1.ply"):
    """A sequence of two frames whose second is ``data``."""
    folder = tmp / "seq"
    folder.mkdir()
    (folder / "frame_0.ply").write_bytes(binary([[0, 1, 2], [0, 2, 3]]))
    (folder / name).write_bytes(data)
    return Case([str(folder)], name, broken_file=folder / name)


# ------------------------------------------------------------------ broken PLY files


@case
def non_ascii_header(tmp):
    data = binary([[0, 1, 2]]).replace(b"ply\n", "ply\ncomment caf\u00e9 \u00e0 Z\u00fcrich\n".encode(), 1)
    return broken_frame(tmp, data)


@case
def huge_vertex_count_ascii(tmp):
    data = ascii_ply(GOOD_ASCII_VERTICES, ["3 0 1 2"], n_vertices=10**12)
    return broken_frame(tmp, data)


@case
def ascii_too_few_numbers(tmp):
    c = broken_frame(tmp, ascii_ply(["0 0 0", "1 0", "1 1 0", "0 1 0"], ["3 0 1 2"]))
    c.culprit = "line 11: vertex 1 has 2 numbers"  # the header has 9 lines
    return c


# broken second frames of a PLY sequence: name → a function making the file's bytes
BROKEN_FRAMES = {
    "empty_file": lambda: b"",
    "text_file_named_ply": lambda: b"hello, I am not a mesh\n",
    "garbage_bytes": lambda: np.random.default_rng(1).integers(0, 256, 4096, np.uint8).tobytes(),
    "missing_end_header": lambda: header().replace(b"end_header\n", b"") + QUAD.tobytes(),
    "end_header_without_line_break": lambda: header(n_faces=None, n_vertices=0).rstrip(b"\n"),
    "unknown_format":
        lambda: binary([[0, 1, 2]]).replace(b"binary_little_endian", b"binary_middle_endian"),
    "unknown_property_type":
        lambda: binary([[0, 1, 2]]).replace(b"property float y", b"property float3 y"),
    "unknown_header_keyword": lambda: binary([[0, 1, 2]], extra=["elemnt edge 3"]),
    "huge_vertex_count_binary":
        lambda: binary([[0, 1, 2]]).replace(b"element vertex 4", b"element vertex 1000000000000"),
    "huge_face_count_binary": lambda: binary([[0, 1, 2]], n_faces=10**12),
    "truncated_in_vertices": lambda: binary([[0, 1, 2]])[:-30],
    "truncated_in_faces": lambda: binary([[0, 1, 2], [0, 2, 3], [0, 1, 3]])[:-5],
    "truncated_ascii": lambda: ascii_ply(GOOD_ASCII_VERTICES, ["3 0 1 2"], n_faces=3),
    "trailing_bytes": lambda: binary([[0, 1, 2]]) + b"\0" * 7,
    "ascii_not_a_number": lambda: ascii_ply(["0 0 0", "1 0 zero", "1 1 0", "0 1 0"], ["3 0 1 2"]),
    "ascii_list_longer_than_line": lambda: ascii_ply(GOOD_ASCII_VERTICES, ["3 0 1 2", "4 0 1 2"]),
    "ascii_negative_list_count": lambda: ascii_ply(GOOD_ASCII_VERTICES, ["3 0 1 2", "-1 0 1 2"]),
    "face_with_two_corners_binary": lambda: binary([[0, 1, 2], [0, 1]]),
    "face_with_two_corners_ascii": lambda: ascii_ply(GOOD_ASCII_VERTICES, ["2 0 1", "2 1 2"]),
    "index_out_of_range": lambda: binary([[0, 1, 2], [0, 2, 4]]),
    "negative_index": lambda: binary([[0, 1, 2], [0, -1, 3]]),
    "non_integer_index": lambda: ascii_ply(GOOD_ASCII_VERTICES, ["3 0 1 2.5"]),
    "negative_list_count_binary":
        lambda: binary([[0, 1, 2], [0, 2, 3]], count="<i4")[:-16] + np.array([-3, 0, 2, 3], "<i4").tobytes(),
    "huge_list_count_binary":
        lambda: binary([[0, 1, 2]], count="<u4")[:-16] + np.array([4_000_000_000, 0, 1, 2], "<u4").tobytes(),
    "no_vertex_element":
        lambda: b"ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n0\n",
    "vertex_without_z": lambda: ascii_ply(["0 0", "1 0", "1 1"], ["3 0 1 2"], vertex_props="xy"),
    "duplicate_property":
        lambda: binary([[0, 1, 2]]).replace(b"property float z", b"property float x"),
    "face_without_vertex_indices":
        lambda: binary([[0, 1, 2]]).replace(b"vertex_indices", b"corner_ids"),
}
for _name, _make in BROKEN_FRAMES.items():
    CASES[_name] = lambda tmp, make=_make: broken_frame(tmp, make())


@case
def first_frame_without_faces(tmp):
    folder = tmp / "seq"
    folder.mkdir()
    (folder / "frame_0.ply").write_bytes(header(n_faces=0) + QUAD.tobytes())
    (folder / "frame_1.ply").write_bytes(binary([[0, 1, 2]]))
    return Case([str(folder)], "frame_0.ply")


# ------------------------------------------------------------------ sequences


@case
def empty_folder(tmp):
    (tmp / "seq").mkdir()
    return Case([str(tmp / "seq")], "seq")


@case
def folder_without_ply_files(tmp):
    (tmp / "seq").mkdir()
    (tmp / "seq" / "notes.txt").write_text("frames to come")
    return Case([str(tmp / "seq")], "no .ply or .obj files")


@case
def glob_matching_nothing(tmp):
    sequence(tmp)
    return Case([str(tmp / "seq" / "*.PLY2")], "*.PLY2")


@case
def missing_input(tmp):
    return Case([str(tmp / "nowhere")], "nowhere")


@case
def single_frame_previous(tmp):
    return Case([str(sequence(tmp, frames=1))], "frame_0.ply", ["--reference", "previous"])


@case
def single_frame_first(tmp):
    return Case([str(sequence(tmp, frames=1))], "frame_0.ply", ["--reference", "first"])


@case
def vertex_count_differs(tmp):
    folder = sequence(tmp, frames=4)
    write_ply(folder / "frame_2.ply", np.vstack([VERTICES, [[5, 5, 5]]]), FACES)
    return Case([str(folder)], "frame_2.ply", also="frame_0.ply")


@case
def faces_differ(tmp):
    folder = sequence(tmp, frames=4)
    write_ply(folder / "frame_3.ply", VERTICES, FACES[:, [0, 2, 1]])
    return Case([str(folder)], "frame_3.ply", also="frame_0.ply")


@case
def uv_reference_without_uv(tmp):
    return Case([str(sequence(tmp, uv=False))], "texture coordinates", ["--reference", "uv"])


@case
def unknown_reference(tmp):
    return Case([str(sequence(tmp))], "prev", ["--reference", "prev"])


@case
def reference_is_a_folder(tmp):
    (tmp / "rest.ply").mkdir()
    return Case([str(sequence(tmp))], "rest.ply", ["--reference", str(tmp / "rest.ply")])


@case
def reference_mesh_does_not_match(tmp):
    write_ply(tmp / "rest.ply", VERTICES[:6], [[0, 1, 4], [0, 4, 3]])
    return Case([str(sequence(tmp))], "rest.ply", ["--reference", str(tmp / "rest.ply")],
                also="frame_0.ply")


@case
def unknown_field(tmp):
    return Case([str(sequence(tmp))], "strech", ["--fields", "stretch,strech"])


@case
def bad_compression(tmp):
    return Case([str(sequence(tmp))], "gzip=12", ["--compression", "gzip=12"])


@case
def uv_scale_not_a_number(tmp):
    return Case([str(sequence(tmp))], "--uv-scale", ["--uv-scale", "half"])


@case
def no_frames_given(tmp):
    return Case([], "FRAMES")


# ------------------------------------------------------------------ output paths and faults


def no_work(*args, **kwargs):
    raise AssertionError("frames were looked at before the output path was checked")


BEFORE_ANY_WORK = {"clothtool.analysis.sequence.discover_frames": no_work}


@case
def output_folder_missing(tmp):
    return Case([str(sequence(tmp))], "missing", output=tmp / "missing" / "out.h5",
                patch=BEFORE_ANY_WORK)


@case
def output_is_a_folder(tmp):
    (tmp / "out" / "result.h5").mkdir(parents=True)
    return Case([str(sequence(tmp))], "result.h5", output=tmp / "out" / "result.h5",
                patch=BEFORE_ANY_WORK)


@case
def output_is_an_input_frame(tmp):
    folder = sequence(tmp)
    frame = folder / "frame_1.ply"
    return Case([str(folder)], "frame_1.ply", output=frame)


@case
def output_is_the_reference_mesh(tmp):
    write_ply(tmp / "rest.ply", VERTICES, FACES)
    return Case([str(sequence(tmp))], "rest.ply", ["--reference", str(tmp / "rest.ply")],
                output=tmp / "rest.ply")


@case
def input_is_not_a_regular_file(tmp):
    os.mkfifo(tmp / "pipe.ply")
    return Case([str(tmp / "pipe.ply")], "pipe.ply: not a regular file")


@case
def output_folder_not_writable(tmp):
    (tmp / "out").mkdir()
    real = os.access
    def access(path, mode):  # chmod does not stop root, so pretend
        return False if os.path.abspath(path) == str(tmp / "out") else real(path, mode)
    return Case([str(sequence(tmp))], "not writable",
                patch={"clothtool.io.h5.os.access": access, **BEFORE_ANY_WORK})


@case
def disk_full_while_writing(tmp):
    def full(self, key, value):
        raise OSError(28, "No space left on device")
    return Case([str(sequence(tmp))], "No space left on device",
                patch={"h5py.Dataset.__setitem__": full})


@case
def out_of_memory(tmp):
    def huge(self, dtype):
        raise MemoryError("Unable to allocate 74.5 GiB for an array")
    return Case([str(sequence(tmp))], "out of memory: Unable to allocate 74.5 GiB",
                patch={"clothtool.analysis.deformation2d.KernelPlan.allocate": huge})


@case
def internal_bug(tmp):
    def bug(*args):
        raise ZeroDivisionError("a bug in a kernel")
    return Case([str(sequence(tmp))], "ZeroDivisionError: a bug in a kernel", code=1,
                patch={"clothtool.analysis.sequence.deformation_fields_and_next_rest": bug})


@case
def sidecar_fails_after_the_hdf5_is_complete(tmp):
    def bug(h5, name):
        raise KeyError("a bug in the XDMF writer")
    return Case([str(sequence(tmp))], "a bug in the XDMF writer", code=1,
                patch={"clothtool.analysis.sequence.xdmf_text": bug})


# ------------------------------------------------------------------ broken OBJ files

GOOD_OBJ = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"


def broken_obj(tmp, data, line, options=()):
    """An OBJ sequence of two frames whose second is ``data``; the message must name ``line``."""
    folder = tmp / "seq"
    folder.mkdir()
    (folder / "frame_0.obj").write_bytes(GOOD_OBJ + b"f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (folder / "frame_1.obj").write_bytes(data)
    return Case([str(folder)], f"frame_1.obj: line {line}:", list(options),
                broken_file=folder / "frame_1.obj")


# broken second frames of an OBJ sequence: name → (its text, the line the message must name)
BROKEN_OBJ = {
    "obj_index_out_of_range": (GOOD_OBJ + b"f 1 2 3\nf 1 3 5\n", 10),
    "obj_negative_index_out_of_range": (GOOD_OBJ + b"f 1 2 3\nf -1 -2 -5\n", 10),
    "obj_index_zero": (GOOD_OBJ + b"f 0 1 2\n", 9),
    "obj_texture_index_out_of_range": (GOOD_OBJ + b"f 1/1 2/2 3/9\n", 9),
    "obj_face_with_two_corners": (GOOD_OBJ + b"f 1 2 3\nf 1 2\n", 10),
    "obj_bad_corner": (GOOD_OBJ + b"f 1/1/1/1 2 3\n", 9),
    "obj_non_integer_index": (GOOD_OBJ + b"f 1 2.5 3\n", 9),
    "obj_vertex_with_two_coordinates": (GOOD_OBJ.replace(b"v 1 1 0", b"v 1 1") + b"f 1 2 3\n", 3),
    "obj_non_numeric_coordinate": (GOOD_OBJ.replace(b"v 1 1 0", b"v 1 one 0") + b"f 1 2 3\n", 3),
    "obj_unknown_statement": (GOOD_OBJ + b"f 1 2 3\nbogus 1 2\n", 10),
}
for _name, (_data, _line) in BROKEN_OBJ.items():
    CASES[_name] = lambda tmp, data=_data, line=_line: broken_obj(tmp, data, line)


@case
def obj_uv_missing_on_some_corners(tmp):
    """A seam mesh whose second face lost its vt: fine for other references, not for uv."""
    folder = tmp / "seq"
    folder.mkdir()
    (folder / "frame_0.obj").write_bytes(GOOD_OBJ + b"f 1/1 2/2 3/3\nf 1/1 3 4/4\n")
    return Case([str(folder)], "frame_0.obj: line 10:", ["--reference", "uv"], also="uv on every corner")


@case
def ply_texcoord_missing_on_some_faces(tmp):
    folder = tmp / "seq"
    folder.mkdir()
    data = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            b"property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
            b"3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 0\n")
    (folder / "frame_0.ply").write_bytes(data)
    return Case([str(folder)], "frame_0.ply: face 1:", ["--reference", "uv"], also="uv on every corner")


@case
def mixed_ply_and_obj_in_a_folder(tmp):
    folder = sequence(tmp)
    (folder / "frame_9.obj").write_bytes(GOOD_OBJ + b"f 1 2 3\n")
    return Case([str(folder)], "both .ply and .obj", also=str(folder))


@case
def broken_obj_reference(tmp):
    folder = sequence(tmp)
    (tmp / "rest.obj").write_bytes(b"v 0 0 0\nf 1 2 3\n")
    return Case([str(folder)], "rest.obj: line 2:", ["--reference", str(tmp / "rest.obj")])


# ------------------------------------------------------------------ the checks


def run(tmp, c, monkeypatch):
    output = c.output
    if output is None:
        output = tmp / "out" / "out.h5"
        output.parent.mkdir(exist_ok=True)
    for target, replacement in c.patch.items():
        monkeypatch.setattr(target, replacement)
    tracemalloc.start()
    try:
        result = CliRunner().invoke(main, ["analyze", *c.inputs, "-o", str(output), *c.options])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    monkeypatch.undo()
    return result, output, peak


def snapshot(folder):
    """Names and contents of the files in ``folder`` (hidden temporary files included)."""
    if not folder.is_dir():
        return {}
    return {p.name: p.read_bytes() if p.is_file() else "folder" for p in folder.iterdir()}


def check(result, c, peak):
    assert result.exit_code == c.code, (result.exit_code, result.output, result.exception)
    assert result.stdout == ""
    message = result.stderr
    assert message.startswith("clothtool: ") and message.endswith("\n")
    assert message.count("\n") == 1, message  # one line
    assert "Traceback" not in result.output
    assert c.culprit in message, message
    assert c.also in message, message
    assert peak < PEAK_BYTES, peak  # huge declared counts fail at once, not after allocating


@pytest.mark.parametrize("name", sorted(CASES))
def test_corpus_case_fails_cleanly(tmp_path, monkeypatch, name):
    c = CASES[name](tmp_path)
    folder = (c.output or tmp_path / "out" / "out.h5").parent
    before = snapshot(folder)
    result, output, peak = run(tmp_path, c, monkeypatch)
    check(result, c, peak)
    assert snapshot(folder) == before, "output or temporary file left behind"
    if not folder.is_dir() or output.exists():
        return
    output.write_bytes(PREVIOUS)  # again, over an existing result and its XDMF
    output.with_suffix(".xdmf").write_bytes(PREVIOUS)
    before = snapshot(folder)
    result, output, peak = run(tmp_path, c, monkeypatch)
    check(result, c, peak)
    assert snapshot(folder) == before, "existing output changed or temporary file left behind"


def test_corpus_is_large_enough():
    assert len(CASES) >= 30


def test_broken_files_raise_input_error_from_the_library(tmp_path):
    """The same files through ``read_mesh`` give InputError naming the file, nothing else."""
    count = 0
    for name, builder in CASES.items():
        (tmp_path / name).mkdir()
        c = builder(tmp_path / name)
        if c.broken_file is not None:
            with pytest.raises(InputError, match=c.broken_file.name):
                read_mesh(c.broken_file)
            count += 1
    assert count >= 25


def test_folder_passed_as_a_file(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        read_ply(tmp_path)


def test_debug_shows_the_traceback_and_keeps_the_exit_code(tmp_path):
    result = CliRunner().invoke(main, ["--debug", "analyze", str(tmp_path / "nowhere"),
                                       "-o", str(tmp_path / "o.h5")])
    assert result.exit_code == 2
    assert result.stderr.startswith("Traceback")
    assert result.stderr.splitlines()[-1] == f"clothtool: error: {tmp_path / 'nowhere'}: no such file or folder"


def test_non_finite_coordinates_are_flagged_not_rejected(tmp_path):
    """A NaN or inf coordinate flags the triangles using that vertex (bit 2) and
    makes their float fields NaN; the other triangles and the run are unaffected."""
    folder = sequence(tmp_path, frames=3)
    x = VERTICES * [1.2, 1, 1]
    x[5] = [np.nan, 0, 0]
    x[7] = [0, np.inf, 0]
    write_ply(folder / "frame_1.ply", x, FACES, binary=False)  # ascii 'nan' and 'inf'
    out = tmp_path / "out.h5"
    result = CliRunner().invoke(main, ["analyze", str(folder), "-o", str(out)])
    assert result.exit_code == 0, result.output
    touched = np.isin(FACES, [5, 7]).any(axis=1)
    with h5py.File(out) as f:
        flags = f["face/flags"][:]
        stretch = f["face/stretch"][:]
    for p in (0, 1):  # (0, 1): frame 1 deformed; (1, 2): frame 1 is the reference
        assert np.all(flags[p][touched] & 4)
        assert np.all(np.isnan(stretch[p][touched]))
        assert np.all(flags[p][~touched] == 0)
        assert np.all(np.isfinite(stretch[p][~touched]))


@pytest.mark.parametrize("args", [["--help"], ["analyze", "--help"]])
def test_help_documents_the_exit_codes(args):
    text = " ".join(CliRunner().invoke(main, args).output.split())
    for code in ("0 done", "2 bad input", "3 numerical failure", "130 interrupted", "1 internal error"):
        assert code in text


def test_a_large_file_that_is_not_a_ply_is_not_read_whole(tmp_path):
    big = tmp_path / "video.ply"
    with open(big, "wb") as fh:
        fh.truncate(1 << 30)  # 1 GiB, sparse
    tracemalloc.start()
    with pytest.raises(InputError, match="video.ply: not a PLY file"):
        read_ply(big)
    assert tracemalloc.get_traced_memory()[1] < 1 << 20
    tracemalloc.stop()


@pytest.fixture(scope="module")
def result_file(tmp_path_factory):
    """A small valid analysis result, and a file that is not HDF5."""
    tmp = tmp_path_factory.mktemp("result")
    out = tmp / "r.h5"
    assert CliRunner().invoke(main, ["analyze", str(sequence(tmp)), "-o", str(out)]).exit_code == 0
    (tmp / "bad.h5").write_bytes(b"not HDF5 at all")
    return tmp


@pytest.mark.parametrize("args,culprit", [
    (["info", "{dir}/bad.h5"], "bad.h5: not an HDF5 file"),
    (["info", "{dir}/missing.h5"], "missing.h5"),
    (["export", "{dir}/bad.h5", "-o", "{out}/x.ply"], "bad.h5"),
    (["export", "{dir}/r.h5", "--pair", "99", "-o", "{out}/x.ply"], "99"),
    (["export", "{dir}/r.h5", "--field", "bogus", "-o", "{out}/x.ply"], "bogus"),
    (["plot", "{dir}/bad.h5", "-o", "{out}/x.png"], "bad.h5"),
    (["plot", "{dir}/r.h5", "-o", "{out}/x.xyz"], "unknown image format 'xyz'"),
    (["merge", "{dir}/bad.h5", "-o", "{out}/m.h5"], "bad.h5"),
    (["merge", "{dir}/r.h5", "-o", "{dir}/r.h5"], "r.h5"),
])
def test_other_commands_fail_cleanly(tmp_path, result_file, args, culprit):
    pytest.importorskip("matplotlib")
    before = snapshot(result_file)
    args = [a.format(dir=result_file, out=tmp_path) for a in args]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("clothtool: error: ")
    assert culprit in result.stderr
    assert list(tmp_path.iterdir()) == []
    assert snapshot(result_file) == before
