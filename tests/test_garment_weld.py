"""A sewn garment through its weld: the two panels of ``benchmarks garment`` (sewn around a
turning capsule) weld at frame 6 and the welded start of the rest of the run is
intersection-free, with ``solver.first_cut_iterations`` off and on; and a weld whose welded
start would cross is not made (the pairs stay sewn, no crossing frame is written)."""

import sys
from pathlib import Path

import numpy as np
import pytest

import clothtool
from benchmarks.bench_garment import config, garment
from clothtool.contact.intersect import has_intersections
from clothtool.errors import NumericalError
from clothtool.io.ply import read_ply

sys.path.insert(0, str(Path(__file__).parent))
from garment_meshes import apart_pair, write_obj  # noqa: E402

FRAMES = 10


@pytest.mark.parametrize("first_cut", [0, 20])
def test_sewn_panels_weld_without_crossing(tmp_path, first_cut):
    path, seams, top, _ = garment(tmp_path)
    out = tmp_path / "out"
    cfg = config(path, seams, top, out)
    cfg["time"]["frames"] = FRAMES
    cfg["solver"] = {"first_cut_iterations": first_cut}
    clothtool.simulate(cfg, progress=False)
    a = np.concatenate([s["a"] for s in seams])
    b = np.concatenate([s["b"] for s in seams])
    merge = np.arange(len(read_ply(out / "frame_00000.ply").vertices))
    merge[b] = a  # the welded surface: each seam pair one vertex
    last = read_ply(out / f"frame_{FRAMES:05d}.ply")
    assert np.array_equal(last.vertices[a], last.vertices[b])  # welded
    assert not has_intersections(last.vertices, merge[last.faces])


def patched_seam(tmp_path, lift=0.0024):
    """Two panels side by side in x, the right one ``lift`` m above the left so each seam
    pair (a the left panel's right edge, b the right panel's left edge) is ``lift`` apart in
    z, and a strip of cloth halfway between them along the whole seam: welding each pair at
    its mean puts the seam into the strip."""
    x, lf, rf, luv, ruv, a, b = apart_pair(gap=0.0)
    x[len(x) // 2:, 2] = lift
    strip = np.array([[-0.03, -0.02], [0.03, -0.02], [0.03, 0.32], [-0.03, 0.32]])
    n = len(x)
    x = np.concatenate([x, np.column_stack([strip, np.full(4, 0.5 * lift)])])
    sf = np.array([[0, 1, 2], [0, 2, 3]]) + n
    path = write_obj(tmp_path / "patched.obj", x, [("left", lf, luv), ("right", rf, ruv),
                                                   ("strip", sf, strip[sf - n])])
    return path, a, b


def test_a_weld_whose_welded_start_would_cross_is_not_made(tmp_path):
    """The seam pairs start within the weld distance (2.4 against 5 mm) with a strip of
    cloth between them: the weld would move each pair onto the strip, so it is refused (the
    run says why), the pairs stay apart and every frame is written crossing-free; at
    ``mesh.sewing.time`` the run stops naming the check the weld failed."""
    path, a, b = patched_seam(tmp_path)
    cfg = {"mesh": {"obj": str(path), "seams": [{"a": a.tolist(), "b": b.tolist()}],
                    "sewing": {"time": 0.2, "weld": 0.005}},
           "material": {"damping": 0.05},
           "scene": {"gravity": [0, 0, 0], "self_collision": {"thickness": 0.002}},
           "time": {"fps": 30, "frames": 3}}
    out = tmp_path / "out"
    lines = []
    clothtool.simulate(cfg, output_dir=out, progress=False, log=lines.append)
    assert any(line.startswith("mesh.seams: sewn at frame 1 but not welded") for line in lines)
    assert not any("welded at frame" in line for line in lines)
    for k in range(4):
        frame = read_ply(out / f"frame_{k:05d}.ply")
        gap = np.linalg.norm(frame.vertices[a] - frame.vertices[b], axis=1)
        assert gap.min() > 0.0  # not welded
        assert not has_intersections(frame.vertices, frame.faces)
    cfg["time"]["frames"] = 12
    with pytest.raises(NumericalError, match=r"mesh\.seams sewn since frame 1 but not welded "
                                             r"in mesh\.sewing\.time \(0\.2 s\)"):
        clothtool.simulate(cfg, output_dir=tmp_path / "out2", progress=False)
