"""Fuzzing the PLY and OBJ readers with hypothesis: random bytes, and valid files (ascii and
binary; OBJ of every corner form) mutated in their header and body. Every outcome is a consistent PlyMesh or an
InputError naming the file, never another exception, a hang or a large allocation."""

import contextlib
import os
import signal
import tracemalloc

import numpy as np
import pytest
from conftest import grid
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from clothtool.errors import InputError
from clothtool.io.obj import parse_obj
from clothtool.io.ply import PlyMesh, parse_ply, write_ply

# CLOTHTOOL_FUZZ_EXAMPLES=20000 pytest tests/test_fuzz.py  for a longer hunt
FUZZ = settings(max_examples=int(os.environ.get("CLOTHTOOL_FUZZ_EXAMPLES", 300)), deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
HANG_SECONDS = 10
NAME = "fuzzed.ply"


def seeds(tmp_path_factory):
    """Valid files: ascii and binary, triangles and polygons, with and without extras."""
    folder = tmp_path_factory.mktemp("seeds")
    vertices, faces = grid(4, 3)
    uv = {"s": vertices[:, 0].astype(np.float32), "t": vertices[:, 1].astype(np.float32)}
    quads = np.array([[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6]])
    out = {}
    for name, kw in {
        "binary": dict(faces=faces),
        "binary_uv": dict(faces=faces, vertex_properties=uv),
        "binary_quads": dict(faces=quads),
        "ascii": dict(faces=faces, binary=False),
        "ascii_uv_quads": dict(faces=quads, vertex_properties=uv, binary=False),
    }.items():
        path = folder / f"{name}.ply"
        write_ply(path, vertices, **kw)
        out[name] = path.read_bytes()
    mixed = (b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\n"
             b"property double y\nproperty double z\nproperty uchar red\nelement face 2\n"
             b"property list int uint vertex_indices\nend_header\n")
    body = np.zeros(4, ">f8,>f8,>f8,u1")
    body["f1"] = [0, 1, 1, 0]
    body["f2"] = [0, 0, 1, 1]
    mixed += body.tobytes()
    mixed += np.array([4], ">i4").tobytes() + np.array([0, 1, 2, 3], ">u4").tobytes()
    mixed += np.array([3], ">i4").tobytes() + np.array([0, 2, 3], ">u4").tobytes()
    out["big_endian_mixed_polygons"] = mixed
    ints = (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\n"
            b"property float y\nproperty float z\nelement face 3\n"
            b"property list int int vertex_indices\nproperty uchar flags\nend_header\n")
    ints += np.arange(15, dtype="<f4").tobytes()
    for poly in ([0, 1, 2], [0, 2, 3, 4], [1, 3, 4]):
        ints += np.array([len(poly), *poly], "<i4").tobytes() + b"\x07"
    out["int_counts_varying_polygons"] = ints
    return out


@pytest.fixture(scope="module")
def seed_files(tmp_path_factory):
    files = seeds(tmp_path_factory)
    for data in files.values():
        assert isinstance(parse_ply(data, NAME), PlyMesh)
    return files


class Hang(BaseException):
    """Raised by the alarm: a BaseException, so that no reader's error handling can hide it."""


@contextlib.contextmanager
def no_hang(seconds=HANG_SECONDS):
    """Raise :class:`Hang` once the block has used ``seconds`` of this process's CPU time
    (ITIMER_PROF: a loaded machine slows the wall clock, not the CPU a loop burns)."""
    def expire(signum, frame):
        raise Hang(f"reading took more than {seconds} s of CPU")
    old = signal.signal(signal.SIGPROF, expire)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old)


def parsed(parse, data, name, bytes_per_input_byte, **kwargs):
    """parse(data, name)'s mesh, or None for a one-line InputError naming the file; checks the
    mesh is consistent and that the peak allocation stays proportional to the input."""
    tracemalloc.start()
    try:
        with no_hang():
            mesh = parse(data, name, **kwargs)
    except InputError as exc:
        assert name in str(exc) and "\n" not in str(exc)
        return None
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert peak < (8 << 20) + bytes_per_input_byte * len(data), f"peak allocation {peak} bytes"
    n = len(mesh.vertices)
    assert mesh.vertices.shape == (n, 3) and mesh.vertices.dtype == np.float64
    assert mesh.faces.ndim == 2 and mesh.faces.shape[1] == 3 and mesh.faces.dtype == np.int64
    assert mesh.face_source.shape == (len(mesh.faces),)
    if mesh.faces.size:
        assert 0 <= mesh.faces.min() and mesh.faces.max() < n
    return mesh


