"""The USD cache (output.format usd): one .usda stage that OpenUSD's own reader (usd-core's
``pxr``) opens: the cloth's points at every time code equal the PLY frames as float32, its
``st`` primvar the OBJ frames' vt, one GeomSubset per panel, the colliders with their motion,
time codes per second = fps; a run that fails leaves no stage; a bad output path is one line."""

import subprocess
import sys

import numpy as np
import pytest
from conftest import simulated

from clothtool.io.obj import read_obj
from clothtool.io.ply import read_ply
from clothtool.io.caches.usd import UsdaWriter, prim_name
from clothtool.sim.model.config import load_config
from clothtool.sim.scene import RunScene

pxr = pytest.importorskip("pxr", reason="needs usd-core (pip install usd-core)")
from pxr import Usd, UsdGeom  # noqa: E402

FPS, FRAMES, EVERY = 30, 6, 2
SCENE = {"mesh": {"grid": {"nx": 9, "ny": 6, "width": 0.8, "height": 0.5, "plane": "xz"}},
         "scene": {"pins": ["top_corners"], "gravity": [0, 0, -9.81],
                   "colliders": [{"sphere": {"center": [0, 0.3, 0], "radius": 0.1,
                                             "motion": {"translate": {"velocity": [0, -0.2, 0]}}}}]},
         "time": {"frames": FRAMES, "fps": FPS},
         "output": {"format": ["ply", "obj", "usd"], "every": EVERY}}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return simulated(tmp_path_factory, SCENE, "usd")


def test_the_stage_opens_with_the_frames_at_their_time_codes(run):
    stage = Usd.Stage.Open(str(run / "usd" / "cloth.usda"))
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, FRAMES)
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/clothtool/cloth"))
    codes = list(range(0, FRAMES + 1, EVERY))
    assert mesh.GetPointsAttr().GetTimeSamples() == codes
    for k in codes:
        ply = read_ply(run / f"frame_{k:05d}.ply")
        got = np.array(mesh.GetPointsAttr().Get(k), np.float32)
        np.testing.assert_array_equal(got, ply.vertices.astype(np.float32))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * len(ply.faces)
    assert np.array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()), ply.faces.ravel())


def test_st_is_the_obj_frames_vt(run):
    stage = Usd.Stage.Open(str(run / "usd" / "cloth.usda"))
    st = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/clothtool/cloth")).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    obj = read_obj(run / "obj" / "frame_00000.obj")
    np.testing.assert_array_equal(np.array(st.Get(), np.float32),
                                  obj.corner_uv.reshape(-1, 2).astype(np.float32))


def test_the_colliders_move_as_the_simulation_moves_them(run):
    stage = Usd.Stage.Open(str(run / "usd" / "cloth.usda"))
    sphere = UsdGeom.Mesh(stage.GetPrimAtPath("/clothtool/colliders/colliders_0_sphere"))
    scene = RunScene(load_config(SCENE))
    x0 = read_ply(run / "frame_00000.ply").vertices
    centre, extent = x0.mean(axis=0), float(np.ptp(x0, axis=0).max())
    for k in range(0, FRAMES + 1, EVERY):
        (surface,) = scene.surfaces(k / FPS, centre, extent)
        np.testing.assert_array_equal(np.array(sphere.GetPointsAttr().Get(k), np.float32),
                                      surface.vertices.astype(np.float32))
    low = np.array(sphere.GetPointsAttr().Get(FRAMES))[:, 1].min()
    assert low == pytest.approx(0.2 - 0.2 * FRAMES / FPS, abs=1e-6)  # it moved down


def test_each_panel_is_a_geom_subset(tmp_path):
    faces = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6]])
    writer = UsdaWriter(tmp_path / "c.usda", faces, np.zeros((3, 3, 2)),
                        {"front": [0, 1], "back panel": [2], "1st": []}, fps=24)
    writer.add(0, np.zeros((7, 3)))
    writer.add(1, np.ones((7, 3)))
    writer.close()
    stage = Usd.Stage.Open(str(tmp_path / "c.usda"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/clothtool/cloth"))
    subsets = {s.GetPrim().GetName(): list(s.GetIndicesAttr().Get())
               for s in UsdGeom.Subset.GetAllGeomSubsets(mesh)}
    assert subsets == {"front": [0, 1], "back_panel": [2]}  # an empty one is left out
    assert stage.GetTimeCodesPerSecond() == 24
    assert prim_name("1st") == "_1st"


def test_a_failed_run_leaves_no_stage(tmp_path):
    writer = UsdaWriter(tmp_path / "c.usda", np.array([[0, 1, 2]]), fps=30)
    writer.add(0, np.zeros((3, 3)))
    writer.close(ok=False)
    assert list(tmp_path.iterdir()) == []


def test_an_unwritable_usd_path_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "usd").write_text("a file where the usd folder goes")
    config = tmp_path / "scene.yaml"
    import yaml

    config.write_text(yaml.safe_dump(SCENE))
    proc = subprocess.run([sys.executable, "-c", "from clothtool.cli import run; run()",
                           "simulate", str(config), "-o", str(out), "-q"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "usd: output path exists and is not a folder" in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["usd"]


@pytest.mark.parametrize("fmt, message", [
    ("abc", "output.format[1]: 'abc': Alembic is not written; write 'usd' and convert it in "
            "Blender (import USD, export Alembic)"),
    ("fbx", "output.format[1] must be one of ply, obj, mdd, usd, got 'fbx'"),
])
def test_a_format_we_do_not_write_is_one_line_and_writes_nothing(tmp_path, fmt, message):
    import yaml

    config = tmp_path / "scene.yaml"
    config.write_text(yaml.safe_dump({**SCENE, "output": {"format": ["ply", fmt]}}))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", "from clothtool.cli import run; run()",
                           "simulate", str(config), "-o", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert message in proc.stderr
    assert not out.exists()
