"""Ctrl-C and SIGTERM in the middle of a long analyze: exit code 130, no temporary
file left, and the previous output byte-identical."""

import os
import signal
import sys


import pytest
from conftest import grid, interrupt_when

from clothtool.io.ply import write_ply

PREVIOUS = b"the result of an earlier run"


@pytest.fixture(scope="module")
def long_sequence(tmp_path_factory):
    """60 frames of a 150 × 150 grid (a few seconds of work and ~300 MB of output),
    stored as two files and 60 links to them."""
    root = tmp_path_factory.mktemp("long")
    vertices, faces = grid(150, 150)
    (root / "src").mkdir()
    (root / "seq").mkdir()
    write_ply(root / "src" / "a.ply", vertices, faces)
    write_ply(root / "src" / "b.ply", vertices * [1.1, 1.0, 1.0], faces)
    for k in range(60):
        os.symlink(root / "src" / f"{'ab'[k % 2]}.ply", root / "seq" / f"frame_{k}.ply")
    return root / "seq"


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_mid_write_leaves_nothing(tmp_path, long_sequence, signum):
    out = tmp_path / "out.h5"
    out.write_bytes(PREVIOUS)
    (tmp_path / "out.xdmf").write_bytes(PREVIOUS)
    def writing():  # the temporary file is being filled
        tmp = [p for p in tmp_path.iterdir() if p.name.startswith(".out.h5.tmp-")]
        return bool(tmp) and tmp[0].stat().st_size > 20 << 20

    stdout, stderr = interrupt_when(
        [sys.executable, "-m", "clothtool.cli", "analyze", long_sequence, "-o", out], writing,
        signum, "analyze writing")
    assert b"Traceback" not in stderr + stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5", "out.xdmf"]
    assert out.read_bytes() == PREVIOUS
    assert (tmp_path / "out.xdmf").read_bytes() == PREVIOUS


def test_a_dropped_interrupt_still_stops_publication(tmp_path, monkeypatch):
    """A signal whose KeyboardInterrupt Python dropped (raised in a weakref callback,
    say) is remembered: the output is not renamed into place and the run stops."""
    from clothtool import interrupt
    from clothtool.analysis.sequence import analyze_sequence

    folder = tmp_path / "seq"
    folder.mkdir()
    vertices, faces = grid(4, 4)
    for k in range(3):
        write_ply(folder / f"f{k}.ply", vertices * (1 + k), faces)
    out = tmp_path / "out.h5"
    out.write_bytes(PREVIOUS)
    monkeypatch.setattr(interrupt, "_received", [signal.SIGTERM])
    with pytest.raises(KeyboardInterrupt):
        analyze_sequence(folder, out)
    assert out.read_bytes() == PREVIOUS
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5", "seq"]


def test_interrupted_ply_write_leaves_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "mesh.ply"
    path.write_bytes(PREVIOUS)
    vertices, faces = grid(5, 5)

    def interrupted(fh, records):  # after the header is written
        raise KeyboardInterrupt

    monkeypatch.setattr("clothtool.io.ply._write_ascii_records", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_ply(path, vertices, faces, binary=False)
    monkeypatch.undo()
    assert path.read_bytes() == PREVIOUS
    assert [p.name for p in tmp_path.iterdir()] == ["mesh.ply"]


def test_failed_close_is_reported_and_cleaned_up(tmp_path, monkeypatch):
    """A write error that only shows when the HDF5 file is closed (flushing to a full disk)
    is an InputError naming the output, and nothing is renamed into place."""
    import h5py

    from clothtool.errors import InputError
    from clothtool.io.h5 import AtomicH5

    out = tmp_path / "out.h5"
    out.write_bytes(PREVIOUS)
    real_close = h5py.File.close

    def full(self):
        real_close(self)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(h5py.File, "close", full)
    with pytest.raises(InputError, match="out.h5: cannot write: No space left on device"):
        with AtomicH5(out) as f:
            f["x"] = [1, 2, 3]
    assert out.read_bytes() == PREVIOUS
    assert [p.name for p in tmp_path.iterdir()] == ["out.h5"]
