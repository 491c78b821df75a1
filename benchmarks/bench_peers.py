"""Peers on our scenes: Blender's own cloth and NVIDIA Newton's VBD beside clothtool, in one run.

    python -m benchmarks peers           # (under --full too; not in the default make bench)

Scenes (z up, gravity −9.81 m/s² along z, 30 fps; one mesh, vertex for vertex, for every
simulator):

- ``sheet``: a 64 × 64 grid, 1.1 m square, horizontal, held at the two corners of one edge,
  90 frames; the material of sample_data/hanging_sheet.yaml;
- ``drop``: a 48 × 48 grid, 0.9 m square, 0.2 m above a sphere of radius 0.25 m, self-collision
  on, collision and self-collision distances 2 mm, 60 frames; the material of
  sample_data/drape.yaml (friction 0.3 on the sphere, 0.2 cloth on cloth);
- ``twist``: sample_data/twist.yaml (ours) and Newton's own cloth-twist example (VBD with
  self-contact), 360 frames at 60 fps, where Newton installs.

Ours runs at the solver's defaults (after an untimed one-frame run that loads the kernels),
Blender at its cloth defaults (quality 5 steps per frame, ``benchmarks/peer_blender.py`` in
``.venv-bpy``), Newton's example as it comes (``benchmarks/peer_newton.py`` in
``.venv-newton``). Per row: the CPU time of the frames (every thread of the process), steps
per frame, crossing frames (``ipctk.has_intersections`` on every frame: cloth triangles
crossing each other or, on the drop, the sphere's; the sphere as Blender's UV sphere, 48
segments × 24 rings, whose vertices lie on it), on the drop the deepest vertex inside the
sphere, and on the sheet the sag (pin height − mean vertex height at the last frame) against
a tightly converged run of ours (BDF2, 4 steps per frame, Newton to 1e-4 m/s, PCG to 1e-6)
with the largest vertex distance to it at the last frame; the same at 2 steps per frame shows
how converged it is. The peers' materials are their defaults,
not ours: their sag differs by model as well as by solver error.

A peer that is not installed is a row saying so, with its install line. Writes ``peers.md``
and ``peers.csv``. The Python of a peer: ``BPY_PYTHON`` (default
``.venv-bpy/bin/python`` of this checkout), ``CLOTHTOOL_NEWTON_PYTHON`` (default
``.venv-newton/bin/python``).
"""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import markdown_table, write_csv

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
BLENDER_INSTALL = "python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy==5.0.1"
NEWTON_INSTALL = ("python3 -m venv .venv-newton && .venv-newton/bin/pip install newton "
                  "warp-lang usd-core")
SPHERE_SEGMENTS, SPHERE_RINGS = 48, 24
DISTANCE = 0.002  # m: collision and self-collision distances of the drop
# The converged sheet: BDF2 at 4 steps per frame, Newton to 1e-4 m/s (the default 0.04), PCG
# to 1e-6; about 5× the default's CPU time. Its check: the same at 2 steps per frame.
TIGHT = dict(integrator="bdf2", newton_iterations=60, newton_tolerance=1e-4, tolerance=1e-6,
             max_iterations=3000)
TIGHT_STEPS = (4, 2)
COLUMNS = ["scene", "simulator", "vertices", "frames", "CPU s", "× ours", "steps/frame",
           "Newton it/step", "crossing frames (ipctk)", "deepest in sphere mm", "sag m",
           "sag − converged mm", "max distance to converged mm", "note"]


def peer_python(env_name, venv):
    """The Python of a peer: ``$env_name``, else ``venv/bin/python`` of this checkout, or None
    when it is not there."""
    path = Path(os.environ.get(env_name, ROOT / venv / "bin" / "python"))
    return path if path.exists() else None