def outcome(data, reuse=None):
    """parse_ply's result or None for an InputError (:func:`parsed`)."""
    mesh = parsed(parse_ply, data, NAME, 200, reuse=reuse)
    if mesh is None:
        return None
    n = len(mesh.vertices)
    for values in mesh.vertex_properties.values():
        assert len(values) == n
    return mesh


@FUZZ
@given(st.binary(max_size=4096))
def test_random_bytes(data):
    outcome(data)


@FUZZ
@given(st.sampled_from([b"ply\n", b"ply\nformat ascii 1.0\n", b"ply\nformat binary_little_endian 1.0\n"]),
       st.binary(max_size=2048))
def test_random_bytes_after_a_plausible_start(start, data):
    outcome(start + data)


INTERESTING = [0, 1, 2, 3, 0x7F, 0x80, 0xFF, 0xFFFF, 2**31 - 1, 2**32 - 1, -1, -3, -(2**31)]


@st.composite
def edit(draw):
    """Bytes to put in place of ``length`` bytes: a random byte, or an interesting
    integer (negative, huge) packed as 1, 2 or 4 bytes in either byte order."""
    if draw(st.booleans()):
        return bytes([draw(st.sampled_from([0, 0xFF, 0x80, *b"9- \nx."]) | st.integers(0, 255))])
    value = draw(st.sampled_from(INTERESTING))
    size = draw(st.sampled_from([1, 2, 4]))
    order = draw(st.sampled_from(["little", "big"]))
    return (value % (1 << (8 * size))).to_bytes(size, order)


def edited(draw, data, place):
    """``data`` with 1-8 edits (overwrite, insert, delete) at offsets drawn by ``place(data)``
    (None: no edit this time), and maybe truncated."""
    data = bytearray(data)
    for _ in range(draw(st.integers(1, 8))):
        at = place(data)
        if at is None:
            continue
        kind = draw(st.sampled_from(["overwrite", "insert", "delete"]))
        if kind == "delete":
            del data[at:at + draw(st.integers(1, 4))]
            continue
        new = draw(edit())
        if kind == "overwrite":
            data[at:at + len(new)] = new
        else:
            data[at:at] = new
    if draw(st.integers(0, 3)) == 0:
        data = data[:draw(st.integers(0, len(data)))]
    return bytes(data)


