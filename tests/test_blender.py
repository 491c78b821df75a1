"""Frames opened by real Blender: headless ``blender -b`` (a subprocess) imports an OBJ frame
of a simulation with its Wavefront importer, and the run's MDD point cache through a Mesh
Cache modifier on its base mesh; vertex count, faces, uv per corner, positions and the time
samples (the cache played at another frame rate than the run's) are compared with ours.

Needs ``blender`` on PATH (or in $BLENDER); without it the test is skipped. Debian/Ubuntu:
``apt-get install --no-install-recommends blender`` (Debian 12 has 3.4.1, built without
Alembic and USD: hence the MDD cache).
"""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import clothtool
from clothtool.io.obj import read_obj
from clothtool.io.ply import read_ply

INSTALL = ("needs Blender (Debian/Ubuntu: apt-get install --no-install-recommends blender; "
           "or set BLENDER to its path)")
FPS, FRAMES, EVERY, PLAY_FPS = 30, 6, 2, 60

# Run by Blender: argv after "--" = the OBJ frame, the cache's base mesh, the cache, the scene
# fps, the last scene frame and the JSON file to write. Blender's Python has no numpy here.
PROBE = r'''
import json, sys
import bpy

frame_obj, base_obj, cache, fps, last, out = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)


def imported(path):
    bpy.ops.wm.obj_import(filepath=path)
    (ob,) = bpy.context.selected_objects
    return ob


def positions(mesh):
    co = [0.0] * (3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", co)
    return co


ob = imported(frame_obj)
me = ob.data
uv = me.uv_layers.active.data
result = {"version": bpy.app.version_string,
          "alembic": bpy.app.build_options.alembic, "usd": bpy.app.build_options.usd,
          "vertices": len(me.vertices), "positions": positions(me),
          "loops": [[me.loops[i].vertex_index for i in p.loop_indices] for p in me.polygons],
          "uv": [[list(uv[i].uv) for i in p.loop_indices] for p in me.polygons],
          "uv_layers": len(me.uv_layers)}
base = imported(base_obj)
scene = bpy.context.scene
scene.render.fps = int(fps)
modifier = base.modifiers.new("cache", "MESH_CACHE")
modifier.cache_format = "MDD"
modifier.filepath = cache
modifier.time_mode = "TIME"
frames = []
for f in range(int(last) + 1):
    scene.frame_set(f)
    evaluated = base.evaluated_get(bpy.context.evaluated_depsgraph_get())
    frames.append(positions(evaluated.to_mesh()))
    evaluated.to_mesh_clear()
result["cache"] = {"vertices": len(base.data.vertices), "frames": frames}
json.dump(result, open(out, "w"))
'''


def blender():
    found = os.environ.get("BLENDER") or shutil.which("blender")
    if not found:
        pytest.skip(INSTALL)
    return found


def run_blender(tmp_path, *args):
    script, out = tmp_path / "probe.py", tmp_path / "blender.json"
    script.write_text(PROBE)
    proc = subprocess.run([blender(), "-b", "--factory-startup", "--python-exit-code", "1",
                           "--python", str(script), "--", *map(str, args), str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and out.is_file(), proc.stdout[-3000:] + proc.stderr[-3000:]
    return json.loads(out.read_text())


def test_blender_imports_the_obj_frame_and_plays_the_cache(tmp_path, capsys):
    blender()
    run = tmp_path / "run"
    config = {"mesh": {"grid": {"nx": 9, "ny": 6, "width": 0.8, "height": 0.5, "plane": "xz"}},
              "scene": {"pins": ["top_corners"], "gravity": [0, 0, -9.81]},
              "time": {"frames": FRAMES, "fps": FPS},
              "output": {"format": ["ply", "obj", "mdd"], "every": EVERY}}
    clothtool.simulate(config, output_dir=run, progress=False)
    last = FRAMES * PLAY_FPS // FPS
    got = run_blender(tmp_path, run / "obj" / f"frame_{FRAMES:05d}.obj", run / "cache" / "cloth.obj",
                      run / "cache" / "cloth.mdd", PLAY_FPS, last)
    with capsys.disabled():
        print(f"\nBlender {got['version']}: alembic {got['alembic']}, usd {got['usd']}")

    ours = read_obj(run / "obj" / f"frame_{FRAMES:05d}.obj")
    n = len(ours.vertices)
    assert got["vertices"] == n and got["uv_layers"] == 1
    np.testing.assert_array_equal(np.reshape(got["positions"], (n, 3)), ours.vertices.astype(np.float32))
    assert got["loops"] == ours.faces.tolist()  # same triangles, same corner order
    np.testing.assert_array_equal(np.array(got["uv"], np.float32), ours.corner_uv.astype(np.float32))

    # the samples at their times: frame f of the 60 fps scene is t = f/60 s; Blender
    # interpolates linearly between the samples around t
    written = [read_ply(run / f"frame_{k:05d}.ply").vertices for k in range(0, FRAMES + 1, EVERY)]
    sample_times = np.arange(0, FRAMES + 1, EVERY) / FPS
    assert got["cache"]["vertices"] == n and len(got["cache"]["frames"]) == last + 1
    for f, played in enumerate(got["cache"]["frames"]):
        t = f / PLAY_FPS
        k = min(int(np.searchsorted(sample_times, t, side="right")) - 1, len(written) - 2)
        a = (t - sample_times[k]) / (sample_times[k + 1] - sample_times[k])
        expected = (1 - a) * written[k] + a * written[k + 1]
        np.testing.assert_allclose(np.reshape(played, (n, 3)), expected, rtol=0, atol=2e-7,
                                   err_msg=f"scene frame {f}")
        if a == 0:  # a sample's own time: its positions exactly (as float32)
            np.testing.assert_array_equal(np.reshape(played, (n, 3)),
                                          written[k].astype(np.float32))