def scene(name, n=None, frames=None):
    """(our config dict, the scene's arrays for a peer) of ``sheet`` or ``drop``; ``n`` ×
    ``n`` vertices and ``frames`` frames instead of the scene's own (the tests' tiny runs)."""
    from clothtool.geometry import grid_triangles

    if name == "sheet":
        n_own, size, frames_own = 64, 1.1, 90
        material = {"density": 0.2, "stretch": 5000.0, "shear": 50.0, "bend": 1.0e-5,
                    "damping": 0.01}
        scene_cfg = {"pins": ["top_corners"]}
    elif name == "drop":
        n_own, size, frames_own = 48, 0.9, 60
        material = {"density": 0.2, "stretch": 1000.0, "shear": 100.0, "bend": 1.0e-5,
                    "damping": 0.01}
        scene_cfg = {"pins": [], "colliders": [{"sphere": {"center": [0.0, 0.0, -0.45],
                                                           "radius": 0.25, "friction": 0.3}}],
                     "collision_margin": DISTANCE,
                     "self_collision": {"thickness": DISTANCE, "friction": 0.2}}
    else:
        raise ValueError(name)
    n, frames = n or n_own, frames or frames_own
    config = {"mesh": {"grid": {"nx": n, "ny": n, "width": size, "height": size, "plane": "xy"}},
              "material": material, "scene": {"gravity": [0.0, 0.0, -9.81], **scene_cfg},
              "time": {"fps": 30, "frames": frames}}
    u = (np.arange(n) / (n - 1) - 0.5) * size
    vertices = np.zeros((n * n, 3))
    vertices[:, 0] = np.tile(u, n)
    vertices[:, 1] = np.repeat(u, n)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v00 = (j * n + i).ravel()
    arrays = {"vertices": vertices, "faces": grid_triangles(n, n),
              "quads": np.stack([v00, v00 + 1, v00 + n + 1, v00 + n], 1),
              "pins": np.array([(n - 1) * n, n * n - 1] if name == "sheet" else [], np.int64),
              "frames": frames, "fps": 30}
    if name == "drop":
        arrays.update(sphere=np.array([0.0, 0.0, -0.45, 0.25]), segments=SPHERE_SEGMENTS,
                      rings=SPHERE_RINGS, distance=DISTANCE)
    return config, arrays


def uv_sphere(center, radius, segments=SPHERE_SEGMENTS, rings=SPHERE_RINGS):
    """(vertices, triangles) of a UV sphere as Blender makes it: ``rings`` − 1 rings of
    ``segments`` vertices and two poles, every vertex on the sphere."""
    theta = np.pi * np.arange(1, rings) / rings
    phi = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.sin(theta)[:, None] * np.cos(phi), np.sin(theta)[:, None] * np.sin(phi),
                     np.cos(theta)[:, None] + 0.0 * phi], -1).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 0.0, 1.0]], ring, [[0.0, 0.0, -1.0]]]) * radius + center
    top, bottom = 0, len(vertices) - 1
    s = np.arange(segments)
    nxt = (s + 1) % segments
    faces = [np.stack([np.full(segments, top), 1 + s, 1 + nxt], 1)]
    for r in range(rings - 2):
        a, b = 1 + r * segments + s, 1 + r * segments + nxt
        c, d = a + segments, b + segments
        faces += [np.stack([a, c, d], 1), np.stack([a, d, b], 1)]
    last = 1 + (rings - 2) * segments
    faces.append(np.stack([last + s, np.full(segments, bottom), last + nxt], 1))
    return vertices, np.concatenate(faces).astype(np.int64)


def crossing_frames(positions, faces, obstacle=None):
    """Frames of ``positions`` (F, N, 3) in which triangles cross (ipctk.has_intersections),
    with the ``obstacle`` (vertices, triangles) beside the cloth."""
    import ipctk

    from clothtool.contact.broadphase import mesh_edges

    n = positions.shape[1]
    if obstacle is not None:
        faces = np.concatenate([faces, obstacle[1] + n])
    edges = mesh_edges(faces)
    count = 0
    for x in positions:
        y = x if obstacle is None else np.concatenate([x, obstacle[0]])
        count += bool(ipctk.has_intersections(ipctk.CollisionMesh(y, edges, faces), y))
    return count