@st.composite
def mutated(draw, files):
    """A seed file with 1-8 edits and maybe truncated (:func:`edited`). An edit lands in the
    header, anywhere in the body, or in the last quarter (the face block)."""
    name = draw(st.sampled_from(sorted(files)))
    header_end = files[name].index(b"end_header") + len(b"end_header\n")

    def place(data):
        where = draw(st.sampled_from(["header", "body", "tail"]))
        lo, hi = {"header": (0, header_end), "body": (header_end, len(data)),
                  "tail": (max(header_end, len(data) * 3 // 4), len(data))}[where]
        return draw(st.integers(lo, hi - 1)) if hi > lo else None

    return name, edited(draw, files[name], place)


TOKENS = ["0", "-1", "1", "3", "255", "4294967295", "1000000000000", "99999999999999999999",
          "float", "double", "uchar", "int", "uint", "list", "vertex", "face", "x", "s",
          "vertex_indices", "binary_little_endian", "binary_big_endian", "ascii", "end_header",
          "nan", "inf", "1e308", "", "\u00e9"]


@st.composite
def retokened(draw, files):
    """A seed file with 1-3 whitespace-separated words (header or ascii body) replaced by
    troublesome ones: huge and negative counts, other types, non-ASCII."""
    name = draw(st.sampled_from(sorted(files)))
    data = files[name]
    header_end = data.index(b"end_header")
    text_end = len(data) if b"format ascii" in data[:header_end] else header_end
    words = data[:text_end].decode("ascii").split(" ")
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(words) - 1))
        lines = words[i].split("\n")
        j = draw(st.integers(0, len(lines) - 1))
        lines[j] = draw(st.sampled_from(TOKENS))
        words[i] = "\n".join(lines)
    return name, " ".join(words).encode("utf-8") + data[text_end:]


@FUZZ
@given(st.data())
def test_mutated_files(seed_files, data):
    name, mutant = data.draw(mutated(seed_files))
    outcome(mutant)
    outcome(mutant, reuse=parse_ply(seed_files[name], NAME))  # the face-block reuse path


@FUZZ
@given(st.data())
def test_retokened_files(seed_files, data):
    name, mutant = data.draw(retokened(seed_files))
    assume(mutant != seed_files[name])
    outcome(mutant)
    outcome(mutant, reuse=parse_ply(seed_files[name], NAME))


@pytest.mark.parametrize("count", ["1000000000000", "4294967295", "200000000"])
@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
@pytest.mark.parametrize("element", ["vertex", "face"])
def test_huge_declared_counts_allocate_nothing(seed_files, fmt, element, count):
    seed = seed_files["ascii" if fmt == "ascii" else "binary"]
    start = seed.index(f"element {element} ".encode())
    stop = seed.index(b"\n", start)
    data = seed[:start] + f"element {element} {count}".encode() + seed[stop:]
    assert outcome(data) is None  # and the peak allocation check inside outcome()


# ---------------------------------------------------------------------------- OBJ

OBJ_NAME = "fuzzed.obj"


def obj_seeds():
    """Valid OBJ files: every corner form, negative indices, polygons, mixed forms, extras."""
    vertices, faces = grid(4, 3)
    v = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist())
    vt = "".join(f"vt {x!r} {y!r}\n" for x, y, _ in vertices.tolist())
    tri = faces + 1
    out = {
        "plain": v + "".join("f %d %d %d\n" % tuple(f) for f in tri),
        "vt": v + vt + "".join("f %d/%d %d/%d %d/%d\n" % (a, a, b, b, c, c) for a, b, c in tri),
        "vn": v + "vn 0 0 1\n" + "".join("f %d//1 %d//1 %d//1\n" % tuple(f) for f in tri),
        "vtn": v + vt + "vn 0 0 1\n" + "".join("f %d/%d/1 %d/%d/1 %d/%d/1\n" % (a, a, b, b, c, c)
                                              for a, b, c in tri),
        "negative": v + "".join("f %d %d %d\n" % tuple(f - 13) for f in tri),
        "quads_mixed": "# c\no x\n" + v + vt + "g a\ns 1\nusemtl m\nf 1/1 2/2 6/6 5/5\n"
                       "f 2 3 7 6\nf 3/3 4/4 8/8\nf 3 8 7 # comment\n  f 5 6 7 11 10\n",
        "w_colours": "".join(f"v {x!r} {y!r} {z!r} 1.0 0.5 0.5 0.5\n" for x, y, z in vertices.tolist())
                     + "".join("f %d %d %d\r\n" % tuple(f) for f in tri),
    }
    return {k: t.encode() for k, t in out.items()}


@pytest.fixture(scope="module")
def obj_files():
    files = obj_seeds()
    for data in files.values():
        assert isinstance(parse_obj(data, OBJ_NAME), PlyMesh)
    return files


def obj_outcome(data):
    """parse_obj's result or None for a one-line InputError naming the file (:func:`parsed`)."""
    mesh = parsed(parse_obj, data, OBJ_NAME, 400)
    if mesh is None:
        return None
    if mesh.corner_uv is not None:
        assert mesh.corner_uv.shape == (len(mesh.faces), 3, 2)
        assert mesh.corner_uv_missing.shape == (len(mesh.faces),)
    return mesh


