"""Fuzzing the tetrahedral mesh readers with hypothesis: valid files of every format (binary
and ascii) mutated anywhere, truncated, or replaced by random bytes. Every outcome is a
consistent TetMesh or an InputError naming the file, never another exception or a hang."""

import time

import numpy as np
import pytest
from conftest import TET_VARIANTS, tet_grid, write_tet_file
from hypothesis import given
from hypothesis import strategies as st
from test_fuzz import FUZZ, edited, no_hang

from clothtool.errors import InputError
from clothtool.io.tetmesh import TetMesh, read_tet_mesh

X, TETS = tet_grid(2, np.random.default_rng(3))


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    """variant → (extension, bytes of the file); tetgen also as 'tetgen_ele' (its .ele)."""
    folder = tmp_path_factory.mktemp("tet_seeds")
    out = {}
    for variant in TET_VARIANTS:
        path = write_tet_file(folder / variant, X, TETS, variant)
        out[variant] = (path.suffix, path.read_bytes())
        if variant == "tetgen":
            out["tetgen_ele"] = (".ele", path.with_suffix(".ele").read_bytes())
    return out


def outcome(folder, variant, data, seeds):
    """Write ``data`` as the file of ``variant`` (for TetGen the other file of the pair is the
    valid seed) and read it: a consistent TetMesh, or None for an InputError naming it."""
    node = folder / "fuzzed.node"
    if variant.startswith("tetgen"):
        ele = folder / "fuzzed.ele"
        node.write_bytes(data if variant == "tetgen" else seeds["tetgen"][1])
        ele.write_bytes(data if variant == "tetgen_ele" else seeds["tetgen_ele"][1])
        path, names = node, ("fuzzed.node", "fuzzed.ele")
    else:
        path = folder / f"fuzzed{seeds[variant][0]}"
        path.write_bytes(data)
        names = (path.name,)
    try:
        with no_hang():
            mesh = read_tet_mesh(path)
    except InputError as exc:
        assert any(name in str(exc) for name in names) and "\n" not in str(exc), str(exc)
        return None
    assert isinstance(mesh, TetMesh)
    n = len(mesh.vertices)
    assert mesh.vertices.shape == (n, 3) and mesh.vertices.dtype == np.float64
    assert mesh.tets.ndim == 2 and mesh.tets.shape[1] == 4 and mesh.tets.dtype == np.int64
    assert len(mesh.tets) and 0 <= mesh.tets.min() and mesh.tets.max() < n
    return mesh


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("tet_fuzz")


def test_seeds_read(folder, seeds):
    for variant in seeds:
        mesh = outcome(folder, variant, seeds[variant][1], seeds)
        np.testing.assert_array_equal(mesh.tets, TETS)


@FUZZ
@given(st.sampled_from(sorted(TET_VARIANTS) + ["tetgen_ele"]), st.binary(max_size=2048))
def test_random_bytes(folder, seeds, variant, data):
    outcome(folder, variant, data, seeds)


@st.composite
def mutated(draw, seeds):
    """A seed file with 1-8 edits anywhere, maybe truncated (:func:`test_fuzz.edited`)."""
    variant = draw(st.sampled_from(sorted(seeds)))
    data = seeds[variant][1]
    return variant, edited(draw, data, lambda d: draw(st.integers(0, len(d) - 1)) if d else None)


@FUZZ
@given(st.data())
def test_mutated_files(folder, seeds, data):
    variant, mutant = data.draw(mutated(seeds))
    outcome(folder, variant, mutant, seeds)


WORDS = [b"0", b"-1", b"4294967295", b"1000000000000", b"nan", b"inf", b"x", b"", b"tetra",
         b"triangle", b'"UInt8"', b'"Float32"', b"binary", b"ascii", b"\xc3\xa9"]


@FUZZ
@given(st.data())
def test_retokened_files(folder, seeds, data):
    """1-3 whitespace-separated words of a seed replaced by troublesome ones (counts, types)."""
    variant = data.draw(st.sampled_from(sorted(seeds)))
    words = seeds[variant][1].split(b" ")
    for _ in range(data.draw(st.integers(1, 3))):
        words[data.draw(st.integers(0, len(words) - 1))] = data.draw(st.sampled_from(WORDS))
    outcome(folder, variant, b" ".join(words), seeds)


def test_a_huge_gmsh_node_tag_fails_at_once(folder, seeds):
    """meshio's Gmsh 4.1 reader allocates a table of max(node tag) + 1 entries: 24 GB here."""
    text = seeds["msh41_ascii"][1]
    start = text.index(b"$Nodes\n")
    tag = f"\n{len(X)}\n".encode()  # the last node tag of the single node block
    last = text.index(tag, start)
    mutant = text[:last] + b"\n3000000000\n" + text[last + len(tag):]
    started = time.process_time()  # CPU time: a loaded machine does not slow it
    assert outcome(folder, "msh41_ascii", mutant, seeds) is None
    assert time.process_time() - started < 5