def run_ours(config, out):
    """(positions (F + 1, N, 3), CPU s, steps per frame, Newton iterations per step) of our run
    of ``config``, after an untimed one-frame run (the kernels loaded or compiled)."""
    from clothtool.io.ply import read_ply
    from clothtool.sim.api import simulate

    simulate(config, output_dir=out / "warm", overrides={"time.frames": 1}, progress=False)
    started = time.process_time()
    result = simulate(config, output_dir=out / "run", progress=False)
    cpu = time.process_time() - started
    frames = sorted((out / "run").glob("frame_*.ply"))
    positions = np.stack([read_ply(p).vertices for p in frames])
    steps = max(result.steps, 1)
    return positions, cpu, result.steps / (len(frames) - 1), result.newton_iterations / steps


def run_peer(python, script, arrays, tmp):
    """The peer's OUT.npz as a dict (``script`` run with ``python`` on ``arrays``)."""
    spec, out = tmp / "peer_scene.npz", tmp / "peer_out.npz"
    np.savez(spec, **arrays)
    subprocess.run([str(python), str(script), str(spec), str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    return dict(np.load(out))


def sag(positions, pins):
    """Pin height − mean vertex height (m) at the last frame (z up)."""
    return float(positions[-1, pins, 2].mean() - positions[-1, :, 2].mean())


def scene_rows(name, tmp, blender, n=None, frames=None):
    """Our row and Blender's (or its skip row) on ``name`` (:func:`scene`), measured one after
    the other; on the sheet, our converged run's row too."""
    config, arrays = scene(name, n, frames)
    obstacle = None
    if name == "drop":
        obstacle = uv_sphere(arrays["sphere"][:3], arrays["sphere"][3])
    frames = arrays["frames"]
    runs = []
    x, cpu, steps, newton = run_ours(config, tmp / f"{name}_ours")
    runs.append({"simulator": "clothtool (defaults)", "positions": x, "CPU s": cpu,
                 "steps/frame": steps, "Newton it/step": newton})
    if blender is None:
        runs.append({"simulator": "Blender cloth", "note": f"not installed: {BLENDER_INSTALL}"})
    else:
        out = run_peer(blender, HERE / "peer_blender.py", arrays, tmp)
        runs.append({"simulator": "Blender cloth (defaults)", "positions": out["positions"],
                     "CPU s": float(out["cpu"]), "steps/frame": int(out["quality"])})
    reference = None
    if name == "sheet":
        for steps in TIGHT_STEPS:
            x, cpu, _, newton = run_ours({**config, "solver": {**TIGHT, "substeps": steps}},
                                         tmp / f"{name}_tight{steps}")
            reference = x if reference is None else reference
            runs.append({"simulator": f"clothtool, BDF2 ×{steps} solved tightly"
                         + (" (converged)" if steps == TIGHT_STEPS[0] else ""),
                         "positions": x, "CPU s": cpu, "steps/frame": steps,
                         "Newton it/step": newton})
    rows = []
    for run in runs:
        row = {"scene": name, "vertices": len(arrays["vertices"]), "frames": frames,
               **{k: v for k, v in run.items() if k != "positions"}}
        x = run.get("positions")
        if x is not None:
            crossing = crossing_frames(x, arrays["faces"], obstacle)
            row["crossing frames (ipctk)"] = f"{crossing}/{len(x)}"
            if obstacle is not None:
                centre, radius = arrays["sphere"][:3], arrays["sphere"][3]
                depth = radius - np.linalg.norm(x - centre, axis=2).min()
                row["deepest in sphere mm"] = 1e3 * max(float(depth), 0.0)
            if reference is not None:
                row["sag m"] = sag(x, arrays["pins"])
                row["sag − converged mm"] = 1e3 * (row["sag m"] - sag(reference, arrays["pins"]))
                row["max distance to converged mm"] = 1e3 * float(
                    np.linalg.norm(x[-1] - reference[-1], axis=1).max())
        rows.append(row)
    return rows


def twist_rows(tmp, newton):
    """Ours and Newton's VBD (or its skip row) on the twist."""
    from clothtool.sim.model.builder import build_model
    from clothtool.sim.model.config import load_config

    config = ROOT / "sample_data" / "twist.yaml"
    x, cpu, steps, its = run_ours(config, tmp / "twist_ours")
    faces = build_model(load_config(config)).faces
    rows = [{"scene": "twist", "simulator": "clothtool (sample_data/twist.yaml)",
             "vertices": x.shape[1], "frames": len(x) - 1, "CPU s": cpu, "steps/frame": steps,
             "Newton it/step": its,
             "crossing frames (ipctk)": f"{crossing_frames(x, faces)}/{len(x)}"}]
    if newton is None:
        rows.append({"scene": "twist", "simulator": "NVIDIA Newton VBD",
                     "note": f"not installed: {NEWTON_INSTALL}"})
        return rows
    out = run_peer(newton, HERE / "peer_newton.py", {"frames": len(x) - 1}, tmp)
    y = out["positions"]
    rows.append({"scene": "twist", "simulator": f"NVIDIA Newton VBD ({int(out['iterations'])} "
                 "iterations per step)", "vertices": y.shape[1], "frames": len(y) - 1,
                 "CPU s": float(out["cpu"]), "steps/frame": int(out["substeps"]),
                 "crossing frames (ipctk)": f"{crossing_frames(y, out['faces'])}/{len(y)}"})
    return rows


def ratios(rows):
    """Each row's CPU time over ours on the same scene (``× ours``)."""
    ours = {r["scene"]: r["CPU s"] for r in rows if r["simulator"].startswith("clothtool (")}
    for r in rows:
        if isinstance(r.get("CPU s"), float) and r["scene"] in ours:
            r["× ours"] = r["CPU s"] / ours[r["scene"]]
    return rows


def write_tables(rows, out_dir):
    """``peers.md`` and ``peers.csv`` in ``out_dir``; returns the Markdown."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_csv(out_dir / "peers.csv", rows, COLUMNS)
    text = ("## Peers on our scenes: Blender's cloth and NVIDIA Newton's VBD (bench_peers.py)\n\n"
            "In one run, z up, 30 fps (the twist 60). `sheet`: 64 × 64, 1.1 m, held at two "
            "corners, 90 frames; `drop`: 48 × 48, 0.9 m, 0.2 m above a sphere of radius 0.25 m, "
            "self-collision at 2 mm, 60 frames; `twist`: sample_data/twist.yaml and Newton's "
            "cloth-twist example. `CPU s`: the frames' CPU time, every thread; `× ours`: over "
            "ours on the scene. Crossing frames: ipctk.has_intersections on every frame (the "
            "rest state included), cloth with itself and, on the drop, with Blender's UV sphere. "
            "`sag`: pin height − mean height at the last frame, against ours solved tightly at "
            "4 steps per frame (Newton to 1e-4 m/s, PCG to 1e-6; the same at 2 steps per frame "
            "shows how converged that is). Peers run at their own default materials. Written by "
            "`python -m benchmarks peers`.\n\n" + markdown_table(rows, COLUMNS))
    (out_dir / "peers.md").write_text(text)
    return text


def run(out_dir):
    blender = peer_python("BPY_PYTHON", ".venv-bpy")
    newton = peer_python("CLOTHTOOL_NEWTON_PYTHON", ".venv-newton")
    rows = []
    with tempfile.TemporaryDirectory(prefix="clothtool-peers-") as tmp:
        for name in ("sheet", "drop"):
            rows += scene_rows(name, Path(tmp), blender)
            print(write_tables(ratios(rows), out_dir), flush=True)  # the table so far
        rows += twist_rows(Path(tmp), newton)
    print(write_tables(ratios(rows), out_dir))


if __name__ == "__main__":
    run(sys.argv[1] if len(sys.argv) > 1 else "bench-results")