OBJ_BYTES = list(b"vtnf/-# \n\r\t0123456789.e+") + [0, 0xFF, 0xC3]
OBJ_TOKENS = ["0", "-1", "-99", "1", "3", "99999999999999999999", "1/1", "1//1", "1/1/1", "1/",
              "/1", "1//", "1///1", "1/-1", "--1", "1-2", "1.5", "nan", "inf", "1e308", "v", "vt",
              "vn", "f", "o", "#", "usemtl", "", "\u00e9", "\\"]


@FUZZ
@given(st.data())
def test_obj_mutated_bytes(obj_files, data):
    name = data.draw(st.sampled_from(sorted(obj_files)))
    text = bytearray(obj_files[name])
    for _ in range(data.draw(st.integers(1, 8))):
        at = data.draw(st.integers(0, len(text) - 1))
        kind = data.draw(st.sampled_from(["overwrite", "insert", "delete"]))
        byte = data.draw(st.sampled_from(OBJ_BYTES) | st.integers(0, 255))
        if kind == "overwrite":
            text[at] = byte
        elif kind == "insert":
            text.insert(at, byte)
        else:
            del text[at:at + data.draw(st.integers(1, 4))]
    if data.draw(st.integers(0, 3)) == 0:
        text = text[:data.draw(st.integers(0, len(text)))]
    obj_outcome(bytes(text))


@FUZZ
@given(st.data())
def test_obj_retokened(obj_files, data):
    name = data.draw(st.sampled_from(sorted(obj_files)))
    words = obj_files[name].decode().split(" ")
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.integers(0, len(words) - 1))
        lines = words[i].split("\n")
        j = data.draw(st.integers(0, len(lines) - 1))
        lines[j] = data.draw(st.sampled_from(OBJ_TOKENS))
        words[i] = "\n".join(lines)
    obj_outcome(" ".join(words).encode("utf-8"))


@FUZZ
@given(st.binary(max_size=4096))
def test_obj_random_bytes(data):
    obj_outcome(data)


def test_obj_fast_path_never_misreads(obj_files):
    """Per-corner words the vectorised face parser must not take apart wrongly: whatever the
    fast path accepts, the per-line path reads the same."""
    from clothtool.io import obj

    base = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
    for face in [b"f 1/1/1/1 2 3", b"f 1//1 2/1 3/1/1", b"f 1/2 3 4/4/1", b"f 1-2 3 4",
                 b"f 1/1 2/2 3/3\nf 1 2//1 3/3/1", b"f 1 2 3 4\nf 1 2 3", b"f 1/-1 2/-2 3/-3"]:
        data = base + face + b"\n"
        try:
            fast = parse_obj(data, OBJ_NAME)
        except InputError:
            fast = None
        try:
            slow = obj._finish(obj._parse_per_line(data, OBJ_NAME), OBJ_NAME)
        except InputError:
            slow = None
        assert (fast is None) == (slow is None), face
        if fast is not None:
            np.testing.assert_array_equal(fast.faces, slow.faces)
            np.testing.assert_array_equal(fast.corner_uv, slow.corner_uv)


# ---------------------------------------------------------------------------- configs

CONFIG = """\
mesh:
  grid: {nx: 6, ny: 5, width: 1.0, height: 0.8, plane: xz}
material: {density: 0.2, stretch: [5000.0, 800.0], rest_stretch: [1.1, 1.0], shear: 50.0,
           bend: 1.0e-5, damping: 0.01}
scene:
  gravity: [0, -9.81, 0]
  pins: [top_corners, 3]
  colliders:
    - sphere: {center: [0, -0.5, 0], radius: 0.3}
    - plane: {point: [0, -1, 0], normal: [0, 1, 0]}
solver: {method: implicit, substeps: 1, tolerance: 1.0e-6, max_iterations: 500,
         iterations: 10, chebyshev_rho: 0.0}
time: {fps: 30, frames: 120}
output: {dir: out/, every: 1}
"""

