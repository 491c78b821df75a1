"""What a simulation writes in each ``output.format``: PLY frames, OBJ frames with the
pattern's uv per corner (read back exactly, and analysed exactly as the PLY frames), and the
MDD point cache with its base mesh; the writers on their own (round trips, uv seams, groups)."""

import tempfile

import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import grid, simulated
from hypothesis import given, settings
from hypothesis import strategies as st

import clothtool
from clothtool.cli import main
from clothtool.errors import InputError, NumericalError
from clothtool.io.caches.mdd import MddWriter, read_mdd
from clothtool.io.obj import read_obj
from clothtool.io.caches.obj_writer import ObjWriter, write_obj
from clothtool.io.ply import read_ply
from clothtool.sim.model.config import load_config
from clothtool.sim.output import FrameWriter

CONFIG = {"mesh": {"grid": {"nx": 7, "ny": 5, "width": 0.6, "height": 0.4}},
          "scene": {"pins": ["top_corners"]},
          "time": {"frames": 6, "fps": 30},
          "output": {"format": ["ply", "obj", "mdd"], "every": 2}}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A short hanging-sheet run written in all three formats, every second frame."""
    return simulated(tmp_path_factory, CONFIG)


def stats_times(out):
    rows = np.genfromtxt(out / "stats.csv", delimiter=",", names=True)
    return rows["frame"].astype(int), rows["time"]


def test_every_format_holds_the_same_frames(run):
    frames, times = stats_times(run)
    assert list(frames) == [0, 2, 4, 6]
    cache_times, cache = read_mdd(run / "cache" / "cloth.mdd")
    np.testing.assert_array_equal(cache_times, times.astype(np.float32))
    base = read_obj(run / "cache" / "cloth.obj")
    for k, frame in enumerate(frames):
        ply = read_ply(run / f"frame_{frame:05d}.ply")
        obj = read_obj(run / "obj" / f"frame_{frame:05d}.obj")
        np.testing.assert_array_equal(obj.vertices, ply.vertices)  # 17 digits: exact
        np.testing.assert_array_equal(obj.faces, ply.faces)
        np.testing.assert_array_equal(obj.corner_uv, ply.uv[ply.faces])  # per vertex → per corner
        np.testing.assert_array_equal(cache[k], ply.vertices.astype(np.float32))
    np.testing.assert_array_equal(base.vertices, read_ply(run / "frame_00000.ply").vertices)
    assert sorted(p.name for p in (run / "obj").iterdir()) == [f"frame_{f:05d}.obj" for f in frames]
    assert sorted(p.name for p in (run / "cache").iterdir()) == ["cloth.mdd", "cloth.obj"]
    assert not [p for p in run.rglob(".*")]  # no temporary file left


def all_datasets(path):
    out = {}
    with h5py.File(path) as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if hasattr(obj, "shape") else None)
    return out


@pytest.mark.parametrize("reference", ["previous", "first", "uv"])
def test_analyze_reads_the_obj_frames_as_the_ply_frames(run, tmp_path, reference):
    for kind, frames in (("ply", run), ("obj", run / "obj")):
        result = CliRunner().invoke(main, ["analyze", str(frames), "-o", str(tmp_path / f"{kind}.h5"),
                                           "--reference", reference, "--kabsch", "-q"])
        assert result.exit_code == 0, result.output
    a, b = all_datasets(tmp_path / "obj.h5"), all_datasets(tmp_path / "ply.h5")
    assert "face/stretch" in a and "vertex/rotation" in a
    # the rest uv is stored as it was read: per corner from OBJ vt, per vertex from PLY s t
    if reference == "uv":
        np.testing.assert_array_equal(a.pop("mesh/corner_uv"), b["mesh/uv"][b["mesh/faces"]])
        b.pop("mesh/uv")
    assert set(a) == set(b)
    for name in a:
        if name == "frames":  # the file names
            assert [p.decode().replace("/obj/", "/").replace(".obj", ".ply") for p in a[name]] \
                == [p.decode() for p in b[name]]
        else:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_default_is_ply_only(tmp_path):
    out = tmp_path / "out"
    clothtool.simulate({**CONFIG, "output": {}}, output_dir=out, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml"] + \
        [f"frame_{k:05d}.ply" for k in range(7)] + ["stats.csv"]


def test_obj_only_and_a_rerun_clears_the_earlier_run(tmp_path):
    out = tmp_path / "out"
    clothtool.simulate(CONFIG, output_dir=out, progress=False)
    (out / "notes.txt").write_text("mine")
    (out / "obj" / "mine.obj").write_text("v 0 0 0\n")
    clothtool.simulate({**CONFIG, "output": {"format": "obj"}, "time": {"frames": 1}},
                       output_dir=out, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["cache", "config.yaml", "notes.txt", "obj",
                                                     "stats.csv"]
    assert sorted(p.name for p in (out / "obj").iterdir()) == ["frame_00000.obj", "frame_00001.obj",
                                                               "mine.obj"]
    assert list((out / "cache").iterdir()) == []


def test_the_resolved_config_beside_the_frames_reruns_the_same_frames(run, tmp_path,
                                                                     monkeypatch):
    text = (run / "config.yaml").read_text()
    assert yaml.safe_load(text)["output"]["dir"] == str(run)  # where the frames went, absolute
    monkeypatch.chdir(tmp_path)  # read back from elsewhere
    again = load_config(run / "config.yaml")
    assert again.time.frames == CONFIG["time"]["frames"] and again.output.every == 2
    clothtool.simulate(again, output_dir=tmp_path / "again", progress=False)
    for k in (0, 2, 4, 6):
        name = f"frame_{k:05d}.ply"
        assert (tmp_path / "again" / name).read_bytes() == (run / name).read_bytes()


@pytest.mark.parametrize("sample", ["drape", "garment", "hanging_sheet", "stack", "tablecloth",
                                    "twist"])
def test_resolved_yaml_reads_back_as_the_same_config(sample, tmp_path, monkeypatch):
    from dataclasses import replace
    from pathlib import Path

    from clothtool.sim.model.config import resolved_yaml
    from clothtool.sim.model.schema import resolve_paths

    config = load_config(Path(__file__).parent.parent / "sample_data" / f"{sample}.yaml")
    (tmp_path / "config.yaml").write_text(resolved_yaml(config))
    monkeypatch.chdir(tmp_path)
    again = load_config(tmp_path / "config.yaml")
    absolute = replace(resolve_paths(config, Path.cwd()), source=None)
    normal = lambda c: yaml.safe_dump(resolved_yaml(c))  # noqa: E731 (paths normalised)
    assert normal(replace(again, source=None)) == normal(absolute)
    assert again.scene == replace(absolute.scene, colliders=again.scene.colliders)
    assert len(again.scene.colliders) == len(config.scene.colliders)
    assert again.material == config.material and again.mesh.seams == config.mesh.seams


def test_a_sweep_runs_own_config_is_left_as_it_is(tmp_path):
    (tmp_path / "config.yaml").write_text(yaml.safe_dump({**CONFIG, "output": {"dir": "."}}))
    before = (tmp_path / "config.yaml").read_text()
    clothtool.simulate(tmp_path / "config.yaml", progress=False)
    assert (tmp_path / "config.yaml").read_text() == before
    assert (tmp_path / "frame_00006.ply").is_file()


def test_a_run_refused_at_the_start_writes_no_config(tmp_path):
    bad = {**CONFIG, "scene": {"colliders": [{"sphere": {"center": [0, 0, 0], "radius": 0.1}}]}}
    with pytest.raises(InputError):
        clothtool.simulate(bad, output_dir=tmp_path / "out", progress=False)
    assert not (tmp_path / "out" / "config.yaml").exists()


@pytest.mark.parametrize("value, message", [
    ("stl", r"output.format\[0\] must be one of ply, obj, mdd, usd, got 'stl'"),
    (["ply", "obj", "ply"], "output.format names 'ply' twice"),
    ([], "output.format must be a list of ply, obj, mdd and usd, got"),
    ({"ply": 1}, "output.format must be a list of ply, obj, mdd and usd, got"),
    (["ply", "obi"], r"output.format\[1\] must be one of ply, obj, mdd, usd, got 'obi' \(did you mean 'obj'\?\)"),
])
def test_bad_format_is_one_line_naming_the_key(value, message):
    with pytest.raises(InputError, match=message):
        load_config({**CONFIG, "output": {"format": value}})


def test_format_from_yaml_and_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(CONFIG))
    assert load_config(path).output.format == ("ply", "obj", "mdd")
    assert load_config(path, overrides=["output.format=[obj]"]).output.format == ("obj",)


def test_a_blow_up_keeps_the_cache_of_the_frames_before_it(tmp_path):
    faces = grid(3, 3)[1]
    x = grid(3, 3)[0]
    with pytest.raises(NumericalError):
        with FrameWriter(tmp_path, faces, x[:, :2], formats=("mdd",)) as writer:
            writer.write_frame(0, x, 0.0)
            writer.write_frame(1, x + 1, 0.5)
            raise NumericalError("simulation blew up at frame 2")
    times, positions = read_mdd(tmp_path / "cache" / "cloth.mdd")
    np.testing.assert_array_equal(times, [0.0, 0.5])
    np.testing.assert_array_equal(positions[1], (x + 1).astype(np.float32))
    with pytest.raises(KeyError):
        with FrameWriter(tmp_path / "b", faces, None, formats=("mdd",)) as writer:
            writer.write_frame(0, x, 0.0)
            raise KeyError("a bug")
    # the base mesh (the initial frame) stays, as PLY frames would; no cache, no temporary file
    assert [p.name for p in (tmp_path / "b" / "cache").iterdir()] == ["cloth.obj"]


# ------------------------------------------------------------------ the writers


def test_mdd_layout_is_big_endian_lightwave(tmp_path):
    writer = MddWriter(tmp_path / "a.mdd", 2)
    writer.add(0.0, [[1, 2, 3], [4, 5, 6]])
    writer.add(0.25, [[7, 8, 9], [10, 11, 12]])
    writer.close()
    data = (tmp_path / "a.mdd").read_bytes()
    assert data[:8] == b"\0\0\0\x02\0\0\0\x02"
    assert np.frombuffer(data[8:16], ">f4").tolist() == [0.0, 0.25]
    assert np.frombuffer(data[16:], ">f4").tolist() == list(range(1, 13))
    assert [p.name for p in tmp_path.iterdir()] == ["a.mdd"]
    writer = MddWriter(tmp_path / "b.mdd", 1)
    writer.add(0.0, [[0, 0, 0]])
    with pytest.raises(ValueError, match="times must increase"):
        writer.add(0.0, [[0, 0, 0]])
    writer.close(ok=False)
    assert [p.name for p in tmp_path.iterdir()] == ["a.mdd"]


@pytest.mark.parametrize("cut, message", [(4, "too short"), (20, "but the header says 2 samples")])
def test_read_mdd_names_a_broken_file(tmp_path, cut, message):
    writer = MddWriter(tmp_path / "a.mdd", 2)
    writer.add(0.0, np.zeros((2, 3)))
    writer.add(1.0, np.ones((2, 3)))
    writer.close()
    (tmp_path / "b.mdd").write_bytes((tmp_path / "a.mdd").read_bytes()[:cut])
    with pytest.raises(InputError, match=f"b.mdd: .*{message}"):
        read_mdd(tmp_path / "b.mdd")


def test_obj_with_a_uv_seam_and_groups(tmp_path):
    """Two panels sharing an edge (vertices 1 and 2) with different uv on each side."""
    x = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0.5]], float)
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    corner_uv = np.array([[[0, 0], [1, 0], [1, 1]], [[5, 0], [6, 0], [5, 1]]], float)
    write_obj(tmp_path / "a.obj", x, faces, corner_uv=corner_uv, groups=(["front", "back"], [0, 1]))
    text = (tmp_path / "a.obj").read_text()
    assert text.count("\nvt ") == 6 and "g front\nf 1/1 2/2 3/3\ng back\nf 2/4 4/5 3/6\n" in text
    mesh = read_obj(tmp_path / "a.obj")
    np.testing.assert_array_equal(mesh.corner_uv, corner_uv)
    np.testing.assert_array_equal(mesh.faces, faces)
    write_obj(tmp_path / "b.obj", x, faces)
    assert "vt" not in (tmp_path / "b.obj").read_text()
    assert read_obj(tmp_path / "b.obj").corner_uv is None


def test_later_frames_reuse_the_face_block(tmp_path):
    x, faces = grid(5, 4)
    writer = ObjWriter(faces, x[faces][..., :2])
    writer.write(tmp_path / "f0.obj", x)
    writer.write(tmp_path / "f1.obj", x * 2)
    first = read_obj(tmp_path / "f0.obj")
    later = read_obj(tmp_path / "f1.obj", reuse=first)
    assert later.faces is first.faces
    np.testing.assert_array_equal(later.vertices, x * 2)


finite = st.floats(-1e6, 1e6, allow_nan=False, width=64) | st.floats(-1e-300, 1e-300, width=64)


@settings(max_examples=60, deadline=None)
@given(st.integers(3, 12).flatmap(lambda n: st.tuples(
    st.lists(st.tuples(finite, finite, finite), min_size=n, max_size=n),
    st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1), st.integers(0, n - 1)),
             min_size=1, max_size=10),
    st.lists(st.tuples(finite, finite), min_size=30, max_size=30))))
def test_obj_round_trip_is_exact(case):
    vertices, faces, uv = (np.array(v, dtype) for v, dtype in zip(case, (float, np.int64, float)))
    corner_uv = uv[:3 * len(faces)].reshape(-1, 3, 2)
    with tempfile.TemporaryDirectory() as folder:
        write_obj(f"{folder}/r.obj", vertices, faces, corner_uv=corner_uv)
        mesh = read_obj(f"{folder}/r.obj")
    np.testing.assert_array_equal(mesh.vertices, vertices)
    np.testing.assert_array_equal(mesh.faces, faces)
    np.testing.assert_array_equal(mesh.corner_uv, corner_uv)
