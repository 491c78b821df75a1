"""The USD cache opened by real Blender 5: the ``bpy`` module (Blender as a Python package,
5.0.1 for Python 3.11) imports a run's ``usd/cloth.usda`` headless (USD importer: a Mesh
Sequence Cache on the cloth and on each collider), exports it as Alembic and imports that
back; in both, the vertex count, the uv per corner, the positions at every time sample and
the last frame's equal ours (float32).

``bpy`` pins numpy < 2, so it lives in a venv of its own, run as a subprocess: $BPY_PYTHON,
else ``.venv-bpy/bin/python`` in the checkout (``.ci/run`` makes it); without it the test is
skipped with the install line.
"""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import clothtool
from clothtool.io.obj import read_obj
from clothtool.io.ply import read_ply

ROOT = Path(__file__).resolve().parent.parent
INSTALL = ("needs Blender 5 as the bpy module in its own venv: python3.11 -m venv .venv-bpy && "
           ".venv-bpy/bin/pip install bpy==5.0.1 (or set BPY_PYTHON to such a python)")
FPS, FRAMES, EVERY = 30, 6, 2

# Run by bpy's python: argv = the USD file, the Alembic file to write, the last frame, the JSON
# file to write.
PROBE = r'''
import json, sys
import bpy

usd, abc, last, out = sys.argv[1:5]


def read(name):
    """Vertex count, uv per corner and positions at every scene frame of object ``name``."""
    scene = bpy.context.scene
    ob = bpy.data.objects[name]
    frames, uv = [], None
    for f in range(int(last) + 1):
        scene.frame_set(f)
        ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
        me = ev.to_mesh()
        co = [0.0] * (3 * len(me.vertices))
        me.vertices.foreach_get("co", co)
        frames.append(co)
        if uv is None and me.uv_layers.active is not None:
            uv = [list(d.uv) for d in me.uv_layers.active.data]
            loops = [me.loops[i].vertex_index for p in me.polygons for i in p.loop_indices]
        n = len(me.vertices)
        ev.to_mesh_clear()
    return {"vertices": n, "frames": frames, "uv": uv, "loops": loops,
            "modifiers": [m.type for m in ob.modifiers]}


bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.render.fps = 30
bpy.ops.wm.usd_import(filepath=usd)
result = {"version": bpy.app.version_string, "usd": read("cloth"),
          "objects": sorted(o.name for o in bpy.data.objects)}
bpy.ops.wm.alembic_export(filepath=abc, start=0, end=int(last))
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.render.fps = 30
bpy.ops.wm.alembic_import(filepath=abc)
result["alembic"] = read("cloth")
json.dump(result, open(out, "w"))
'''


def bpy_python():
    found = os.environ.get("BPY_PYTHON") or ROOT / ".venv-bpy" / "bin" / "python"
    if not Path(found).is_file():
        pytest.skip(INSTALL)
    return str(found)


def test_blender_5_imports_the_usd_cache_and_its_alembic_export(tmp_path, capsys):
    python = bpy_python()
    run = tmp_path / "run"
    config = {"mesh": {"grid": {"nx": 9, "ny": 6, "width": 0.8, "height": 0.5, "plane": "xz"}},
              "scene": {"pins": ["top_corners"], "gravity": [0, 0, -9.81],
                        "colliders": [{"sphere": {"center": [0, 0.3, 0], "radius": 0.1}}]},
              "time": {"frames": FRAMES, "fps": FPS},
              "output": {"format": ["ply", "obj", "usd"], "every": EVERY}}
    clothtool.simulate(config, output_dir=run, progress=False)
    script, out = tmp_path / "probe.py", tmp_path / "bpy.json"
    script.write_text(PROBE)
    proc = subprocess.run([python, str(script), str(run / "usd" / "cloth.usda"),
                           str(tmp_path / "cloth.abc"), str(FRAMES), str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and out.is_file(), proc.stdout[-3000:] + proc.stderr[-3000:]
    got = json.loads(out.read_text())
    with capsys.disabled():
        print(f"\nBlender {got['version']} (bpy): {got['objects']}")
    assert "colliders_0_sphere" in got["objects"]
    assert (tmp_path / "cloth.abc").is_file()

    obj = read_obj(run / "obj" / "frame_00000.obj")
    written = {k: read_ply(run / f"frame_{k:05d}.ply").vertices.astype(np.float32)
               for k in range(0, FRAMES + 1, EVERY)}
    n = len(obj.vertices)
    for kind in ("usd", "alembic"):
        cache = got[kind]
        assert cache["vertices"] == n, kind
        assert "MESH_SEQUENCE_CACHE" in cache["modifiers"], kind
        assert cache["loops"] == obj.faces.ravel().tolist(), kind  # same corners, same order
        np.testing.assert_array_equal(np.array(cache["uv"], np.float32),
                                      obj.corner_uv.reshape(-1, 2).astype(np.float32),
                                      err_msg=kind)
        for k, x in written.items():  # every time sample, the last frame's too
            np.testing.assert_array_equal(np.reshape(cache["frames"][k], (n, 3)), x,
                                          err_msg=f"{kind}: frame {k}")
        # between samples Blender interpolates, as the frames between written ones are
        mid = np.reshape(cache["frames"][1], (n, 3))
        assert np.all(np.minimum(written[0], written[2]) - 1e-6 <= mid)
        assert np.all(mid <= np.maximum(written[0], written[2]) + 1e-6)