CONTACT_CONFIG = """\
mesh:
  grid: {nx: 6, ny: 5, width: 1.0, height: 0.8, plane: xz}
scene:
  gravity: [0, -9.81, 0]
  pins:
    - {vertices: left_edge, rotate: {center: [0, 0, 0], axis: [1, 0, 0], speed: 1.0472, until: 10.0}}
    - {vertices: [12, 13], translate: {velocity: [0, 0, 0.5], until: 2.0}}
  colliders:
    - mesh: {ply: body.ply, friction: 0.3}
    - mesh: {obj: body.obj}
    - mesh: {frames: body/, fps: 30, friction: 0.3}
  collision_margin: 1.0e-3
  self_collision: {thickness: 0.002, friction: 0.2}
solver: {method: implicit, newton_iterations: 8}
time: {fps: 60, frames: 10}
"""

KEYS = ["mesh", "grid", "ply", "nx", "ny", "width", "height", "plane", "material", "density",
        "stretch", "rest_stretch", "shear", "bend", "damping", "scene", "gravity", "pins", "colliders", "sphere",
        "center", "radius", "point", "normal", "solver", "method", "substeps", "tolerance",
        "max_iterations", "iterations", "chebyshev_rho", "time", "fps", "frames", "output", "dir", "every", "bogus", "",
        "vertices", "rotate", "translate", "axis", "speed", "until", "velocity", "obj",
        "friction", "self_collision", "thickness", "collision_margin"]
SCALARS = (st.none() | st.booleans() | st.integers(-10**20, 10**20) | st.floats()
           | st.sampled_from(KEYS + ["xy", "top_corners", "1e5", "implicit", "vbd", "-0", "nan"])
           | st.text(max_size=8))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=4), inner,
                                        max_size=4), max_leaves=20)


@pytest.fixture(scope="module")
def load_config():
    from clothtool.sim.model.config import load_config

    return load_config


def config_outcome(load, source):
    with no_hang():
        try:
            return load(source)
        except InputError:  # (a key with a line break in it is flattened by the CLI)
            return None


@FUZZ
@pytest.mark.parametrize("base", [CONFIG, CONTACT_CONFIG], ids=["plain", "contact"])
@given(data=st.data())
def test_mutated_config_text(load_config, tmp_path_factory, base, data):
    text = bytearray(base.encode())
    for _ in range(data.draw(st.integers(1, 6))):
        at = data.draw(st.integers(0, len(text) - 1))
        kind = data.draw(st.sampled_from(["overwrite", "insert", "delete"]))
        byte = data.draw(st.sampled_from(list(b"[]{}:,-#&*!|>'\"\t\n 9.e") + [0xC3, 0xFF])
                         | st.integers(0, 255))
        if kind == "overwrite":
            text[at] = byte
        elif kind == "insert":
            text.insert(at, byte)
        else:
            del text[at]
    path = tmp_path_factory.getbasetemp() / "fuzzed.yaml"
    path.write_bytes(bytes(text))
    config_outcome(load_config, path)


@FUZZ
@given(st.dictionaries(st.sampled_from(KEYS), VALUES, max_size=6))
def test_random_config_structures(load_config, raw):
    config_outcome(load_config, raw)


@FUZZ
@given(st.sampled_from(["mesh", "material", "scene", "solver", "time", "output"]), VALUES)
def test_one_section_replaced(load_config, section, value):
    import yaml

    raw = yaml.safe_load(CONFIG)
    raw[section] = value
    config_outcome(load_config, raw)


@FUZZ
@given(st.sampled_from(["pins", "colliders", "self_collision", "collision_margin"]), VALUES,
       st.integers(0, 2))
def test_one_contact_key_replaced(load_config, key, value, index):
    """The new scene keys, and one entry of the pin and collider lists, replaced at random."""
    import yaml

    raw = yaml.safe_load(CONTACT_CONFIG)
    if key in ("pins", "colliders") and index < len(raw["scene"][key]):
        raw["scene"][key][index] = value
    else:
        raw["scene"][key] = value
    config_outcome(load_config, raw)


@pytest.mark.parametrize("text", ["mesh: " + "[" * 20000, "mesh: " + "{a: " * 20000,
                                  "a: &a [x, x]\nb: [*a, *a, *a]\n", "\x00\x01", "mesh: !!python/object:os.system {}"])
def test_pathological_yaml(load_config, tmp_path, text):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    assert config_outcome(load_config, path) is None
